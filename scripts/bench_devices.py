"""Scaling over the GPUs of one node: steady env steps/s of the same run on 1, 2, ..., N devices.

For each preset, `rlq train experiment=<preset> devices=k` runs once per device count k (one
process each, as a user would run it); the report gives each run's steady env steps/s (rlq's mean
over its training chunks, compile excluded), its speed-up over one device and its efficiency
(speed-up / k), and whether the targets hold: >= 1.9x on 2 devices, >= 0.9 k x on k devices.

Strong scaling (``--scale strong``): the same config on k devices; ``devices=k`` is an explicit value,
so with ``num_seeds`` below k each seed's envs split over the devices (the same numbers). Weak scaling
(``--scale weak``): ``num_seeds`` times k (each device keeps the 1-device run's work; seeds split over
devices). By default both, in one report. ``--minibatch-shuffle per_shard global`` repeats the strong
scaling runs with each ``algo.minibatch_shuffle`` (PPO, PQN): per_shard keeps each minibatch's gather on
the devices that hold its envs, global gathers every minibatch from all of them (weak scaling splits
no seed's envs, where the two are the same).

The ceiling of strong scaling (``--scale bound``, one device is enough): the preset on one device with its
env batch cut to 1/k, for each k. A device that is not saturated by the whole batch steps 1/k of it in
more than 1/k of the time, so k devices can at best reach ``k x steps/s(N/k) / steps/s(N)``, whatever
they exchange (the report's ``ideal_speedup``; humanoid PPO on an H200: 1.24x for 4096 envs on 2 GPUs).

    python scripts/bench_devices.py --out bench_devices.json          # humanoid PPO, brittle star PPO
    python scripts/bench_devices.py --preset humanoid_ppo --devices 1 2 --scale strong \
        --minibatch-shuffle per_shard global --out bench_shuffle.json    # the two samplings on 1 vs 2 GPUs
    XLA_FLAGS=--xla_force_host_platform_device_count=2 python scripts/bench_devices.py \\
        --preset cartpole_ppo --devices 1 2 --override budget.env_steps=4096 log_every_steps=1024 \\
        algo.num_envs=8 algo.num_steps=32 eval.episodes=2 video.at_end=false   # CPU smoke check
    python scripts/bench_devices.py --preset humanoid_ppo --devices 1 2 4 8 --scale bound   # on one GPU
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import ask_jax, device_name, run_figures, run_rlq  # noqa: E402

PRESETS = ("humanoid_ppo", "brittle_star_ppo_direct")
#: a short steady phase after the compile: env steps per seed of each run, per preset
BUDGETS = {"humanoid_ppo": 3_276_800, "brittle_star_ppo_direct": 1_310_720}
#: speed-up targets: at least this fraction of k on k devices (1.9x on 2)
TARGET = {2: 0.95}
TARGET_OTHER = 0.9


def local_device_count() -> int:
    return int(ask_jax("print(jax.local_device_count())"))


def default_counts(available: int) -> list[int]:
    counts = [k for k in (1, 2, 4, 8, 16) if k <= available]
    return counts if available in counts else [*counts, available]


def preset_overrides(preset: str, overrides: list[str]) -> list[str]:
    """Every run's overrides: the preset at its short budget, no video, no periodic evaluation, quiet."""
    budget = [f"budget.env_steps={BUDGETS[preset]}"] if preset in BUDGETS else []
    return [f"experiment={preset}", *budget, "logger=quiet", "video.at_end=false", "eval.every_steps=0", *overrides]


def env_batch(overrides: list[str]) -> tuple[str, int]:
    """The config key and size of the batch a run splits over ``env`` devices (e.g. ``algo.num_envs``)."""
    from rlq.algos import algorithm_spec
    from rlq.config.compose import compose

    algo = compose(overrides).algo
    return algorithm_spec(algo).env_batch(algo)


def bench_bound(preset: str, counts: list[int], overrides: list[str]) -> dict:
    """One device with 1/k of the preset's env batch for each k: the ceiling of strong scaling on k devices."""
    common = preset_overrides(preset, overrides)
    key, size = env_batch(common)
    runs = []
    for k in counts:
        if size % k:
            raise SystemExit(f"{preset}: {key}={size} does not split over {k} devices")
        print(f"[bench_devices] {preset}: 1 device, {key}={size // k}", file=sys.stderr, flush=True)
        figures = run_figures(run_rlq([*common, "devices=1", f"{key}={size // k}"]))
        runs.append({"devices": k, key: size // k, **figures})
    for run, ideal in zip(runs, ideal_speedups(runs), strict=True):
        run["ideal_speedup"] = ideal
    return {"preset": preset, "scale": "bound", "overrides": common, "runs": runs}


def ideal_speedups(runs: list[dict]) -> list[float | None]:
    """k x steps/s(N/k) / steps/s(N) for runs on one device with 1/k of the batch (the first: k = 1)."""
    whole = runs[0]["steady_env_steps_per_s"]
    return [round(r["devices"] * r["steady_env_steps_per_s"] / whole, 3) if whole else None for r in runs]


def bench_preset(
    preset: str, counts: list[int], scale: str, num_seeds: int, overrides: list[str], shuffle: str | None = None
) -> dict:
    """One preset's runs on each device count; ``shuffle``: their ``algo.minibatch_shuffle`` (None: the config's)."""
    overrides = [*overrides, f"algo.minibatch_shuffle={shuffle}"] if shuffle else overrides
    common = preset_overrides(preset, overrides)
    runs = []
    for k in counts:
        seeds = num_seeds * k if scale == "weak" else num_seeds
        print(f"[bench_devices] {preset}: {k} device(s), {seeds} seed(s)", file=sys.stderr, flush=True)
        figures = run_figures(run_rlq([*common, f"devices={k}", f"num_seeds={seeds}"]))
        runs.append({"devices": k, "num_seeds": seeds, **figures})
    base = runs[0]["steady_env_steps_per_s"]
    for run in runs:
        k = run["devices"]
        speedup = run["steady_env_steps_per_s"] / base if base else float("nan")
        run["speedup"] = round(speedup, 3)
        run["efficiency"] = round(speedup / k, 3)
        run["meets_target"] = speedup >= TARGET.get(k, TARGET_OTHER) * k
    return {"preset": preset, "scale": scale, "minibatch_shuffle": shuffle, "overrides": common, "runs": runs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--preset", nargs="+", default=list(PRESETS), help="experiment presets (conf/experiment/)")
    parser.add_argument(
        "--devices", nargs="+", type=int, help="device counts (default: 1, 2, 4, ... up to all; --scale bound: 1, 2, 4)"
    )
    parser.add_argument("--scale", nargs="+", choices=("strong", "weak", "bound"), default=["strong", "weak"])
    parser.add_argument("--num-seeds", type=int, default=1, help="seeds of the 1-device run")
    parser.add_argument(
        "--minibatch-shuffle",
        nargs="+",
        choices=("per_shard", "global"),
        help="strong scaling once per algo.minibatch_shuffle (default: the config's; PPO and PQN presets only)",
    )
    parser.add_argument("--override", nargs="*", default=[], help="more `rlq train` overrides for every run")
    parser.add_argument("--out", type=Path, help="write the JSON report here as well")
    args = parser.parse_args()
    if "bound" in args.scale and len(args.scale) > 1:
        parser.error("--scale bound runs on one device: give it alone")
    bound_only = args.scale == ["bound"]
    counts = args.devices or ([1, 2, 4] if bound_only else default_counts(local_device_count()))
    if counts[0] != 1:
        counts = [1, *counts]
    results = [
        bench_bound(p, counts, args.override)
        if scale == "bound"
        else bench_preset(p, counts, scale, args.num_seeds, args.override, shuffle)
        for p in args.preset
        for scale in args.scale
        for shuffle in ((args.minibatch_shuffle or [None]) if scale == "strong" else [None])
    ]
    report = {"benchmark": "devices", "device": device_name(), "device_counts": counts, "results": results}
    text = json.dumps(report, indent=2)
    print(text)
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
