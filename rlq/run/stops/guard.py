"""The divergence guard: a run whose losses, returns or parameters turn NaN/Inf, or whose losses or parameter norm
pass the configured bounds (``guard:``), stops at once.

After every update the compiled chunk adds boolean flags to the metrics (``finite/<name>``): the
parameters' global norm is finite, and no loss or return is ±Inf. They leave the device with the
chunk's metrics, so the guard costs no extra transfer. Only those are checked, not every leaf of
the state: an empty MAP-Elites cell holds -inf fitness by design. A metric that is NaN means "no
value in this update" (no episode ended, learning has not started) and is not a divergence; a
NaN that matters reaches the parameters and is caught there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

PREFIX = "finite/"


def guarded(name: str) -> bool:
    """Whether the metric ``name`` is one the guard checks (losses and returns)."""
    return name.endswith("loss") or name.endswith("return")


def params_norm(params: Any) -> jax.Array:
    """The global L2 norm of a parameter pytree (Inf once a parameter nears float32's range)."""
    leaves = [jnp.asarray(x, jnp.float32) for x in jax.tree.leaves(params)]
    return jnp.sqrt(sum(jnp.sum(jnp.square(x)) for x in leaves)) if leaves else jnp.zeros(())


@dataclass(frozen=True)
class Bounds:
    """Finite blow-ups the guard also stops (``guard.*``, rlq/declared/run.py; None: no bound): a loss whose magnitude
    passes ``max_abs_loss`` (PPO at lr=1e9: a value loss of 5e17 with every number finite), parameters whose
    global norm passes ``max_params_norm``."""

    max_abs_loss: float | None = None
    max_params_norm: float | None = None

    @classmethod
    def from_config(cls, guard: Any) -> Bounds:
        if not guard:
            return cls()
        return cls(guard.get("max_abs_loss"), guard.get("max_params_norm"))

    def limit(self, name: str) -> tuple[str, float] | None:
        """(the key, its bound) that applies to the checked quantity ``name``, if any."""
        if name == "params_norm" and self.max_params_norm is not None:
            return "guard.max_params_norm", self.max_params_norm
        if name.endswith("loss") and self.max_abs_loss is not None:
            return "guard.max_abs_loss", self.max_abs_loss
        return None

    def ok(self, name: str, value: jax.Array) -> jax.Array:
        """On the device: ``value`` of the checked quantity ``name`` is not ±Inf and within its bound, if any (NaN
        passes: a metric without a value this update)."""
        limit = self.limit(name)
        return ~jnp.isinf(value) & (True if limit is None else ~(jnp.abs(value) > limit[1]))


NO_BOUNDS = Bounds()


def flags(params: Any | None, metrics: dict[str, jax.Array], bounds: Bounds = NO_BOUNDS) -> dict[str, jax.Array]:
    """On the device: one boolean per checked quantity, True while it is finite and within its bound."""
    out = {f"{PREFIX}{k}": bounds.ok(k, v) for k, v in metrics.items() if guarded(k)}
    if params is not None:
        norm = params_norm(params)
        out[f"{PREFIX}params_norm"] = ~jnp.isnan(norm) & bounds.ok("params_norm", norm)
    return out


def with_flags(
    update: Callable[..., tuple[Any, dict]], params: Callable[[Any], Any] | None, bounds: Bounds = NO_BOUNDS
) -> Callable[..., tuple[Any, dict]]:
    """``update`` (``update(state, *args)``: the hyperparameters) that also returns the guard's flags of its new state
    and metrics."""

    def checked(state, *args):
        state, metrics = update(state, *args)
        return state, {**metrics, **flags(params(state) if params else None, metrics, bounds)}

    return checked


def split(metrics: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(the algorithm's metrics, the guard's flags by checked name) of a chunk on the host."""
    plain = {k: v for k, v in metrics.items() if not k.startswith(PREFIX)}
    return plain, {k[len(PREFIX) :]: np.asarray(v) for k, v in metrics.items() if k.startswith(PREFIX)}


def first_failure(checks: dict[str, np.ndarray], env_steps: np.ndarray) -> tuple[str, int, int] | None:
    """(name, seed, env steps) of the first update whose check failed; arrays are [seeds, updates]."""
    worst = None
    for name, ok in checks.items():
        bad = np.argwhere(~ok.astype(bool))
        for seed, update in bad:
            if worst is None or update < worst[3]:
                worst = (name, int(seed), int(env_steps[seed, update]), int(update))
    return None if worst is None else worst[:3]
