"""brax's humanoid (MJX backend) behind the rlq Env protocol.

brax's ``State`` lives in ``EnvState.inner["brax"]`` (with the env's randomised model fields in
``inner["model"]``); termination comes from brax's ``done``, truncation from rlq's TimeLimit, so
brax's EpisodeWrapper/AutoResetWrapper are not used. brax's metrics (forward reward, x
velocity, ...) are copied into ``info`` every step.
"""

from __future__ import annotations

import contextlib
import functools
import math
import threading
from collections.abc import Iterator, Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from brax import envs as brax_envs
from mujoco import mjx

from rlq.declared.envs.humanoid import Config
from rlq.envs.humanoid import (
    feet_contact,
    gym_physics,
    mjx_patches,
    mjx_unroll,
    mjx_vectorized,
    mjx_warp,
    model_load,
    randomize,
)
from rlq.envs.mujoco.impl import resolve_impl
from rlq.envs.mujoco.render import MujocoRendering, qpos_frames
from rlq.lib import settings
from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import Box

#: env config keys passed to brax's Humanoid constructor
BRAX_KEYS = (
    "forward_reward_weight",
    "ctrl_cost_weight",
    "healthy_reward",
    "terminate_when_unhealthy",
    "healthy_z_range",
    "reset_noise_scale",
    "exclude_current_positions_from_observation",
    "n_frames",
)
#: env.unroll_physics: which of the physics' fixed-length loops are traced unrolled (rlq.envs.humanoid.mjx_unroll)
UNROLL = ("none", "linesearch", "all")
#: env.substep_carry: what brax's loop over the n_frames physics steps carries (rlq.envs.humanoid.mjx_unroll)
SUBSTEP_CARRY = ("data", "mjx", "state")
#: brax's side camera that tracks the humanoid's centre of mass (humanoid.xml)
CAMERA = "track"
#: held while a thread traces the physics (see Humanoid._physics_tracing)
TRACING = threading.RLock()
#: MuJoCo Warp's contact buffer, shared by all envs of a batch (48 per env for 21,845 envs)
WARP_CONTACTS = 1 << 20
#: the most env.contact_cost_weight takes off one step's reward (Gym's Humanoid-v1 and Gymnasium's Humanoid-v5)
CONTACT_COST_MAX = 10.0


def _float32(tree: Mapping) -> dict[str, jax.Array]:
    return {k: jnp.asarray(v, jnp.float32) for k, v in tree.items()}


class Humanoid(MujocoRendering, Env):
    """17 torques in [-1, 1]; episodes of ``episode_length`` control steps (``env.action_repeat``
    is rlq's ActionRepeat wrapper, which brings the limit down to ``episode_length / repeat``).

    ``reset_cache`` asks rlq's AutoReset to start every later episode of an env from that env's
    first state (as brax's AutoResetWrapper does) instead of computing a fresh MJX reset in
    every step; the randomised model of an env then stays fixed for the run, as in brax.

    ``mjx_impl="warp"`` steps the same model with MuJoCo Warp (rlq.envs.humanoid.mjx_warp); its contact
    buffer holds ``warp_contacts`` contacts shared by all envs of a batch.

    ``unroll_physics`` traces MJX's linesearch trips ("linesearch"), or those and the
    ``n_frames`` physics steps ("all"), as straight-line code (rlq.envs.humanoid.mjx_unroll): same
    arithmetic, fewer separate GPU launches per step, a longer compile. With ``reset_cache`` the
    reset's forward pass runs once per env and run, so it keeps MJX's loop: the run's init program
    then compiles faster, and so does the chunk beside it (docs/humanoid.md).

    ``substep_carry`` says what the loop over the ``n_frames`` physics steps carries (same results
    each way; rlq.envs.humanoid.mjx_unroll): ``"mjx"`` (default) MJX's data, with brax's own fields built
    once after the loop; ``"data"`` brax's state, rebuilt by every trip (brax's own loop);
    ``"state"`` only MuJoCo's integration state (the last physics step is traced a second time,
    after the loop, so compiles take longer). With ``unroll_physics="all"`` there is no loop and
    ``"mjx"`` is ``"data"``.

    ``vectorized_cdof`` and ``vectorized_com_vel`` compute MJX's motion DOFs and its body and DOF
    velocities for all DOFs at once (rlq.envs.humanoid.mjx_vectorized; cheaper GPU kernels; the first gives
    MJX's numbers bit for bit, the second sums in another order). These and ``"mjx"`` apply to
    MJX-JAX only; with ``mjx_impl="warp"`` the loop stays brax's.

    Videos: brax's side camera ``track``, one frame per control step.

    ``contact_forces`` appends each body's external contact force and torque (MuJoCo's ``cfrc_ext`` from
    ``mjx.rne_postconstraint``, 6 per body, the world body left out) to brax's observation, which leaves them out:
    Gym's Humanoid-v1 observed them (Mania et al.'s linear policies learned on that observation) and Gymnasium's
    Humanoid-v5 does by default (``include_cfrc_ext_in_observation``). MJX-JAX only.

    ``contact_cost_weight`` takes Gym's Humanoid-v1 impact cost off the reward: the weight times the sum of squares of
    those wrenches, at most ``CONTACT_COST_MAX`` per step (``info["reward_contact"]``: minus the cost). MJX-JAX only.

    ``algo.descriptor=feet_contact`` (QDax's ``humanoid_uni``): the fraction of an episode's steps each foot
    touches the floor (rlq.envs.humanoid.feet_contact), from ``feet_on_floor``.
    """

    descriptor_wrappers = {feet_contact.NAME: feet_contact.FeetContactTime}
    #: brax scales [-1, 1] to the motors' control range without clipping and MuJoCo clamps the control; the control
    #: cost is charged on the unclamped value, as in Gym's Humanoid-v1
    clamps_actions = True

    def __init__(
        self,
        episode_length: int = 1000,
        randomize_ranges: randomize.Ranges | None = None,
        reset_cache: bool = True,
        mjx_impl: str = "jax",
        warp_contacts: int = WARP_CONTACTS,
        unroll_physics: str = "none",
        substep_carry: str = "data",
        vectorized_cdof: bool = False,
        vectorized_com_vel: bool = False,
        quick_model_load: bool = False,
        contact_forces: bool = False,
        contact_cost_weight: float = 0.0,
        contacts: str = "feet",
        integrator: str = "euler",
        solver_iterations: int | None = None,
        **brax_kwargs,
    ):
        if unroll_physics not in UNROLL:
            raise ValueError(f"env.unroll_physics must be one of {list(UNROLL)}, got {unroll_physics!r}")
        if substep_carry not in SUBSTEP_CARRY:
            raise ValueError(f"env.substep_carry must be one of {list(SUBSTEP_CARRY)}, got {substep_carry!r}")
        if substep_carry == "state" and unroll_physics == "all":
            raise ValueError("env.substep_carry=state needs the physics-step loop; env.unroll_physics=all unrolls it")
        keys = {
            "contacts": contacts,
            "integrator": integrator,
            "solver_iterations": solver_iterations,
            "contact_cost_weight": contact_cost_weight,
        }
        problem = settings.problems(Config, keys, "env")
        if problem:
            raise ValueError(problem)
        mjx_impl = resolve_impl(mjx_impl)
        brax_physics = gym_physics.is_brax_physics(contacts, integrator, solver_iterations)
        if not brax_physics and mjx_impl != "jax":
            raise ValueError(
                "env.contacts, env.integrator and env.solver_iterations rebuild the MJX-JAX model: use env.mjx_impl=jax"
            )
        if contact_forces and mjx_impl != "jax":
            raise ValueError(
                "env.include_cfrc_ext_in_observation=true reads MJX-JAX's contact forces: use env.mjx_impl=jax"
            )
        if contact_cost_weight and mjx_impl != "jax":
            raise ValueError("env.contact_cost_weight reads MJX-JAX's contact forces: use env.mjx_impl=jax")
        self.patches = mjx_patches.active_patches(
            mjx_impl, unroll_physics, substep_carry, vectorized_cdof, vectorized_com_vel, quick_model_load
        )
        mjx_patches.check_versions(self.patches)
        with model_load.arrays_by_transfer() if quick_model_load else contextlib.nullcontext():
            self._env = brax_envs.get_environment("humanoid", backend="mjx", **brax_kwargs)
            if not brax_physics:
                self._env.sys = gym_physics.gym_system(self._env.sys, contacts, integrator, solver_iterations)
        self.mjx_impl = mjx_impl
        if mjx_impl == "warp":
            mjx_warp.use_warp(self._env, warp_contacts)
        self.unroll_physics = unroll_physics
        self.vectorized_cdof = bool(vectorized_cdof) and mjx_impl == "jax"
        self.vectorized_com_vel = bool(vectorized_com_vel) and mjx_impl == "jax"
        if unroll_physics == "all":
            self._env.pipeline_step = mjx_unroll.unrolled_pipeline_step(self._env)
        if substep_carry == "state":
            self._env.pipeline_step = mjx_unroll.state_carry_pipeline_step(self._env)
        if substep_carry == "mjx" and unroll_physics != "all" and mjx_impl == "jax":
            self._env.pipeline_step = mjx_unroll.mjx_carry_pipeline_step(self._env)
        self._sys = self._env.sys
        self._ranges = randomize_ranges
        self.max_episode_steps = int(episode_length)
        self.reset_cache = bool(reset_cache)
        self.mj_model = self._sys.mj_model
        self._feet = feet_contact.feet_of(self.mj_model)
        self.render_fps = max(1, round(1.0 / float(self._env.dt)))
        self.contact_forces = bool(contact_forces)
        self.contact_cost_weight = float(contact_cost_weight)
        obs_dim = observation_size(
            self.mj_model, self._env._exclude_current_positions_from_observation, self.contact_forces
        )
        self.observation_space = Box.uniform(-math.inf, math.inf, obs_dim)
        self.action_space = Box.uniform(-1.0, 1.0, self._env.action_size)

    @property
    def brax_env(self):
        return self._env

    @contextlib.contextmanager
    def _model(self, overrides: Mapping[str, jax.Array]) -> Iterator[None]:
        """Trace brax's reset/step with this env's randomised model fields."""
        if not overrides:
            yield
            return
        self._env.sys = randomize.apply(self._sys, overrides)
        try:
            yield
        finally:
            self._env.sys = self._sys

    @contextlib.contextmanager
    def _physics_tracing(self, unroll: bool = True) -> Iterator[None]:
        """MJX's linesearch unrolled (if ``unroll``) and its ``cdof`` and ``com_vel`` vectorised,
        as asked, while the physics is traced (reset's forward pass too). These patch MJX's
        modules, and a run traces its evaluation program in a second thread
        (rlq.run.programs.compiling.compile_programs): one thread at a time traces the physics."""
        with TRACING, contextlib.ExitStack() as stack:
            if unroll and self.unroll_physics != "none":
                stack.enter_context(mjx_unroll.unrolled_linesearch())
            if self.vectorized_cdof:
                stack.enter_context(mjx_vectorized.vectorized_cdof())
            if self.vectorized_com_vel:
                stack.enter_context(mjx_vectorized.vectorized_com_vel())
            yield

    # brax's reset and step, each traced once per process: a run's init, chunk and evaluation
    # programs call them with the same per-env shapes, and MJX's physics takes seconds to trace
    # (a second program's step traced and lowered in 2.0 s instead of 4.4 s on a CPU; the evaluation
    # program's trace on an H200 host 3.6-4.5 s instead of 4.9-7.2 s). XLA inlines the calls: the
    # same states bit for bit (checked over 5 steps on a CPU).
    @functools.cached_property
    def _physics_reset(self):
        def reset(key: jax.Array, overrides: Mapping[str, jax.Array]):
            with self._physics_tracing(unroll=not self.reset_cache), self._model(overrides):
                return self._env.reset(key)

        return jax.jit(reset)

    @functools.cached_property
    def _physics_step(self):
        def step(brax_state: Any, action: jax.Array, overrides: Mapping[str, jax.Array]):
            with self._physics_tracing(), self._model(overrides):
                return self._env.step(brax_state, action)

        return jax.jit(step)

    def feet_on_floor(self, state: EnvState) -> jax.Array:
        """(2,) 1.0 where the right, then the left foot touches the floor in ``state``, else 0.0."""
        return feet_contact.on_floor(state.inner["brax"].pipeline_state.geom_xpos, self._feet)

    def frame_arrays(self, states: EnvState) -> dict[str, np.ndarray]:
        return {"qpos": np.asarray(states.inner["brax"].pipeline_state.qpos)}

    def draw_frames(self, arrays: Mapping[str, np.ndarray]) -> Iterator[np.ndarray]:
        return qpos_frames(self.mj_model, arrays["qpos"], lambda t, data: CAMERA)

    def _wrenches(self, brax_state: Any) -> jax.Array | None:
        """Every body's external contact wrench, (bodies, 6), the world body left out; None where neither the
        observation nor the reward reads them."""
        if not (self.contact_forces or self.contact_cost_weight):
            return None
        data = mjx.rne_postconstraint(self._sys, brax_state.pipeline_state)
        # mujoco-mjx 3.17 keeps cfrc_ext among its implementation's fields (the public name is deprecated there)
        return data._impl.cfrc_ext[1:]

    def _observe(self, brax_state: Any, wrenches: jax.Array | None) -> jax.Array:
        """brax's observation, and with ``contact_forces`` every body's external contact wrench after it."""
        if not self.contact_forces:
            return brax_state.obs
        assert wrenches is not None
        return jnp.concatenate([brax_state.obs, wrenches.reshape(-1).astype(brax_state.obs.dtype)])

    def _contact_cost(self, wrenches: jax.Array | None) -> dict[str, jax.Array]:
        """``{"reward_contact": -cost}`` with ``contact_cost_weight``, else nothing."""
        if not self.contact_cost_weight:
            return {}
        assert wrenches is not None
        cost = jnp.minimum(self.contact_cost_weight * jnp.sum(jnp.square(wrenches)), CONTACT_COST_MAX)
        return {"reward_contact": -cost.astype(jnp.float32)}

    def reset(self, key: jax.Array) -> EnvState:
        key, reset_key, model_key = jax.random.split(key, 3)
        overrides = randomize.sample(model_key, self._sys, self._ranges) if self._ranges else {}
        state = self._physics_reset(reset_key, overrides)
        state = state.replace(metrics=_float32(state.metrics))
        wrenches = self._wrenches(state)
        info = {**state.metrics, **self._contact_cost(wrenches)}
        return initial_state(self._observe(state, wrenches), {"brax": state, "model": overrides}, key, info=info)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        overrides = state.inner["model"]
        brax_state = state.inner["brax"]
        # brax updates ``metrics`` in place: hand it a copy so the caller's state stays intact
        brax_state = brax_state.replace(metrics=dict(brax_state.metrics), info=dict(brax_state.info))
        nxt = self._physics_step(brax_state, action, overrides)
        # some brax metrics are Python floats (the healthy reward): keep reset's dtypes
        nxt = nxt.replace(metrics=_float32(nxt.metrics))
        wrenches = self._wrenches(nxt)
        contact = self._contact_cost(wrenches)
        reward = jnp.asarray(nxt.reward, jnp.float32)
        if contact:
            reward = reward + contact["reward_contact"]
        return state.replace(
            obs=self._observe(nxt, wrenches),
            reward=reward,
            terminated=jnp.asarray(nxt.done > 0.5, bool),
            truncated=jnp.zeros((), bool),
            info={**state.info, **nxt.metrics, **contact},
            inner={"brax": nxt, "model": overrides},
        )


def observation_size(mj_model: Any, exclude_current_positions: bool, contact_forces: bool = False) -> int:
    """The length of brax's humanoid observation (brax 0.14's ``Humanoid._get_obs``): joint positions
    (without the root's x, y when excluded), joint velocities, each body's inertia (10) and
    centre-of-mass velocity (6), actuator forces (one per DOF); with ``contact_forces`` each body's external
    contact wrench (6) too. Read off the model rather than from a traced reset, which takes a second or more of
    every run's start."""
    links = mj_model.nbody - 1  # the world body is not one of brax's links
    per_link = 16 + (6 if contact_forces else 0)
    return mj_model.nq - (2 if exclude_current_positions else 0) + 2 * mj_model.nv + per_link * links


def make(cfg: Config) -> Env:
    kwargs = {k: getattr(cfg, k) for k in BRAX_KEYS if getattr(cfg, k) is not None}
    if "healthy_z_range" in kwargs:
        kwargs["healthy_z_range"] = tuple(kwargs["healthy_z_range"])
    return Humanoid(
        episode_length=cfg.episode_length,
        randomize_ranges=randomize.parse(cfg.randomize),
        reset_cache=cfg.reset_cache,
        mjx_impl=cfg.mjx_impl,
        warp_contacts=cfg.warp_contacts,
        unroll_physics=cfg.unroll_physics,
        substep_carry=cfg.substep_carry,
        vectorized_cdof=cfg.vectorized_cdof,
        vectorized_com_vel=cfg.vectorized_com_vel,
        quick_model_load=cfg.quick_model_load,
        contact_forces=cfg.include_cfrc_ext_in_observation,
        contact_cost_weight=cfg.contact_cost_weight,
        contacts=cfg.contacts,
        integrator=cfg.integrator,
        solver_iterations=cfg.solver_iterations,
        **kwargs,
    )
