"""Whole `rlq train` processes, each with its own empty compile cache unless told: process wall time,
JAX's logged trace / lowering / XLA compile seconds, the host's busy cores, the run's own figures and,
for LunarLander, the Box2D score of the final policy.

    python scripts/bench_cold_start.py --plan plan.json --out cold_start.json --deadline 560

The plan is a JSON list of runs, in order: ``{"name": ..., "args": [override, ...], "env": {VAR: value},
"cache": "cold" | <name of an earlier run whose cache to reuse>, "box2d": episodes, "keep_stderr": prefix,
"video": true, "timeout": seconds}`` (``keep_stderr``: the run's stderr lines that start with ``prefix`` go into the report, e.g.
an entry point's timeline; ``video``: keep the final video, whose time the console's "rendering" line
gives, in ``phases_s`` with the other phases; ``timeout``: this run's own limit). Every run gets
``JAX_LOG_COMPILES=1 logger.wandb.mode=disabled`` (and ``video.at_end=false`` unless ``video``) and its own run directory;
its record holds the host's load averages (1, 5, 15 min) as it started and ended (``load_before``, ``load_after``:
on shared cores a figure means little without them). The report is rewritten after each run, so a run cut off by ``--deadline`` (seconds from the start) leaves
the earlier ones; a run is not started with less than ``--min-left`` seconds left.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import tempfile
import time
from pathlib import Path

from bench_common import QUIET, CpuSampler, box2d_returns, train_process

LOGGED = re.compile(r"Finished (tracing|jaxpr to MLIR module conversion|XLA compilation of) (\S+).*? in ([0-9.]+) sec")
PHASE = re.compile(r"^rlq: (compiling|evaluating|rendering): ([0-9.]+) s$", re.MULTILINE)
KIND = {"tracing": "trace", "jaxpr to MLIR module conversion": "lower", "XLA compilation of": "compile"}


def run_one(spec: dict, caches: dict[str, str], work: Path, timeout: float, box2d_now: bool = True) -> dict:
    name = spec["name"]
    cache = caches[spec["cache"]] if spec.get("cache", "cold") != "cold" else tempfile.mkdtemp(dir=work, prefix="cc_")
    caches[name] = cache
    run_dir = work / f"run_{name}"
    quiet = [arg for arg in QUIET if not (spec.get("video") and arg.startswith("video."))]
    args = [*spec["args"], f"compile_cache={cache}", *quiet]
    env = {"JAX_LOG_COMPILES": "1", "PYTHONUNBUFFERED": "1", **spec.get("env", {})}
    load_before = [round(load, 2) for load in os.getloadavg()]
    with CpuSampler(period=1.0) as cpu:
        proc = train_process(args, run_dir, env=env, timeout=timeout, entry=spec.get("entry"))
    rc, stdout, stderr, wall = proc["rc"], proc["stdout"], proc["stderr"], proc["process_wall_s"]
    result: dict = {"name": name, "command": "rlq train " + " ".join(spec["args"]), "env": spec.get("env", {})}
    result.update({"cache": spec.get("cache", "cold"), "rc": rc, "process_wall_s": round(wall, 2)})
    result.update(load_before=load_before, load_after=[round(load, 2) for load in os.getloadavg()])
    logged = [[KIND[m.group(1)], m.group(2)[:40], float(m.group(3))] for m in LOGGED.finditer(stderr + stdout)]
    result["logged"] = [entry for entry in logged if entry[2] >= 0.3]
    result["xla_compile_s"] = [entry[2] for entry in logged if entry[0] == "compile" and entry[2] >= 0.3]
    summary_path = run_dir / "summary.json"
    if summary_path.exists():
        summary = json.loads(summary_path.read_text())
        for key in ("wall_s", "compile_s", "steady_env_steps_per_s", "env_steps", "eval_return", "cached_programs"):
            result[key] = summary.get(key)
        rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
        train = [r for r in rows if r["kind"] == "train"]
        if train:
            result["first_train_row_s"] = train[0].get("wall_s")
    result["busy_cores_each_s"] = [round(busy, 1) for busy in cpu.samples]
    result["phases_s"] = {m.group(1): float(m.group(2)) for m in PHASE.finditer(stderr)}
    if spec.get("keep_stderr"):
        result["stderr_lines"] = [line for line in stderr.splitlines() if line.startswith(spec["keep_stderr"])]
    if rc != 0:
        result["stderr_tail"] = stderr[-2500:]
    result["run_dir"] = str(run_dir)
    if box2d_now and spec.get("box2d") and rc == 0:
        result.update(box2d(run_dir, spec["box2d"]))
    return result


def box2d(run_dir: Path, episodes: int) -> dict:
    """The final policy's mean return per seed on Gymnasium's Box2D LunarLander (policy on the CPU)."""
    t = time.perf_counter()
    try:
        returns = box2d_returns(run_dir, episodes, cpu_only=True)
    except RuntimeError as err:
        return {"box2d_error": str(err)[-1500:]}
    return {"box2d_return": returns, "box2d_eval_s": round(time.perf_counter() - t, 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plan", type=Path, required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--deadline", type=float, default=560.0)
    parser.add_argument("--min-left", type=float, default=40.0)
    parser.add_argument("--box2d-at-end", action="store_true", help="score on Box2D after all runs, side by side")
    args = parser.parse_args()
    t0 = time.perf_counter()
    plan = json.loads(args.plan.read_text())
    work = Path(tempfile.mkdtemp(prefix="cold_start_"))
    caches: dict[str, str] = {}
    results: list[dict] = []
    for spec in plan:
        left = args.deadline - (time.perf_counter() - t0)
        if left < args.min_left:
            results.append({"name": spec["name"], "skipped": f"{left:.0f} s left"})
            continue
        timeout = min(left - 5, float(spec.get("timeout", left)))
        result = run_one(spec, caches, work, timeout=timeout, box2d_now=not args.box2d_at_end)
        results.append(result)
        args.out.write_text(json.dumps({"runs": results}, indent=1))
        brief = {
            k: result.get(k) for k in ("name", "rc", "load_before", "process_wall_s", "compile_s", "xla_compile_s")
        }
        brief.update({k: result.get(k) for k in ("steady_env_steps_per_s", "eval_return", "box2d_return")})
        print(json.dumps(brief), flush=True)
    if args.box2d_at_end:
        from concurrent.futures import ThreadPoolExecutor

        scored = [(r, s) for r, s in zip(results, plan, strict=True) if s.get("box2d") and r.get("rc") == 0]
        with ThreadPoolExecutor(max_workers=max(1, len(scored))) as pool:
            scores = list(pool.map(lambda rs: box2d(Path(rs[0]["run_dir"]), rs[1]["box2d"]), scored))
        for (result, _), score in zip(scored, scores, strict=True):
            result.update(score)
            print(json.dumps({"name": result["name"], **score})[:300], flush=True)
    args.out.write_text(json.dumps({"runs": results}, indent=1))


if __name__ == "__main__":
    main()
