"""``env=humanoid``'s keys: Humanoid from brax (MJX backend), 17 torques in [-1, 1], runs in +x. The keys from
``forward_reward_weight`` on go to brax's Humanoid constructor. Heavy on CPU (~80 s to compile, ~0.2 s per step):
train on a GPU."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rlq.declared.envs.shared import Discretize
from rlq.lib.settings import FINITE, NON_NEGATIVE, POSITIVE_INT, OneOf, Range, setting

#: env.contacts: brax's humanoid.xml (only the feet touch the floor) or Gym's Humanoid-v1 (every geom collides)
CONTACTS = ("feet", "all")
#: env.integrator: brax's humanoid.xml's (euler) or Gym's Humanoid-v1's (rk4)
INTEGRATORS = ("euler", "rk4")


@dataclass(frozen=True)
class Config:
    """``env=humanoid``'s keys: type, default, allowed values and meaning. The physics patches (``unroll_physics``
    to ``quick_model_load``) each replace private code of mujoco-mjx 3.17 / brax 0.14
    (rlq/envs/humanoid/mjx_patches.py), so all are off here (brax's own physics) and the env refuses them on other
    versions; experiment=humanoid_ppo turns them on (faster on a GPU; docs/humanoid.md)."""

    name: str = setting("humanoid")
    #: physics-control steps before truncation (rlq's TimeLimit)
    episode_length: int = setting(1000, POSITIVE_INT)
    #: control steps per agent step (rlq's ActionRepeat wrapper: rewards summed)
    action_repeat: int = setting(1, POSITIVE_INT)
    #: bins per observation dimension for tabular methods (rlq.declared.envs.shared.Discretize)
    discretize: Discretize | None = setting(None)
    #: AutoReset restarts each env from its own first state (as brax) instead of a fresh MJX reset computed every
    #: step; false: fresh reset noise (and model) every episode
    reset_cache: bool = setting(True)
    #: MJX implementation of the physics step: jax, warp (MuJoCo Warp's kernels, same model; pip install -e
    #: ".[cuda]") or auto (warp on an NVIDIA GPU); docs/humanoid.md: when it pays
    mjx_impl: str = setting("jax")
    #: warp: contact buffer shared by all envs of a batch (>= ~48 per env x envs x seeds)
    warp_contacts: int = setting(1048576, POSITIVE_INT)
    #: none | linesearch | all: trace MJX's linesearch trips (and with all, the n_frames physics steps) unrolled:
    #: same arithmetic, fewer GPU launches per step, longer compile (docs/humanoid.md). A reset run once per env
    #: (reset_cache) keeps MJX's loop: it compiles faster and gains nothing unrolled
    unroll_physics: str = setting("none")
    #: data | mjx | state: what the loop over the n_frames physics steps carries: brax's state, rebuilt every trip
    #: (brax's own loop); MJX's data, brax's fields built once after it; or MuJoCo's integration state only (traces
    #: the physics twice: longer compile). Same results each way (docs/humanoid.md)
    substep_carry: str = setting("data")
    #: MJX's motion DOFs (cdof) for all DOFs at once instead of per body group: same numbers, a cheaper GPU kernel
    #: (rlq.envs.humanoid.mjx_vectorized; MJX-JAX only)
    vectorized_cdof: bool = setting(False)
    #: MJX's body velocities and cdof_dot from one 0/1 matrix product over DOFs instead of a level-by-level tree
    #: scan: same sums in another order (float rounding), cheaper
    vectorized_com_vel: bool = setting(False)
    #: brax's model load makes its arrays with device transfers instead of jnp.array, which compiles ~80 small
    #: programs on a GPU (1.6-1.9 s per env built): same arrays
    quick_model_load: bool = setting(False)
    #: append each body's external contact force and torque (MuJoCo's cfrc_ext, 6 per body) to brax's observation,
    #: which leaves them out: Gym's Humanoid-v1 observed them, Gymnasium's Humanoid-v5 does by default (its key's
    #: name). MJX-JAX only (env.mjx_impl=jax)
    include_cfrc_ext_in_observation: bool = setting(False)
    #: Gym's Humanoid-v1 impact cost (Gymnasium's Humanoid-v5 names it contact_cost_weight, 5e-7): the weight times
    #: the sum of squares of every body's external contact wrench (cfrc_ext), at most 10 per step, taken off the
    #: reward; 0: brax's humanoid, which charges none. MJX-JAX only (env.mjx_impl=jax)
    contact_cost_weight: float = setting(0.0, NON_NEGATIVE)
    #: feet | all: which geoms touch: brax's humanoid.xml lets only the feet touch the floor; all is Gym's
    #: Humanoid-v1 (every geom collides with the floor and the others). MJX-JAX only (rlq/envs/humanoid/gym_physics.py)
    contacts: str = setting("feet", OneOf(CONTACTS))
    #: euler | rk4: the physics step's integrator (brax's humanoid.xml: euler; Gym's Humanoid-v1: rk4). MJX-JAX only
    integrator: str = setting("euler", OneOf(INTEGRATORS))
    #: the constraint solver's Newton iterations per physics step; null: brax's (1, with 4 line-search steps).
    #: MJX-JAX only
    solver_iterations: int | None = setting(None, Range(1, integer=True, nullable=True, null="null (brax's 1)"))
    #: per-env domain randomisation, e.g. {friction: [0.6, 1.4], gain_delta: [-5, 5]} (the MJX tutorial's ranges;
    #: gains += delta with bias[1] = -gain); randomize.py's check
    randomize: dict[str, Any] | None = setting(None)
    forward_reward_weight: float = setting(1.25, FINITE)
    ctrl_cost_weight: float = setting(0.1, NON_NEGATIVE)
    healthy_reward: float = setting(5.0, FINITE)
    terminate_when_unhealthy: bool = setting(True)
    #: torso height range of a healthy humanoid (brax's and the MJX tutorial's default)
    healthy_z_range: tuple[float, ...] = setting((1.0, 2.0))
    #: uniform noise on initial joint positions and velocities
    reset_noise_scale: float = setting(0.01, NON_NEGATIVE)
    exclude_current_positions_from_observation: bool = setting(True)
    #: physics steps (dt 0.003 s) per control step
    n_frames: int = setting(5, POSITIVE_INT)
