"""The humanoid's feet-contact descriptor for quality-diversity archives (QDax's ``humanoid_uni``): the fraction
of an episode's steps in which each foot touches the floor, two numbers in [0, 1].

As QDax counts it (its ``FeetContactWrapper`` and ``get_feet_contact_proportion``): the states the policy acted in,
from the reset's to the one before the episode's last step, each foot's flag 1 when its contact with the floor has
a distance <= 0. brax's humanoid.xml lets only the feet's spheres touch the floor (every other geom has
``contype=0 conaffinity=0``), and a sphere's contact with a plane has distance ``z - radius - floor height``, so
the flags are read off the feet's positions: the same test for MJX's JAX implementation and MuJoCo Warp (whose
contacts brax does not reformat), no contact list searched. Feet in the model's order: right, then left (QDax's
order of the ``right_shin`` and ``left_shin`` links that carry them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from rlq.lib.env_api import EnvState, ResultWrapper

#: the feet's geoms in brax's humanoid.xml, in the model's order, and the floor's
FEET = ("right_foot", "left_foot")
FLOOR = "floor"
#: the descriptor's name (``algo.descriptor``) and its ``info`` entry
NAME = "feet_contact"


@dataclass(frozen=True)
class Feet:
    """Where to read the feet's contact: their geoms' ids and radii, the floor's height."""

    geoms: np.ndarray
    radii: np.ndarray
    floor_z: float


def feet_of(mj_model: mujoco.MjModel) -> Feet:
    """The feet's spheres and the floor plane of a humanoid model; ValueError if the model has other shapes."""
    ids = [mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_GEOM, name) for name in (*FEET, FLOOR)]
    if min(ids) < 0:
        raise ValueError(f"the humanoid model needs geoms named {', '.join((*FEET, FLOOR))}")
    *feet, floor = ids
    if any(mj_model.geom_type[g] != mujoco.mjtGeom.mjGEOM_SPHERE for g in feet):
        raise ValueError("the feet-contact descriptor reads spheres' heights: the humanoid's feet are not spheres")
    level = np.allclose(mj_model.geom_quat[floor], [1.0, 0.0, 0.0, 0.0])
    if mj_model.geom_type[floor] != mujoco.mjtGeom.mjGEOM_PLANE or not level:
        raise ValueError("the feet-contact descriptor needs a level floor plane")
    radii = mj_model.geom_size[feet, 0].astype(np.float32)
    return Feet(np.asarray(feet, np.int32), radii, float(mj_model.geom_pos[floor, 2]))


def on_floor(geom_xpos: jax.Array, feet: Feet) -> jax.Array:
    """(feet,) 1.0 where a foot's sphere reaches the floor (contact distance <= 0), else 0.0."""
    dist = geom_xpos[feet.geoms, 2] - jnp.asarray(feet.radii) - feet.floor_z
    return (dist <= 0.0).astype(jnp.float32)


class FeetContactTime(ResultWrapper):
    """``info["feet_contact"]``: per foot, the share of the states the episode's actions were taken in so far (the
    reset's, then each later step's start: the state a step ends in counts when the next step leaves it) in which
    the foot touched the floor; zeros at the reset. The base env (``unwrapped``) gives one state's flags:
    ``feet_on_floor(state) -> (feet,)`` of 0.0 and 1.0."""

    def on_reset(self, state: EnvState) -> EnvState:
        count = self._flags(state).shape[0]
        extras = {
            **state.extras,
            "feet_contact_sum": jnp.zeros(count, jnp.float32),
            "feet_contact_steps": jnp.zeros((), jnp.float32),
        }
        return state.replace(extras=extras, info={**state.info, NAME: jnp.zeros(count, jnp.float32)})

    def on_step(self, state: EnvState, nxt: EnvState) -> EnvState:
        total = state.extras["feet_contact_sum"] + self._flags(state)  # the state the action was taken in
        steps = state.extras["feet_contact_steps"] + 1.0
        extras = {**nxt.extras, "feet_contact_sum": total, "feet_contact_steps": steps}
        return nxt.replace(extras=extras, info={**nxt.info, NAME: total / steps})

    def _flags(self, state: EnvState) -> jax.Array:
        base: Any = self.env.unwrapped
        return jnp.asarray(base.feet_on_floor(self.env.base_states(state)), jnp.float32)
