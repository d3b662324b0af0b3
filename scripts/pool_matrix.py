"""Pools one pair's N-seed results of several programs into one row of the matrix: where N seeds in one program
would outlast a machine's time limit, the seeds run as a few programs of consecutive seeds (e.g. 4 + 4 + 8 from
base seed 9900), and this writes the record of all of them, each program's time kept as a part.

    python scripts/pool_matrix.py --pair lunar:map_elites --bases 9900 9904 9908 \\
        --out docs/results/matrix_h200_2026_12_02.json

The parts are the file's ``seeds`` records of the pair with those base seeds (the latest of each). They must have
run and been scored on the same threshold by the same rlq commit, and their seeds must follow on from one another
(no seed twice, none missing). Parts of different commits pool only with ``--commits-differ-because TEXT``, the
reason the pair's recipe and code are the same in both (e.g. the commits between them change another algorithm
only); the record keeps that text and each part's commit. The pooled record replaces an earlier one of the same
pair, seed count and base seed; scripts/render_matrix.py shows its parts' times. Bad input: one line, exit 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from matrix_pairs import BadPair, OneLineParser, parse_pair

POOLED_BY = "scripts/pool_matrix.py"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = OneLineParser("pool_matrix", description=__doc__.splitlines()[0])
    parser.add_argument("--pair", required=True, help="env:algo, e.g. lunar:map_elites")
    parser.add_argument("--bases", nargs="+", type=int, required=True, help="the parts' base seeds")
    parser.add_argument("--out", type=Path, required=True, help="the result file that holds the parts")
    parser.add_argument(
        "--commits-differ-because",
        metavar="TEXT",
        help="pool parts of different rlq commits; TEXT says why the pair runs the same code in each (kept)",
    )
    return parser.parse_args(argv)


def part(records: list[dict], pair: str, base: int) -> dict:
    """The latest scored ``seeds`` record of ``pair`` from ``base`` (the one written last of those)."""
    mine = [r for r in records if r["pair"] == pair and r["kind"] == "seeds" and r["base_seed"] == base]
    mine = [r for r in mine if "parts" not in r]
    if not mine:
        raise BadPair(f"--bases {base}: the file has no {pair} result from base seed {base}")
    record = mine[-1]
    if record.get("rc") != 0 or "per_seed" not in record or "failed" in record:
        raise BadPair(f"--bases {base}: the {pair} result from base seed {base} did not run to a score")
    return record


def pooled(records: list[dict], pair: str, bases: list[int], commits_differ_because: str | None = None) -> dict:
    """The record of ``pair``'s results from ``bases``, pooled (checks in the module's docstring)."""
    if len(set(bases)) != len(bases):
        raise BadPair("--bases: a base seed is named twice")
    if len(bases) < 2:
        raise BadPair("--bases: give at least two base seeds (one is a row already)")
    parts = sorted((part(records, pair, base) for base in bases), key=lambda r: r["base_seed"])
    for before, after in zip(parts, parts[1:], strict=False):
        end = before["base_seed"] + before["num_seeds"]
        if after["base_seed"] != end:
            raise BadPair(f"--bases: seeds {end} .. {after['base_seed'] - 1} are missing or run twice between parts")
    for field in ("threshold", "machine"):
        if len({json.dumps(r[field], sort_keys=True) for r in parts}) > 1:
            raise BadPair(f"--bases: the parts differ in {field}; pool results of one recipe and machine only")
    commits = sorted({r["rlq_commit"] for r in parts})
    if len(commits) > 1 and not commits_differ_because:
        raise BadPair(
            f"--bases: the parts differ in rlq_commit ({', '.join(commits)}); pool results of one commit, or say with "
            "--commits-differ-because why the pair's code is the same in each"
        )
    first = parts[0]
    record = {key: first[key] for key in ("pair", "env", "algo", "kind", "threshold", "machine")}
    record["rlq_commit"] = parts[-1]["rlq_commit"]
    record.update(
        num_seeds=sum(r["num_seeds"] for r in parts),
        base_seed=first["base_seed"],
        command="; ".join(r["command"] for r in parts),
        rc=0,
        date=max(r["date"] for r in parts),
        per_seed=[score for r in parts for score in r["per_seed"]],
        parts=[
            {key: r.get(key) for key in ("base_seed", "num_seeds", "process_wall_s", "compile_s", "rlq_commit")}
            for r in parts
        ],
        pooled_by=POOLED_BY,
    )
    if len(commits) > 1:
        record["commits_differ_because"] = commits_differ_because
    if first["threshold"]["value"] is not None:
        record["over_threshold"] = sum(r["over_threshold"] for r in parts)
    return record


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    try:
        parse_pair(args.pair)
        if not args.out.is_file():
            raise BadPair(f"--out {args.out}: no such result file")
        report = json.loads(args.out.read_text())
        record = pooled(report["results"], args.pair, args.bases, args.commits_differ_because)
    except BadPair as err:
        print(f"pool_matrix: error: {err}", file=sys.stderr)
        raise SystemExit(2) from None
    same = (record["pair"], "seeds", record["num_seeds"], record["base_seed"])
    kept = [r for r in report["results"] if (r["pair"], r["kind"], r["num_seeds"], r["base_seed"]) != same]
    report["results"] = [*kept, record]
    args.out.write_text(json.dumps(report, indent=1) + "\n")
    print(json.dumps({k: record[k] for k in ("pair", "num_seeds", "base_seed", "over_threshold") if k in record}))


if __name__ == "__main__":
    main()
