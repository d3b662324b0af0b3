"""The CPG controller: the agent's action modulates a central pattern generator whose outputs
become the brittle star's joint targets (rlq/cpg.py holds the oscillator math).

- ``mode=leading_arm``: action ``Discrete(5)``, the leading arm of T0's pattern.
- ``mode=parametric``: action ``Box`` of 26 (5 arms): R (10), X (10), omega, one IP->OOP phase
  bias per arm (T2's genotype), clipped to its bounds.
- ``modulate=at_reset``: the first action of an episode is latched and later ones are ignored
  (open loop, as in the MAP-Elites tutorial; ``reset`` takes no action, so "at reset" means the
  episode's first step). ``every_step``: each action sets the modulation of that step.

One CPG step of length ``dt`` = the env's control timestep precedes every env step; oscillator
2k (IP) drives every in-plane joint of arm k and 2k+1 (OOP) every out-of-plane joint, matched
through the env's actuator layout (parsed from biorobot's actuator names).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from omegaconf import DictConfig

from rlq import cpg
from rlq.envs.base import Env, EnvState, Wrapper
from rlq.envs.spaces import Box, Discrete

BRITTLE_STAR_ENVS = ("brittle_star", "brittle_star_undirected")
MODES = ("leading_arm", "parametric")
MODULATE = ("every_step", "at_reset")


@dataclass(frozen=True)
class CPGConfig:
    mode: str = "leading_arm"
    modulate: str = "every_step"
    integrator: str = "euler"
    coupling: str = "ring"
    coupling_weight: float = 5.0
    amplitude_gain: float = 20.0
    offset_gain: float = 20.0
    phase_noise: float = 0.01
    leading_amplitude: float = 0.5
    leading_omega: float = math.pi
    leading_arm: int | None = None
    max_amplitude: float = 1.0
    max_offset: float = 1.0
    max_omega: float = 3 * math.pi


@struct.dataclass
class CPGInner:
    env: Any
    cpg: cpg.CPGState
    modulation: cpg.Modulation
    latched: jax.Array


def _config(controller_cfg: DictConfig) -> CPGConfig:
    fields = CPGConfig.__dataclass_fields__
    return CPGConfig(**{k: v for k, v in controller_cfg.items() if k in fields})


def check(controller_cfg: DictConfig, env_cfg: DictConfig) -> str | None:
    if env_cfg.name not in BRITTLE_STAR_ENVS:
        return "controller=cpg needs a brittle star env (env=brittle_star or env=brittle_star_undirected)"
    cfg = _config(controller_cfg)
    for key, value, options in (
        ("mode", cfg.mode, MODES),
        ("modulate", cfg.modulate, MODULATE),
        ("integrator", cfg.integrator, ("euler", "rk4")),
        ("coupling", cfg.coupling, ("ring", "arm", "none")),
    ):
        if value not in options:
            return f"controller.{key} must be one of {', '.join(options)}, got {value!r}"
    num_arms = int(env_cfg.get("num_arms", 5))
    if cfg.mode == "leading_arm" and num_arms != 5:
        return f"controller.mode=leading_arm needs 5 arms, got env.num_arms={num_arms} (use controller.mode=parametric)"
    if cfg.leading_arm is not None and not 0 <= cfg.leading_arm < num_arms:
        return f"controller.leading_arm must be null or an arm index 0..{num_arms - 1}, got {cfg.leading_arm}"
    return None


class CPGController(Wrapper):
    """Brittle star env driven through a CPG; the oscillators live in ``EnvState.inner``."""

    def __init__(self, env: Env, cfg: CPGConfig):
        super().__init__(env)
        base = env.unwrapped
        layout = base.layout
        self.cfg = cfg
        self.num_arms = int(layout.arm.max()) + 1
        self.num_oscillators = 2 * self.num_arms
        self.dt = float(base.control_timestep)
        self._weights = jnp.asarray(cpg.coupling_weights(self.num_arms, cfg.coupling, cfg.coupling_weight), jnp.float32)
        self._osc_of_action = jnp.asarray(2 * layout.arm + layout.kind)
        self._low, self._high = jnp.asarray(layout.low), jnp.asarray(layout.high)
        bound = np.zeros(self.num_oscillators)
        bound[2 * layout.arm + layout.kind] = np.maximum(np.abs(layout.low), np.abs(layout.high))
        self._leading_amplitude = jnp.asarray(cfg.leading_amplitude * bound, jnp.float32)
        if cfg.mode == "leading_arm":
            self._action_space = Discrete(self.num_arms)
        else:
            low, high = cpg.parametric_bounds(self.num_arms, cfg.max_amplitude, cfg.max_offset, cfg.max_omega)
            self._action_space = Box(tuple(map(float, low)), tuple(map(float, high)))

    @property
    def action_space(self) -> Discrete | Box:  # type: ignore[override]
        return self._action_space

    def modulation(self, action: jax.Array) -> cpg.Modulation:
        if self.cfg.mode == "leading_arm":
            arm = action if self.cfg.leading_arm is None else self.cfg.leading_arm
            arm = jnp.clip(jnp.asarray(arm, jnp.int32), 0, self.num_arms - 1)
            return cpg.leading_arm_modulation(arm, self._leading_amplitude, self.cfg.leading_omega)
        space = self._action_space
        params = jnp.clip(jnp.asarray(action, jnp.float32), jnp.asarray(space.low), jnp.asarray(space.high))
        return cpg.parametric_modulation(params, self.num_arms)

    def joint_targets(self, state: cpg.CPGState) -> jax.Array:
        """Each arm's (IP, OOP) outputs repeated over its segments, clipped to the joint ranges."""
        return jnp.clip(cpg.output(state)[self._osc_of_action], self._low, self._high)

    def base_states(self, states: EnvState) -> EnvState:
        return self.env.base_states(states.replace(inner=states.inner.env))

    def reset(self, key: jax.Array) -> EnvState:
        key, cpg_key = jax.random.split(key)
        state = self.env.reset(key)
        n = self.num_oscillators
        idle = cpg.Modulation(R=jnp.zeros(n), X=jnp.zeros(n), omega=jnp.zeros(n), rho=jnp.zeros((n, n)))
        inner = CPGInner(
            env=state.inner,
            cpg=cpg.init_state(cpg_key, n, self.cfg.phase_noise),
            modulation=idle,
            latched=jnp.zeros((), bool),
        )
        return state.replace(inner=inner)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        inner: CPGInner = state.inner
        mod = self.modulation(action)
        if self.cfg.modulate == "at_reset":
            mod = jax.tree.map(lambda old, new: jnp.where(inner.latched, old, new), inner.modulation, mod)
        osc = cpg.step(
            inner.cpg, mod, self._weights, self.dt, self.cfg.amplitude_gain, self.cfg.offset_gain, self.cfg.integrator
        )
        nxt = self.env.step(state.replace(inner=inner.env), self.joint_targets(osc))
        return nxt.replace(inner=CPGInner(env=nxt.inner, cpg=osc, modulation=mod, latched=jnp.ones((), bool)))


def wrap(env: Env, controller_cfg: DictConfig, env_cfg: DictConfig) -> Env:
    problem = check(controller_cfg, env_cfg)
    if problem:
        raise ValueError(problem)
    return CPGController(env, _config(controller_cfg))
