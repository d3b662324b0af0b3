"""`rlq compare <run or multirun dir>... [metric=eval/return] [x=env_steps|wall_s] [threshold=N] [out=PATH]`."""

from __future__ import annotations

import math
import sys
from pathlib import Path

from rlq.errors import UsageError
from rlq.tools.compare import compare, summary_lines

KEYS = {"metric", "x", "out", "threshold"}
USAGE = "usage: rlq compare <run or multirun dir>... [metric=eval/return] [x=env_steps|wall_s] [threshold=N] [out=PATH]"
HELP = f"""{USAGE}

Learning curves of one metric, each seed's and the mean ± std over seeds (legend beside the plot), to a PNG, and a table of each run's final metrics
(console and CSV). Per group, the console and the plot give the interquartile mean of its seeds' final values with
its 95 % bootstrap interval (rliable) beside mean ± std and, with threshold=, the seeds at or above it. Runs are grouped by the overrides that tell them apart, seed left out: the seed= jobs
of a sweep and the seeds of a num_seeds>1 run are the curves of one group. A multirun directory stands
for all its jobs.

options:
  <dir>...     run directories (outputs/<date>/<time>_<name>) or multirun directories (multirun/<date>/<time>)
  metric=K/M   the metric to draw, <kind>/<name> of metrics.jsonl's rows (default eval/return;
               e.g. train/episode_return, eval/archive-occupancy)
  x=X          env_steps (default) or wall_s
  threshold=N  count each group's seeds whose final value is at or above N (e.g. threshold=475)
  out=PATH     writes PATH.png and PATH.csv (default: compare_<metric> in the one directory given,
               else in the directory that holds the compared runs)
"""


def compare_main(args: list[str]) -> None:
    options, dirs = {}, []
    for arg in args:
        key, sep, value = arg.partition("=")
        if not sep:
            dirs.append(Path(arg))
        elif key in KEYS:
            options[key] = value
        else:
            raise UsageError(f"unknown option '{key}'; {USAGE}")
    if not dirs:
        raise UsageError(f"needs at least one run or multirun directory; {USAGE}")
    out = Path(options["out"]) if "out" in options else None
    threshold = parse_threshold(options["threshold"]) if "threshold" in options else None
    result = compare(dirs, options.get("metric", "eval/return"), options.get("x", "env_steps"), out, threshold)
    print("\n".join(summary_lines(result)), file=sys.stdout)
    print(f"rlq compare: {len(result.table)} runs -> {result.png}, {result.csv}", file=sys.stdout)


def parse_threshold(text: str) -> float:
    """``threshold=``'s value: a finite number."""
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"threshold={text}: not a number; give e.g. threshold=475") from None
    if not math.isfinite(value):
        raise UsageError(f"threshold={text}: give a finite number, e.g. threshold=475")
    return value
