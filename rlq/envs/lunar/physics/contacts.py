"""Leg and hull contacts with the terrain, and the leg contacts' part of the solver.

Manifolds come from ``rlq.envs.lunar.physics.collide``; each leg is tested against the (at most) two
terrain edges under it. Velocity constraints follow b2ContactSolver: friction first, then the
normal impulses, sequentially per point or with the 2-point block solver; warm starting carries
impulses of matching contact features from step to step. Only the legs respond physically: a
hull contact ends the episode, so the hull is only tested for touching.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.physics.body import (
    F32,
    HULL_CENTROID,
    HULL_NORMALS,
    HULL_VERTS,
    INV_I,
    INV_MASS,
    LEG_NORMALS,
    LEG_VERTS,
    LOCAL_CENTER,
    cross_vs,
    cross_vv,
)
from rlq.envs.lunar.physics.collide import Manifold, collide, position_points, rotate, world_points

NUM_EDGES = C.CHUNKS - 1


def _leg_candidates(c: jax.Array, a: jax.Array) -> jax.Array:
    """The (at most) two terrain edges each leg can touch: (2 legs, 2 slots) edge indices."""
    xs = c[1:, None, 0] + rotate(a[1:, None], LEG_VERTS[None])[..., 0]
    k0 = jnp.floor((xs.min(-1) - C.CONTACT_RADIUS) / (C.W / NUM_EDGES)).astype(jnp.int32)
    k0 = jnp.clip(k0, 0, NUM_EDGES - 1)
    return jnp.stack([k0, jnp.minimum(k0 + 1, NUM_EDGES - 1)], axis=-1)


def leg_manifolds(
    c: jax.Array, a: jax.Array, v1: jax.Array, v2: jax.Array, idx: jax.Array | None = None
) -> tuple[Manifold, jax.Array]:
    """Manifolds (2 legs, 2 slots) and their edge indices (by default the edges under each leg);
    a repeated edge slot is invalid."""
    idx = _leg_candidates(c, a) if idx is None else idx
    origin = c[1:]  # legs' origins are their centres

    def one(o, ang, k):
        return collide(LEG_VERTS, LEG_NORMALS, jnp.zeros(2, F32), o, ang, v1[k], v2[k])

    m = jax.vmap(jax.vmap(one, in_axes=(None, None, 0)))(origin, a[1:], idx)
    dup = jnp.stack([jnp.zeros(2, bool), idx[:, 1] == idx[:, 0]], axis=-1)
    return m.replace(valid=m.valid & ~dup[..., None]), idx


def hull_manifolds(c: jax.Array, a: jax.Array, v1: jax.Array, v2: jax.Array) -> Manifold:
    origin = c[0] - rotate(a[0], LOCAL_CENTER[0])
    return jax.vmap(lambda p, q: collide(HULL_VERTS, HULL_NORMALS, HULL_CENTROID, origin, a[0], p, q))(v1, v2)


def scatter_touching(m: Manifold, idx: jax.Array) -> jax.Array:
    touching = jnp.any(m.valid, axis=-1)
    out = jnp.zeros((2, NUM_EDGES), bool)
    legs = jnp.broadcast_to(jnp.arange(2)[:, None], idx.shape)
    return out.at[legs, idx].max(touching)


class ContactConst(struct.PyTreeNode):
    """Per leg contact point (2 legs × 4 points: 2 candidate edges × 2 manifold points)."""

    valid: jax.Array  # (2 legs, 4 points)
    r: jax.Array  # (2, 4, 2) lever arms from the legs' centres
    n: jax.Array  # (2, 4, 2) normals (ground -> leg)
    normal_mass: jax.Array  # (2, 4)
    tangent_mass: jax.Array  # (2, 4)
    block: jax.Array  # (2, 2) slot uses Box2D's 2-point block solver
    k_block: jax.Array  # (2, 2, 3) k11, k12, k22 of each slot's 2-point normal system


def constants(m: Manifold, c: jax.Array, a: jax.Array, block_solve: bool) -> ContactConst:
    origin = c[1:]
    normal, points, _ = jax.vmap(jax.vmap(world_points, in_axes=(0, None, None)))(m, origin, a[1:])
    n = jnp.broadcast_to(normal[:, :, None, :], points.shape).reshape(2, 4, 2)
    r = (points - origin[:, None, None, :]).reshape(2, 4, 2)
    im, ii = INV_MASS[1], INV_I[1]
    rn = cross_vv(r, n)
    t = jnp.stack([n[..., 1], -n[..., 0]], -1)
    rt = cross_vv(r, t)
    kn = im + ii * rn**2
    kt = im + ii * rt**2
    valid = m.valid.reshape(2, 4)
    rn_s = rn.reshape(2, 2, 2)
    k11 = im + ii * rn_s[..., 0] ** 2
    k22 = im + ii * rn_s[..., 1] ** 2
    k12 = im + ii * rn_s[..., 0] * rn_s[..., 1]
    both = jnp.all(m.valid, axis=-1)
    well_conditioned = k11 * k11 < 1000.0 * (k11 * k22 - k12 * k12)
    block = both & well_conditioned & block_solve
    # an ill-conditioned pair is solved as one point (Box2D drops the second)
    drop = both & ~well_conditioned
    valid = valid & ~jnp.stack([jnp.zeros_like(drop), drop], -1).reshape(2, 4)
    return ContactConst(
        valid=valid,
        r=r,
        n=n,
        normal_mass=jnp.where(kn > 0, 1.0 / kn, 0.0),
        tangent_mass=jnp.where(kt > 0, 1.0 / kt, 0.0),
        block=block,
        k_block=jnp.stack([k11, k12, k22], -1),
    )


def solve_velocity(vl, wl, pn, pt, cc: ContactConst):
    """One velocity sweep over the leg contacts; the two legs are independent and run together."""
    im, ii = INV_MASS[1], INV_I[1]
    mu = C.LEG_GROUND_FRICTION

    def apply(vl, wl, i, lam_vec):
        return vl + im * lam_vec, wl + ii * cross_vv(cc.r[:, i], lam_vec)

    for s in range(2):
        for i in (2 * s, 2 * s + 1):
            t = jnp.stack([cc.n[:, i, 1], -cc.n[:, i, 0]], -1)
            dv = vl + cross_vs(wl, cc.r[:, i])
            lam = cc.tangent_mass[:, i] * -jnp.sum(dv * t, -1)
            max_f = mu * pn[:, i]
            new = jnp.clip(pt[:, i] + lam, -max_f, max_f)
            lam = jnp.where(cc.valid[:, i], new - pt[:, i], 0.0)
            pt = pt.at[:, i].set(jnp.where(cc.valid[:, i], new, pt[:, i]))
            vl, wl = apply(vl, wl, i, lam[:, None] * t)
        vl, wl, pn = _solve_normals(vl, wl, pn, cc, s)
    return vl, wl, pn, pt


def block_impulses(k11, k12, k22, a0, a1, vn0, vn1):
    """The 2-point block solver's new normal impulses (b2ContactSolver's total enumeration of the
    LCP): ``k`` the pair's effective-mass matrix, ``a0, a1`` the accumulated impulses, ``vn0, vn1``
    the normal velocities. Where no case holds, the impulses stay."""
    b0 = vn0 - (k11 * a0 + k12 * a1)
    b1 = vn1 - (k12 * a0 + k22 * a1)
    det = k11 * k22 - k12 * k12
    safe = jnp.where(det != 0, det, 1.0)
    x0_full = -(k22 * b0 - k12 * b1) / safe
    x1_full = -(k11 * b1 - k12 * b0) / safe
    x0_first = -b0 / k11
    vn1_first = k12 * x0_first + b1
    x1_second = -b1 / k22
    vn0_second = k12 * x1_second + b0
    case1 = (x0_full >= 0) & (x1_full >= 0)
    case2 = (x0_first >= 0) & (vn1_first >= 0)
    case3 = (x1_second >= 0) & (vn0_second >= 0)
    case4 = (b0 >= 0) & (b1 >= 0)
    x0 = jnp.where(case1, x0_full, jnp.where(case2, x0_first, jnp.where(case3, 0.0, 0.0)))
    x1 = jnp.where(case1, x1_full, jnp.where(case2, 0.0, jnp.where(case3, x1_second, 0.0)))
    solved = case1 | case2 | case3 | case4
    x0 = jnp.where(solved, x0, a0)
    x1 = jnp.where(solved, x1, a1)
    return x0, x1


def _solve_normals(vl, wl, pn, cc: ContactConst, s: int):
    """Normal impulses of slot ``s``: sequential per point, or Box2D's 2-point block solver."""
    im, ii = INV_MASS[1], INV_I[1]
    i0, i1 = 2 * s, 2 * s + 1
    # sequential
    vl_s, wl_s, pn_s = vl, wl, pn
    for i in (i0, i1):
        n = cc.n[:, i]
        dv = vl_s + cross_vs(wl_s, cc.r[:, i])
        lam = -cc.normal_mass[:, i] * jnp.sum(dv * n, -1)
        new = jnp.maximum(pn_s[:, i] + lam, 0.0)
        lam = jnp.where(cc.valid[:, i], new - pn_s[:, i], 0.0)
        pn_s = pn_s.at[:, i].set(jnp.where(cc.valid[:, i], new, pn_s[:, i]))
        vl_s = vl_s + im * lam[:, None] * n
        wl_s = wl_s + ii * lam * cross_vv(cc.r[:, i], n)
    # block (b2ContactSolver's total enumeration of the 2-point LCP)
    n = cc.n[:, i0]
    r0, r1 = cc.r[:, i0], cc.r[:, i1]
    k11, k12, k22 = cc.k_block[:, s, 0], cc.k_block[:, s, 1], cc.k_block[:, s, 2]
    a0, a1 = pn[:, i0], pn[:, i1]
    vn0 = jnp.sum((vl + cross_vs(wl, r0)) * n, -1)
    vn1 = jnp.sum((vl + cross_vs(wl, r1)) * n, -1)
    x0, x1 = block_impulses(k11, k12, k22, a0, a1, vn0, vn1)
    d0, d1 = x0 - a0, x1 - a1
    p = (d0 + d1)[:, None] * n
    vl_b = vl + im * p
    wl_b = wl + ii * (cross_vv(r0, d0[:, None] * n) + cross_vv(r1, d1[:, None] * n))
    pn_b = pn.at[:, i0].set(x0).at[:, i1].set(x1)
    blk = cc.block[:, s]
    vl = jnp.where(blk[:, None], vl_b, vl_s)
    wl = jnp.where(blk, wl_b, wl_s)
    pn = jnp.where(blk[:, None], pn_b, pn_s)
    return vl, wl, pn


def warm_impulses(keys: jax.Array, impulses: jax.Array, m: Manifold, idx: jax.Array) -> jax.Array:
    """Impulses (2 legs, 2 slots, 2 points, 2) carried over from matching contact features."""
    old_key = keys[jnp.arange(2)[:, None], idx]  # (2, 2 slots, 2 old points)
    old_imp = impulses[jnp.arange(2)[:, None], idx]  # (2, 2, 2 old, 2)
    match = (m.key[..., :, None] == old_key[..., None, :]) & (old_key[..., None, :] >= 0)
    warm = jnp.sum(match.astype(F32)[..., None] * old_imp[:, :, None], axis=-2)
    return jnp.where(m.valid[..., None], warm, 0.0)


def store_impulses(m: Manifold, idx: jax.Array, pn: jax.Array, pt: jax.Array):
    imp = jnp.stack([pn, pt], -1).reshape(2, 2, 2, 2) * m.valid[..., None]
    legs = jnp.broadcast_to(jnp.arange(2)[:, None], idx.shape)
    store = jnp.zeros((2, NUM_EDGES, 2, 2), F32).at[legs, idx].add(imp)
    key = jnp.where(m.valid, m.key, -1)
    keys = jnp.full((2, NUM_EDGES, 2), -1, jnp.int32).at[legs, idx].max(key)
    return store, keys


def position_pass(c: jax.Array, a: jax.Array, m: Manifold, baumgarte: float = C.BAUMGARTE):
    """One position sweep over the leg contacts (b2ContactSolver::SolvePositionConstraints);
    also returns each leg's smallest separation before correction."""
    im_l, ii_l = INV_MASS[1], INV_I[1]
    min_sep = jnp.zeros(2, F32)
    cl, al = c[1:], a[1:]
    for s in range(2):
        ms = jax.tree.map(lambda x, s=s: x[:, s], m)
        for j in range(2):
            n, points, sep = jax.vmap(position_points)(ms, cl, al)
            p, sp = points[:, j], sep[:, j]
            ok = ms.valid[:, j]
            r = p - cl
            min_sep = jnp.minimum(min_sep, jnp.where(ok, sp, 0.0))
            corr = jnp.clip(baumgarte * (sp + C.LINEAR_SLOP), -C.MAX_LINEAR_CORRECTION, 0.0)
            k = im_l + ii_l * cross_vv(r, n) ** 2
            lam = jnp.where(ok & (k > 0), -corr / jnp.where(k > 0, k, 1.0), 0.0)
            pvec = lam[:, None] * n
            cl = cl + im_l * pvec
            al = al + ii_l * cross_vv(r, pvec)
    return c.at[1:].set(cl), a.at[1:].set(al), min_sep
