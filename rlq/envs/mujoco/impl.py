"""Which implementation of MuJoCo steps an MJX env: MJX's JAX implementation or MuJoCo Warp.

MJX 3.17 ships MuJoCo Warp and calls its CUDA kernels through XLA's FFI (``impl="warp"``); Warp
also runs them on the CPU (slowly: the tests use it there to check the integration). Warp makes
only the contacts that touch and solves only their constraint rows, where MJX's JAX
implementation evaluates every collision pair of the model at every step; on contact-heavy models
such as the brittle star that makes Warp several times faster on a GPU (docs/brittle_star.md).
Warp keeps the contacts of every env of a batched call in one buffer (``naconmax``) shared by the
batch and drops contacts beyond it, so the buffer must hold the most contacts that all envs of a
program can have at once.

``auto`` picks Warp where it pays: JAX's default device is an NVIDIA GPU, warp-lang is installed
and mujoco-mjx is a version rlq ran Warp with (rlq sizes Warp's buffers and quiets its solver
warnings through MJX's private fields: ``rlq.envs.brittle_star.model.put_on_device``); otherwise the
JAX implementation. ``warp`` on another mujoco-mjx version is refused.
"""

from __future__ import annotations

import importlib.util
from importlib.metadata import PackageNotFoundError, version
from typing import Any

import jax
import jax.numpy as jnp

#: MJX implementations of the physics step, and ``auto``
MJX_IMPLS = ("jax", "warp", "auto")
#: the mujoco-mjx release (major, minor) whose MuJoCo Warp integration rlq was run with
WARP_WRITTEN_FOR = (3, 17)


def release(text: str) -> tuple[int, ...]:
    """A version string's leading numbers: "3.18.0rc1" -> (3, 18, 0)."""
    parts = []
    for piece in text.split("."):
        digits = "".join(ch for ch in piece if ch.isdigit())
        if not digits:
            break
        parts.append(int(digits))
    return tuple(parts)


def mjx_release(installed: str | None = None) -> tuple[int, ...]:
    """(major, minor) of the installed mujoco-mjx (or of ``installed``); () if it is not installed."""
    try:
        text = installed if installed is not None else version("mujoco-mjx")
    except PackageNotFoundError:
        return ()
    return release(text)[:2]


def warp_installed() -> bool:
    return importlib.util.find_spec("warp") is not None


def on_nvidia_gpu() -> bool:
    """JAX's default device is a CUDA GPU (MuJoCo Warp's kernels are CUDA only)."""
    device = jax.devices()[0]
    return device.platform == "gpu" and "cuda" in device.client.platform_version.lower()


def resolve_impl(impl: str, installed_mjx: str | None = None) -> str:
    """``jax`` or ``warp`` for ``env.mjx_impl``: ``ValueError`` for an unknown name or ``warp`` on a
    mujoco-mjx release rlq did not run Warp with, ``ImportError`` for ``warp`` without warp-lang;
    ``auto`` is ``warp`` on an NVIDIA GPU where ``warp`` would be accepted, else ``jax``."""
    if impl not in MJX_IMPLS:
        raise ValueError(f"env.mjx_impl must be one of {list(MJX_IMPLS)}, got {impl!r}")
    release_ok = mjx_release(installed_mjx) == WARP_WRITTEN_FOR
    if impl == "auto":
        return "warp" if release_ok and warp_installed() and on_nvidia_gpu() else "jax"
    if impl == "warp" and not release_ok:
        found = ".".join(map(str, mjx_release(installed_mjx))) or "none"
        wanted = ".".join(map(str, WARP_WRITTEN_FOR))
        raise ValueError(
            f"env.mjx_impl=warp was written for mujoco-mjx {wanted}.x (it reads MJX's private fields), "
            f"but {found} is installed; use env.mjx_impl=jax"
        )
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
