"""Gymnasium's Box2D LunarLander-v3 as a host-side reference simulator.

Besides the Gymnasium interface, every draw the env makes from its ``np_random`` is recorded
(terrain heights, initial force, wind offsets, per-step engine dispersion), and ``draws(seed, n)``
returns them ahead of time, so the JAX port (``rlq.envs.lunar.env``) can be driven by exactly the same
random numbers.
"""

from __future__ import annotations

import copy
from typing import Any, cast

import numpy as np
from gymnasium.envs.box2d.lunar_lander import LunarLander

from rlq.declared.envs.lunar import Box2DConfig, task_options
from rlq.lib.env_api import HostEnv
from rlq.lib.spaces import Box, Discrete

OBS_LOW = (-2.5, -2.5, -10.0, -10.0, -2 * np.pi, -10.0, 0.0, 0.0)
OBS_HIGH = (2.5, 2.5, 10.0, 10.0, 2 * np.pi, 10.0, 1.0, 1.0)


class _RecordingGenerator:
    """Forwards ``uniform``/``integers`` to a numpy Generator and logs every result."""

    def __init__(self, rng: np.random.Generator, log: list[tuple[str, Any]]):
        self._rng = rng
        self._log = log

    def uniform(self, *args, **kwargs):
        out = self._rng.uniform(*args, **kwargs)
        self._log.append(("uniform", out))
        return out

    def integers(self, *args, **kwargs):
        out = self._rng.integers(*args, **kwargs)
        self._log.append(("integers", out))
        return out


class _RecordingLunarLander(LunarLander):
    """LunarLander whose ``np_random`` records its draws into ``self.draw_log``."""

    draw_log: list[tuple[str, Any]]

    @property  # type: ignore[misc]  # Gymnasium's np_random is read-write; this one records its draws
    def np_random(self) -> Any:  # type: ignore[override]
        if not hasattr(self, "draw_log"):
            self.draw_log = []
        return _RecordingGenerator(super().np_random, self.draw_log)


class LunarBox2D(HostEnv):
    """Gymnasium's LunarLander-v3 (Box2D) with a time limit and recorded random draws."""

    def __init__(
        self,
        continuous: bool = False,
        enable_wind: bool = False,
        wind_power: float = 15.0,
        turbulence_power: float = 1.5,
        gravity: float = -10.0,
        max_episode_steps: int | None = 1000,
    ):
        self._settings: dict[str, Any] = dict(
            continuous=continuous,
            enable_wind=enable_wind,
            wind_power=wind_power,
            turbulence_power=turbulence_power,
            gravity=gravity,
            max_episode_steps=max_episode_steps,
        )
        self.continuous = bool(continuous)
        self.enable_wind = bool(enable_wind)
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self.env = _RecordingLunarLander(
            continuous=self.continuous,
            gravity=gravity,
            enable_wind=self.enable_wind,
            wind_power=wind_power,
            turbulence_power=turbulence_power,
        )
        self.observation_space = Box(OBS_LOW, OBS_HIGH)
        self.action_space = Box.uniform(-1.0, 1.0, 2) if self.continuous else Discrete(4)
        self._t = 0

    def reset(self, seed: int) -> tuple[np.ndarray, dict]:
        self.env.draw_log = []
        obs, info = self.env.reset(seed=int(seed))
        self._t = 0
        return obs, info

    def fresh(self) -> LunarBox2D:
        return LunarBox2D(**self._settings)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self.continuous:
            action = np.asarray(action, np.float32)
        else:
            action = int(action)
        obs, reward, terminated, _, info = self.env.step(action)
        self._t += 1
        truncated = (not terminated) and self.max_episode_steps is not None and self._t >= self.max_episode_steps
        return obs, float(reward), bool(terminated), truncated, info

    def recorded_draws(self) -> dict[str, np.ndarray]:
        """The draws made since the last reset, split into their roles (see ``draws``)."""
        return _split_log(self.env.draw_log, self.enable_wind)

    def draws(self, seed: int, num_steps: int) -> dict[str, np.ndarray]:
        """Every random number an episode of ``seed`` uses, for ``num_steps`` steps after reset.

        Returns ``terrain`` (12 raw chunk heights, before the helipad is flattened),
        ``init_force`` (2), ``wind_idx`` (2 ints, zeros without wind) and ``dispersion``
        (``num_steps + 1`` × 2, already divided by SCALE; row 0 is the step inside reset).
        The per-step draws do not depend on the actions, so they can be drawn ahead of time.
        """
        self.reset(seed)
        future = cast(np.random.Generator, copy.deepcopy(self.env._np_random))
        out = self.recorded_draws()
        extra = [[future.uniform(-1.0, 1.0) for _ in range(2)] for _ in range(num_steps)]
        scale = 30.0
        out["dispersion"] = np.concatenate([out["dispersion"], np.asarray(extra, np.float64).reshape(-1, 2) / scale])
        return out

    @property
    def lander(self) -> Any:
        """The underlying Box2D lander body (for diagnostics)."""
        return self.env.lander

    def close(self) -> None:
        self.env.close()


def _split_log(log: list[tuple[str, Any]], wind: bool) -> dict[str, np.ndarray]:
    values = [v for _, v in log]
    terrain = np.asarray(values[0], np.float64)
    init_force = np.asarray(values[1:3], np.float64)
    rest = values[3:]
    wind_idx = np.zeros(2, np.int64)
    if wind:
        wind_idx = np.asarray(rest[:2], np.int64)
        rest = rest[2:]
    dispersion = np.asarray(rest, np.float64).reshape(-1, 2) / 30.0
    return {"terrain": terrain, "init_force": init_force, "wind_idx": wind_idx, "dispersion": dispersion}


def make(cfg: Box2DConfig) -> LunarBox2D:
    return LunarBox2D(**task_options(cfg))
