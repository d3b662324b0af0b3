"""Generic env wrappers: time limit, episode statistics, auto-reset, return window, observation discretisation."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

import jax
import jax.numpy as jnp

from rlq.lib.env_api import Env, EnvState, ResultWrapper, Wrapper, episodes_go_on
from rlq.lib.spaces import Box, Discrete


def _merges_itself(node) -> bool:
    """MJX data (``mjx.Data``, brax's MJX state) merges by its own ``where``: MuJoCo Warp's buffers
    shared by all envs of a batch must not be selected per env."""
    return callable(getattr(node, "where", None)) and hasattr(node, "qpos")


def _select(pred: jax.Array, on_true, on_false):
    """Leaf-wise ``where`` of two pytrees with the same structure, broadcasting a scalar pred."""

    def pick(a, b):
        if _merges_itself(b):
            return b.where(pred, a)
        a, b = jnp.asarray(a), jnp.asarray(b)
        return jnp.where(jnp.reshape(pred, pred.shape + (1,) * (a.ndim - pred.ndim)), a, b)

    return jax.tree.map(pick, on_true, on_false, is_leaf=_merges_itself)


class ActionRepeat(Wrapper):
    """Holds each action for ``repeat`` steps of the wrapped env and sums their rewards.

    A decision then spans ``repeat`` control steps (e.g. a leading arm held for one second, so
    the reward of a choice is not drowned by the CPG's transient). Steps after the episode ends
    inside a repeat are frozen, not simulated further.
    """

    def __init__(self, env: Env, repeat: int):
        super().__init__(env)
        self._repeat = int(repeat)

    @property
    def max_episode_steps(self) -> int | None:  # type: ignore[override]
        inner = self.env.max_episode_steps
        return None if inner is None else -(-inner // self._repeat)

    @property
    def render_fps(self) -> int:  # type: ignore[override]
        return max(1, round(self.env.render_fps / self._repeat))

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        def one(carry, _):
            current, total, ended = carry
            nxt = _select(ended, current, self.env.step(current, action))
            total = total + jnp.where(ended, 0.0, nxt.reward)
            return (nxt, total, jnp.logical_or(ended, nxt.done)), None

        start = (state, jnp.zeros((), jnp.float32), jnp.zeros((), bool))
        (last, total, _), _ = jax.lax.scan(one, start, None, length=self._repeat)
        return last.replace(reward=total)


class TimeLimit(ResultWrapper):
    """Truncates episodes after ``max_steps`` steps (``extras["t"]`` counts them)."""

    def __init__(self, env: Env, max_steps: int):
        super().__init__(env)
        self._max_steps = int(max_steps)

    @property
    def max_episode_steps(self) -> int:  # type: ignore[override]
        return self._max_steps

    def on_reset(self, state: EnvState) -> EnvState:
        return state.replace(extras={**state.extras, "t": jnp.zeros((), jnp.int32)})

    def on_step(self, state: EnvState, nxt: EnvState) -> EnvState:
        t = state.extras["t"] + 1
        truncated = jnp.logical_or(nxt.truncated, t >= self._max_steps)
        truncated = jnp.logical_and(truncated, jnp.logical_not(nxt.terminated))
        return nxt.replace(truncated=truncated, extras={**nxt.extras, "t": t})


class EpisodeStats(ResultWrapper):
    """Accumulates the return and length of the running episode.

    ``info["episode_return"]`` and ``info["episode_length"]`` hold the running totals including
    the current transition; read them where ``done`` is true to get completed-episode figures.
    """

    def on_reset(self, state: EnvState) -> EnvState:
        zero_f, zero_i = jnp.zeros((), jnp.float32), jnp.zeros((), jnp.int32)
        extras = {**state.extras, "episode_return": zero_f, "episode_length": zero_i}
        info = {**state.info, "episode_return": zero_f, "episode_length": zero_i}
        return state.replace(extras=extras, info=info)

    def on_step(self, state: EnvState, nxt: EnvState) -> EnvState:
        ret = state.extras["episode_return"] + nxt.reward.astype(jnp.float32)
        length = state.extras["episode_length"] + 1
        extras = {**nxt.extras, "episode_return": ret, "episode_length": length}
        info = {**nxt.info, "episode_return": ret, "episode_length": length}
        return nxt.replace(extras=extras, info=info)


class AutoReset(Wrapper):
    """Starts a new episode inside ``step`` whenever one ends.

    The returned state keeps the reward, done flags and info of the finished transition; its
    ``obs`` is the first observation of the new episode and ``info["final_obs"]`` the last
    observation of the old one (needed to bootstrap on truncation).

    An env whose reset is expensive (MJX physics) may set ``reset_cache = True``: the first state
    of each env is then kept in ``extras["reset_cache"]`` and every later episode of that env
    starts from it (as brax's AutoResetWrapper does), instead of computing a fresh reset in every
    step and discarding it where the episode goes on.
    """

    def reset(self, key: jax.Array) -> EnvState:
        state = self.env.reset(key)
        state = state.replace(info={**state.info, "final_obs": state.obs})
        if getattr(self.env, "reset_cache", False):
            first = {"obs": state.obs, "inner": state.inner, "extras": state.extras}
            state = state.replace(extras={**state.extras, "reset_cache": first})
        return state

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        key, reset_key = jax.random.split(state.key)
        stepping = state.replace(key=key)
        cached = "reset_cache" in state.extras
        first: dict[str, Any]
        if not episodes_go_on():  # an evaluation: no reset to pay for
            nxt = self.env.step(stepping, action)
            return nxt.replace(info={**nxt.info, "final_obs": nxt.obs})
        if cached:
            nxt = self.env.step(stepping, action)
            first = cast(dict[str, Any], state.extras["reset_cache"])
        else:
            nxt, fresh = self.env.step_and_reset(stepping, action, reset_key)
            first = {"obs": fresh.obs, "inner": fresh.inner, "extras": fresh.extras}
        done = nxt.done
        extras = _select(done, first["extras"], {k: v for k, v in nxt.extras.items() if k != "reset_cache"})
        if cached:
            extras["reset_cache"] = first
        return nxt.replace(
            obs=_select(done, first["obs"], nxt.obs),
            inner=_select(done, first["inner"], nxt.inner),
            extras=extras,
            info={**nxt.info, "final_obs": nxt.obs},
        )


class ReturnWindow(Wrapper):
    """Keeps the returns of the last ``size`` episodes this env finished, for ``window_return``.

    Goes above ``AutoReset`` (whose reset would clear it) and reads ``info["episode_return"]``
    where an episode ends. Each env keeps a ring of ``size`` returns and the step each ended at
    (``extras["return_window"]``); envs of a batch step together, so those steps order the
    episodes of all envs and ``window_return`` takes the latest ``size`` of the batch.
    """

    KEY = "return_window"

    def __init__(self, env: Env, size: int):
        super().__init__(env)
        self.size = int(size)

    def reset(self, key: jax.Array) -> EnvState:
        state = self.env.reset(key)
        window = {
            "returns": jnp.zeros(self.size, jnp.float32),
            "ended": jnp.full(self.size, -1, jnp.int32),
            "count": jnp.zeros((), jnp.int32),
            "t": jnp.zeros((), jnp.int32),
        }
        return state.replace(extras={**state.extras, self.KEY: window})

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        window = cast(dict[str, jax.Array], state.extras[self.KEY])
        inner = state.replace(extras={k: v for k, v in state.extras.items() if k != self.KEY})
        nxt = self.env.step(inner, action)
        t, done = window["t"] + 1, nxt.done
        # one slot written where an episode ended; elsewhere the write goes out of bounds and is dropped
        # (cheaper per step than a select over the whole ring)
        slot = jnp.where(done, window["count"] % self.size, self.size)
        window = {
            "returns": window["returns"].at[slot].set(nxt.info["episode_return"], mode="drop"),
            "ended": window["ended"].at[slot].set(t, mode="drop"),
            "count": window["count"] + done.astype(jnp.int32),
            "t": t,
        }
        return nxt.replace(extras={**nxt.extras, self.KEY: window})


def window_return(windows: Sequence[dict[str, jax.Array]], size: int) -> jax.Array:
    """Mean return of the last ``size`` episodes finished by batches of envs that step together
    (``extras["return_window"]`` of ``ReturnWindow``, any leading axes); NaN before any ended."""
    returns = jnp.concatenate([w["returns"].reshape(-1) for w in windows])
    ended = jnp.concatenate([w["ended"].reshape(-1) for w in windows])
    latest, index = jax.lax.top_k(ended, min(size, ended.shape[0]))
    valid = latest >= 0
    count = valid.sum()
    total = jnp.where(valid, returns[index], 0.0).sum()
    return jnp.where(count > 0, total / jnp.maximum(count, 1), jnp.nan)


class DiscretizeObservation(Wrapper):
    """Maps a Box observation to one integer: per-dimension equal-width bins, mixed radix.

    Values outside ``[low, high]`` are clipped into the edge bins, so unbounded dimensions need
    explicit ranges.
    """

    def __init__(self, env: Env, bins: tuple[int, ...], low: tuple[float, ...], high: tuple[float, ...]):
        super().__init__(env)
        space = env.observation_space
        if not isinstance(space, Box):
            raise ValueError("DiscretizeObservation needs a Box observation space")
        if not (len(bins) == len(low) == len(high) == space.shape[0]):
            raise ValueError(
                f"discretisation needs {space.shape[0]} bins/low/high values, got {len(bins)}/{len(low)}/{len(high)}"
            )
        self._bins = jnp.asarray(bins, jnp.int32)
        self._low = jnp.asarray(low, jnp.float32)
        self._high = jnp.asarray(high, jnp.float32)
        n = 1
        for b in bins:
            n *= int(b)
        self._n = n
        radix = [1]
        for b in reversed(bins[1:]):
            radix.insert(0, radix[0] * int(b))
        self._radix = jnp.asarray(radix, jnp.int32)

    @property
    def observation_space(self) -> Discrete:  # type: ignore[override]
        return Discrete(self._n)

    def index(self, obs: jax.Array) -> jax.Array:
        """The bin index of one continuous observation."""
        frac = (obs - self._low) / (self._high - self._low)
        per_dim = jnp.clip(jnp.floor(frac * self._bins).astype(jnp.int32), 0, self._bins - 1)
        return jnp.sum(per_dim * self._radix)

    def _map(self, state: EnvState) -> EnvState:
        info = dict(state.info)
        if "final_obs" in info:
            info["final_obs"] = self.index(info["final_obs"])
        return state.replace(obs=self.index(state.obs), info=info)

    def reset(self, key: jax.Array) -> EnvState:
        return self._map(self.env.reset(key))

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        return self._map(self.env.step(state, action))
