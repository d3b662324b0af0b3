"""Gymnasium's LunarLander ``heuristic`` controller, written in jnp (jit- and vmap-able)."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from rlq.envs.lunar import consts as C
from rlq.lib.env_api import Env, EnvState


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


def heuristic_episodes(env: Env, state: EnvState, max_steps: int = 1000) -> dict[str, jax.Array]:
    """Run the heuristic from a batch of reset states of a bare ``rlq.envs.lunar.env`` env until every
    episode ends (or ``max_steps``). Per episode: return, length, landed, crashed, the step of the
    first leg contact (-1: none) and the vertical speed (m/s) one step before it."""
    continuous = bool(getattr(env, "continuous", False))
    vy_scale = C.FPS / (C.H / 2)
    n = state.obs.shape[0]
    zf, zi, zb = jnp.zeros(n, jnp.float32), jnp.zeros(n, jnp.int32), jnp.zeros(n, bool)
    carry: dict[str, Any] = dict(
        state=state, ret=zf, length=zi, done=zb, landed=zb, crashed=zb, first=zi - 1, vy=zf + jnp.nan
    )

    def cond(c):
        return jnp.any(~c["done"]) & (c["length"].max() < max_steps)

    def body(c):
        s = c["state"]
        nxt = jax.vmap(env.step)(s, jax.vmap(lambda o: heuristic(o, continuous))(s.obs))
        live = ~c["done"]
        length = c["length"] + live
        contact = (nxt.obs[:, 6] > 0) | (nxt.obs[:, 7] > 0)
        new_first = live & (c["first"] < 0) & contact
        return dict(
            state=nxt,
            ret=c["ret"] + jnp.where(live, nxt.reward, 0.0),
            length=length,
            done=c["done"] | (live & (nxt.terminated | (length >= max_steps))),
            landed=c["landed"] | (live & nxt.info["landed"]),
            crashed=c["crashed"] | (live & nxt.info["crashed"]),
            first=jnp.where(new_first, length, c["first"]),
            vy=jnp.where(new_first, s.obs[:, 3] * vy_scale, c["vy"]),
        )

    out: dict[str, Any] = jax.lax.while_loop(cond, body, carry)
    return {k: out[k] for k in ("ret", "length", "landed", "crashed", "first", "vy")}
