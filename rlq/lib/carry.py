"""Loop carries: ones that start batched, and ones whose types stay fixed from the first update on."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from jax.typing import DTypeLike

PyTree = Any


def batched_zeros(like: jax.Array, shape: tuple[int, ...] = (), dtype: DTypeLike = jnp.float32) -> jax.Array:
    """Zeros of ``shape`` and ``dtype`` that depend on ``like``: under ``vmap`` they are batched as
    ``like`` is. XLA folds most of the dependence away (LunarLander's optimized chunk: 10 more
    instructions of 18.9k).

    A ``while_loop`` or ``fori_loop`` whose carry starts unbatched (plain ``jnp.zeros``) but comes
    out of the body batched is batched twice at every ``vmap`` level: JAX batches the body, finds
    the carry batched, and batches the body again. Starting the carry batched saves that second
    pass: LunarLander's step runs under two levels (the envs, and the step beside the reset), and
    its chunk traces and lowers faster, with the same numbers (figures: docs/history/benchmarks.md)."""
    zeros = jnp.zeros(shape, dtype)
    return jnp.where(like == like, zeros, zeros)


def strongly_typed(tree: PyTree) -> PyTree:
    """``tree`` with every weakly typed array made strong, same values and dtypes.

    Some libraries' states change weak types from one step to the next (evosax's ``best_fitness``
    is weak at init and strong after a step; Open_ES's ``std`` the reverse). A state carried from
    update to update then changes type after one step, and a jitted update called on it
    compiles a second time (MAP-Elites' ES emitter in ``bench_map_elites.py --qdax``: the first run's
    evaluations/s fell to 479 from 742-807 on an H200)."""
    return jax.tree.map(lambda x: jnp.asarray(x, dtype=x.dtype) if getattr(x, "weak_type", False) else x, tree)
