"""The position sweeps on component arrays: the GPU form of ``step``'s position solve.

The stacked position sweep (``contacts.position_pass``, then ``joints.solve_position`` per joint)
compiles to 49 kernels per trip of its loop on a GPU, as the velocity sweeps did (81) before
``fused_sweeps``. Here the hull's and the legs' positions and angles are one array per component
and each contact point's manifold data is split before the loop, so a sweep is elementwise
arithmetic. Box2D's order and arithmetic are kept; the two forms differ in float rounding only.
``SolverConfig.sweep_layout`` chooses between them as it does for the velocity sweeps.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.physics.body import INV_I, INV_MASS, solve22
from rlq.envs.lunar.physics.collide import FACE_EDGE, Manifold
from rlq.envs.lunar.physics.fused_sweeps import LEG_IS
from rlq.envs.lunar.physics.joints import ANCHOR_A, ANCHOR_B, ORDER, limit_position
from rlq.lib.carry import batched_zeros


class PointConst(struct.PyTreeNode):
    """One manifold point of each leg (arrays over the 2 legs), as ``collide.position_points`` reads it."""

    valid: jax.Array
    face_edge: jax.Array
    nx: jax.Array  # FACE_EDGE: world normal; FACE_POLY: normal in the leg's frame
    ny: jax.Array
    plane_x: jax.Array  # FACE_EDGE: world point of the edge; FACE_POLY: vertex in the leg's frame
    plane_y: jax.Array
    px: jax.Array  # FACE_EDGE: point in the leg's frame; FACE_POLY: world point
    py: jax.Array


def point_constants(m: Manifold) -> tuple[PointConst, ...]:
    """The leg manifolds (2 legs, 2 candidate edges) as four points in ``position_pass``'s order:
    edge 0's two points, then edge 1's."""
    return tuple(
        PointConst(
            valid=m.valid[:, s, j],
            face_edge=m.kind[:, s] == FACE_EDGE,
            nx=m.normal[:, s, 0],
            ny=m.normal[:, s, 1],
            plane_x=m.plane[:, s, 0],
            plane_y=m.plane[:, s, 1],
            px=m.points[:, s, j, 0],
            py=m.points[:, s, j, 1],
        )
        for s in range(2)
        for j in range(2)
    )


def _rotate(cos, sin, x, y):
    return cos * x - sin * y, sin * x + cos * y


def contact_position(legs, min_sep, p: PointConst, baumgarte: float):
    """One point's position correction for both legs (b2ContactSolver::SolvePositionConstraints).

    ``legs``: (cx, cy, angle), each (2,); ``min_sep``: each leg's smallest separation so far."""
    im, ii = INV_MASS[1], INV_I[1]
    cx, cy, al = legs
    cos, sin = jnp.cos(al), jnp.sin(al)
    n_poly = _rotate(cos, sin, p.nx, p.ny)
    plane_poly = _rotate(cos, sin, p.plane_x, p.plane_y)
    pt_body = _rotate(cos, sin, p.px, p.py)
    fe = p.face_edge
    nx, ny = jnp.where(fe, p.nx, n_poly[0]), jnp.where(fe, p.ny, n_poly[1])
    plane_x = jnp.where(fe, p.plane_x, cx + plane_poly[0])
    plane_y = jnp.where(fe, p.plane_y, cy + plane_poly[1])
    clip_x, clip_y = jnp.where(fe, cx + pt_body[0], p.px), jnp.where(fe, cy + pt_body[1], p.py)
    sep = (clip_x - plane_x) * nx + (clip_y - plane_y) * ny - C.CONTACT_RADIUS
    nx, ny = jnp.where(fe, nx, -nx), jnp.where(fe, ny, -ny)

    rx, ry = clip_x - cx, clip_y - cy
    min_sep = jnp.minimum(min_sep, jnp.where(p.valid, sep, 0.0))
    corr = jnp.clip(baumgarte * (sep + C.LINEAR_SLOP), -C.MAX_LINEAR_CORRECTION, 0.0)
    rn = rx * ny - ry * nx
    k = im + ii * rn**2
    lam = jnp.where(p.valid & (k > 0), -corr / jnp.where(k > 0, k, 1.0), 0.0)
    qx, qy = lam * nx, lam * ny
    return (cx + im * qx, cy + im * qy, al + ii * (rx * qy - ry * qx)), min_sep


def joint_position(j: int, hull, legs, limit_state):
    """One position sweep of joint ``j`` (``joints.solve_position``): the limit, then the anchors.

    ``hull``: (cx, cy, angle); ``legs``: (cx, cy, angle), each (2,). Returns them and the ok flag."""
    b = j + 1
    ma, mb, ia, ib = INV_MASS[0], INV_MASS[b], INV_I[0], INV_I[b]
    (cax, cay, aa), (cbx, cby, ab) = hull, (legs[0][j], legs[1][j], legs[2][j])
    lim, ang_err = limit_position(j, aa, ab, limit_state)
    aa, ab = aa - ia * lim, ab + ib * lim

    rax, ray = _rotate(jnp.cos(aa), jnp.sin(aa), ANCHOR_A[0], ANCHOR_A[1])
    rbx, rby = _rotate(jnp.cos(ab), jnp.sin(ab), ANCHOR_B[j, 0], ANCHOR_B[j, 1])
    err_x, err_y = cbx + rbx - cax - rax, cby + rby - cay - ray
    k11 = ma + mb + ia * ray**2 + ib * rby**2
    k12 = -ia * rax * ray - ib * rbx * rby
    k22 = ma + mb + ia * rax**2 + ib * rbx**2
    i0, i1 = solve22(k11, k12, k12, k22, err_x, err_y)
    imp_x, imp_y = -i0, -i1
    hull = (cax - ma * imp_x, cay - ma * imp_y, aa - ia * (rax * imp_y - ray * imp_x))
    new_leg = (cbx + mb * imp_x, cby + mb * imp_y, ab + ib * (rbx * imp_y - rby * imp_x))
    legs = tuple(jnp.where(LEG_IS[j], new, old) for new, old in zip(new_leg, legs, strict=True))
    ok = (jnp.sqrt(err_x**2 + err_y**2) <= C.LINEAR_SLOP) & (ang_err <= C.ANGULAR_SLOP)
    return hull, legs, ok


def position_sweeps(c, a, m: Manifold, limit, iterations: int, contacts: bool):
    """``step``'s position solve on components: up to ``iterations`` sweeps (the leg contacts unless
    ``contacts`` is False, then the joints in Box2D's order) that stop once every constraint is
    within Box2D's slops. Takes and returns the stacked ``c`` (3, 2) and ``a`` (3,), and whether
    the positions were solved."""
    points = point_constants(m) if contacts else ()

    def body(carry):
        i, hull, legs, _ = carry
        min_sep = jnp.zeros_like(legs[2])
        for p in points:
            legs, min_sep = contact_position(legs, min_sep, p, C.BAUMGARTE)
        ok = (min_sep[0] >= -3.0 * C.LINEAR_SLOP) & (min_sep[1] >= -3.0 * C.LINEAR_SLOP)
        for j in ORDER:
            hull, legs, joint_ok = joint_position(j, hull, legs, limit[j])
            ok = ok & joint_ok
        return i + 1, hull, legs, ok

    def running(carry):
        i, _, _, solved = carry
        return (i < iterations) & ~solved

    start = (
        batched_zeros(a[0], dtype=jnp.int32),
        (c[0, 0], c[0, 1], a[0]),
        (c[1:, 0], c[1:, 1], a[1:]),
        batched_zeros(a[0], dtype=jnp.bool_),
    )
    _, hull, legs, solved = jax.lax.while_loop(running, body, start)
    c = jnp.concatenate([jnp.stack(hull[:2])[None], jnp.stack(legs[:2], axis=-1)])
    return c, jnp.concatenate([hull[2][None], legs[2]]), solved
