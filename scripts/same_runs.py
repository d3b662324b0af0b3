"""Are two runs the same bit for bit: every metrics.jsonl row (its wall-clock ``wall_s`` aside) and every
checkpoint's bytes? For a change that must not change results: the same command and seed, on the same machine, with
the code before and after it.

    python scripts/same_runs.py RUN_DIR_BEFORE RUN_DIR_AFTER [--out same.json]

Prints one line per difference (at most ``--show``) and exits 1 if there is any, 0 if the two runs are the same.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

#: row keys that measure time, not results
CLOCK_KEYS = ("wall_s",)


def rows(run: Path) -> list[dict]:
    """metrics.jsonl's rows without their clock keys."""
    lines = (run / "metrics.jsonl").read_text().splitlines()
    return [{k: v for k, v in json.loads(line).items() if k not in CLOCK_KEYS} for line in lines if line.strip()]


def checkpoints(run: Path) -> dict[str, str]:
    """Each checkpoint file's name and the sha256 of its bytes (the states, bit for bit)."""
    return {
        path.relative_to(run).as_posix(): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in sorted((run / "checkpoints").glob("*.msgpack"))
    }


def differences(before: Path, after: Path) -> list[str]:
    out = []
    rows_a, rows_b = rows(before), rows(after)
    if len(rows_a) != len(rows_b):
        out.append(f"metrics.jsonl: {len(rows_a)} rows against {len(rows_b)}")
    for i, (a, b) in enumerate(zip(rows_a, rows_b, strict=False)):
        for key in sorted(set(a) | set(b)):
            if a.get(key, "<missing>") != b.get(key, "<missing>"):  # json floats: repr round-trips float64
                out.append(f"metrics.jsonl row {i} ({a.get('kind')}) {key}: {a.get(key)!r} against {b.get(key)!r}")
    ckpt_a, ckpt_b = checkpoints(before), checkpoints(after)
    if not ckpt_a:
        out.append(f"{before}: no checkpoint")
    for name in sorted(set(ckpt_a) | set(ckpt_b)):
        if ckpt_a.get(name) != ckpt_b.get(name):
            out.append(f"{name}: sha256 {ckpt_a.get(name)} against {ckpt_b.get(name)}")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--show", type=int, default=20, help="differences printed at most")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    found = differences(args.before, args.after)
    hashes = checkpoints(args.before)
    report = {
        "before": str(args.before),
        "after": str(args.after),
        "rows": len(rows(args.before)),
        "checkpoints": hashes,
        "same": not found,
        "differences": found,
    }
    if args.out:
        args.out.write_text(json.dumps(report, indent=1))
    for line in found[: args.show]:
        print(line)
    print(f"{'same' if not found else 'DIFFERENT'}: {report['rows']} rows, {len(hashes)} checkpoint(s)")
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
