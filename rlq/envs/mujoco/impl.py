"""Which implementation of MuJoCo steps an MJX env: MJX's JAX implementation or MuJoCo Warp.

MJX 3.17 ships MuJoCo Warp and calls its CUDA kernels through XLA's FFI (``impl="warp"``); Warp
also runs them on the CPU (slowly: the tests use it there to check the integration). Warp makes
only the contacts that touch and solves only their constraint rows, where MJX's JAX
implementation evaluates every collision pair of the model at every step; on contact-heavy models
such as the brittle star that makes Warp several times faster on a GPU (docs/brittle_star.md).
Warp keeps the contacts of every env of a batched call in one buffer (``naconmax``) shared by the
batch and drops contacts beyond it, so the buffer must hold the most contacts that all envs of a
program can have at once.

``auto`` picks Warp where it pays: JAX's default device is an NVIDIA GPU and warp-lang is
installed; otherwise the JAX implementation.
"""

from __future__ import annotations

import importlib.util
from typing import Any

import jax
import jax.numpy as jnp

#: MJX implementations of the physics step, and ``auto``
MJX_IMPLS = ("jax", "warp", "auto")


def warp_installed() -> bool:
    return importlib.util.find_spec("warp") is not None


def on_nvidia_gpu() -> bool:
    """JAX's default device is a CUDA GPU (MuJoCo Warp's kernels are CUDA only)."""
    device = jax.devices()[0]
    return device.platform == "gpu" and "cuda" in device.client.platform_version.lower()


def resolve_impl(impl: str) -> str:
    """``jax`` or ``warp`` for ``env.mjx_impl``: ``ValueError`` for an unknown name, ``ImportError``
    for ``warp`` without warp-lang; ``auto`` is ``warp`` on an NVIDIA GPU with warp-lang, else ``jax``."""
    if impl not in MJX_IMPLS:
        raise ValueError(f"env.mjx_impl must be one of {list(MJX_IMPLS)}, got {impl!r}")
    if impl == "auto":
        return "warp" if warp_installed() and on_nvidia_gpu() else "jax"
    if impl == "warp" and not warp_installed():
        raise ImportError('env.mjx_impl=warp needs warp-lang: pip install -e ".[warp]"')
    return impl


def with_template_buffers(template: Any, data: Any) -> Any:
    """``data``'s per-env fields with ``template``'s buffers that MuJoCo Warp shares across a batch.

    Those buffers (contacts, constraint rows) are scratch that every physics step rewrites. Under
    a second ``vmap`` (over seeds) a ``while_loop`` whose stopping test differs per seed batches its
    whole carry, these buffers included, and Warp then refuses them; taking them from the template
    (a constant, batched by nothing) before each step keeps them in Warp's shape. ``Data.where``
    takes the batch-shared fields from the Data it is called on.
    """
    return template.where(jnp.ones((), bool), data)
