"""LunarLander's landing descriptor for quality-diversity archives: where and how hard it comes down."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from rlq.lib.env_api import EnvState, Wrapper


class LandingReport(Wrapper):
    """``info["landing"]`` = (x, touchdown speed) from LunarLander's observation
    ``[x, y, vx, vy, angle, angular velocity, leg 1 contact, leg 2 contact]``."""

    def reset(self, key: jax.Array) -> EnvState:
        state = self.env.reset(key)
        extras = {**state.extras, "touched": jnp.zeros((), bool), "touchdown_speed": jnp.zeros((), jnp.float32)}
        landing = jnp.stack([state.obs[0], jnp.zeros(())]).astype(jnp.float32)
        return state.replace(extras=extras, info={**state.info, "landing": landing})

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        nxt = self.env.step(state, action)
        obs = nxt.obs
        speed = jnp.linalg.norm(obs[2:4])
        contact = jnp.logical_or(obs[6] > 0.5, obs[7] > 0.5)
        touched = state.extras["touched"]
        touchdown = jnp.where(
            jnp.logical_and(contact, jnp.logical_not(touched)), speed, state.extras["touchdown_speed"]
        )
        touched = jnp.logical_or(touched, contact)
        landing = jnp.stack([obs[0], jnp.where(touched, touchdown, speed)]).astype(jnp.float32)
        extras = {**nxt.extras, "touched": touched, "touchdown_speed": touchdown.astype(jnp.float32)}
        return nxt.replace(extras=extras, info={**nxt.info, "landing": landing})
