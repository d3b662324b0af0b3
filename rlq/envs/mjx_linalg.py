"""Batched small Cholesky factor and solve as single GPU kernels (Pallas), for MJX's dense solves.

MJX factors and solves with ``jax.scipy.linalg.cho_factor``/``cho_solve`` twice per physics step
(the mass matrix, and the Newton solver's Hessian). On a GPU, XLA runs each batched 27x27 factor
as several cuSOLVER kernels and each solve as two cuBLAS triangular solves, each launch with its
own pointer-array set-up; for the humanoid these are the largest kernels of an env step. Here one
Pallas kernel factors a block of matrices held in registers, and one solves, so a factor or a
solve is one launch. Same algorithm (column-by-column Cholesky, forward then back substitution),
float32 throughout; results agree with XLA's to rounding.

``fast_cholesky()`` swaps the two functions in while MJX is traced (like rlq.envs.mjx_unroll);
matrices larger than ``MAX_SIZE`` keep XLA's implementation.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
from collections.abc import Iterator

import jax
import jax.numpy as jnp
from jax.experimental import pallas as pl
from jax.experimental.pallas import triton as pl_triton

#: matrices up to this size (padded to a power of two in the kernel) use the Pallas kernels
MAX_SIZE = 32
#: matrices per kernel program (one per lane) and warps per program
BLOCK = 128
WARPS = 4


def _padded_size(n: int) -> int:
    return max(2, 1 << (n - 1).bit_length())


def _factor_kernel(a_ref, u_ref):
    """Cholesky of a block of matrices, every entry a vector over the block's matrices (one lane
    each), so the whole factor is lane-wise arithmetic with no exchange between threads."""
    n = a_ref.shape[-1]
    low = {}
    for j in range(n):
        pivot = a_ref[:, j, j]
        for k in range(j):
            pivot = pivot - low[j, k] * low[j, k]
        low[j, j] = jnp.sqrt(pivot)
        for i in range(j + 1, n):
            entry = a_ref[:, i, j]
            for k in range(j):
                entry = entry - low[i, k] * low[j, k]
            low[i, j] = entry / low[j, j]
    zero = jnp.zeros_like(low[0, 0])
    for i in range(n):
        for j in range(n):
            u_ref[:, i, j] = low[j, i] if j >= i else zero


def _solve_kernel(u_ref, b_ref, x_ref):
    """``U^T U x = b`` by forward then back substitution, lane-wise as in ``_factor_kernel``."""
    n = u_ref.shape[-1]
    y = []
    for i in range(n):
        entry = b_ref[:, i]
        for k in range(i):
            entry = entry - u_ref[:, k, i] * y[k]
        y.append(entry / u_ref[:, i, i])
    x = [None] * n
    for i in reversed(range(n)):
        entry = y[i]
        for k in range(i + 1, n):
            entry = entry - u_ref[:, i, k] * x[k]
        x[i] = entry / u_ref[:, i, i]
    for i in range(n):
        x_ref[:, i] = x[i]


@dataclasses.dataclass(frozen=True)
class Launch:
    """How the kernels run: matrices per program (one per lane), warps per program, and whether
    the matrices are padded to a power-of-two size (Triton's block shapes) or loaded as they are."""

    block: int = BLOCK
    warps: int = WARPS
    pad: bool = False
    interpret: bool = False


def _blocked_call(kernel, out_tail: tuple[int, ...], launch: Launch, *args: jax.Array) -> jax.Array:
    """Runs ``kernel`` over ``args`` (same leading batch) in programs of ``launch.block`` matrices."""
    batch = args[0].shape[0]
    block = min(launch.block, _padded_size(batch))
    padded = -(-batch // block) * block
    args = [jnp.pad(x, [(0, padded - batch)] + [(0, 0)] * (x.ndim - 1), constant_values=1.0) for x in args]

    def spec(tail):
        return pl.BlockSpec((block, *tail), lambda i: (i,) + (0,) * len(tail))

    out = pl.pallas_call(
        kernel,
        out_shape=jax.ShapeDtypeStruct((padded, *out_tail), jnp.float32),
        grid=(padded // block,),
        in_specs=[spec(x.shape[1:]) for x in args],
        out_specs=spec(out_tail),
        compiler_params=None if launch.interpret else pl_triton.CompilerParams(num_warps=launch.warps),
        interpret=launch.interpret,
    )(*args)
    return out[:batch]


def _embed(a: jax.Array, size: int) -> jax.Array:
    """``a`` [B, n, n] in the top-left of identity matrices [B, size, size]."""
    if a.shape[-1] == size:
        return a
    eye = jnp.eye(size, dtype=jnp.float32)
    return jax.lax.dynamic_update_slice(jnp.broadcast_to(eye, (a.shape[0], size, size)), a, (0, 0, 0))


def batched_cholesky_upper(a: jax.Array, launch: Launch = Launch()) -> jax.Array:
    """Upper factors ``U`` with ``a = U^T U`` for symmetric positive-definite ``a`` [..., n, n]."""
    n = a.shape[-1]
    size = _padded_size(n) if launch.pad else n
    flat = a.reshape(-1, n, n).astype(jnp.float32)
    flat = (flat + jnp.swapaxes(flat, -1, -2)) * 0.5
    u = _blocked_call(_factor_kernel, (size, size), launch, _embed(flat, size))
    return u[:, :n, :n].reshape(a.shape).astype(a.dtype)


def batched_cho_solve_upper(u: jax.Array, b: jax.Array, launch: Launch = Launch()) -> jax.Array:
    """``x`` with ``U^T U x = b`` for upper factors ``u`` [..., n, n] and vectors ``b`` [..., n]."""
    n = u.shape[-1]
    size = _padded_size(n) if launch.pad else n
    flat_u = _embed(u.reshape(-1, n, n).astype(jnp.float32), size)
    flat_b = jnp.pad(b.reshape(-1, n).astype(jnp.float32), [(0, 0), (0, size - n)])
    x = _blocked_call(_solve_kernel, (size,), launch, flat_u, flat_b)
    return x[:, :n].reshape(b.shape).astype(b.dtype)


def _vmappable(fn):
    """``fn`` (which takes any leading batch) as a function whose vmap batches into one call."""

    @jax.custom_batching.custom_vmap
    def wrapped(*args):
        return fn(*args)

    @wrapped.def_vmap
    def rule(axis_size, in_batched, *args):
        args = [x if batched else jnp.broadcast_to(x, (axis_size, *x.shape)) for x, batched in zip(args, in_batched)]
        return wrapped(*args), True

    return wrapped


@functools.cache
def _functions(launch: Launch):
    return (
        _vmappable(functools.partial(batched_cholesky_upper, launch=launch)),
        _vmappable(functools.partial(batched_cho_solve_upper, launch=launch)),
    )


@contextlib.contextmanager
def fast_cholesky(launch: Launch = Launch()) -> Iterator[None]:
    """While active, ``jax.scipy.linalg.cho_factor``/``cho_solve`` on float32 matrices of at most
    ``MAX_SIZE`` rows (upper factors, vector right-hand sides: MJX's dense calls) run the Pallas
    kernels; every other call goes to jax's own functions."""
    linalg = jax.scipy.linalg
    original_factor, original_solve = linalg.cho_factor, linalg.cho_solve
    factor, solve = _functions(launch)

    def cho_factor(a, lower=False, overwrite_a=False, check_finite=True):
        if lower or a.ndim != 2 or a.shape[0] > MAX_SIZE or a.dtype != jnp.float32:
            return original_factor(a, lower=lower, overwrite_a=overwrite_a, check_finite=check_finite)
        return factor(a), False

    def cho_solve(c_and_lower, b, overwrite_b=False, check_finite=True):
        c, lower = c_and_lower
        if lower or c.ndim != 2 or b.ndim != 1 or c.shape[0] > MAX_SIZE or c.dtype != jnp.float32:
            return original_solve(c_and_lower, b, overwrite_b=overwrite_b, check_finite=check_finite)
        return solve(c, b)

    linalg.cho_factor, linalg.cho_solve = cho_factor, cho_solve
    try:
        yield
    finally:
        linalg.cho_factor, linalg.cho_solve = original_factor, original_solve
