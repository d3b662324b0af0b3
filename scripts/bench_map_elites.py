"""MAP-Elites benchmark on the brittle star QD task (experiment=brittle_star_map_elites).

Three parts, each optional, all written to one JSON file (``--out``):
- ``--sizes``: evaluations/s of one MAP-Elites iteration (select, vary, score every offspring's
  episode, insert) at each number of offspring per iteration, timed after compilation;
- ``--runs``: `rlq train experiment=brittle_star_map_elites` and `experiment=brittle_star_random_search`
  as a user runs them (process start to exit), ``--seeds`` seeds each (one process per seed, so
  each wall time is a whole run), with the final QD metrics, the per-iteration curves and the
  final heatmaps copied to ``--figures``;
- ``--qdax``: QDax's MAPElites (MapElitesRepertoire over the same grid, through its MixingEmitter the
  preset's gaussian mutation, sigma 0.1 for the brittle star, or for a preset with ``algo.variation=iso_line``
  QDax's own ``isoline_variation`` at the preset's widths and bounds) driving rlq's own scoring function with the
  preset's batch size and budget, against rlq's MAP-Elites in the same process: both compiled
  once, then whole runs of each in alternating order (``--qdax-repeats``): evaluations/s after
  compilation, final coverage, QD score and furthest elite, and their medians. QDax is a benchmark-only dependency
  (``bash scripts/qdax_wheels.sh`` fetches its wheels for an offline GPU machine).

    python scripts/bench_map_elites.py --sizes 128 512 1024 2048 4096 --out map_elites.json
    python scripts/bench_map_elites.py --runs --seeds 0 1 2 --figures figs --out map_elites.json
    python scripts/bench_map_elites.py --qdax --out map_elites.json
    python scripts/bench_map_elites.py --qdax --preset experiment=brittle_star_map_elites_es --qdax-repeats 3 --out es.json
    python scripts/bench_map_elites.py --qdax --qdax-seeds 2 --qdax-sides rlq --out rest.json  # finish a cut-off run
    python scripts/bench_map_elites.py --sizes 4 --override env.simulation_time=0.2 --out x.json  # CPU smoke test
    python scripts/bench_map_elites.py --qdax --preset env=humanoid --override algo=map_elites --qdax-repeats 3 \
        --no-qdax-warmup --out humanoid.json      # QDax's humanoid_uni task (conf/tuned/humanoid_map_elites.yaml)
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench_common import run_header  # noqa: E402

from rlq.algos import make_algo  # noqa: E402
from rlq.config.compose import compose  # noqa: E402
from rlq.run.programs.env_stack import make_env  # noqa: E402
from rlq.run.programs.keys import seed_keys  # noqa: E402

PRESET = "experiment=brittle_star_map_elites"
SIDES = ("qdax", "rlq")
BASELINE = "experiment=brittle_star_random_search"


def timed_iterations(preset: str, overrides: list[str], iterations: int) -> dict:
    """Compile one MAP-Elites iteration, run one to fill the archive, then time ``iterations``."""
    cfg = compose([preset, *overrides])
    env = make_env(cfg)
    algo = make_algo(cfg.algo, env, budget_env_steps=10**12)
    keys = seed_keys(int(cfg.seed), 1)  # as `rlq train seed=<seed>` draws seed 0's key
    t0 = time.perf_counter()
    init = jax.jit(jax.vmap(lambda key: algo.init(key, algo.hyperparams))).lower(keys).compile()
    state = init(keys)
    update = jax.jit(jax.vmap(lambda s: algo.update(s, algo.hyperparams))).lower(state).compile()
    compile_s = time.perf_counter() - t0
    state, metrics = update(state)
    jax.block_until_ready(state)
    t1 = time.perf_counter()
    for _ in range(iterations):
        state, metrics = update(state)
    jax.block_until_ready(state)
    seconds = time.perf_counter() - t1
    batch = int(cfg.algo.batch_size)
    return {
        "batch_size": batch,
        "compile_s": round(compile_s, 2),
        "iterations": iterations,
        "seconds": round(seconds, 3),
        "evaluations_per_s": round(iterations * batch / seconds, 1),
        "control_steps_per_s": round(iterations * batch * env.max_episode_steps / seconds, 1),
        "coverage": float(metrics["archive-occupancy"][0]),
    }


def preset_run(preset: str, seed: int, overrides: list[str], figures: Path | None, batch: int | None) -> dict:
    """One `rlq train` process of a preset: wall time, final QD metrics, curves, final heatmap.
    ``batch``: offspring per iteration (MAP-Elites' batch_size, random search's population)."""
    from bench_common import run_rlq

    if batch is not None:
        overrides = [f"algo.{'population' if preset == BASELINE else 'batch_size'}={batch}", *overrides]
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp) / "run"
        out = run_rlq([preset, f"seed={seed}", "video.at_end=false", *overrides], keep_dir=run_dir)
        name = preset.split("=", 1)[1]
        if figures is not None:
            figures.mkdir(parents=True, exist_ok=True)
            shutil.copy(run_dir / "figures" / "heatmap_seed0_final.png", figures / f"{name}_seed{seed}_heatmap.png")
    keys = ("evaluations", "archive-occupancy", "qd-score", "maximum-fitness", "furthest-distance-travelled")
    train = [r for r in out["rows"] if r["kind"] == "train" and r["seed"] == "mean"]
    final = train[-1]
    return {
        "preset": name,
        "seed": seed,
        "process_wall_s": out["process_wall_s"],
        "compile_s": out["summary"]["compile_s"],
        "final": {k: final.get(k) for k in keys},
        "curve": [{k: r.get(k) for k in ("wall_s", *keys)} for r in train],
    }


def qdax_side_by_side(
    preset: str,
    overrides: list[str],
    seeds: list[int],
    sides: tuple[str, ...] = SIDES,
    warmup: bool = True,
    on_run: Callable[[dict], None] = lambda partial: None,
) -> dict:
    """QDax's MAPElites on rlq's scoring function against rlq's MAP-Elites, same budget, in this
    process. Both are compiled once and warmed up with a whole run each; then one whole run of each
    side per seed, alternating which goes first, each from a fresh init with its own key, so
    neither gains from running second (an earlier one-run-each comparison depended on the order).
    ``on_run`` receives the report so far after every run, so a run cut off by a time limit keeps
    what finished (``sides``: the sides to run, e.g. only rlq to finish a cut-off comparison)."""
    from qdax.core.containers.mapelites_repertoire import compute_euclidean_centroids
    from qdax.core.emitters.mutation_operators import isoline_variation
    from qdax.core.emitters.standard_emitters import MixingEmitter
    from qdax.core.map_elites import MAPElites
    from qdax.utils.metrics import default_qd_metrics

    from rlq.algos.map_elites import grid_of
    from rlq.algos.qd import archive as qd_archive
    from rlq.algos.qd import measures
    from rlq.algos.qd.genotypes import make_genotype
    from rlq.algos.qd.scoring import make_keyed_scoring_fn, with_one_key

    cfg = compose([preset, *overrides])
    env = make_env(cfg)
    batch = int(cfg.algo.batch_size)
    iterations = int(cfg.budget.env_steps) // (batch * env.max_episode_steps)
    genotype = make_genotype(cfg.algo, env)
    grid = grid_of(cfg.algo)
    dims = cfg.algo.descriptor_dims
    scoring = with_one_key(
        make_keyed_scoring_fn(
            env,
            genotype.apply,
            1,
            descriptor_key=measures.DESCRIPTOR_KEYS[cfg.algo.descriptor],
            fitness=cfg.algo.fitness,
            descriptor_dims=None if dims is None else tuple(int(d) for d in dims),
        )
    )
    low, high = jnp.asarray(genotype.low), jnp.asarray(genotype.high)
    sigma = float(cfg.algo.sigma)

    def furthest_elite(repertoire) -> jax.Array:
        """rlq's ``furthest-distance-travelled`` of QDax's repertoire, through rlq's own archive metrics."""
        fitness = repertoire.fitnesses.reshape(-1)
        as_archive = qd_archive.Archive(repertoire.genotypes, fitness, repertoire.descriptors, fitness > -jnp.inf)
        return qd_archive.metrics(as_archive)["furthest-distance-travelled"]

    def qdax_scoring(genotypes, key):
        fitness, descriptors, extras = scoring(genotypes, key)
        return fitness, descriptors, {"env_steps": extras["env_steps"]}

    def mutation(x, key):
        return jnp.clip(x + sigma * jax.random.normal(key, x.shape), low, high)

    def iso_line(x1, x2, key):
        iso, line = float(cfg.algo.iso_sigma), float(cfg.algo.line_sigma)
        return isoline_variation(x1, x2, key, iso_sigma=iso, line_sigma=line, minval=low, maxval=high)

    if cfg.algo.variation == "iso_line":
        emitter = MixingEmitter(mutation_fn=None, variation_fn=iso_line, variation_percentage=1.0, batch_size=batch)
    else:
        emitter = MixingEmitter(mutation_fn=mutation, variation_fn=None, variation_percentage=0.0, batch_size=batch)
    metrics_fn = lambda repertoire: default_qd_metrics(repertoire, qd_offset=float(cfg.algo.qd_offset))  # noqa: E731
    map_elites = MAPElites(scoring_function=qdax_scoring, emitter=emitter, metrics_function=metrics_fn)
    centroids = compute_euclidean_centroids(grid_shape=grid.shape, minval=list(grid.low), maxval=list(grid.high))
    qdax_init, qdax_update = jax.jit(map_elites.init), jax.jit(map_elites.update)

    def qdax_run(seed: int) -> dict:
        key = jax.random.PRNGKey(seed)
        key, init_key, first_key = jax.random.split(key, 3)
        first = jax.random.uniform(init_key, (batch, genotype.dim), minval=low, maxval=high)
        repertoire, emitter_state, _ = qdax_init(first, centroids, first_key)
        key, sub = jax.random.split(key)
        repertoire, emitter_state, metrics = qdax_update(repertoire, emitter_state, sub)
        jax.block_until_ready(repertoire)
        t0 = time.perf_counter()
        for _ in range(iterations - 2):
            key, sub = jax.random.split(key)
            repertoire, emitter_state, metrics = qdax_update(repertoire, emitter_state, sub)
        jax.block_until_ready(repertoire)
        return {
            "steady_evaluations_per_s": round((iterations - 2) * batch / (time.perf_counter() - t0), 1),
            "coverage_percent": round(float(metrics["coverage"]), 2),
            "qd_score": round(float(metrics["qd_score"]), 1),
            "furthest_m": round(float(furthest_elite(repertoire)), 3),
        }

    algo = make_algo(cfg.algo, env, budget_env_steps=10**12)
    rlq_init = jax.jit(jax.vmap(lambda key: algo.init(key, algo.hyperparams)))
    rlq_update = jax.jit(jax.vmap(lambda s: algo.update(s, algo.hyperparams)))

    def rlq_run(seed: int) -> dict:
        state = rlq_init(seed_keys(seed, 1))  # the init iteration scores `batch` random genotypes, as QDax's
        state, metrics = rlq_update(state)
        jax.block_until_ready(state)
        t0 = time.perf_counter()
        for _ in range(iterations - 2):
            state, metrics = rlq_update(state)
        jax.block_until_ready(state)
        return {
            "steady_evaluations_per_s": round((iterations - 2) * batch / (time.perf_counter() - t0), 1),
            "coverage_percent": round(100 * float(metrics["archive-occupancy"][0]), 2),
            "qd_score": round(float(metrics["qd-score"][0]), 1),
            "furthest_m": round(float(metrics["furthest-distance-travelled"][0]), 3),
        }

    run_side = {"qdax": qdax_run, "rlq": rlq_run}
    t0 = time.perf_counter()
    warmed = {name: run_side[name](10_000) for name in sides} if warmup else {}
    report: dict = {
        "preset": preset,
        "batch_size": batch,
        "iterations": iterations,
        "seeds": seeds,
        "compile_and_warmup_s": round(time.perf_counter() - t0, 1),
        "warmup": warmed,
        "runs": {name: [] for name in sides},
    }
    keys = ("steady_evaluations_per_s", "coverage_percent", "qd_score", "furthest_m")
    for rep, seed in enumerate(seeds):
        order = [name for name in (("rlq", "qdax") if rep % 2 else ("qdax", "rlq")) if name in sides]
        for name in order:
            report["runs"][name].append({"seed": seed, "position": order.index(name), **run_side[name](seed)})
            print(json.dumps({name: report["runs"][name][-1]}), file=sys.stderr, flush=True)
            report["median"] = {
                side: {key: float(np.median([r[key] for r in runs])) for key in keys}
                for side, runs in report["runs"].items()
                if runs
            }
            on_run(report)
    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="*", default=[], help="offspring per iteration to time")
    parser.add_argument("--iterations", type=int, default=5, help="timed iterations per size")
    parser.add_argument("--runs", action="store_true", help="the two presets end to end, as `rlq train`")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument(
        "--presets", nargs="+", choices=("map_elites", "random_search"), default=["map_elites", "random_search"]
    )
    parser.add_argument("--batch-size", type=int, default=None, help="--runs: offspring per iteration")
    parser.add_argument("--qdax", action="store_true", help="QDax's MAPElites side by side")
    parser.add_argument(
        "--preset",
        default=PRESET,
        help="--sizes, --qdax and --runs' map_elites: the MAP-Elites preset (experiment=..., or env=... with "
        "--override algo=map_elites)",
    )
    parser.add_argument("--qdax-repeats", type=int, default=4, help="--qdax: whole runs of each, alternating")
    parser.add_argument("--qdax-seeds", type=int, nargs="+", default=None, help="--qdax: these seeds, not 0..repeats-1")
    parser.add_argument("--qdax-sides", nargs="+", choices=SIDES, default=list(SIDES), help="--qdax: which sides run")
    parser.add_argument(
        "--qdax-warmup",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="--qdax: a whole untimed run of each first (--no-qdax-warmup: only the QD figures matter)",
    )
    parser.add_argument("--override", nargs="*", default=[], help="config overrides for every part")
    parser.add_argument("--figures", type=Path, default=None, help="where to copy the final heatmaps")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    report: dict = {**run_header(), "command": " ".join(sys.argv), "overrides": args.override}

    def save() -> None:
        args.out.write_text(json.dumps(report, indent=2))

    if args.sizes:
        report["throughput"] = []
        for size in args.sizes:
            report["throughput"].append(
                timed_iterations(args.preset, [f"algo.batch_size={size}", *args.override], args.iterations)
            )
            print(json.dumps(report["throughput"][-1]), file=sys.stderr, flush=True)
            save()
    if args.runs:
        report["runs"] = []
        for preset in [{"map_elites": args.preset, "random_search": BASELINE}[name] for name in args.presets]:
            for seed in args.seeds:
                report["runs"].append(preset_run(preset, seed, args.override, args.figures, args.batch_size))
                print(json.dumps({k: v for k, v in report["runs"][-1].items() if k != "curve"}), file=sys.stderr)
                save()
    if args.qdax:
        seeds = args.qdax_seeds if args.qdax_seeds is not None else list(range(args.qdax_repeats))

        def keep(partial: dict) -> None:
            report["qdax_side_by_side"] = partial
            save()

        qdax_side_by_side(args.preset, args.override, seeds, tuple(args.qdax_sides), args.qdax_warmup, keep)
    save()


if __name__ == "__main__":
    main()
