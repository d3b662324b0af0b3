"""Batched small Cholesky factor + solve: XLA's (cuSOLVER/cuBLAS on a GPU) vs rlq's Pallas kernels.

The shape is MJX's humanoid: ``--batch`` matrices of ``--size`` rows, one factor and one solve per
call (as MJX's Newton step does). Reported per implementation: microseconds per call (median of
``--repeats`` timed calls of a jitted ``--calls``-long chain, so launch gaps count) and the largest
difference of the solution from XLA's.

    python scripts/bench_cholesky.py --out docs/results/cholesky_h100.json           # GPU
    python scripts/bench_cholesky.py --batch 8 --calls 2 --blocks 1 2 --interpret    # CPU smoke
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import statistics
import time
from pathlib import Path

import jax
import jax.numpy as jnp
from bench_common import write_report

from rlq.envs import mjx_linalg


def problem(batch: int, size: int) -> tuple[jax.Array, jax.Array]:
    """Symmetric positive-definite matrices (conditioned like a mass matrix plus constraint terms)."""
    k1, k2 = jax.random.split(jax.random.PRNGKey(0))
    m = jax.random.normal(k1, (batch, size, size))
    return m @ jnp.swapaxes(m, -1, -2) / size + 0.1 * jnp.eye(size), jax.random.normal(k2, (batch, size))


def factor_and_solve(a: jax.Array, b: jax.Array) -> jax.Array:
    return jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(a), b)


def chain(calls: int):
    """``calls`` dependent factor+solve calls (each right-hand side is the last solution)."""

    def run(a, b):
        for _ in range(calls):
            b = jax.vmap(factor_and_solve)(a, b)
        return b

    return run


def timed(fn, a, b, repeats: int, calls: int) -> float:
    jax.block_until_ready(fn(a, b))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(a, b))
        times.append(time.perf_counter() - start)
    return statistics.median(times) / calls * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batch", type=int, default=4096)
    parser.add_argument("--size", type=int, default=27)
    parser.add_argument("--calls", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--blocks", type=int, nargs="+", default=[32, 64, 128, 256], help="matrices per Pallas program")
    parser.add_argument("--warps", type=int, nargs="+", default=[1, 4], help="warps per Pallas program")
    parser.add_argument("--pad", choices=["no", "yes", "both"], default="no", help="pad matrices to 2^k rows")
    parser.add_argument("--interpret", action="store_true", help="Pallas interpreted (CPU)")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()

    a, b = problem(args.batch, args.size)
    reference = jax.jit(chain(1))(a, b)
    results = [
        {"impl": "xla", "us_per_call": round(timed(jax.jit(chain(args.calls)), a, b, args.repeats, args.calls), 1)}
    ]
    print(json.dumps(results[0]), flush=True)
    pads = {"no": [False], "yes": [True], "both": [False, True]}[args.pad]
    for block, warps, pad in itertools.product(args.blocks, args.warps, pads):
        launch = mjx_linalg.Launch(block=block, warps=warps, pad=pad, interpret=args.interpret)
        with mjx_linalg.fast_cholesky(launch):
            one, many = jax.jit(chain(1)), jax.jit(chain(args.calls))
            start = time.perf_counter()
            error = float(jnp.max(jnp.abs(one(a, b) - reference)))
            compile_s = time.perf_counter() - start
            us = timed(many, a, b, args.repeats, args.calls)
        row = {"impl": "pallas", **dataclasses.asdict(launch), "us_per_call": round(us, 1)}
        results.append({**row, "max_abs_diff": error, "first_call_s": round(compile_s, 2)})
        print(json.dumps(results[-1]), flush=True)
    write_report("cholesky", [{"batch": args.batch, "size": args.size, **row} for row in results], args.out)


if __name__ == "__main__":
    main()
