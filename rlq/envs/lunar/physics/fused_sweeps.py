"""The velocity sweeps on component arrays: the form a GPU runs as one kernel per sweep.

A step's velocity sweeps (the joints, then the leg contacts, 30 to 180 times) are long chains of
small arithmetic. On stacked arrays (``joints.solve_velocity``, ``contacts.solve_velocity``:
``.at[...].set`` updates, sums over an axis of 2, ``jnp.stack``) XLA:GPU compiles one sweep into
about 80 kernels, launched one after another. Here each quantity is its own array (x, y and
angular velocity; each contact point's impulses), so a sweep is elementwise arithmetic that XLA:GPU
fuses into one kernel. XLA:CPU instead recomputes the shared values for each of the sweep's outputs
(about 1.5 times slower per step), so ``velocity_sweeps`` and ``contact_sweeps`` run this form
except on a CPU (``SolverConfig.sweep_layout``). The arithmetic is Box2D's, in its order, as in the
stacked form; they differ only in float rounding (XLA contracts different products into FMAs).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.physics.body import INV_I, INV_MASS, solve22
from rlq.envs.lunar.physics.contacts import ContactConst, block_impulses
from rlq.envs.lunar.physics.joints import AT_LOWER, INACTIVE, MOTOR_SPEED, ORDER

#: which entry of a per-leg (2,) array is leg ``j``'s: a sweep updates it with a select, which fuses
LEG_IS = (np.array([True, False]), np.array([False, True]))
LAYOUTS = ("auto", "stacked", "components")


def by_layout(layout: str, stacked: Callable, components: Callable, *args: Any) -> Any:
    """``stacked(*args)`` or ``components(*args)``; ``auto``: the stacked form on a CPU, the
    component form elsewhere.

    ``auto`` reads the platform of the device set with ``jax.default_device`` around the trace, as
    ``rlq train`` sets it, and then traces one form. Without one, both forms are traced and the
    choice is made when the program is lowered for its device (``jax.lax.platform_dependent``),
    which costs the other form's trace, a sizeable share of a LunarLander training program's."""
    if layout == "auto":
        platform = _default_device_platform()
        if platform is None:
            return jax.lax.platform_dependent(*args, cpu=stacked, default=components)
        layout = "stacked" if platform == "cpu" else "components"
    return stacked(*args) if layout == "stacked" else components(*args)


def _default_device_platform() -> str | None:
    device = jax.config.values["jax_default_device"]
    if device is None:
        return None
    return device if isinstance(device, str) else device.platform


class SweepJoint(struct.PyTreeNode):
    """A joint's constants (``joints.init``) split into components."""

    ra: tuple[jax.Array, jax.Array]
    rb: tuple[jax.Array, jax.Array]
    k: tuple[tuple[jax.Array, jax.Array, jax.Array], ...]  # k[column][row]
    limit_state: jax.Array


def sweep_joint(const: tuple) -> SweepJoint:
    ra, rb, k, limit_state = const
    return SweepJoint(
        ra=(ra[0], ra[1]),
        rb=(rb[0], rb[1]),
        k=tuple((k[col, 0], k[col, 1], k[col, 2]) for col in range(3)),
        limit_state=limit_state,
    )


def _cross3(a, b):
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


def _dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _solve33(k, b):
    """b2Mat33::Solve33 (Cramer's rule) with columns ``k[0], k[1], k[2]``, on components."""
    ex, ey, ez = k
    det = _dot3(ex, _cross3(ey, ez))
    det = jnp.where(det != 0, 1.0 / jnp.where(det != 0, det, 1.0), 0.0)
    return (
        det * _dot3(b, _cross3(ey, ez)),
        det * _dot3(ex, _cross3(b, ez)),
        det * _dot3(ex, _cross3(ey, b)),
    )


def joint_velocity(j: int, hull, legs, impulse, motor, const: SweepJoint, dt: float):
    """One velocity sweep of joint ``j`` (b2RevoluteJoint::SolveVelocityConstraints).

    ``hull``: (vx, vy, w) of the hull; ``legs``: (vx, vy, w), each (2,) over the legs;
    ``impulse``: per joint (x, y, z) accumulated impulses; ``motor``: per joint motor impulse."""
    b = j + 1
    ma, mb, ia, ib = INV_MASS[0], INV_MASS[b], INV_I[0], INV_I[b]
    (vax, vay, wa), (vbx, vby, wb) = hull, (legs[0][j], legs[1][j], legs[2][j])
    (rax, ray), (rbx, rby), k = const.ra, const.rb, const.k

    cdot = wb - wa - MOTOR_SPEED[j]
    max_imp = dt * C.LEG_SPRING_TORQUE
    new_motor = jnp.clip(motor[j] - cdot / (ia + ib), -max_imp, max_imp)
    lam = new_motor - motor[j]
    motor = tuple(new_motor if i == j else m for i, m in enumerate(motor))
    wa = wa - ia * lam
    wb = wb + ib * lam

    cdot_x = vbx + -wb * rby - vax - -wa * ray
    cdot_y = vby + wb * rbx - vay - wa * rax
    acc0, acc1, acc2 = impulse[j]
    # limit active: 3 × 3 solve; when the limit would pull, the point constraint alone
    imp3 = tuple(-x for x in _solve33(k, (cdot_x, cdot_y, wb - wa)))
    new_z = acc2 + imp3[2]
    release = jnp.where(const.limit_state == AT_LOWER, new_z < 0, new_z > 0)
    red0, red1 = solve22(k[0][0], k[1][0], k[0][1], k[1][1], -cdot_x + acc2 * k[2][0], -cdot_y + acc2 * k[2][1])
    imp_lim = (jnp.where(release, red0, imp3[0]), jnp.where(release, red1, imp3[1]), jnp.where(release, -acc2, imp3[2]))
    acc_lim = (
        jnp.where(release, acc0 + red0, acc0 + imp3[0]),
        jnp.where(release, acc1 + red1, acc1 + imp3[1]),
        jnp.where(release, 0.0, acc2 + imp3[2]),
    )
    # limit inactive: 2 × 2 point constraint
    p0, p1 = solve22(k[0][0], k[1][0], k[0][1], k[1][1], -cdot_x, -cdot_y)
    active = const.limit_state != INACTIVE
    imp_x, imp_y, imp_z = (jnp.where(active, lim, pt) for lim, pt in zip(imp_lim, (p0, p1, 0.0), strict=True))
    acc = tuple(
        jnp.where(active, lim, a + pt) for lim, a, pt in zip(acc_lim, (acc0, acc1, acc2), (p0, p1, 0.0), strict=True)
    )
    impulse = tuple(acc if i == j else imp for i, imp in enumerate(impulse))

    vax, vay = vax - ma * imp_x, vay - ma * imp_y
    wa = wa - ia * (rax * imp_y - ray * imp_x + imp_z)
    vbx, vby = vbx + mb * imp_x, vby + mb * imp_y
    wb = wb + ib * (rbx * imp_y - rby * imp_x + imp_z)
    leg = LEG_IS[j]
    legs = tuple(jnp.where(leg, new, old) for new, old in zip((vbx, vby, wb), legs, strict=True))
    return (vax, vay, wa), legs, impulse, motor


class SweepConst(struct.PyTreeNode):
    """``contacts.ContactConst`` split into components: per contact point (or block slot), one
    array over the two legs."""

    valid: tuple[jax.Array, ...]  # 4 points, each (2 legs,)
    rx: tuple[jax.Array, ...]
    ry: tuple[jax.Array, ...]
    nx: tuple[jax.Array, ...]
    ny: tuple[jax.Array, ...]
    normal_mass: tuple[jax.Array, ...]
    tangent_mass: tuple[jax.Array, ...]
    block: tuple[jax.Array, ...]  # 2 slots, each (2 legs,)
    k11: tuple[jax.Array, ...]
    k12: tuple[jax.Array, ...]
    k22: tuple[jax.Array, ...]


def sweep_constants(cc: ContactConst) -> SweepConst:
    points, slots = range(4), range(2)
    return SweepConst(
        valid=tuple(cc.valid[:, i] for i in points),
        rx=tuple(cc.r[:, i, 0] for i in points),
        ry=tuple(cc.r[:, i, 1] for i in points),
        nx=tuple(cc.n[:, i, 0] for i in points),
        ny=tuple(cc.n[:, i, 1] for i in points),
        normal_mass=tuple(cc.normal_mass[:, i] for i in points),
        tangent_mass=tuple(cc.tangent_mass[:, i] for i in points),
        block=tuple(cc.block[:, s] for s in slots),
        k11=tuple(cc.k_block[:, s, 0] for s in slots),
        k12=tuple(cc.k_block[:, s, 1] for s in slots),
        k22=tuple(cc.k_block[:, s, 2] for s in slots),
    )


def contact_velocity(vx, vy, wl, pn, pt, sc: SweepConst):
    """One velocity sweep over the leg contacts; the two legs are independent and run together.

    ``vx, vy, wl``: the legs' velocities (2,); ``pn, pt``: normal and tangent impulses, 4 points
    of (2,). The arithmetic is b2ContactSolver's, in its order."""
    im, ii = INV_MASS[1], INV_I[1]
    mu = C.LEG_GROUND_FRICTION
    pn, pt = list(pn), list(pt)
    for s in range(2):
        for i in (2 * s, 2 * s + 1):
            rx, ry, tx, ty = sc.rx[i], sc.ry[i], sc.ny[i], -sc.nx[i]
            dvx, dvy = vx + -wl * ry, vy + wl * rx
            lam = sc.tangent_mass[i] * -(dvx * tx + dvy * ty)
            max_f = mu * pn[i]
            new = jnp.clip(pt[i] + lam, -max_f, max_f)
            lam = jnp.where(sc.valid[i], new - pt[i], 0.0)
            pt[i] = jnp.where(sc.valid[i], new, pt[i])
            px, py = lam * tx, lam * ty
            vx, vy, wl = vx + im * px, vy + im * py, wl + ii * (rx * py - ry * px)
        vx, vy, wl, pn = _contact_normals(vx, vy, wl, pn, sc, s)
    return vx, vy, wl, tuple(pn), tuple(pt)


def _contact_normals(vx, vy, wl, pn: list, sc: SweepConst, s: int):
    """Normal impulses of slot ``s``: sequential per point, or Box2D's 2-point block solver."""
    im, ii = INV_MASS[1], INV_I[1]
    i0, i1 = 2 * s, 2 * s + 1
    # sequential
    vx_s, vy_s, wl_s, pn_s = vx, vy, wl, list(pn)
    for i in (i0, i1):
        rx, ry, nx, ny = sc.rx[i], sc.ry[i], sc.nx[i], sc.ny[i]
        dvx, dvy = vx_s + -wl_s * ry, vy_s + wl_s * rx
        lam = -sc.normal_mass[i] * (dvx * nx + dvy * ny)
        new = jnp.maximum(pn_s[i] + lam, 0.0)
        lam = jnp.where(sc.valid[i], new - pn_s[i], 0.0)
        pn_s[i] = jnp.where(sc.valid[i], new, pn_s[i])
        vx_s, vy_s = vx_s + im * lam * nx, vy_s + im * lam * ny
        wl_s = wl_s + ii * lam * (rx * ny - ry * nx)
    # block (b2ContactSolver's total enumeration of the 2-point LCP)
    nx, ny = sc.nx[i0], sc.ny[i0]
    r0x, r0y, r1x, r1y = sc.rx[i0], sc.ry[i0], sc.rx[i1], sc.ry[i1]
    k11, k12, k22 = sc.k11[s], sc.k12[s], sc.k22[s]
    a0, a1 = pn[i0], pn[i1]
    vn0 = (vx + -wl * r0y) * nx + (vy + wl * r0x) * ny
    vn1 = (vx + -wl * r1y) * nx + (vy + wl * r1x) * ny
    x0, x1 = block_impulses(k11, k12, k22, a0, a1, vn0, vn1)
    d0, d1 = x0 - a0, x1 - a1
    px, py = (d0 + d1) * nx, (d0 + d1) * ny
    vx_b, vy_b = vx + im * px, vy + im * py
    wl_b = wl + ii * ((r0x * (d0 * ny) - r0y * (d0 * nx)) + (r1x * (d1 * ny) - r1y * (d1 * nx)))
    blk = sc.block[s]
    pn = list(pn_s)
    pn[i0], pn[i1] = jnp.where(blk, x0, pn_s[i0]), jnp.where(blk, x1, pn_s[i1])
    return jnp.where(blk, vx_b, vx_s), jnp.where(blk, vy_b, vy_s), jnp.where(blk, wl_b, wl_s), pn


def velocity_sweeps(
    v, w, impulse, motor, pn, pt, jconsts: list, cc: ContactConst | None, iterations: int, dt: float, unroll: int
):
    """The step's velocity sweeps (each: the joints in Box2D's order, then the leg contacts unless
    ``cc`` is None) on components. Takes and returns the stacked arrays: ``v`` (3, 2), ``w`` (3,),
    ``impulse`` (2, 3), ``motor`` (2,), ``pn, pt`` (2 legs, 4 points)."""
    joints = [sweep_joint(const) for const in jconsts]
    sc = None if cc is None else sweep_constants(cc)

    def sweep(_, carry):
        hull, legs, impulse, motor, pn, pt = carry
        for j in ORDER:
            hull, legs, impulse, motor = joint_velocity(j, hull, legs, impulse, motor, joints[j], dt)
        if sc is not None:
            vx, vy, wl = legs
            vx, vy, wl, pn, pt = contact_velocity(vx, vy, wl, pn, pt, sc)
            legs = (vx, vy, wl)
        return hull, tuple(legs), impulse, motor, pn, pt

    start = (
        (v[0, 0], v[0, 1], w[0]),
        (v[1:, 0], v[1:, 1], w[1:]),
        tuple((impulse[j, 0], impulse[j, 1], impulse[j, 2]) for j in range(2)),
        (motor[0], motor[1]),
        tuple(pn[:, i] for i in range(4)),
        tuple(pt[:, i] for i in range(4)),
    )
    hull, legs, impulse, motor, pn, pt = jax.lax.fori_loop(0, iterations, sweep, start, unroll=unroll)
    v = jnp.concatenate([jnp.stack(hull[:2])[None], jnp.stack(legs[:2], axis=-1)])
    w = jnp.concatenate([hull[2][None], legs[2]])
    impulse, motor = jnp.stack([jnp.stack(imp) for imp in impulse]), jnp.stack(motor)
    return v, w, impulse, motor, jnp.stack(pn, axis=1), jnp.stack(pt, axis=1)


def contact_sweeps(vl, wl, cc: ContactConst, sweeps: jax.Array):
    """``sweeps`` velocity sweeps of the leg contacts alone from zero impulses (the time-of-impact
    sub-step) on components: the legs' ``vl`` (2, 2) and ``wl`` (2,) after them."""
    sc = sweep_constants(cc)
    zeros = tuple(jnp.zeros_like(wl) for _ in range(4))

    def sweep(_, carry):
        vx, vy, wl, pn, pt = carry
        return contact_velocity(vx, vy, wl, pn, pt, sc)

    vx, vy, wl, _, _ = jax.lax.fori_loop(0, sweeps, sweep, (vl[:, 0], vl[:, 1], wl, zeros, zeros))
    return jnp.stack([vx, vy], axis=-1), wl
