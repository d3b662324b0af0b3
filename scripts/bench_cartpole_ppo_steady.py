"""Steady cost of one CartPole PPO update, rlq against the PureJaxRL-style anchor, in one process.

Whole processes (scripts/bench_cartpole_ppo.py) mix start-up, compile and training, and a 2-core
machine drifts by 10 % between them. This compiles rlq's chunk program (PureJaxRL's settings, as that
script runs them) and the anchor's whole program for the same number of updates, then runs them in
turn, ``--rounds`` times, and reports each side's milliseconds per update: differences of a few per
cent show here that whole processes hide. Compile time is not counted.

    python scripts/bench_cartpole_ppo_steady.py --rounds 8 --out steady.json
    python scripts/bench_cartpole_ppo_steady.py --epochs 1 --minibatches 1   # mostly the rollout
"""

from __future__ import annotations

import argparse
import datetime
import json
import statistics
import time
from pathlib import Path

import anchor_purejaxrl_ppo as anchor
import jax
from bench_cartpole_ppo import PUREJAXRL
from bench_common import device_name

from rlq.config.compose import compose
from rlq.run.programs.build import build, call_chunk, with_hyper
from rlq.run.programs.compiling import program_options
from rlq.run.programs.keys import seed_keys


def rlq_runner(overrides: list[str], updates: int):
    """A function running ``updates`` PPO updates in rlq's compiled chunks (compiled here)."""
    cfg = compose([*overrides, "num_seeds=1", "video.at_end=false", "compile_cache=null"])
    programs = build(cfg)
    keys = seed_keys(0, 1)
    init = programs.init.lower(keys, programs.hyper_shape).compile(program_options("init", None))
    state = init(keys, programs.hyper)
    chunk = with_hyper(
        programs.chunk.lower(state, programs.hyper_shape).compile(program_options("chunk", None)),
        programs.hyper,
    )
    calls = max(1, updates // programs.updates_per_chunk)
    holder = [state]

    def run() -> None:
        state = holder[0]
        for _ in range(calls):  # as the training loop calls a chunk and fetches its metrics
            state, metrics = call_chunk(chunk, state, programs.calls_per_chunk)
            jax.device_get(metrics)
        holder[0] = jax.block_until_ready(state)

    return run, calls * programs.updates_per_chunk


def anchor_runner(updates: int, epochs: int, minibatches: int):
    """The anchor's whole program for ``updates`` updates (compiled here), called with a new key each time."""
    config = {**anchor.CONFIG, "UPDATE_EPOCHS": epochs, "NUM_MINIBATCHES": minibatches}
    config["TOTAL_TIMESTEPS"] = updates * config["NUM_ENVS"] * config["NUM_STEPS"]
    program = jax.jit(anchor.make_train(config)).lower(jax.random.PRNGKey(0)).compile()
    count = [0]

    def run() -> None:
        count[0] += 1
        jax.block_until_ready(program(jax.random.PRNGKey(count[0])))

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=8)
    parser.add_argument("--epochs", type=int, default=4)
    parser.add_argument("--minibatches", type=int, default=4)
    parser.add_argument("--updates", type=int, default=976, help="per call (PureJaxRL's 5e5 steps: 976)")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    if min(args.rounds, args.epochs, args.minibatches, args.updates) < 1:
        parser.error("--rounds, --epochs, --minibatches and --updates must be at least 1")
    overrides = [
        *(o for o in PUREJAXRL if not o.startswith(("algo.update_epochs", "algo.num_minibatches"))),
        f"algo.update_epochs={args.epochs}",
        f"algo.num_minibatches={args.minibatches}",
    ]
    rlq_run, updates = rlq_runner(overrides, args.updates)
    sides = {"rlq": rlq_run, "anchor": anchor_runner(updates, args.epochs, args.minibatches)}
    for run in sides.values():  # first calls allocate; not counted
        run()
    ms: dict[str, list[float]] = {name: [] for name in sides}
    for i in range(args.rounds):
        for name in ("anchor", "rlq") if i % 2 else ("rlq", "anchor"):
            start = time.perf_counter()
            sides[name]()
            ms[name].append(round((time.perf_counter() - start) / updates * 1e3, 4))
        print(json.dumps({name: values[-1] for name, values in ms.items()}), flush=True)
    median = {name: statistics.median(values) for name, values in ms.items()}
    report = {
        "benchmark": "cartpole_ppo_steady_update",
        "date": datetime.date.today().isoformat(),
        "device": device_name(),
        "command": "rlq's chunk: " + " ".join(overrides),
        "updates_per_call": updates,
        "ms_per_update": ms,
        "median_ms_per_update": median,
        "rlq_over_anchor": round(median["rlq"] / median["anchor"], 3),
    }
    if args.out:
        args.out.write_text(json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
