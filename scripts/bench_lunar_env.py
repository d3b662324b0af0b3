"""env=lunar throughput: env steps/s of the training stack (time limit, episode statistics,
auto-reset) with random actions, at each ``--envs`` batch size, for each solver setting.

Writes JSON to ``--out`` after every measurement (partial results survive an interruption).

    python scripts/bench_lunar_env.py --out bench_lunar_env.json
    python scripts/bench_lunar_env.py --envs 1 64 --steps 5   # CPU smoke test
"""

from __future__ import annotations

import argparse
import itertools
import json
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax

from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.lib.env_api import Env
from rlq.run.programs.env_stack import make_env

DEFAULT_ENVS = [1, 16, 256, 1024, 4096, 16384, 65536]
#: name -> (velocity iterations, position iterations); "box2d" is Gymnasium's world.Step setting
SOLVERS = {"box2d": (180, 60), "fast": (30, 10)}


def log(message: str) -> None:
    print(f"[bench {time.strftime('%H:%M:%S')}] {message}", file=sys.stderr, flush=True)


def random_steps(env: Env, num_envs: int, steps: int) -> Callable[[Any, jax.Array], Any]:
    """``run(state, key)``: ``steps`` scanned steps of ``num_envs`` envs with random actions."""
    space = env.action_space

    def run(state: Any, key: jax.Array) -> Any:
        def one(state: Any, k: jax.Array) -> tuple[Any, None]:
            actions = jax.vmap(space.sample)(jax.random.split(k, num_envs))
            return jax.vmap(env.step)(state, actions), None

        return jax.lax.scan(one, state, jax.random.split(key, steps))[0]

    return run


def lunar_env(continuous: bool, iterations: tuple[int, int], unroll: int) -> Env:
    """env=lunar with its declared defaults (no tuned recipe) but for the variant, the solver's (velocity,
    position) iterations and its unroll, wrapped as ``rlq train`` wraps it."""
    cfg = compose(
        [
            "env=lunar",
            "controller=direct",
            *WITHOUT_TUNED,
            f"env.continuous={continuous}",
            f"env.solver.velocity_iterations={iterations[0]}",
            f"env.solver.position_iterations={iterations[1]}",
            f"env.solver.unroll={unroll}",
            "return_window=0",
        ]
    )
    return make_env(cfg)


def throughput(num_envs: int, steps: int, continuous: bool, iterations: tuple[int, int], unroll: int) -> dict:
    env = lunar_env(continuous, iterations, unroll)
    run = jax.jit(random_steps(env, num_envs, steps))
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), num_envs))
    start = time.perf_counter()
    state = run(state, jax.random.PRNGKey(1))
    jax.block_until_ready(state.obs)
    compile_and_first = time.perf_counter() - start
    start = time.perf_counter()
    state = run(state, jax.random.PRNGKey(2))
    jax.block_until_ready(state.obs)
    wall = time.perf_counter() - start
    return {
        "envs": num_envs,
        "steps": steps,
        "env_steps_per_s": round(num_envs * steps / wall, 1),
        "wall_s": round(wall, 3),
        "compile_and_first_run_s": round(compile_and_first, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", type=int, nargs="+", default=DEFAULT_ENVS)
    parser.add_argument("--steps", type=int, default=200, help="scanned steps per measurement")
    parser.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=list(SOLVERS))
    parser.add_argument("--variants", nargs="+", default=["discrete", "continuous"])
    parser.add_argument("--unroll", type=int, nargs="+", default=[1], help="env.solver.unroll values")
    parser.add_argument("--out", default="bench_lunar_env.json")
    args = parser.parse_args()

    device = jax.devices()[0]
    report: dict = {
        "device": f"{device.platform} | {device.device_kind}",
        "jax": jax.__version__,
        "python": platform.python_version(),
        "results": [],
    }
    for solver in args.solvers:
        for variant, unroll in itertools.product(args.variants, args.unroll):
            for n in args.envs:
                log(f"solver={solver} {variant} unroll={unroll} envs={n}")
                row = throughput(n, args.steps, variant == "continuous", SOLVERS[solver], unroll)
                row.update(solver=solver, iterations=list(SOLVERS[solver]), variant=variant, unroll=unroll)
                report["results"].append(row)
                log(f"  {row['env_steps_per_s']:,.0f} env steps/s")
                Path(args.out).write_text(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
