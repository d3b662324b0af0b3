"""Fitness and descriptor measures of black-box evaluation, named in config.

A measure is read from the evaluation record (``rlq.lib.rollout.evaluate``: each episode's ``info``
at the step it ended). Some measures need an env wrapper that writes their ``info`` entry;
``wrap_measure`` adds it inside the auto-reset (``make_env`` calls it).

- fitness ``return``: the episode return; ``energy``: minus the mean |joint actuator force| over
  the episode (brittle star: ``info["energy"]``), i.e. the energy spent, to be minimised; ``distance``: how far
  the body ends from where it started (the undirected brittle star: ``info["distance_from_origin"]``).
- descriptor ``final_xy``: where the body ends (brittle star disk xy, metres); ``landing``
  (LunarLander): the x position at the episode's end and the speed at the first leg contact (the
  impact speed when no leg touched), both in observation units; ``feet_contact`` (the humanoid,
  QDax's ``humanoid_uni``): the fraction of the episode's steps each foot (right, left) touches the
  floor, in [0, 1]; ``last_obs``: the observation at the episode's end. ``algo.descriptor_dims`` picks
  components of any descriptor.

An env reports its own descriptors: in ``info`` (the brittle star's ``final_xy``) or through a wrapper
it names in ``Env.descriptor_wrappers`` (LunarLander's ``landing``, the humanoid's ``feet_contact``), so
nothing here reads one env's observation layout. ``last_obs`` is the one generic descriptor.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import jax
import jax.numpy as jnp

from rlq.lib.env_api import Env, EnvState, Wrapper

Record = dict[str, jax.Array]

FITNESS: dict[str, Callable[[Record], jax.Array]] = {
    "return": lambda record: record["episode_return"],
    "energy": lambda record: -record["energy"],
    "distance": lambda record: record["distance_from_origin"],
}
#: the info key each fitness needs from the env
FITNESS_KEYS = {"return": "episode_return", "energy": "energy", "distance": "distance_from_origin"}
#: an env that reports each fitness, for the line that refuses another
FITNESS_ENVS = {"return": "any env", "energy": "a brittle star env", "distance": "env=brittle_star_undirected"}
#: descriptor name -> the info key it is read from
DESCRIPTOR_KEYS = {"final_xy": "final_xy", "landing": "landing", "feet_contact": "feet_contact", "last_obs": "last_obs"}


class LastObservation(Wrapper):
    """``info["last_obs"]``: the observation a transition ends in (before any auto-reset)."""

    def reset(self, key: jax.Array) -> EnvState:
        state = self.env.reset(key)
        return state.replace(info={**state.info, "last_obs": jnp.asarray(state.obs, jnp.float32)})

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        nxt = self.env.step(state, action)
        return nxt.replace(info={**nxt.info, "last_obs": jnp.asarray(nxt.obs, jnp.float32)})


#: descriptors any env can report, through a wrapper of their own
GENERIC_WRAPPERS: dict[str, type[Wrapper]] = {"last_obs": LastObservation}


def wrap_measure(env: Env, descriptor: str | None) -> Env:
    """Add the wrapper a descriptor needs: the env's own (``Env.descriptor_wrappers``) or a generic one;
    none for descriptors the env reports in its ``info``."""
    name = descriptor or ""
    wrapper = env.unwrapped.descriptor_wrappers.get(name) or GENERIC_WRAPPERS.get(name)
    return wrapper(env) if wrapper else env


def check(fitness: str, descriptor: str | None, info_keys: set[str], own: Iterable[str] = ()) -> str | None:
    """A one-line problem with the named measures on an env (wrapped by ``wrap_measure``) whose episodes
    report ``info_keys``, or None. ``own``: the descriptors the env reports through wrappers of its own
    (``Env.descriptor_wrappers``), named among those it reports."""
    if fitness not in FITNESS:
        return f"algo.fitness must be one of {', '.join(FITNESS)}, got {fitness!r}"
    if FITNESS_KEYS[fitness] not in info_keys:
        return (
            f"algo.fitness={fitness} needs an env that reports {FITNESS_KEYS[fitness]!r} (e.g. {FITNESS_ENVS[fitness]})"
        )
    if descriptor is None:
        return None
    if descriptor not in DESCRIPTOR_KEYS:
        return f"algo.descriptor must be one of {', '.join(DESCRIPTOR_KEYS)}, got {descriptor!r}"
    if DESCRIPTOR_KEYS[descriptor] not in info_keys:
        wrapped = set(GENERIC_WRAPPERS) | set(own)
        reported = [name for name, key in DESCRIPTOR_KEYS.items() if key in info_keys or name in wrapped]
        return f"algo.descriptor={descriptor} is not reported by this env; it reports {', '.join(reported)}"
    return None
