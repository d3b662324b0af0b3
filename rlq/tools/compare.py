"""Compare runs: learning curves of one metric (mean ± std over seeds), a table of final metrics and, per group,
the interquartile mean of its seeds' final values with a 95 % bootstrap interval and the fraction of seeds over a
threshold (rlq.tools.seed_stats).

A run is a directory `rlq train` wrote (`.hydra/` and `metrics.jsonl`); a multirun directory stands
for all its jobs. Runs are grouped by the overrides that distinguish them, seed left out, so every
seed of one configuration -- the `seed=` jobs of a sweep and the seeds of a `num_seeds>1` run
alike -- is one curve of its group's band.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rlq.errors import UsageError
from rlq.store.outputs import check_output_file
from rlq.store.runs import (
    Curve,
    Run,
    distinguishing_keys,
    final_table,
    is_run,
    load_runs,
    seed_curves,
    split_metric,
    write_csv,
)
from rlq.tools.seed_stats import SeedStats, seed_stats

X_KEYS = ("env_steps", "wall_s")


@dataclass
class Comparison:
    """What `compare` drew and wrote: curves per group (label -> curves), the table and the files."""

    metric: str
    x: str
    groups: dict[str, list[Curve]]
    table: list[dict[str, Any]]
    png: Path | None = None
    csv: Path | None = None
    keys: list[str] = field(default_factory=list)
    #: per group, the figures over its seeds' final values (IQM and interval, median, seeds over ``threshold``)
    stats: dict[str, SeedStats] = field(default_factory=dict)
    threshold: float | None = None


def group_label(run: Run, keys: Sequence[str]) -> str:
    label = ",".join(f"{key}={run.value(key)}" for key in keys if key != "seed")
    return label or str(run.config["run_name"])


def band(curves: Sequence[Curve]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean and standard deviation over curves, on the x values they share (interpolated where their
    x values differ, e.g. wall time; only over the x range every curve covers)."""
    if all(len(c.x) == len(curves[0].x) and np.array_equal(c.x, curves[0].x) for c in curves):
        grid = curves[0].x
    else:
        low, high = max(c.x[0] for c in curves), min(c.x[-1] for c in curves)
        grid = np.unique(np.concatenate([c.x for c in curves]))
        grid = grid[(grid >= low) & (grid <= high)]
    ys = np.stack([np.interp(grid, c.x, c.y) for c in curves])
    return grid, ys.mean(axis=0), ys.std(axis=0)


def group_stats(groups: dict[str, list[Curve]], threshold: float | None) -> dict[str, SeedStats]:
    """Per group, the statistics of its seeds' final values (each curve's last point)."""
    return {label: seed_stats([curve.y[-1] for curve in curves], threshold) for label, curves in groups.items()}


def stats_label(stats: SeedStats) -> str:
    """A group's IQM, its interval and (with a threshold) its seeds over it, in a few words."""
    over = f", {stats.over}/{stats.n} ≥ {stats.threshold:g}" if stats.threshold is not None else ""
    return f"IQM {stats.iqm:.4g} [{stats.iqm_low:.4g}, {stats.iqm_high:.4g}]{over}"


def draw_iqm(axes: Any, comparison: Comparison, colors: Sequence[str]) -> None:
    """Each group's final IQM as a diamond with its 95 % interval, at the group's last x, labelled with the
    interval and the seeds over the threshold; the threshold as a dashed line."""
    for color, (label, curves) in zip(colors, comparison.groups.items(), strict=True):
        stats = comparison.stats.get(label)
        if stats is None:
            continue
        x = max(float(curve.x[-1]) for curve in curves)
        below, above = stats.iqm - stats.iqm_low, stats.iqm_high - stats.iqm
        axes.errorbar(
            [x], [stats.iqm], yerr=[[below], [above]], color=color, marker="D", markersize=7, capsize=4,
            linestyle="none", label=f"{label}: {stats_label(stats)}", gid="iqm",
        )  # fmt: skip
    if comparison.threshold is not None:
        axes.axhline(comparison.threshold, color="0.3", linestyle="--", linewidth=1, gid="threshold")


def draw(comparison: Comparison) -> Any:
    """The figure (matplotlib, Agg): each seed's curve thin, each group's mean bold over a ±1 std band, one colour
    per group, the legend beside the axes. Curves of a few points (a short run: its final evaluation alone) show
    their points, and a band over a single x value is an error bar, so every seed and the spread stay visible."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(10, 5))
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    colors = [f"C{i % 10}" for i in range(len(comparison.groups))]
    xs = np.concatenate([c.x for curves in comparison.groups.values() for c in curves])
    few = False
    for color, (label, curves) in zip(colors, comparison.groups.items(), strict=True):
        grid, mean, std = band(curves)
        few = few or len(grid) <= 20  # a curve of one or a few points shows as points
        for curve in curves:
            axes.plot(curve.x, curve.y, color=color, alpha=0.45, linewidth=0.8, marker="." if few else None, gid="seed")
        axes.plot(
            grid, mean, color=color, linewidth=2, marker="o" if few else None, label=f"{label} ({len(curves)} seeds)"
        )
        if len(grid) > 1:
            axes.fill_between(grid, mean - std, mean + std, color=color, alpha=0.2, linewidth=0, gid="band")
        else:
            axes.errorbar(grid, mean, yerr=std, color=color, capsize=6, linewidth=1.5, gid="band")
    draw_iqm(axes, comparison, colors)
    axes.set_xlabel(comparison.x)
    axes.set_ylabel(comparison.metric)
    if xs.size and xs.min() >= 0 and xs.max() - xs.min() <= 0.05 * xs.max():  # one x (a final evaluation): from 0
        axes.set_xlim(0, 1.05 * xs.max() or 1.0)
    each = "small points" if few else "thin"
    axes.set_title(f"{comparison.metric}: mean ± std over seeds ({each}: each seed)")
    axes.grid(alpha=0.3)
    axes.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    figure.tight_layout()
    return figure


def plot(comparison: Comparison, path: Path) -> Path:
    """``draw`` to a PNG at ``path`` (the legend outside the axes included)."""
    draw(comparison).savefig(path, dpi=120, bbox_inches="tight")
    return path


def default_out(paths: Sequence[Path], runs: Sequence[Run], metric: str) -> Path:
    """Where `rlq compare` writes without ``out=``: in the one directory given, else beside the compared runs (the
    directory that holds them all), never the working directory by chance."""
    name = f"compare_{metric.replace('/', '_')}"
    if len(paths) == 1:
        return paths[0] / name
    return Path(os.path.commonpath([str(run.path.resolve()) for run in runs])) / name


def compare(
    paths: Sequence[Path],
    metric: str = "eval/return",
    x: str = "env_steps",
    out: Path | None = None,
    threshold: float | None = None,
) -> Comparison:
    """Group the runs under ``paths``, draw ``metric`` against ``x`` to ``<out>.png`` and write the table of
    final metrics to ``<out>.csv`` (``out`` defaults to ``compare_<metric>`` in the one directory given,
    else in the directory holding the compared runs, ``default_out``); per group, the IQM of its seeds'
    final values with its interval and, with ``threshold``, the seeds at or above it."""
    if x not in X_KEYS:
        raise UsageError(f"x={x}: choose one of {', '.join(X_KEYS)}")
    if threshold is not None and not np.isfinite(threshold):
        raise UsageError(f"threshold={threshold}: give a finite number, e.g. threshold=475")
    split_metric(metric)
    runs = load_runs(paths)
    keys = distinguishing_keys(runs)
    groups: dict[str, list[Curve]] = {}
    for run in runs:
        groups.setdefault(group_label(run, keys), []).extend(seed_curves(run, metric, x))
    groups = {label: curves for label, curves in groups.items() if curves}
    if not groups:
        names = sorted({f"{r['kind']}/{k}" for run in runs for r in run.rows for k in r if k not in ("kind", "seed")})
        raise UsageError(f"no run has {metric} rows; these runs log: {', '.join(names) or 'nothing yet'}")
    root = paths[0] if len(paths) == 1 and not is_run(paths[0]) else None
    comparison = Comparison(metric, x, groups, final_table(runs, keys, metric, root), keys=keys, threshold=threshold)
    comparison.stats = group_stats(groups, threshold)
    if out is None:
        out = default_out(paths, runs, metric)
    out = out.with_suffix("") if out.suffix in (".png", ".csv") else out
    for path in (out.parent / f"{out.name}.png", out.parent / f"{out.name}.csv"):
        check_output_file(path, "out")
    out.parent.mkdir(parents=True, exist_ok=True)
    comparison.png = plot(comparison, out.parent / f"{out.name}.png")
    comparison.csv = write_csv(comparison.table, out.parent / f"{out.name}.csv")
    return comparison


def summary_lines(comparison: Comparison) -> list[str]:
    """The console table: one line per group, final value mean ± std over its seeds' curves, their IQM with its
    95 % bootstrap interval and, with a threshold, the seeds at or above it."""
    width = max(len(label) for label in comparison.groups)
    cells = []
    for label, curves in comparison.groups.items():
        finals = np.asarray([curve.y[-1] for curve in curves])
        steps = max(int(curve.x[-1]) for curve in curves) if comparison.x == "env_steps" else None
        stats = comparison.stats.get(label) or seed_stats(finals, comparison.threshold)
        iqm = f"{stats.iqm:.4g} [{stats.iqm_low:.4g}, {stats.iqm_high:.4g}]"
        over = f"{stats.over}/{stats.n} ({stats.fraction_over:.0%})" if stats.fraction_over is not None else None
        at = f"{steps:,}" if steps is not None else "-"
        cells.append((label, len(curves), f"{finals.mean():>10.4g} ± {finals.std():<10.3g}", iqm, over, at))
    iqm_width = max(len("IQM [95 % CI]"), *(len(c[3]) for c in cells))
    over_head = f"seeds ≥ {comparison.threshold:g}" if comparison.threshold is not None else None
    head = f"{'group':<{width}}  seeds  final {comparison.metric} (mean ± std)  {'IQM [95 % CI]':<{iqm_width}}"
    lines = [head + (f"  {over_head}" if over_head else "") + "  at env steps"]
    for label, seeds, mean, iqm, over, at in cells:
        share = f"  {over:<{len(over_head)}}" if over_head and over else ""
        lines.append(f"{label:<{width}}  {seeds:>5}  {mean}  {iqm:<{iqm_width}}{share}  {at}")
    return lines
