"""Rigid-body physics of the lander (hull + two legs) on a polyline terrain, in pure JAX.

``step`` mirrors what Box2D 2.3 does inside Gymnasium's ``world.Step(1/FPS, 180, 60)``:

1. collide: the contacts at the current positions (computed at the end of the previous step)
   give begin/end contact events for the leg flags and the crash flag;
2. integrate velocities (gravity, external force and torque on the hull);
3. sequential impulses: warm start, then ``velocity_iterations`` sweeps over the two revolute
   joints (``lunar_joints``) and the leg contacts (``lunar_contacts``);
4. integrate positions (symplectic Euler, Box2D's per-step motion clamps);
5. ``position_iterations`` non-linear Gauss-Seidel sweeps (contacts, then joints) that stop as
   soon as penetration and joint drift are within Box2D's slops;
6. sleep: all three bodies slower than the sleep tolerances for 0.5 s put the lander to rest;
7. continuous collision (``lunar_toi``): a leg that would sink past Box2D's time-of-impact target
   is moved back to the impact, its contacts solved alone, and moved on; its contact begins now;
8. collide at the new positions, for the next step.

Body 0 is the hull, bodies 1 and 2 are Gymnasium's ``legs[0]`` and ``legs[1]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
from flax import struct

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.physics import contacts as K
from rlq.envs.lunar.physics import fused_positions as FP
from rlq.envs.lunar.physics import fused_sweeps as F
from rlq.envs.lunar.physics import joints as J
from rlq.envs.lunar.physics.body import F32, INV_I, INV_MASS, LOCAL_CENTER, cross_vv, origins
from rlq.envs.lunar.physics.collide import Manifold, rotate
from rlq.envs.lunar.physics.toi import leg_time_of_impact
from rlq.lib.carry import batched_zeros

NUM_EDGES = K.NUM_EDGES

__all__ = ["PhysicsState", "SolverConfig", "StepEvents", "apply_impulse", "initial_state", "origins", "step"]


@dataclass(frozen=True)
class SolverConfig:
    """Box2D's settings in Gymnasium: 6 × 30 velocity and 2 × 30 position iterations."""

    velocity_iterations: int = 180
    position_iterations: int = 60
    gravity: float = -10.0
    dt: float = 1.0 / C.FPS
    warm_start: bool = True
    block_solve: bool = True
    #: continuous collision for the legs (Box2D's TOI sub-steps); off: only its contact events
    toi: bool = True
    #: velocity sweeps per iteration of the compiled loop in the stacked form (the CPU's): the same
    #: arithmetic, fewer loop trips (slower on a CPU beyond 1; see docs/lunar.md)
    unroll: int = 1
    #: the same for the component form (the GPU's), where each loop trip costs about 10 us besides
    #: its kernels: at 6, Box2D's 180 sweeps for 256 envs step 1.5x faster on an H200, for about
    #: 11 s more compile per program (docs/lunar.md)
    component_unroll: int = 1
    #: the velocity and position sweeps on stacked arrays (fast on a CPU) or on one array per
    #: component (a few fused kernels per sweep on a GPU; ``fused_sweeps``, ``fused_positions``);
    #: auto: per platform
    sweep_layout: str = "auto"

    def __post_init__(self) -> None:
        if min(self.velocity_iterations, self.position_iterations) < 1:
            raise ValueError("env.solver.velocity_iterations and env.solver.position_iterations must be >= 1")
        for name in ("unroll", "component_unroll"):
            if getattr(self, name) < 1:
                raise ValueError(f"env.solver.{name} must be >= 1, got {getattr(self, name)}")
        if self.sweep_layout not in F.LAYOUTS:
            raise ValueError(
                f"env.solver.sweep_layout must be one of {', '.join(F.LAYOUTS)}, got {self.sweep_layout!r}"
            )


class PhysicsState(struct.PyTreeNode):
    """Bodies (hull, legs[0], legs[1]) and the solver's memory between steps."""

    c: jax.Array  # (3, 2) centres of mass
    a: jax.Array  # (3,) angles
    v: jax.Array  # (3, 2) linear velocities of the centres of mass
    w: jax.Array  # (3,) angular velocities
    sleep_time: jax.Array  # (3,)
    joint_impulse: jax.Array  # (2, 3) accumulated point (x, y) and limit impulses
    motor_impulse: jax.Array  # (2,)
    limit_state: jax.Array  # (2,) lunar_joints.INACTIVE / AT_LOWER / AT_UPPER
    leg_touching: jax.Array  # (2, NUM_EDGES) bool: leg/edge contacts touching
    hull_touching: jax.Array  # (NUM_EDGES,) bool
    contact_key: jax.Array  # (2, NUM_EDGES, 2) int: feature ids of the stored impulses
    contact_impulse: jax.Array  # (2, NUM_EDGES, 2, 2) (normal, tangent) per contact point
    manifold: Manifold  # (2 legs, 2 candidate edges) contacts at the current positions
    manifold_edges: jax.Array  # (2, 2) edge index of each candidate
    hull_contact: jax.Array  # (NUM_EDGES,) hull manifolds with points at the current positions


class StepEvents(struct.PyTreeNode):
    """What Gymnasium's contact listener and ``lander.awake`` would report for one step."""

    leg_begin: jax.Array  # (2,) a contact of the leg began (collide phase)
    leg_end: jax.Array  # (2,) a contact of the leg ended (collide phase)
    leg_toi_begin: jax.Array  # (2,) a contact began during continuous collision (after collide)
    hull_begin: jax.Array  # () a hull contact began: game over
    asleep: jax.Array  # () the lander came to rest


def _no_contacts() -> tuple[Manifold, jax.Array, jax.Array]:
    m = Manifold(
        valid=jnp.zeros((2, 2, 2), bool),
        kind=jnp.zeros((2, 2), jnp.int32),
        normal=jnp.zeros((2, 2, 2), F32),
        plane=jnp.zeros((2, 2, 2), F32),
        points=jnp.zeros((2, 2, 2, 2), F32),
        key=jnp.zeros((2, 2, 2), jnp.int32),
        separation=jnp.ones((2, 2), F32),
    )
    return m, jnp.zeros((2, 2), jnp.int32), jnp.zeros(NUM_EDGES, bool)


def initial_state(origin: jax.Array, angle: jax.Array) -> PhysicsState:
    """Bodies at rest at the given origins (3, 2) and angles (3,), clear of the terrain."""
    origin = jnp.asarray(origin, F32)
    angle = jnp.asarray(angle, F32)
    m, idx, hull = _no_contacts()
    return PhysicsState(
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
        manifold=m,
        manifold_edges=idx,
        hull_contact=hull,
    )


def apply_impulse(ps: PhysicsState, impulse: jax.Array, point: jax.Array) -> PhysicsState:
    """Box2D ``ApplyLinearImpulse`` on the hull at a world point."""
    v = ps.v.at[0].add(INV_MASS[0] * impulse)
    w = ps.w.at[0].add(INV_I[0] * cross_vv(point - ps.c[0], impulse))
    return ps.replace(v=v, w=w)


def _solve_positions(c, a, m: Manifold, limit, iterations: int, contacts: bool):
    """Position sweeps (contacts, then joints) with Box2D's early exit once within the slops.

    A ``while_loop``: the sweeps stop when every env of a batch is solved (usually after a few),
    instead of running all ``iterations`` and discarding the extra ones."""

    def body(carry):
        i, c, a, _ = carry
        if contacts:
            c, a, min_sep = K.position_pass(c, a, m)
            ok = jnp.all(min_sep >= -3.0 * C.LINEAR_SLOP)
        else:
            ok = jnp.ones((), bool)
        for j in J.ORDER:
            c, a, joint_ok = J.solve_position(j, c, a, limit[j])
            ok = ok & joint_ok
        return i + 1, c, a, ok

    def running(carry):
        i, _, _, solved = carry
        return (i < iterations) & ~solved

    start = (batched_zeros(a[0], dtype=jnp.int32), c, a, batched_zeros(a[0], dtype=jnp.bool_))
    _, c, a, solved = jax.lax.while_loop(running, body, start)
    return c, a, solved


def step(
    ps: PhysicsState,
    v1: jax.Array,
    v2: jax.Array,
    force: jax.Array,
    torque: jax.Array,
    cfg: SolverConfig,
    contacts: bool = True,
) -> tuple[PhysicsState, StepEvents]:
    """One ``world.Step`` over terrain edges ``v1``-``v2`` (NUM_EDGES, 2) with a force and a torque
    on the hull. ``contacts=False`` skips all collision work: only valid while the lander is far
    above the terrain (the step inside reset)."""
    dt = cfg.dt
    m, idx, hull_now = ps.manifold, ps.manifold_edges, ps.hull_contact
    touching = K.scatter_touching(m, idx)

    v = ps.v + dt * jnp.array([0.0, cfg.gravity], F32)
    v = v.at[0].add(dt * INV_MASS[0] * force)
    w = ps.w.at[0].add(dt * INV_I[0] * torque)

    if contacts:
        cc = K.constants(m, ps.c, ps.a, cfg.block_solve)
        warm = K.warm_impulses(ps.contact_key, ps.contact_impulse, m, idx)
        warm = warm if cfg.warm_start else jnp.zeros_like(warm)
        pn = warm[..., 0].reshape(2, 4) * cc.valid
        pt = warm[..., 1].reshape(2, 4) * cc.valid
        tangent = jnp.stack([cc.n[..., 1], -cc.n[..., 0]], -1)
        p_warm = pn[..., None] * cc.n + pt[..., None] * tangent
        v = v.at[1:].add(INV_MASS[1] * p_warm.sum(1))
        w = w.at[1:].add(INV_I[1] * cross_vv(cc.r, p_warm).sum(1))
    else:
        pn = pt = jnp.zeros((2, 4), F32)
    v, w, impulse, motor, limit, jconsts = J.init(
        ps.a, v, w, ps.joint_impulse, ps.motor_impulse, ps.limit_state, cfg.warm_start
    )

    def stacked(v, w, impulse, motor, pn, pt, jconsts, cc):
        def sweep(_, carry):
            v, w, impulse, motor, pn, pt = carry
            for j in J.ORDER:
                v, w, impulse, motor = J.solve_velocity(j, v, w, impulse, motor, jconsts[j], dt)
            if cc is not None:
                vl, wl, pn, pt = K.solve_velocity(v[1:], w[1:], pn, pt, cc)
                v, w = v.at[1:].set(vl), w.at[1:].set(wl)
            return v, w, impulse, motor, pn, pt

        return jax.lax.fori_loop(0, cfg.velocity_iterations, sweep, (v, w, impulse, motor, pn, pt), unroll=cfg.unroll)

    def components(v, w, impulse, motor, pn, pt, jconsts, cc):
        return F.velocity_sweeps(
            v, w, impulse, motor, pn, pt, jconsts, cc, cfg.velocity_iterations, dt, cfg.component_unroll
        )

    sweep_args = (v, w, impulse, motor, pn, pt, jconsts, cc if contacts else None)
    v, w, impulse, motor, pn, pt = F.by_layout(cfg.sweep_layout, stacked, components, *sweep_args)

    trans = dt * jnp.sqrt(jnp.sum(v**2, -1))
    v = v * jnp.where(trans > C.MAX_TRANSLATION, C.MAX_TRANSLATION / jnp.maximum(trans, 1e-12), 1.0)[:, None]
    rot = dt * jnp.abs(w)
    w = w * jnp.where(rot > C.MAX_ROTATION, C.MAX_ROTATION / jnp.maximum(rot, 1e-12), 1.0)
    position_args = (ps.c + dt * v, ps.a + dt * w, m, limit)
    stacked_positions = partial(_solve_positions, iterations=cfg.position_iterations, contacts=contacts)
    component_positions = partial(FP.position_sweeps, iterations=cfg.position_iterations, contacts=contacts)
    c, a, solved = F.by_layout(cfg.sweep_layout, stacked_positions, component_positions, *position_args)

    moving = (w**2 > C.ANGULAR_SLEEP_TOLERANCE**2) | (jnp.sum(v**2, -1) > C.LINEAR_SLEEP_TOLERANCE**2)
    sleep_time = jnp.where(moving, 0.0, ps.sleep_time + jnp.float32(dt))
    asleep = (jnp.min(sleep_time) >= C.TIME_TO_SLEEP) & solved

    new = ps.replace(
        c=c,
        a=a,
        v=v,
        w=w,
        sleep_time=sleep_time,
        joint_impulse=impulse,
        motor_impulse=motor,
        limit_state=limit,
    )
    no = jnp.zeros(2, bool)
    if not contacts:
        return new, StepEvents(no, no, no, jnp.zeros((), bool), asleep)

    store, keys = K.store_impulses(m, idx, pn, pt)
    if cfg.toi:
        c, a, v, w, toi_legs = leg_time_of_impact(
            ps.c, ps.a, c, a, v, w, v1, v2, touching, cfg.velocity_iterations, dt, cfg.sweep_layout
        )
        new = new.replace(c=c, a=a, v=v, w=w)
    m_end, idx_end = K.leg_manifolds(c, a, v1, v2)
    if cfg.toi:
        toi_pairs = K.scatter_touching(m_end, idx_end) & toi_legs[:, None] & ~touching
    else:
        deep = m_end.valid & (m_end.separation < C.TOI_TARGET)[..., None]
        toi_pairs = K.scatter_touching(m_end.replace(valid=deep), idx_end) & ~touching
    hull_end = K.hull_manifolds(c, a, v1, v2)
    hull_toi = jnp.any(hull_end.valid & (hull_end.separation < C.TOI_TARGET)[:, None], -1) & ~hull_now
    new = new.replace(
        leg_touching=touching | toi_pairs,
        hull_touching=hull_now | hull_toi,
        contact_key=keys,
        contact_impulse=store,
        manifold=m_end,
        manifold_edges=idx_end,
        hull_contact=jnp.any(hull_end.valid, -1),
    )
    events = StepEvents(
        leg_begin=jnp.any(touching & ~ps.leg_touching, -1),
        leg_end=jnp.any(~touching & ps.leg_touching, -1),
        leg_toi_begin=jnp.any(toi_pairs, -1),
        hull_begin=jnp.any(hull_now & ~ps.hull_touching) | jnp.any(hull_toi),
        asleep=asleep,
    )
    return new, events
