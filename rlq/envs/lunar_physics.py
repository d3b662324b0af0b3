"""Rigid-body physics of the lander (hull + two legs) on a polyline terrain, in pure JAX.

The model mirrors what Box2D 2.3 does inside Gymnasium's ``world.Step(1/FPS, 180, 60)``:

1. collide: contact manifolds (legs and hull against the terrain edges) at the current positions,
   with begin/end contact events for the leg flags and the crash flag;
2. integrate velocities (gravity, external force and torque);
3. sequential impulses: warm start, then ``velocity_iterations`` sweeps over the two revolute
   joints (motor, angle limit, point constraint) and the leg contacts (friction, then normal);
4. integrate positions (symplectic Euler);
5. ``position_iterations`` non-linear Gauss-Seidel sweeps (contacts, then joints) that stop as
   soon as penetration and joint drift are within Box2D's slops;
6. sleep: every body slower than the sleep tolerances for 0.5 s puts the lander to rest;
7. continuous collision, reduced to its observable effect: a contact that would otherwise be
   tunnelled into within the step begins now (Box2D's time-of-impact begin event).

Only the legs collide physically; any hull contact ends the episode (Gymnasium's game over), so
the hull only needs contact detection. Body 0 is the hull, bodies 1 and 2 are Gymnasium's
``legs[0]`` and ``legs[1]``; joint ``j`` connects the hull to leg ``j``.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
from flax import struct

from rlq.envs import lunar_consts as C
from rlq.envs.lunar_collide import Manifold, collide, position_points, rotate, world_points

NUM_EDGES = C.CHUNKS - 1
F32 = jnp.float32


@dataclass(frozen=True)
class SolverConfig:
    """Box2D's defaults in Gymnasium: 6 × 30 velocity and 2 × 30 position iterations."""

    velocity_iterations: int = 180
    position_iterations: int = 60
    gravity: float = -10.0
    dt: float = 1.0 / C.FPS
    warm_start: bool = True
    block_solve: bool = True


@struct.dataclass
class PhysicsState:
    """Bodies (hull, legs[0], legs[1]) and the solver's memory between steps."""

    c: jax.Array  # (3, 2) centres of mass
    a: jax.Array  # (3,) angles
    v: jax.Array  # (3, 2) linear velocities of the centres of mass
    w: jax.Array  # (3,) angular velocities
    sleep_time: jax.Array  # (3,)
    joint_impulse: jax.Array  # (2, 3) accumulated point (x, y) and limit impulses
    motor_impulse: jax.Array  # (2,)
    limit_state: jax.Array  # (2,) int: 0 inactive, 1 at lower, 2 at upper limit
    leg_touching: jax.Array  # (2, NUM_EDGES) bool: leg/edge contacts touching
    hull_touching: jax.Array  # (NUM_EDGES,) bool
    contact_key: jax.Array  # (2, NUM_EDGES, 2) int: feature ids of the stored impulses
    contact_impulse: jax.Array  # (2, NUM_EDGES, 2, 2) (normal, tangent) per contact point
    #: contacts at the current positions (what the next step's collide phase sees)
    manifold: Manifold | None = None  # (2 legs, 2 candidate edges)
    manifold_edges: jax.Array | None = None  # (2, 2) edge index of each candidate
    hull_contact: jax.Array | None = None  # (NUM_EDGES,) hull manifolds with points


@struct.dataclass
class StepEvents:
    """What Gymnasium's contact listener and ``lander.awake`` would report for one step."""

    leg_begin: jax.Array  # (2,) a contact of the leg began (collide or time of impact)
    leg_end: jax.Array  # (2,) a contact of the leg ended (collide)
    leg_toi_begin: jax.Array  # (2,) a contact began during continuous collision (after collide)
    hull_begin: jax.Array  # () a hull contact began: game over
    asleep: jax.Array  # () the lander came to rest
    leg_touching: jax.Array  # (2,) any leg contact touching at the start of the step


# ---- constants as float32 arrays ------------------------------------------------------------
INV_MASS = jnp.asarray(C.INV_MASS, F32)
INV_I = jnp.asarray(C.INV_INERTIA, F32)
LOCAL_CENTER = jnp.asarray(C.LOCAL_CENTER, F32)
HULL_VERTS = jnp.asarray(C.HULL_VERTS, F32)
HULL_NORMALS = jnp.asarray(C.HULL_NORMALS, F32)
LEG_VERTS = jnp.asarray(C.LEG_VERTS, F32)
LEG_NORMALS = jnp.asarray(C.LEG_NORMALS, F32)
HULL_CENTROID = jnp.asarray(C.HULL_CENTER, F32)
ANCHOR_A = jnp.asarray(C.ANCHOR_HULL, F32) - LOCAL_CENTER[0]
ANCHOR_B = jnp.asarray(C.ANCHOR_LEG, F32)
LOWER = jnp.asarray(C.LEG_LOWER, F32)
UPPER = jnp.asarray(C.LEG_UPPER, F32)
MOTOR_SPEED = jnp.asarray(C.LEG_MOTOR_SPEED, F32)
REFERENCE = jnp.asarray(C.LEG_REFERENCE_ANGLE, F32)
#: Box2D's island order: legs[1]'s joint is solved before legs[0]'s.
JOINT_ORDER = (1, 0)


def cross_vs(w: jax.Array, r: jax.Array) -> jax.Array:
    """Scalar × vector cross product: w k × r."""
    return jnp.stack([-w * r[..., 1], w * r[..., 0]], axis=-1)


def cross_vv(a: jax.Array, b: jax.Array) -> jax.Array:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def origins(c: jax.Array, a: jax.Array) -> jax.Array:
    """Body origins (Box2D ``body.position``) from centres of mass."""
    return c - rotate(a, LOCAL_CENTER)


def initial_state(origin: jax.Array, angle: jax.Array, v1: jax.Array, v2: jax.Array) -> PhysicsState:
    """Bodies at rest at the given origins (3, 2) and angles (3,) above terrain edges ``v1``-``v2``."""
    origin = jnp.asarray(origin, F32)
    angle = jnp.asarray(angle, F32)
    ps = PhysicsState(
        c=origin + rotate(angle, LOCAL_CENTER),
        a=angle,
        v=jnp.zeros((3, 2), F32),
        w=jnp.zeros(3, F32),
        sleep_time=jnp.zeros(3, F32),
        joint_impulse=jnp.zeros((2, 3), F32),
        motor_impulse=jnp.zeros(2, F32),
        limit_state=jnp.zeros(2, jnp.int32),
        leg_touching=jnp.zeros((2, NUM_EDGES), bool),
        hull_touching=jnp.zeros(NUM_EDGES, bool),
        contact_key=jnp.full((2, NUM_EDGES, 2), -1, jnp.int32),
        contact_impulse=jnp.zeros((2, NUM_EDGES, 2, 2), F32),
    )
    return _with_contacts(ps, v1, v2)


def _with_contacts(ps: PhysicsState, v1: jax.Array, v2: jax.Array) -> PhysicsState:
    m, idx = leg_manifolds(ps.c, ps.a, v1, v2)
    hull = jnp.any(hull_manifolds(ps.c, ps.a, v1, v2).valid, -1)
    return ps.replace(manifold=m, manifold_edges=idx, hull_contact=hull)


# ---- collision --------------------------------------------------------------------------------
def _leg_candidates(c: jax.Array, a: jax.Array) -> jax.Array:
    """The (at most) two terrain edges each leg can touch: (2 legs, 2 slots) edge indices."""
    xs = c[1:, None, 0] + rotate(a[1:, None], LEG_VERTS[None])[..., 0]
    k0 = jnp.floor((xs.min(-1) - C.CONTACT_RADIUS) / (C.W / NUM_EDGES)).astype(jnp.int32)
    k0 = jnp.clip(k0, 0, NUM_EDGES - 1)
    return jnp.stack([k0, jnp.minimum(k0 + 1, NUM_EDGES - 1)], axis=-1)


def leg_manifolds(c: jax.Array, a: jax.Array, v1: jax.Array, v2: jax.Array) -> tuple[Manifold, jax.Array]:
    """Manifolds (2 legs, 2 slots) and their edge indices; a repeated edge slot is invalid."""
    idx = _leg_candidates(c, a)
    origin = c[1:]  # legs' origins are their centres

    def one(o, ang, k):
        return collide(LEG_VERTS, LEG_NORMALS, jnp.zeros(2, F32), o, ang, v1[k], v2[k])

    m = jax.vmap(jax.vmap(one, in_axes=(None, None, 0)))(origin, a[1:], idx)
    dup = jnp.stack([jnp.zeros(2, bool), idx[:, 1] == idx[:, 0]], axis=-1)
    return m.replace(valid=m.valid & ~dup[..., None]), idx


def hull_manifolds(c: jax.Array, a: jax.Array, v1: jax.Array, v2: jax.Array) -> Manifold:
    origin = c[0] - rotate(a[0], LOCAL_CENTER[0])
    return jax.vmap(lambda p, q: collide(HULL_VERTS, HULL_NORMALS, HULL_CENTROID, origin, a[0], p, q))(v1, v2)


def _scatter_touching(m: Manifold, idx: jax.Array) -> jax.Array:
    touching = jnp.any(m.valid, axis=-1)
    out = jnp.zeros((2, NUM_EDGES), bool)
    legs = jnp.broadcast_to(jnp.arange(2)[:, None], idx.shape)
    return out.at[legs, idx].max(touching)


# ---- solver pieces ----------------------------------------------------------------------------
def _solve22(k11, k12, k21, k22, b0, b1):
    det = k11 * k22 - k12 * k21
    det = jnp.where(det != 0, 1.0 / jnp.where(det != 0, det, 1.0), 0.0)
    return det * (k22 * b0 - k12 * b1), det * (k11 * b1 - k21 * b0)


def _solve33(k, b):
    ex, ey, ez = k[0], k[1], k[2]  # columns
    det = jnp.dot(ex, jnp.cross(ey, ez))
    det = jnp.where(det != 0, 1.0 / jnp.where(det != 0, det, 1.0), 0.0)
    return det * jnp.stack([jnp.dot(b, jnp.cross(ey, ez)), jnp.dot(ex, jnp.cross(b, ez)), jnp.dot(ex, jnp.cross(ey, b))])


def _joint_mass(ra: jax.Array, rb: jax.Array, leg: int) -> jax.Array:
    """Columns (ex, ey, ez) of the revolute joint's 3 × 3 effective-mass matrix K."""
    ma, mb, ia, ib = INV_MASS[0], INV_MASS[leg + 1], INV_I[0], INV_I[leg + 1]
    exx = ma + mb + ra[1] ** 2 * ia + rb[1] ** 2 * ib
    eyx = -ra[1] * ra[0] * ia - rb[1] * rb[0] * ib
    ezx = -ra[1] * ia - rb[1] * ib
    eyy = ma + mb + ra[0] ** 2 * ia + rb[0] ** 2 * ib
    ezy = ra[0] * ia + rb[0] * ib
    ezz = ia + ib
    return jnp.stack([jnp.stack([exx, eyx, ezx]), jnp.stack([eyx, eyy, ezy]), jnp.stack([ezx, ezy, ezz])])


def _solve_joint(j: int, vel, jstate, jconst, dt: float):
    """One velocity sweep of revolute joint ``j`` (b2RevoluteJoint::SolveVelocityConstraints)."""
    v, w = vel
    impulse, motor = jstate
    ra, rb, k, limit_state = jconst
    b = j + 1
    ma, mb, ia, ib = INV_MASS[0], INV_MASS[b], INV_I[0], INV_I[b]
    va, wa, vb, wb = v[0], w[0], v[b], w[b]

    cdot = wb - wa - MOTOR_SPEED[j]
    lam = -cdot / (ia + ib)
    max_imp = dt * C.LEG_SPRING_TORQUE
    new_motor = jnp.clip(motor[j] + lam, -max_imp, max_imp)
    lam = new_motor - motor[j]
    motor = motor.at[j].set(new_motor)
    wa = wa - ia * lam
    wb = wb + ib * lam

    cdot1 = vb + cross_vs(wb, rb) - va - cross_vs(wa, ra)
    cdot2 = wb - wa
    acc = impulse[j]
    # limit active: 3 × 3 solve, falling back to the point constraint when the limit would pull
    imp3 = -_solve33(k, jnp.concatenate([cdot1, cdot2[None]]))
    new_z = acc[2] + imp3[2]
    at_lower = limit_state == 1
    release = jnp.where(at_lower, new_z < 0, new_z > 0)
    rhs0 = -cdot1[0] + acc[2] * k[2, 0]
    rhs1 = -cdot1[1] + acc[2] * k[2, 1]
    red0, red1 = _solve22(k[0, 0], k[1, 0], k[0, 1], k[1, 1], rhs0, rhs1)
    imp_lim = jnp.where(release, jnp.stack([red0, red1, -acc[2]]), imp3)
    acc_lim = jnp.where(release, jnp.stack([acc[0] + red0, acc[1] + red1, 0.0]), acc + imp3)
    # limit inactive: 2 × 2 point constraint
    p0, p1 = _solve22(k[0, 0], k[1, 0], k[0, 1], k[1, 1], -cdot1[0], -cdot1[1])
    imp_pt = jnp.stack([p0, p1, 0.0])
    active = limit_state != 0
    imp = jnp.where(active, imp_lim, imp_pt)
    acc = jnp.where(active, acc_lim, acc + imp_pt)
    impulse = impulse.at[j].set(acc)

    p = imp[:2]
    va = va - ma * p
    wa = wa - ia * (cross_vv(ra, p) + imp[2])
    vb = vb + mb * p
    wb = wb + ib * (cross_vv(rb, p) + imp[2])
    v = v.at[0].set(va).at[b].set(vb)
    w = w.at[0].set(wa).at[b].set(wb)
    return (v, w), (impulse, motor)


@struct.dataclass
class _ContactConst:
    valid: jax.Array  # (2 legs, 4 points)
    r: jax.Array  # (2, 4, 2) lever arms from the legs' centres
    n: jax.Array  # (2, 4, 2) normals (ground -> leg)
    normal_mass: jax.Array  # (2, 4)
    tangent_mass: jax.Array  # (2, 4)
    block: jax.Array  # (2, 2) slot uses Box2D's 2-point block solver
    k_block: jax.Array  # (2, 2, 3) k11, k12, k22 of each slot's 2-point normal system


def _contact_const(m: Manifold, c: jax.Array, a: jax.Array, block_solve: bool) -> _ContactConst:
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
    return _ContactConst(
        valid=valid,
        r=r,
        n=n,
        normal_mass=jnp.where(kn > 0, 1.0 / kn, 0.0),
        tangent_mass=jnp.where(kt > 0, 1.0 / kt, 0.0),
        block=block,
        k_block=jnp.stack([k11, k12, k22], -1),
    )


def _solve_contacts(vl, wl, pn, pt, cc: _ContactConst):
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


def _solve_normals(vl, wl, pn, cc: _ContactConst, s: int):
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


def _warm_impulses(ps: PhysicsState, m: Manifold, idx: jax.Array) -> jax.Array:
    """Impulses (2 legs, 2 slots, 2 points, 2) carried over from matching contact features."""
    old_key = ps.contact_key[jnp.arange(2)[:, None], idx]  # (2, 2 slots, 2 old points)
    old_imp = ps.contact_impulse[jnp.arange(2)[:, None], idx]  # (2, 2, 2 old, 2)
    match = (m.key[..., :, None] == old_key[..., None, :]) & (old_key[..., None, :] >= 0)
    warm = jnp.einsum("lspq,lsqk->lspk", match.astype(F32), old_imp)
    return jnp.where(m.valid[..., None], warm, 0.0)


def _store_impulses(m: Manifold, idx: jax.Array, pn: jax.Array, pt: jax.Array):
    imp = jnp.stack([pn, pt], -1).reshape(2, 2, 2, 2) * m.valid[..., None]
    legs = jnp.broadcast_to(jnp.arange(2)[:, None], idx.shape)
    store = jnp.zeros((2, NUM_EDGES, 2, 2), F32).at[legs, idx].add(imp)
    key = jnp.where(m.valid, m.key, -1)
    keys = jnp.full((2, NUM_EDGES, 2), -1, jnp.int32).at[legs, idx].max(key)
    return store, keys


def _solve_positions(c, a, m: Manifold, jconst_limit, iterations: int):
    """Non-linear Gauss-Seidel position correction with Box2D's early exit."""
    limit_state = jconst_limit
    im_l, ii_l = INV_MASS[1], INV_I[1]

    def contact_pass(c, a):
        min_sep = jnp.zeros((), F32)
        cl, al = c[1:], a[1:]
        for s in range(2):
            ms = jax.tree.map(lambda x: x[:, s], m)
            for j in range(2):
                normal, points, sep = jax.vmap(position_points)(ms, cl, al)
                n, p, sp = normal, points[:, j], sep[:, j]
                ok = ms.valid[:, j]
                r = p - cl
                min_sep = jnp.minimum(min_sep, jnp.min(jnp.where(ok, sp, 0.0)))
                corr = jnp.clip(C.BAUMGARTE * (sp + C.LINEAR_SLOP), -C.MAX_LINEAR_CORRECTION, 0.0)
                rn = cross_vv(r, n)
                k = im_l + ii_l * rn**2
                lam = jnp.where(ok & (k > 0), -corr / jnp.where(k > 0, k, 1.0), 0.0)
                pvec = lam[:, None] * n
                cl = cl + im_l * pvec
                al = al + ii_l * cross_vv(r, pvec)
        return c.at[1:].set(cl), a.at[1:].set(al), min_sep >= -3.0 * C.LINEAR_SLOP

    def joint_pass(c, a):
        ok_all = jnp.ones((), bool)
        for j in JOINT_ORDER:
            b = j + 1
            ma, mb, ia, ib = INV_MASS[0], INV_MASS[b], INV_I[0], INV_I[b]
            angle = a[b] - a[0] - REFERENCE[j]
            ls = limit_state[j]
            c_low = angle - LOWER[j]
            c_up = angle - UPPER[j]
            ang_err = jnp.where(ls == 1, -c_low, jnp.where(ls == 2, c_up, 0.0))
            corr = jnp.where(
                ls == 1,
                jnp.clip(c_low + C.ANGULAR_SLOP, -C.MAX_ANGULAR_CORRECTION, 0.0),
                jnp.clip(c_up - C.ANGULAR_SLOP, 0.0, C.MAX_ANGULAR_CORRECTION),
            )
            lim = jnp.where(ls != 0, -corr / (ia + ib), 0.0)
            a = a.at[0].add(-ia * lim).at[b].add(ib * lim)
            ra = rotate(a[0], ANCHOR_A)
            rb = rotate(a[b], ANCHOR_B[j])
            err = c[b] + rb - c[0] - ra
            pos_err = jnp.sqrt(jnp.sum(err**2))
            k11 = ma + mb + ia * ra[1] ** 2 + ib * rb[1] ** 2
            k12 = -ia * ra[0] * ra[1] - ib * rb[0] * rb[1]
            k22 = ma + mb + ia * ra[0] ** 2 + ib * rb[0] ** 2
            i0, i1 = _solve22(k11, k12, k12, k22, err[0], err[1])
            imp = -jnp.stack([i0, i1])
            c = c.at[0].add(-ma * imp).at[b].add(mb * imp)
            a = a.at[0].add(-ia * cross_vv(ra, imp)).at[b].add(ib * cross_vv(rb, imp))
            ok_all = ok_all & (pos_err <= C.LINEAR_SLOP) & (ang_err <= C.ANGULAR_SLOP)
        return c, a, ok_all

    def body(_, carry):
        c, a, solved = carry
        c2, a2, contacts_ok = contact_pass(c, a)
        c2, a2, joints_ok = joint_pass(c2, a2)
        c = jnp.where(solved, c, c2)
        a = jnp.where(solved, a, a2)
        return c, a, solved | (contacts_ok & joints_ok)

    return jax.lax.fori_loop(0, iterations, body, (c, a, jnp.zeros((), bool)))


def step(
    ps: PhysicsState,
    v1: jax.Array,
    v2: jax.Array,
    force: jax.Array,
    torque: jax.Array,
    cfg: SolverConfig,
) -> tuple[PhysicsState, StepEvents]:
    """One ``world.Step``: terrain edges ``v1``/``v2`` (NUM_EDGES, 2); force and torque on the hull."""
    dt = cfg.dt
    # 1. collide at the current positions (computed at the end of the previous step)
    m, idx, hull_now = ps.manifold, ps.manifold_edges, ps.hull_contact
    touching = _scatter_touching(m, idx)
    leg_begin = jnp.any(touching & ~ps.leg_touching, -1)
    leg_end = jnp.any(~touching & ps.leg_touching, -1)
    hull_begin = jnp.any(hull_now & ~ps.hull_touching)

    # 2. integrate velocities
    g = jnp.array([0.0, cfg.gravity], F32)
    v = ps.v + dt * g
    v = v.at[0].add(dt * INV_MASS[0] * force)
    w = ps.w.at[0].add(dt * INV_I[0] * torque)

    # 3. constraints, warm starting
    cc = _contact_const(m, ps.c, ps.a, cfg.block_solve)
    warm = _warm_impulses(ps, m, idx) if cfg.warm_start else jnp.zeros((2, 2, 2, 2), F32)
    pn = warm[..., 0].reshape(2, 4) * cc.valid
    pt = warm[..., 1].reshape(2, 4) * cc.valid
    tangent = jnp.stack([cc.n[..., 1], -cc.n[..., 0]], -1)
    p_warm = pn[..., None] * cc.n + pt[..., None] * tangent
    v = v.at[1:].add(INV_MASS[1] * p_warm.sum(1))
    w = w.at[1:].add(INV_I[1] * cross_vv(cc.r, p_warm).sum(1))

    ra = rotate(ps.a[0], ANCHOR_A)
    joint_angle = ps.a[1:] - ps.a[0] - REFERENCE
    limit = jnp.where(joint_angle <= LOWER, 1, jnp.where(joint_angle >= UPPER, 2, 0)).astype(jnp.int32)
    impulse = ps.joint_impulse
    impulse = impulse.at[:, 2].set(jnp.where(limit == ps.limit_state, impulse[:, 2], 0.0))
    impulse = impulse.at[:, 2].set(jnp.where(limit == 0, 0.0, impulse[:, 2]))
    motor = ps.motor_impulse
    if not cfg.warm_start:
        impulse, motor = jnp.zeros_like(impulse), jnp.zeros_like(motor)
    jconsts = []
    for j in range(2):
        rb = rotate(ps.a[j + 1], ANCHOR_B[j])
        jconsts.append((ra, rb, _joint_mass(ra, rb, j), limit[j]))
    for j in JOINT_ORDER:
        b = j + 1
        p = impulse[j, :2]
        ang = cross_vv(jconsts[j][0], p) + motor[j] + impulse[j, 2]
        v = v.at[0].add(-INV_MASS[0] * p).at[b].add(INV_MASS[b] * p)
        w = w.at[0].add(-INV_I[0] * ang).at[b].add(INV_I[b] * (cross_vv(jconsts[j][1], p) + motor[j] + impulse[j, 2]))

    # 4. velocity iterations
    def vel_iter(_, carry):
        v, w, impulse, motor, pn, pt = carry
        for j in JOINT_ORDER:
            (v, w), (impulse, motor) = _solve_joint(j, (v, w), (impulse, motor), jconsts[j], dt)
        vl, wl, pn, pt = _solve_contacts(v[1:], w[1:], pn, pt, cc)
        return v.at[1:].set(vl), w.at[1:].set(wl), impulse, motor, pn, pt

    v, w, impulse, motor, pn, pt = jax.lax.fori_loop(
        0, cfg.velocity_iterations, vel_iter, (v, w, impulse, motor, pn, pt)
    )
    store, keys = _store_impulses(m, idx, pn, pt)

    # 5. integrate positions (Box2D clamps huge per-step motions)
    trans = dt * jnp.sqrt(jnp.sum(v**2, -1))
    v = v * jnp.where(trans > C.MAX_TRANSLATION, C.MAX_TRANSLATION / jnp.maximum(trans, 1e-12), 1.0)[:, None]
    rot = dt * jnp.abs(w)
    w = w * jnp.where(rot > C.MAX_ROTATION, C.MAX_ROTATION / jnp.maximum(rot, 1e-12), 1.0)
    c = ps.c + dt * v
    a = ps.a + dt * w

    # 6. position iterations
    c, a, solved = _solve_positions(c, a, m, limit, cfg.position_iterations)

    # 7. sleep
    moving = (w**2 > C.ANGULAR_SLEEP_TOLERANCE**2) | (jnp.sum(v**2, -1) > C.LINEAR_SLEEP_TOLERANCE**2)
    sleep_time = jnp.where(moving, 0.0, ps.sleep_time + jnp.float32(dt))
    asleep = (jnp.min(sleep_time) >= C.TIME_TO_SLEEP) & solved

    # 8. time-of-impact begin events at the new positions
    m_end, idx_end = leg_manifolds(c, a, v1, v2)
    deep = m_end.valid & (m_end.separation < C.TOI_TARGET)[..., None]
    toi_pairs = _scatter_touching(m_end.replace(valid=deep), idx_end) & ~touching
    leg_toi = jnp.any(toi_pairs, -1)
    hull_end = hull_manifolds(c, a, v1, v2)
    hull_toi = jnp.any(hull_end.valid & (hull_end.separation < C.TOI_TARGET)[:, None], -1) & ~hull_now

    new = ps.replace(
        c=c,
        a=a,
        v=v,
        w=w,
        sleep_time=sleep_time,
        joint_impulse=impulse,
        motor_impulse=motor,
        limit_state=limit,
        leg_touching=touching | toi_pairs,
        hull_touching=hull_now | hull_toi,
        contact_key=keys,
        contact_impulse=store,
        manifold=m_end,
        manifold_edges=idx_end,
        hull_contact=jnp.any(hull_end.valid, -1),
    )
    events = StepEvents(
        leg_begin=leg_begin,
        leg_end=leg_end,
        leg_toi_begin=leg_toi,
        hull_begin=hull_begin | jnp.any(hull_toi),
        asleep=asleep,
        leg_touching=jnp.any(touching, -1),
    )
    return new, events


def apply_impulse(ps: PhysicsState, impulse: jax.Array, point: jax.Array) -> PhysicsState:
    """Box2D ``ApplyLinearImpulse`` on the hull at a world point."""
    r = point - ps.c[0]
    v = ps.v.at[0].add(INV_MASS[0] * impulse)
    w = ps.w.at[0].add(INV_I[0] * cross_vv(r, impulse))
    return ps.replace(v=v, w=w)

