"""Fitness and descriptor measures of black-box evaluation, named in config.

A measure is read from the evaluation record (``rlq.lib.rollout.evaluate``: each episode's ``info``
at the step it ended). Some measures need an env wrapper that writes their ``info`` entry;
``wrap_measure`` adds it inside the auto-reset (``make_env`` calls it).

- fitness ``return``: the episode return; ``energy``: minus the mean |joint actuator force| over
  the episode (brittle star: ``info["energy"]``), i.e. the energy spent, to be minimised.
- descriptor ``final_xy``: where the body ends (brittle star disk xy, metres); ``landing``
  (LunarLander): the x position at the episode's end and the speed at the first leg contact (the
  impact speed when no leg touched), both in observation units; ``last_obs``: the observation at
  the episode's end. ``algo.descriptor_dims`` picks components of any descriptor.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from rlq.lib.env_api import Env, EnvState, Wrapper

Record = dict[str, jax.Array]

FITNESS: dict[str, Callable[[Record], jax.Array]] = {
    "return": lambda record: record["episode_return"],
    "energy": lambda record: -record["energy"],
}
#: the info key each fitness needs from the env
FITNESS_KEYS = {"return": "episode_return", "energy": "energy"}
#: descriptor name -> the info key it is read from
DESCRIPTOR_KEYS = {"final_xy": "final_xy", "landing": "landing", "last_obs": "last_obs"}
#: descriptors whose wrapper reads one env's observation layout -> that env's class (the wrapper adds
#: its info key to any env, so the key alone does not say the measure means anything there)
OBSERVATION_OF = {"landing": "LunarLander"}


class LastObservation(Wrapper):
    """``info["last_obs"]``: the observation a transition ends in (before any auto-reset)."""

    def reset(self, key: jax.Array) -> EnvState:
        state = self.env.reset(key)
        return state.replace(info={**state.info, "last_obs": jnp.asarray(state.obs, jnp.float32)})

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        nxt = self.env.step(state, action)
        return nxt.replace(info={**nxt.info, "last_obs": jnp.asarray(nxt.obs, jnp.float32)})


class LandingMeasure(Wrapper):
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


WRAPPERS: dict[str, type[Wrapper]] = {"landing": LandingMeasure, "last_obs": LastObservation}


def wrap_measure(env: Env, descriptor: str | None) -> Env:
    """Add the wrapper a descriptor needs (none for measures the env reports itself)."""
    wrapper = WRAPPERS.get(descriptor or "")
    return wrapper(env) if wrapper else env


def check(fitness: str, descriptor: str | None, info_keys: set[str], base_env: str) -> str | None:
    """A one-line problem with the named measures on an env reporting ``info_keys`` whose base env
    (``Env.unwrapped``) is of class ``base_env``, or None."""
    if fitness not in FITNESS:
        return f"algo.fitness must be one of {', '.join(FITNESS)}, got {fitness!r}"
    if FITNESS_KEYS[fitness] not in info_keys:
        return f"algo.fitness={fitness} needs an env that reports {FITNESS_KEYS[fitness]!r} (e.g. a brittle star env)"
    if descriptor is None:
        return None
    if descriptor not in DESCRIPTOR_KEYS:
        return f"algo.descriptor must be one of {', '.join(DESCRIPTOR_KEYS)}, got {descriptor!r}"
    needs = OBSERVATION_OF.get(descriptor)
    if DESCRIPTOR_KEYS[descriptor] not in info_keys or (needs is not None and base_env != needs):
        hint = {"final_xy": "a brittle star env", "landing": "env=lunar"}.get(descriptor, "another env")
        only = f" ({needs} only)" if needs else ""
        return f"algo.descriptor={descriptor} is not reported by this env{only}; use {hint}"
    return None
