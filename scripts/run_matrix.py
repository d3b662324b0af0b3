"""Runs env × algo pairs as a user would and writes each seed's final score against the pair's threshold:
the plain command `rlq train algo=X env=Y num_seeds=N seed=B`, one process per pair (one program for the
N seeds), LunarLander scored on Gymnasium's Box2D env (`rlq eval run=<dir> env=lunar_box2d episodes=100`).

    python scripts/run_matrix.py --pairs lunar:dqn cartpole:ppo --seeds 16 --base-seed 5000 \\
        --machine h200 --out docs/results/matrix_h200_2026_12_02.json [--single-seed]

Every process gets ``logger.wandb.mode=disabled video.at_end=false``, its own run directory and an empty compile
cache (a user's first run). ``--single-seed`` adds, per pair, one cold single-seed run (`seed=B`, no
``num_seeds``): the time a user waits for one result. ``--score-in-background`` scores LunarLander on Box2D (on
the CPU) while the next pairs train: for a GPU machine, whose host cores are otherwise idle. ``--override`` adds
keys to every command (a smoke test on a small budget; they are part of the recorded command). Thresholds come
from scripts/matrix_pairs.py (``--threshold env:algo=value`` replaces one). The JSON file is rewritten after
every process and every scoring, so a run cut off keeps what finished (a run not scored yet says so); results
already in ``--out`` for other pairs (or other seed counts) are kept, so several invocations fill one file per
machine. A process runs to its end, as a user's would, unless ``--timeout`` (seconds per process) or ``--deadline``
(seconds from the start) limits it, as a device call's time does; one cut off is kept as such, unscored. Pair
names, seed counts, thresholds and limits are checked before anything runs (one line, exit 2).
docs/matrix.md's table is generated from these files (scripts/render_matrix.py).
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import tempfile
import time
from concurrent.futures import Future, ThreadPoolExecutor, wait
from pathlib import Path

from bench_common import QUIET, box2d_returns, device_name, package_versions, rlq_commit, train_process
from matrix_pairs import WRITTEN_BY, BadPair, OneLineParser, Threshold, parse_pair, parse_threshold, threshold


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = OneLineParser("run_matrix", description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", nargs="+", required=True, help="env:algo names, e.g. lunar:dqn cartpole:ppo")
    parser.add_argument("--seeds", type=int, default=16, help="num_seeds of each pair's one process")
    parser.add_argument("--base-seed", type=int, default=5000, help="the command's seed= (seeds B .. B+N-1)")
    parser.add_argument("--machine", required=True, help="the machine's name in the result file, e.g. h200")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--single-seed", action="store_true", help="also one cold single-seed run per pair")
    parser.add_argument(
        "--single-seed-only", action="store_true", help="only the cold single-seed runs (no N-seed process)"
    )
    parser.add_argument("--episodes", type=int, default=100, help="Box2D episodes per seed (LunarLander)")
    parser.add_argument("--threshold", nargs="*", default=[], help="env:algo=value in place of the pair's own")
    parser.add_argument(
        "--timeout", type=float, default=None, help="seconds one process may run (default: no limit, as a user's)"
    )
    parser.add_argument(
        "--deadline",
        type=float,
        default=None,
        help="seconds from the start: no run starts after it, one running is cut off",
    )
    parser.add_argument("--min-left", type=float, default=30.0, help="no process starts with fewer seconds left")
    parser.add_argument(
        "--score-in-background",
        action="store_true",
        help="score on Box2D (on the CPU) while the next pairs train (a GPU machine: its host cores are idle)",
    )
    parser.add_argument("--override", nargs="*", default=[], help="more overrides (a smoke test; kept in the command)")
    parser.add_argument("--work", type=Path, default=None, help="where the run directories go (default: a temp dir)")
    args = parser.parse_args(argv)
    try:
        args.pairs = [parse_pair(name) for name in args.pairs]
        if len(set(args.pairs)) != len(args.pairs):
            raise BadPair("a pair is named twice in --pairs")
        if args.seeds < 1:
            raise BadPair(f"--seeds {args.seeds}: needs at least 1 seed")
        if not args.out.parent.is_dir():
            raise BadPair(f"--out {args.out}: no folder {args.out.parent}")
        if args.episodes < 1:
            raise BadPair(f"--episodes {args.episodes}: needs at least 1 episode")
        for flag, value in (("--timeout", args.timeout), ("--deadline", args.deadline)):
            if value is not None and not value > 0:
                raise BadPair(f"{flag} {value:g}: needs a positive number of seconds")
        args.thresholds = {pair: threshold(*pair) for pair in args.pairs}
        for item in args.threshold:
            pair, value = parse_threshold(item, args.pairs)
            old = args.thresholds[pair]
            args.thresholds[pair] = Threshold(old.metric, value, f"given on the command line ({old.why})")
    except BadPair as err:
        parser.error(str(err))
    return args


def command(env: str, algo: str, seeds: int | None, seed: int) -> list[str]:
    """The plain command's overrides, as a user types them (``seeds`` None: a single-seed run)."""
    return [f"algo={algo}", f"env={env}", *([f"num_seeds={seeds}"] if seeds is not None else []), f"seed={seed}"]


def scores(run_dir: Path, summary: dict, limit: Threshold, episodes: int) -> dict:
    """Each seed's final score on the threshold's metric, and the seconds the Box2D scoring took."""
    if limit.metric == "box2d":
        start = time.perf_counter()
        returns = box2d_returns(run_dir, episodes, cpu_only=True)
        return {"per_seed": returns, "episodes": episodes, "scoring_s": round(time.perf_counter() - start, 1)}
    if limit.metric == "eval_return":
        return {"per_seed": summary["eval_return"]}
    if limit.metric not in summary.get("final_eval", {}):
        raise RuntimeError(f"the run's final evaluation has no {limit.metric!r}")
    return {"per_seed": summary["final_eval"][limit.metric]}


def error_line(stderr: str) -> str:
    """The line rlq ends a failed run with (``rlq: error: ...``), else stderr's last line."""
    lines = [line for line in stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("rlq: error")]
    return (errors or lines or [""])[-1][:500]


def run_pair(
    env: str, algo: str, seeds: int | None, args: argparse.Namespace, work: Path, timeout: float | None
) -> dict:
    """One process of the pair: the record the result file keeps, to be scored (``score``) if it ran."""
    limit = args.thresholds[(env, algo)]
    overrides = [*command(env, algo, seeds, args.base_seed), *args.override]
    run_dir = work / f"{env}_{algo}_{'single' if seeds is None else seeds}"
    cache = tempfile.mkdtemp(dir=work, prefix="compile_cache_")
    proc = train_process([*overrides, *QUIET, f"compile_cache={cache}"], run_dir, timeout=timeout)
    record: dict = {
        "pair": f"{env}:{algo}",
        "env": env,
        "algo": algo,
        "kind": "single_seed" if seeds is None else "seeds",
        "num_seeds": seeds or 1,
        "base_seed": args.base_seed,
        "command": "rlq train " + " ".join(overrides),
        "added": [*QUIET, "compile_cache=<empty dir>"],
        "threshold": limit.as_dict(),
        "rc": proc["rc"],
        "process_wall_s": proc["process_wall_s"],
        "machine": args.machine,
        "date": datetime.date.today().isoformat(),
        "rlq_commit": args.commit,
        "packages": args.packages,
        "run_dir": str(run_dir),
    }
    if proc["rc"] == "timeout":
        record["failed"] = f"cut off after {timeout:.0f} s"
        return record
    if proc["rc"] != 0:
        record["refused" if proc["rc"] == 2 else "failed"] = error_line(proc["stderr"])
        return record
    summary = json.loads((run_dir / "summary.json").read_text())
    record.update({key: summary.get(key) for key in ("wall_s", "compile_s", "env_steps", "stopped")})
    record["failed"] = "not scored yet (a runner cut off before scoring leaves this)"
    return record


def score(record: dict, episodes: int) -> dict:
    """``record`` of a run that ended, with each seed's score and the seeds over the threshold."""
    scored = {k: v for k, v in record.items() if k != "failed"}
    run_dir = Path(record["run_dir"])
    limit = Threshold(**record["threshold"])
    try:
        scored.update(scores(run_dir, json.loads((run_dir / "summary.json").read_text()), limit, episodes))
    except (RuntimeError, KeyError) as err:
        return {**scored, "failed": f"scoring: {str(err)[-500:]}"}
    if limit.value is not None:
        scored["over_threshold"] = sum(value >= limit.value for value in scored["per_seed"])
    return scored


def load(out: Path, machine: str) -> list[dict]:
    """The records already in ``out`` (none if it is absent); refuses another machine's file."""
    if not out.exists():
        return []
    report = json.loads(out.read_text())
    if report.get("machine") != machine:
        raise BadPair(f"{out} holds machine {report.get('machine')!r}'s results, not {machine!r}'s")
    return list(report["results"])


def key(record: dict) -> tuple:
    return record["pair"], record["kind"], record["num_seeds"], record["base_seed"]


def merged(records: list[dict], record: dict) -> list[dict]:
    """``records`` with ``record`` in place of the one of the same pair, kind, seed count and base seed."""
    return [r for r in records if key(r) != key(record)] + [record]


def save(out: Path, args: argparse.Namespace, records: list[dict]) -> None:
    """Writes ``records`` as the file's results; the file's other keys (e.g. ``tuning``, ``superseded``: records
    moved aside by hand) are kept."""
    kept = json.loads(out.read_text()) if out.exists() else {}
    report = {
        **kept,
        "written_by": WRITTEN_BY,
        "what": "env x algo pairs run as a user would: the plain command, one process per pair "
        "(scripts/run_matrix.py); per_seed: each seed's final score on the threshold's metric",
        "machine": args.machine,
        "device": args.device,
        "results": sorted(records, key=key),
    }
    out.write_text(json.dumps(report, indent=1) + "\n")


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    try:
        records = load(args.out, args.machine)
    except BadPair as err:
        print(f"run_matrix: error: {err}", file=sys.stderr)
        raise SystemExit(2) from None
    t0 = time.perf_counter()
    args.commit, args.device, args.packages = rlq_commit(), device_name(), package_versions()
    work = args.work or Path(tempfile.mkdtemp(prefix="run_matrix_"))
    work.mkdir(parents=True, exist_ok=True)
    runs = [] if args.single_seed_only else [(pair, args.seeds) for pair in args.pairs]
    runs += [(pair, None) for pair in args.pairs] if args.single_seed or args.single_seed_only else []
    pending: list[Future] = []
    with ThreadPoolExecutor(max_workers=1) as scorer:
        for (env, algo), seeds in runs:
            left = (args.deadline or float("inf")) - (time.perf_counter() - t0)
            if left < args.min_left:
                print(json.dumps({"pair": f"{env}:{algo}", "num_seeds": seeds or 1, "skipped": f"{left:.0f} s left"}))
                continue
            limit = min(args.timeout or float("inf"), left)
            record = run_pair(env, algo, seeds, args, work, timeout=None if limit == float("inf") else limit)
            records = report(args, merged(records, record), record)
            if record["rc"] == 0:
                pending.append(scorer.submit(score, record, args.episodes))
                if not args.score_in_background:
                    wait(pending)
            for future in [f for f in pending if f.done()]:
                pending.remove(future)
                records = report(args, merged(records, future.result()), future.result())
        for future in pending:
            records = report(args, merged(records, future.result()), future.result())


def report(args: argparse.Namespace, records: list[dict], record: dict) -> list[dict]:
    """Save ``records`` and print ``record`` in brief; returns ``records``."""
    save(args.out, args, records)
    brief = ("pair", "num_seeds", "rc", "process_wall_s", "over_threshold", "per_seed", "refused", "failed")
    print(json.dumps({k: record[k] for k in brief if k in record}), flush=True)
    return records


if __name__ == "__main__":
    main()
