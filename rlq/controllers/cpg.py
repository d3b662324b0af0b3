"""The CPG controller: the agent's action modulates a central pattern generator whose outputs
become the brittle star's joint targets (rlq/controllers/oscillators.py holds the oscillator math).

- ``mode=leading_arm``: action ``Discrete(5)``, the leading arm of T0's pattern.
- ``mode=parametric``: action ``Box`` of 26 (5 arms): R (10), X (10), omega, one IP->OOP phase
  bias per arm (T2's genotype), clipped to its bounds.
- ``mode=parametric_segment``: ``Box`` of 4AS + 2A + 1 (71 for 5 x 3): one oscillator per joint,
  R and X per joint, omega, one IP->OOP bias and one segment-to-segment lag per arm.
- ``mode=parametric_symmetric``: ``Box`` of 5: T0's leading-arm pattern with continuous leading
  arm, rower amplitude, leader lift, omega and rower IP->OOP bias (5 arms).
- ``mode=decentralised``: action ``AgentsDiscrete(4, A)``, one role per arm (leader, left rower,
  right rower, idle; rlq/controllers/roles.py), for per-arm learners sharing one table.
- ``modulate=at_reset``: the first action of an episode is latched and later ones are ignored
  (open loop, as in the MAP-Elites tutorial; ``reset`` takes no action, so "at reset" means the
  episode's first step). ``every_step``: each action sets the modulation of that step.

One CPG step of length ``dt`` = the env's control timestep precedes every env step; oscillator
2k (IP) drives every in-plane joint of arm k and 2k+1 (OOP) every out-of-plane joint (in
``parametric_segment``: oscillator ``cpg.segment_osc(arm, segment, kind)`` drives its own joint),
matched through the env's actuator layout (parsed from biorobot's actuator names).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from rlq.controllers import oscillators as cpg
from rlq.controllers import roles
from rlq.controllers.oscillators import CPGState, Modulation
from rlq.declared.controllers.cpg import Config
from rlq.lib.env_api import Env, EnvState, Wrapper
from rlq.lib.spaces import AgentsDiscrete, Box, Discrete

BRITTLE_STAR_ENVS = ("brittle_star", "brittle_star_undirected")
MODES = ("leading_arm", "parametric", "parametric_segment", "parametric_symmetric", "decentralised")
FIVE_ARM_MODES = ("leading_arm", "parametric_symmetric")
MODULATE = ("every_step", "at_reset")


class CPGInner(struct.PyTreeNode):
    env: Any
    cpg: CPGState
    modulation: Modulation
    latched: jax.Array


class EnvSettings(Protocol):
    """What the CPG reads of the env's config: its name, and (a brittle star's) its arms."""

    @property
    def name(self) -> str: ...


@runtime_checkable
class Arms(Protocol):
    @property
    def num_arms(self) -> int: ...


def check(cfg: Config, env_cfg: EnvSettings) -> str | None:
    if env_cfg.name not in BRITTLE_STAR_ENVS:
        return "controller=cpg needs a brittle star env (env=brittle_star or env=brittle_star_undirected)"
    assert isinstance(env_cfg, Arms), "every brittle star declares env.num_arms"
    for key, value, options in (
        ("mode", cfg.mode, MODES),
        ("modulate", cfg.modulate, MODULATE),
        ("integrator", cfg.integrator, ("euler", "rk4")),
        ("coupling", cfg.coupling, ("ring", "arm", "none")),
    ):
        if value not in options:
            return f"controller.{key} must be one of {', '.join(options)}, got {value!r}"
    num_arms = int(env_cfg.num_arms)
    if cfg.mode in FIVE_ARM_MODES and num_arms != 5:
        return f"controller.mode={cfg.mode} needs 5 arms, got env.num_arms={num_arms} (use controller.mode=parametric)"
    if cfg.mode == "decentralised" and num_arms < 3:
        return f"controller.mode=decentralised needs a ring of at least 3 arms, got env.num_arms={num_arms}"
    if cfg.leading_arm is not None and not 0 <= cfg.leading_arm < num_arms:
        return f"controller.leading_arm must be null or an arm index 0..{num_arms - 1}, got {cfg.leading_arm}"
    return None


def oscillator_of_action(layout: Any, per_segment: bool) -> np.ndarray:
    """The oscillator each action (joint) follows: its arm's IP/OOP oscillator, or with
    ``per_segment`` its own (``cpg.segment_osc``); the layout must then hold every joint once."""
    if not per_segment:
        return np.asarray(2 * layout.arm + layout.kind)
    num_arms, num_segments = int(layout.arm.max()) + 1, int(layout.segment.max()) + 1
    index = np.asarray(cpg.segment_osc(layout.arm, layout.segment, layout.kind, num_segments))
    if sorted(index.tolist()) != list(range(2 * num_arms * num_segments)):
        raise ValueError("controller.mode=parametric_segment needs one actuator per arm, segment and joint kind")
    return index


def action_bounds(cfg: Config, num_arms: int, num_segments: int) -> tuple[np.ndarray, np.ndarray]:
    """The Box of a parametric mode's genotype."""
    maxima = (cfg.max_amplitude, cfg.max_offset, cfg.max_omega)
    if cfg.mode == "parametric_segment":
        return cpg.parametric_segment_bounds(num_arms, num_segments, *maxima)
    if cfg.mode == "parametric_symmetric":
        return cpg.parametric_symmetric_bounds(num_arms, *maxima)
    return cpg.parametric_bounds(num_arms, *maxima)


class CPGController(Wrapper):
    """Brittle star env driven through a CPG; the oscillators live in ``EnvState.inner``."""

    def __init__(self, env: Env, cfg: Config):
        super().__init__(env)
        base: Any = env.unwrapped  # a brittle star: check() admits no other env
        layout = base.layout
        self.cfg = cfg
        self.num_arms = int(layout.arm.max()) + 1
        self.num_segments = int(layout.segment.max()) + 1
        per_segment = cfg.mode == "parametric_segment"
        osc_segments = self.num_segments if per_segment else 1
        self.num_oscillators = 2 * self.num_arms * osc_segments
        self.dt = float(base.control_timestep)
        weights = cpg.coupling_weights(self.num_arms, cfg.coupling, cfg.coupling_weight, osc_segments)
        self._weights = jnp.asarray(weights, jnp.float32)
        self._osc_of_action = jnp.asarray(oscillator_of_action(layout, per_segment))
        self._low, self._high = jnp.asarray(layout.low), jnp.asarray(layout.high)
        bound = np.zeros(2 * self.num_arms)
        bound[2 * layout.arm + layout.kind] = np.maximum(np.abs(layout.low), np.abs(layout.high))
        self._leading_amplitude = jnp.asarray(cfg.leading_amplitude * bound, jnp.float32)
        self._action_space: Discrete | AgentsDiscrete | Box
        if cfg.mode == "leading_arm":
            self._action_space = Discrete(self.num_arms)
        elif cfg.mode == "decentralised":
            self._action_space = AgentsDiscrete(roles.NUM_ROLES, self.num_arms)
        else:
            low, high = action_bounds(cfg, self.num_arms, self.num_segments)
            self._action_space = Box(tuple(map(float, low)), tuple(map(float, high)))

    @property
    def action_space(self) -> Discrete | AgentsDiscrete | Box:  # type: ignore[override]
        return self._action_space

    def action_rotations(self) -> np.ndarray | None:
        """The action's index permutations that turn a gait by whole arms (``cpg.arm_rotations``;
        the body is symmetric under them), for the modes whose genotype is laid out arm by arm."""
        if self.cfg.mode == "parametric":
            return cpg.parametric_rotations(self.num_arms)
        if self.cfg.mode == "parametric_segment":
            return cpg.parametric_segment_rotations(self.num_arms, self.num_segments)
        return None

    def modulation(self, action: jax.Array) -> cpg.Modulation:
        if self.cfg.mode == "leading_arm":
            arm = action if self.cfg.leading_arm is None else self.cfg.leading_arm
            arm = jnp.clip(jnp.asarray(arm, jnp.int32), 0, self.num_arms - 1)
            return cpg.leading_arm_modulation(arm, self._leading_amplitude, self.cfg.leading_omega)
        if self.cfg.mode == "decentralised":
            return roles.role_modulation(action, self._leading_amplitude, self.cfg.leading_omega)
        space = self._action_space
        assert isinstance(space, Box), "every other mode has Box actions"
        params = jnp.clip(jnp.asarray(action, jnp.float32), jnp.asarray(space.low), jnp.asarray(space.high))
        if self.cfg.mode == "parametric_segment":
            return cpg.parametric_segment_modulation(params, self.num_arms, self.num_segments)
        if self.cfg.mode == "parametric_symmetric":
            return cpg.parametric_symmetric_modulation(params, self.num_arms)
        return cpg.parametric_modulation(params, self.num_arms)

    def joint_targets(self, state: cpg.CPGState) -> jax.Array:
        """Each joint gets its oscillator's output (an arm's IP/OOP pair repeats over its segments
        except in ``parametric_segment``), clipped to the joint's range."""
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


def wrap(env: Env, cfg: Config, env_cfg: EnvSettings) -> Env:
    problem = check(cfg, env_cfg)
    if problem:
        raise ValueError(problem)
    return CPGController(env, cfg)
