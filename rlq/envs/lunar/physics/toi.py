"""Box2D's continuous collision (b2World::SolveTOI) for the legs.

A leg moving fast enough to sink deeper than Box2D's time-of-impact target within one step is
moved back to the moment its core reaches that distance from the terrain, its contacts there are
solved on their own (position correction, then velocities, without the joint: Box2D's TOI
islands hold only the body and the static ground), and it moves on with its new velocity for the
rest of the step. The joint drift this leaves is corrected by the next step, as in Box2D.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.physics import contacts as K
from rlq.envs.lunar.physics import fused_sweeps as F
from rlq.lib.carry import batched_zeros


def leg_time_of_impact(
    c0, a0, c1, a1, v, w, v1, v2, touching, velocity_iterations: int, dt: float, sweep_layout: str = "auto"
):
    """Legs' TOI sub-steps. ``c0, a0``: positions at the start of the step; ``c1, a1, v, w``: after
    the discrete solve; ``touching`` (2, NUM_EDGES): leg contacts touching at the start of the step.
    Returns the new positions and velocities, and which legs had a time-of-impact event.
    ``sweep_layout``: the velocity sweeps' form (``SolverConfig.sweep_layout``)."""
    m1, idx = K.leg_manifolds(c1, a1, v1, v2)
    m0, _ = K.leg_manifolds(c0, a0, v1, v2, idx)
    was_touching = touching[jnp.arange(2)[:, None], idx]
    hit = m1.valid.any(-1) & (m1.separation < C.TOI_TARGET) & ~was_touching & (m0.separation > C.TOI_TARGET)
    alpha = (m0.separation - C.TOI_TARGET) / jnp.maximum(m0.separation - m1.separation, 1e-9)
    alpha = jnp.where(hit, jnp.clip(alpha, 0.0, 1.0), 1.0).min(-1)  # (2 legs,)
    event = jnp.any(hit, -1)

    lerp = alpha[:, None]
    c = c1.at[1:].set(c0[1:] + lerp * (c1[1:] - c0[1:]))
    a = a1.at[1:].set(a0[1:] + alpha * (a1[1:] - a0[1:]))
    m, _ = K.leg_manifolds(c, a, v1, v2)

    # Only the legs with an event use what follows, so the loops stop once those are done (none
    # at most steps: the loops then run zero times, also when a batch of envs is vmapped).
    def correct(carry):
        i, c, a, done = carry
        c2, a2, min_sep = K.position_pass(c, a, m, C.TOI_BAUMGARTE)
        keep = done[:, None]
        c = c.at[1:].set(jnp.where(keep, c[1:], c2[1:]))
        a = a.at[1:].set(jnp.where(done, a[1:], a2[1:]))
        return i + 1, c, a, done | (min_sep >= -1.5 * C.LINEAR_SLOP)

    def correcting(carry):
        i, _, _, done = carry
        return (i < C.TOI_POSITION_ITERATIONS) & jnp.any(event & ~done)

    start = (batched_zeros(a0[0], dtype=jnp.int32), c, a, batched_zeros(a0[0], (2,), jnp.bool_))
    _, c, a, _ = jax.lax.while_loop(correcting, correct, start)
    cc = K.constants(m, c, a, block_solve=True)
    sweeps = jnp.where(jnp.any(event), velocity_iterations, 0)

    def stacked(vl, wl, cc, sweeps):
        def sweep(_, carry):
            vl, wl, pn, pt = carry
            return K.solve_velocity(vl, wl, pn, pt, cc)

        zeros = batched_zeros(a0[0], (2, 4))
        vl, wl, _, _ = jax.lax.fori_loop(0, sweeps, sweep, (vl, wl, zeros, zeros))
        return vl, wl

    vl, wl = F.by_layout(sweep_layout, stacked, F.contact_sweeps, v[1:], w[1:], cc, sweeps)
    rest = ((1.0 - alpha) * dt)[:, None]
    cl = c[1:] + rest * vl
    al = a[1:] + rest[:, 0] * wl
    pick = event[:, None]
    c_out = c1.at[1:].set(jnp.where(pick, cl, c1[1:]))
    a_out = a1.at[1:].set(jnp.where(event, al, a1[1:]))
    v_out = v.at[1:].set(jnp.where(pick, vl, v[1:]))
    w_out = w.at[1:].set(jnp.where(event, wl, w[1:]))
    return c_out, a_out, v_out, w_out, event
