"""The two leg joints: Box2D 2.3 revolute joints with angle limits and a torque-limited motor.

Joint ``j`` connects the hull (body A) to leg ``j`` (body B). The motor pushes each leg outwards
at 0.3 rad/s with at most LEG_SPRING_TORQUE, so a leg acts as a spring-loaded damper that rests
against its limit; the limit and the point constraint are solved together (3 × 3 block), as in
``b2RevoluteJoint``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.physics.body import INV_I, INV_MASS, constant, cross_vs, cross_vv, solve22
from rlq.envs.lunar.physics.collide import dot, rotate

ANCHOR_A = constant(np.float32(C.ANCHOR_HULL) - np.float32(C.LOCAL_CENTER[0]))
ANCHOR_B = constant(C.ANCHOR_LEG)
LOWER = constant(C.LEG_LOWER)
UPPER = constant(C.LEG_UPPER)
MOTOR_SPEED = constant(C.LEG_MOTOR_SPEED)
REFERENCE = constant(C.LEG_REFERENCE_ANGLE)
#: Box2D's island order: legs[1]'s joint is solved before legs[0]'s.
ORDER = (1, 0)
INACTIVE, AT_LOWER, AT_UPPER = 0, 1, 2


def _cross3(a, b):
    return jnp.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _solve33(k, b):
    """b2Mat33::Solve33 (Cramer's rule) with columns ``k[0], k[1], k[2]``."""
    ex, ey, ez = k[0], k[1], k[2]
    det = dot(ex, _cross3(ey, ez))
    det = jnp.where(det != 0, 1.0 / jnp.where(det != 0, det, 1.0), 0.0)
    return det * jnp.stack([dot(b, _cross3(ey, ez)), dot(ex, _cross3(b, ez)), dot(ex, _cross3(ey, b))])


def _mass(ra: jax.Array, rb: jax.Array, j: int) -> jax.Array:
    """Columns (ex, ey, ez) of the joint's 3 × 3 effective-mass matrix K."""
    ma, mb, ia, ib = INV_MASS[0], INV_MASS[j + 1], INV_I[0], INV_I[j + 1]
    exx = ma + mb + ra[1] ** 2 * ia + rb[1] ** 2 * ib
    eyx = -ra[1] * ra[0] * ia - rb[1] * rb[0] * ib
    ezx = -ra[1] * ia - rb[1] * ib
    eyy = ma + mb + ra[0] ** 2 * ia + rb[0] ** 2 * ib
    ezy = ra[0] * ia + rb[0] * ib
    ezz = ia + ib
    return jnp.stack([jnp.stack([exx, eyx, ezx]), jnp.stack([eyx, eyy, ezy]), jnp.stack([ezx, ezy, ezz])])


def joint_angles(a: jax.Array) -> jax.Array:
    return a[1:] - a[0] - REFERENCE


def init(a, v, w, impulse, motor, prev_limit, warm_start: bool):
    """InitVelocityConstraints: limit states, constants per joint, warm-started velocities."""
    ja = joint_angles(a)
    limit = jnp.where(ja <= LOWER, AT_LOWER, jnp.where(ja >= UPPER, AT_UPPER, INACTIVE)).astype(jnp.int32)
    keep = (limit == prev_limit) & (limit != INACTIVE)
    impulse = impulse.at[:, 2].set(jnp.where(keep, impulse[:, 2], 0.0))
    if not warm_start:
        impulse, motor = jnp.zeros_like(impulse), jnp.zeros_like(motor)
    ra = rotate(a[0], ANCHOR_A)
    consts = []
    for j in range(2):
        rb = rotate(a[j + 1], ANCHOR_B[j])
        consts.append((ra, rb, _mass(ra, rb, j), limit[j]))
    for j in ORDER:
        b = j + 1
        p = impulse[j, :2]
        spin = motor[j] + impulse[j, 2]
        v = v.at[0].add(-INV_MASS[0] * p).at[b].add(INV_MASS[b] * p)
        w = w.at[0].add(-INV_I[0] * (cross_vv(ra, p) + spin)).at[b].add(INV_I[b] * (cross_vv(consts[j][1], p) + spin))
    return v, w, impulse, motor, limit, consts


def solve_velocity(j: int, v, w, impulse, motor, const, dt: float):
    """One velocity sweep of joint ``j`` (b2RevoluteJoint::SolveVelocityConstraints)."""
    ra, rb, k, limit_state = const
    b = j + 1
    ma, mb, ia, ib = INV_MASS[0], INV_MASS[b], INV_I[0], INV_I[b]
    va, wa, vb, wb = v[0], w[0], v[b], w[b]

    cdot = wb - wa - MOTOR_SPEED[j]
    max_imp = dt * C.LEG_SPRING_TORQUE
    new_motor = jnp.clip(motor[j] - cdot / (ia + ib), -max_imp, max_imp)
    lam = new_motor - motor[j]
    motor = motor.at[j].set(new_motor)
    wa = wa - ia * lam
    wb = wb + ib * lam

    cdot1 = vb + cross_vs(wb, rb) - va - cross_vs(wa, ra)
    acc = impulse[j]
    # limit active: 3 × 3 solve; when the limit would pull, the point constraint alone
    imp3 = -_solve33(k, jnp.concatenate([cdot1, (wb - wa)[None]]))
    new_z = acc[2] + imp3[2]
    release = jnp.where(limit_state == AT_LOWER, new_z < 0, new_z > 0)
    red0, red1 = solve22(k[0, 0], k[1, 0], k[0, 1], k[1, 1], -cdot1[0] + acc[2] * k[2, 0], -cdot1[1] + acc[2] * k[2, 1])
    imp_lim = jnp.where(release, jnp.stack([red0, red1, -acc[2]]), imp3)
    acc_lim = jnp.where(release, jnp.stack([acc[0] + red0, acc[1] + red1, 0.0]), acc + imp3)
    # limit inactive: 2 × 2 point constraint
    p0, p1 = solve22(k[0, 0], k[1, 0], k[0, 1], k[1, 1], -cdot1[0], -cdot1[1])
    imp_pt = jnp.stack([p0, p1, 0.0])
    active = limit_state != INACTIVE
    imp = jnp.where(active, imp_lim, imp_pt)
    impulse = impulse.at[j].set(jnp.where(active, acc_lim, acc + imp_pt))

    p = imp[:2]
    va = va - ma * p
    wa = wa - ia * (cross_vv(ra, p) + imp[2])
    vb = vb + mb * p
    wb = wb + ib * (cross_vv(rb, p) + imp[2])
    return v.at[0].set(va).at[b].set(vb), w.at[0].set(wa).at[b].set(wb), impulse, motor


def limit_position(j: int, angle_a, angle_b, limit_state):
    """Joint ``j``'s limit in a position sweep (with slop), from the hull's and the leg's angles:
    the angular impulse to apply (−ia·lim to the hull, +ib·lim to the leg) and the angle error."""
    ia, ib = INV_I[0], INV_I[j + 1]
    angle = angle_b - angle_a - REFERENCE[j]
    c_low, c_up = angle - LOWER[j], angle - UPPER[j]
    ang_err = jnp.where(limit_state == AT_LOWER, -c_low, jnp.where(limit_state == AT_UPPER, c_up, 0.0))
    corr = jnp.where(
        limit_state == AT_LOWER,
        jnp.clip(c_low + C.ANGULAR_SLOP, -C.MAX_ANGULAR_CORRECTION, 0.0),
        jnp.clip(c_up - C.ANGULAR_SLOP, 0.0, C.MAX_ANGULAR_CORRECTION),
    )
    return jnp.where(limit_state != INACTIVE, -corr / (ia + ib), 0.0), ang_err


def solve_position(j: int, c, a, limit_state):
    """One position sweep of joint ``j``: limit (with slop), then the anchor points; ok flag."""
    b = j + 1
    ma, mb, ia, ib = INV_MASS[0], INV_MASS[b], INV_I[0], INV_I[b]
    lim, ang_err = limit_position(j, a[0], a[b], limit_state)
    a = a.at[0].add(-ia * lim).at[b].add(ib * lim)

    ra = rotate(a[0], ANCHOR_A)
    rb = rotate(a[b], ANCHOR_B[j])
    err = c[b] + rb - c[0] - ra
    k11 = ma + mb + ia * ra[1] ** 2 + ib * rb[1] ** 2
    k12 = -ia * ra[0] * ra[1] - ib * rb[0] * rb[1]
    k22 = ma + mb + ia * ra[0] ** 2 + ib * rb[0] ** 2
    i0, i1 = solve22(k11, k12, k12, k22, err[0], err[1])
    imp = -jnp.stack([i0, i1])
    c = c.at[0].add(-ma * imp).at[b].add(mb * imp)
    a = a.at[0].add(-ia * cross_vv(ra, imp)).at[b].add(ib * cross_vv(rb, imp))
    ok = (jnp.sqrt(jnp.sum(err**2)) <= C.LINEAR_SLOP) & (ang_err <= C.ANGULAR_SLOP)
    return c, a, ok
