"""Per-environment domain randomisation of an MJX model (the MJX tutorial's recipe).

Each env draws its own model fields at reset from its key; the env keeps them in
``EnvState.inner`` and steps with ``model.tree_replace(overrides)``. Under the batch ``vmap``
only the overridden fields carry the env axis (the tutorial's ``in_axes``); the rest of the model
stays shared.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import jax

KEYS = ("friction", "gain_delta")


@dataclass(frozen=True)
class Ranges:
    """``friction``: sliding friction of every geom ~ U(lo, hi); ``gain_delta``: every actuator's
    gain += U(lo, hi), with ``biasprm[1] = -gain`` to match (position actuators keep
    force = gain * (ctrl - q)). One draw per env and quantity, as in the tutorial."""

    friction: tuple[float, float] | None = None
    gain_delta: tuple[float, float] | None = None


def _pair(name: str, value: Any) -> tuple[float, float] | None:
    if value is None:
        return None
    values = tuple(float(v) for v in value)
    if len(values) != 2 or values[0] > values[1]:
        raise ValueError(f"env.randomize.{name} must be [low, high] with low <= high, got {list(value)}")
    return values


def parse(cfg: Mapping | None) -> Ranges | None:
    """``env.randomize`` from the config (null: no randomisation)."""
    if not cfg:
        return None
    unknown = sorted(set(cfg) - set(KEYS))
    if unknown:
        raise ValueError(f"unknown env.randomize key(s) {unknown}; use {list(KEYS)}")
    ranges = Ranges(**{k: _pair(k, cfg.get(k)) for k in KEYS})
    return ranges if (ranges.friction or ranges.gain_delta) else None


def sample(key: jax.Array, model: Any, ranges: Ranges) -> dict[str, jax.Array]:
    """One env's overrides of ``model`` fields (an ``mjx.Model`` or brax ``System``)."""
    friction_key, gain_key = jax.random.split(key)
    overrides = {}
    if ranges.friction is not None:
        friction = jax.random.uniform(friction_key, (), minval=ranges.friction[0], maxval=ranges.friction[1])
        overrides["geom_friction"] = model.geom_friction.at[:, 0].set(friction)
    if ranges.gain_delta is not None:
        delta = jax.random.uniform(gain_key, (), minval=ranges.gain_delta[0], maxval=ranges.gain_delta[1])
        gain = model.actuator_gainprm[:, 0] + delta
        overrides["actuator_gainprm"] = model.actuator_gainprm.at[:, 0].set(gain)
        overrides["actuator_biasprm"] = model.actuator_biasprm.at[:, 1].set(-gain)
    return overrides


def apply(model: Any, overrides: Mapping[str, jax.Array]) -> Any:
    return model.tree_replace(dict(overrides)) if overrides else model
