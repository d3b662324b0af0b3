"""The Env protocol every environment, controller and wrapper implements.

An env is a pair of pure functions over an ``EnvState`` pytree::

    reset(key) -> EnvState
    step(state, action) -> EnvState

Randomness used by ``step`` comes from ``state.key``, so ``step`` needs no key argument and an
env can be vmapped and scanned without threading keys by hand. ``reset`` and ``step`` must
return states with identical pytree structure (same ``info`` and ``extras`` keys), because
auto-reset selects between them leaf by leaf.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Callable, Iterator, Mapping
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from rlq.lib.spaces import Space


class EnvState(struct.PyTreeNode):
    """What one environment step hands to its caller.

    Attributes:
        obs: observation after the step (after auto-reset: the first of the next episode).
        reward: reward of the transition just taken.
        terminated: the episode ended in a terminal state (no bootstrap).
        truncated: the episode was cut by a time limit (bootstrap from ``info["final_obs"]``).
        info: per-transition arrays (episode metrics, env quantities such as a distance).
        inner: the simulator's own state (physics, plus any controller state wrapped around it).
        extras: state owned by wrappers (step counters, running returns).
        key: PRNG key consumed by the next ``step``.
    """

    obs: jax.Array
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    info: dict[str, jax.Array]
    inner: Any
    extras: dict[str, jax.Array]
    key: jax.Array

    @property
    def done(self) -> jax.Array:
        return jnp.logical_or(self.terminated, self.truncated)


def info_shapes(env: Env) -> dict[str, jax.ShapeDtypeStruct]:
    """Shape and dtype of each ``info`` entry ``env`` reports: its reset traced abstractly (nothing
    runs or compiles; an MJX env's reset still takes a second or so to trace)."""
    return dict(jax.eval_shape(lambda: env.reset(jax.random.PRNGKey(0))).info)


def initial_state(obs: jax.Array, inner: Any, key: jax.Array, info: dict | None = None) -> EnvState:
    """An ``EnvState`` right after reset: zero reward, not done."""
    return EnvState(
        obs=obs,
        reward=jnp.zeros((), jnp.float32),
        terminated=jnp.zeros((), bool),
        truncated=jnp.zeros((), bool),
        info=dict(info or {}),
        inner=inner,
        extras={},
        key=key,
    )


class Env:
    """Base class of environments. Subclasses set the spaces and implement reset/step."""

    observation_space: Space
    action_space: Space
    #: Episode length limit applied by the TimeLimit wrapper (None: the env never truncates).
    max_episode_steps: int | None = None
    #: Pure JAX (jit/vmap-able) or a host-side simulator (evaluation only).
    jittable: bool = True
    #: Box actions outside ``action_space`` are taken as they come and clamped by the env itself (MuJoCo's control
    #: range), so a policy may hand it its raw outputs (``algo.ars.clip_actions=false``).
    clamps_actions: bool = False
    #: Descriptors this env reports through a wrapper of its own (name -> wrapper class), for
    #: quality-diversity archives (``algo.descriptor``); those it reports in ``info`` need none.
    descriptor_wrappers: ClassVar[Mapping[str, Callable[[Env], Env]]] = {}

    def reset(self, key: jax.Array) -> EnvState:
        raise NotImplementedError

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        raise NotImplementedError

    def step_and_reset(self, state: EnvState, action: jax.Array, key: jax.Array) -> tuple[EnvState, EnvState]:
        """``(step(state, action), reset(key))``, for auto-reset, which keeps the obs, ``inner`` and
        ``extras`` of the new episode's state but not its key. An env whose reset runs the same
        physics as its step (LunarLander's reset ends with a world step) may compute the two
        together, with results equal to the two calls'; one may draw the new episode from ``key``
        directly instead of splitting it first (CartPole)."""
        return self.step(state, action), self.reset(key)

    #: Frames per second of videos made by ``render``.
    render_fps: int = 50

    def render(self, states: EnvState) -> Any:
        """uint8 frames (T, H, W, 3) of states stacked along a leading time axis (host side)."""
        raise NotImplementedError(f"{type(self).__name__} has no renderer")

    def base_states(self, states: EnvState) -> EnvState:
        """``states`` of this env as states of the base env (``unwrapped``): each wrapper that keeps
        its own state in ``inner`` takes it off here. The base env returns them as they are."""
        return states

    @property
    def unwrapped(self) -> Env:
        return self


class Wrapper(Env):
    """Delegates everything to the wrapped env; subclasses override what they change."""

    def __init__(self, env: Env):
        self.env = env

    def __getattr__(self, name: str) -> Any:
        return getattr(self.env, name)

    @property
    def observation_space(self) -> Space:  # type: ignore[override]
        return self.env.observation_space

    @property
    def action_space(self) -> Space:  # type: ignore[override]
        return self.env.action_space

    @property
    def max_episode_steps(self) -> int | None:  # type: ignore[override]
        return self.env.max_episode_steps

    @property
    def jittable(self) -> bool:  # type: ignore[override]
        return self.env.jittable

    @property
    def clamps_actions(self) -> bool:  # type: ignore[override]
        return self.env.clamps_actions

    @property
    def unwrapped(self) -> Env:
        return self.env.unwrapped

    @property
    def render_fps(self) -> int:  # type: ignore[override]
        return self.env.render_fps

    def render(self, states: EnvState) -> Any:
        """The base env renders the states with the wrappers' parts taken off."""
        return self.unwrapped.render(self.base_states(states))

    def base_states(self, states: EnvState) -> EnvState:
        return self.env.base_states(states)

    def reset(self, key: jax.Array) -> EnvState:
        return self.env.reset(key)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        return self.env.step(state, action)


class ResultWrapper(Wrapper):
    """A wrapper that only adds to what the wrapped env's ``reset`` and ``step`` return
    (``on_reset``, ``on_step``), so the wrapped env's ``step_and_reset`` passes through it."""

    def on_reset(self, state: EnvState) -> EnvState:
        return state

    def on_step(self, state: EnvState, nxt: EnvState) -> EnvState:
        """``nxt``, the wrapped env's step from ``state``, as this wrapper returns it."""
        return nxt

    def reset(self, key: jax.Array) -> EnvState:
        return self.on_reset(self.env.reset(key))

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        return self.on_step(state, self.env.step(state, action))

    def step_and_reset(self, state: EnvState, action: jax.Array, key: jax.Array) -> tuple[EnvState, EnvState]:
        nxt, fresh = self.env.step_and_reset(state, action, key)
        return self.on_step(state, nxt), self.on_reset(fresh)


#: True while a program that reads only each env's first episode is traced (``first_episodes_only``)
_first_episodes_only = contextvars.ContextVar("rlq_first_episodes_only", default=False)


@contextlib.contextmanager
def first_episodes_only() -> Iterator[None]:
    """Trace steps whose caller reads each env's first episode only (an evaluation): auto-reset
    wrappers then skip the new episode's reset, whose physics (LunarLander's reset runs a world
    step) would otherwise be traced, compiled and run in every step for nothing. Numbers of the
    first episodes are unchanged; what an env does after its first episode ends is unspecified."""
    token = _first_episodes_only.set(True)
    try:
        yield
    finally:
        _first_episodes_only.reset(token)


def episodes_go_on() -> bool:
    """Whether the steps being traced must start a new episode where one ends (see ``first_episodes_only``)."""
    return not _first_episodes_only.get()


class HostEnv:
    """A simulator stepped on the host (not jittable), e.g. Gymnasium's Box2D LunarLander.

    Used by ``rlq eval`` to test policies trained on a JAX env against a reference simulator.
    Observations and actions are numpy arrays; the interface follows Gymnasium.
    """

    observation_space: Space
    action_space: Space
    max_episode_steps: int | None = None
    jittable: bool = False

    def reset(self, seed: int) -> tuple[Any, dict]:
        raise NotImplementedError

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        raise NotImplementedError

    def fresh(self) -> HostEnv:
        """Another simulator with the same settings, for episodes stepped side by side."""
        raise NotImplementedError

    def close(self) -> None:
        pass
