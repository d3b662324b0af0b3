"""Gymnasium's LunarLander ``heuristic`` controller, written in jnp (jit- and vmap-able)."""

from __future__ import annotations

import jax
import jax.numpy as jnp


def heuristic(obs: jax.Array, continuous: bool = False) -> jax.Array:
    """The action Gymnasium's ``heuristic(env, s)`` picks for observation ``obs`` (8,)."""
    s = obs
    angle_targ = jnp.clip(s[0] * 0.5 + s[2] * 1.0, -0.4, 0.4)
    hover_targ = 0.55 * jnp.abs(s[0])
    angle_todo = (angle_targ - s[4]) * 0.5 - s[5] * 1.0
    hover_todo = (hover_targ - s[1]) * 0.5 - s[3] * 0.5
    contact = (s[6] != 0) | (s[7] != 0)
    angle_todo = jnp.where(contact, 0.0, angle_todo)
    hover_todo = jnp.where(contact, -s[3] * 0.5, hover_todo)
    if continuous:
        return jnp.clip(jnp.stack([hover_todo * 20 - 1, -angle_todo * 20]), -1.0, 1.0)
    main = (hover_todo > jnp.abs(angle_todo)) & (hover_todo > 0.05)
    return jnp.where(main, 2, jnp.where(angle_todo < -0.05, 3, jnp.where(angle_todo > 0.05, 1, 0))).astype(jnp.int32)
