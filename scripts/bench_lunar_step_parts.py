"""Where a LunarLander env step's time goes: the step of a preset's env timed at one batch size
under solver overrides (velocity or position sweeps cut to one, the block solver off, the velocity
sweeps on stacked arrays or on components, 6 or 18 velocity sweeps per loop trip), and the
kernels XLA compiles into each trip of the solver's loops.

On a GPU a batch of thousands of envs is launch-bound: a step's time is its number of
sequential kernels, most of them inside the solver's loops, so the count per trip is the
figure a rewrite of the sweeps has to bring down. Writes JSON to ``--out``.

    python scripts/bench_lunar_step_parts.py --envs 8192 --out lunar_step_parts.json
    python scripts/bench_lunar_step_parts.py --envs 16 --steps 2 --variants preset   # CPU smoke test
"""

from __future__ import annotations

import argparse
import collections
import json
import re
import sys
import time

import jax
from bench_common import run_header
from bench_lunar_env import random_steps

from rlq.config.compose import compose
from rlq.run.programs.env_stack import checked_env

#: name -> overrides of the preset's env
VARIANTS = {
    "preset": [],
    "one_velocity_sweep": ["env.solver.velocity_iterations=1"],
    "one_position_sweep": ["env.solver.position_iterations=1"],
    "one_sweep_each": ["env.solver.velocity_iterations=1", "env.solver.position_iterations=1"],
    "no_block_solver": ["env.solver.block_solve=false"],
    "stacked_sweeps": ["env.solver.sweep_layout=stacked"],
    "component_sweeps": ["env.solver.sweep_layout=components"],
    "unroll_6": ["env.solver.unroll=6", "env.solver.component_unroll=6"],
    "unroll_18": ["env.solver.unroll=18", "env.solver.component_unroll=18"],
}


def opcode(instruction: str) -> str | None:
    """The opcode of an HLO instruction line ``%name = <shape> <opcode>(...)``; the shape of a
    multi-output instruction is a tuple ``(f32[...], ...)``, which holds spaces."""
    _, _, rest = instruction.partition(" = ")
    if rest.startswith("("):
        depth = 0
        for i, ch in enumerate(rest):
            depth += {"(": 1, ")": -1}.get(ch, 0)
            if depth == 0:
                rest = rest[i + 1 :]
                break
    else:
        rest = rest.partition(" ")[2]
    found = re.match(r"\s*([a-z][\w\-]*)\(", rest)
    return found.group(1) if found else None


def loop_bodies(hlo: str) -> list[dict]:
    """Each ``while`` loop of an optimized HLO module: its known trip count (None: data-dependent)
    and its body's top-level instructions by opcode (a GPU launches roughly one kernel per fusion)."""
    bodies: dict[str, list[str]] = {}
    current = None
    for line in hlo.splitlines():
        header = re.match(r"^(?:ENTRY )?%?([\w.\-]+) .*\{$", line)
        if header:
            current = header.group(1)
            bodies[current] = []
        elif current and line.startswith("  ") and " = " in line:
            bodies[current].append(line)
    loops = []
    for instructions in list(bodies.values()):
        for line in instructions:
            if " while(" not in line:
                continue
            body = re.search(r"body=%?([\w.\-]+)", line)
            trip = re.search(r'known_trip_count":\{"n":"(\d+)"', line)
            opcodes = collections.Counter(
                op for op in (opcode(item) for item in bodies.get(body.group(1), [])) if op is not None
            )
            loops.append({"trip_count": int(trip.group(1)) if trip else None, "opcodes": dict(opcodes.most_common())})
    return loops


def measure(preset: str, overrides: list[str], num_envs: int, steps: int) -> dict:
    env = checked_env(compose([f"experiment={preset}", *overrides]), "env")
    run = random_steps(env, num_envs, steps)
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), num_envs))
    start = time.perf_counter()
    compiled = jax.jit(run).lower(state, jax.random.PRNGKey(1)).compile()
    compile_s = time.perf_counter() - start
    state = jax.block_until_ready(compiled(state, jax.random.PRNGKey(1)))
    walls = []
    for i in range(3):
        start = time.perf_counter()
        state = jax.block_until_ready(compiled(state, jax.random.PRNGKey(2 + i)))
        walls.append(time.perf_counter() - start)
    ms = 1000 * min(walls) / steps
    return {
        "overrides": overrides,
        "compile_s": round(compile_s, 2),
        "ms_per_step": round(ms, 3),
        "env_steps_per_s": round(num_envs * 1000 / ms),
        "loops": loop_bodies(compiled.as_text()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="lunar_ppo_gpu", help="experiment whose env is stepped")
    parser.add_argument("--envs", type=int, default=8192)
    parser.add_argument("--steps", type=int, default=16, help="scanned steps per timed call (best of 3)")
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--out", default="lunar_step_parts.json")
    args = parser.parse_args()
    report = {
        "benchmark": "lunar_step_parts",
        **run_header(),
        "command": " ".join(sys.argv),
        "preset": args.preset,
        "envs": args.envs,
        "variants": {},
    }
    for name in args.variants:
        report["variants"][name] = result = measure(args.preset, VARIANTS[name], args.envs, args.steps)
        kernels = [(loop["trip_count"] or "until solved", loop["opcodes"].get("fusion", 0)) for loop in result["loops"]]
        print(
            f"{name}: {result['ms_per_step']} ms per step, (trips, fusions per trip) of its loops {kernels}", flush=True
        )
        with open(args.out, "w") as f:
            json.dump(report, f, indent=1)


if __name__ == "__main__":
    main()
