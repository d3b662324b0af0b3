"""brax's model load with its final array copies made by device transfers (``env.quick_model_load``).

brax's ``mjcf.load_model`` (brax 0.14) ends with ``jax.tree.map(jnp.array, system)``. Each
``jnp.array`` of a shape not seen before compiles a small program: a copy of one of MJX's device
arrays, or the staging of a numpy one. On a GPU that is some 80 small programs, a visible part of a
humanoid run's start (figures: docs/humanoid.md), and the evaluation env loads its own model. ``jax.device_put`` makes the same arrays (values, dtypes, weak types) without compiling.
This swaps the name brax's module reads ``jnp`` under, so it is one of the version-checked patches
(rlq.envs.humanoid.mjx_patches).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from typing import Any

import jax
import jax.numpy as jnp
from brax.io import mjcf as brax_mjcf

#: held while brax's module reads the swapped name: one model load at a time
_LOADING = threading.Lock()


class _TransferredArrays:
    """``jax.numpy`` as brax's loader sees it, with ``array`` a device transfer."""

    def __getattr__(self, name: str) -> Any:
        return getattr(jnp, name)

    @staticmethod
    def array(value: Any) -> jax.Array:
        return jax.device_put(value)


@contextlib.contextmanager
def arrays_by_transfer() -> Iterator[None]:
    """While active, brax's model loader makes its arrays with ``jax.device_put``."""
    with _LOADING:
        original = brax_mjcf.jp
        brax_mjcf.jp = _TransferredArrays()
        try:
            yield
        finally:
            brax_mjcf.jp = original
