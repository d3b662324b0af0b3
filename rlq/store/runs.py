"""Run directories read back as data: each run's overrides, config, metrics rows and summary, its seeds' learning
curves, and the table of final metrics (`rlq compare`'s, a sweep's ``sweep_summary.csv``, an in-program sweep's)."""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rlq.config.plain import read_recorded, read_recorded_config, select
from rlq.errors import RunDirError, UsageError
from rlq.store.files import write_atomic
from rlq.store.jsonfiles import SUMMARY_FIX, read_json_object, read_rows


@dataclass(frozen=True)
class Run:
    """One run directory: its overrides, composed config, group choices, metrics rows and, once it
    has ended, its ``summary.json`` (empty before)."""

    path: Path
    overrides: dict[str, str]
    config: Mapping[str, Any]
    choices: dict[str, str]
    rows: list[dict[str, Any]]
    summary: dict[str, Any] = field(default_factory=dict)

    def value(self, key: str) -> str:
        """The run's value of an override key, also where another run set it and this one did not."""
        if key in self.overrides:
            return self.overrides[key]
        if key in self.choices:
            return str(self.choices[key])
        found = select(self.config, key)
        return "" if found is None else str(found)


@dataclass(frozen=True)
class Curve:
    """One seed's learning curve."""

    run: Path
    seed: int
    x: np.ndarray
    y: np.ndarray


def is_run(path: Path) -> bool:
    return (path / ".hydra" / "config.yaml").is_file()


def find_runs(paths: Sequence[Path]) -> list[Path]:
    """The run directories among ``paths``; a directory that is not a run stands for the runs beneath it."""
    found: list[Path] = []
    for path in paths:
        if not path.is_dir():
            raise RunDirError(f"{path} is not a directory")
        jobs = [path] if is_run(path) else sorted(p.parent.parent for p in path.rglob(".hydra/config.yaml"))
        if not jobs:
            raise RunDirError(f"{path} holds no rlq run (no .hydra/config.yaml in it or beneath it)")
        found += [job for job in jobs if job not in found]
    return found


def _override_items(lines: list[str]) -> dict[str, str]:
    items = {}
    for line in lines:
        key, _, value = str(line).partition("=")
        items[key.lstrip("+~")] = value
    return items


def load_run(path: Path) -> Run:
    hydra_dir = path / ".hydra"
    overrides_file, hydra_file = hydra_dir / "overrides.yaml", hydra_dir / "hydra.yaml"
    overrides = _override_items(list(read_recorded(overrides_file))) if overrides_file.exists() else {}
    choices: dict[str, str] = {}
    if hydra_file.exists():
        found = select(read_recorded(hydra_file), "hydra.runtime.choices")
        choices = {str(k): str(v) for k, v in (found or {}).items() if not str(k).startswith("hydra/")}
    rows = read_rows(path / "metrics.jsonl").rows
    config = read_recorded_config(hydra_dir / "config.yaml")
    summary_file = path / "summary.json"
    summary = read_json_object(summary_file, SUMMARY_FIX) if summary_file.exists() else {}
    return Run(path, overrides, config, choices, rows, summary)


def distinguishing_keys(runs: Sequence[Run]) -> list[str]:
    """The override keys whose values differ between runs (seed included), in a stable order."""
    keys = sorted({key for run in runs for key in run.overrides})
    return [key for key in keys if len({run.value(key) for run in runs}) > 1]


def split_metric(metric: str) -> tuple[str, str]:
    kind, sep, key = metric.partition("/")
    if not sep or not key:
        raise UsageError(
            f"metric={metric}: write <kind>/<name>, e.g. metric=eval/return or metric=train/episode_return"
        )
    return kind, key


def seed_curves(run: Run, metric: str, x: str) -> list[Curve]:
    """One curve per seed of the run (the rows of every seed, not their mean row)."""
    kind, key = split_metric(metric)
    per_seed: dict[int, list[tuple[float, float]]] = {}
    for row in run.rows:
        if row["kind"] == kind and row["seed"] != "mean" and row.get(key) is not None and row.get(x) is not None:
            per_seed.setdefault(int(row["seed"]), []).append((float(row[x]), float(row[key])))
    curves = []
    for seed, points in sorted(per_seed.items()):
        xs, ys = np.asarray(points, np.float64).T
        curves.append(Curve(run.path, seed, xs, ys))
    return curves


def _last_mean_row(run: Run, kind: str) -> dict[str, Any] | None:
    rows = [row for row in run.rows if row["kind"] == kind and row["seed"] == "mean"]
    return rows[-1] if rows else None


def final_table(
    runs: Sequence[Run], keys: Sequence[str], metric: str, root: Path | None = None
) -> list[dict[str, Any]]:
    """One row per run: its distinguishing overrides, the final value of ``metric`` (mean and std over
    the run's seeds) and the final mean row of each kind (``eval/return``, ``train/episode_return``, ...)."""
    table = []
    for run in runs:
        row: dict[str, Any] = {"run": str(run.path.relative_to(root)) if root else str(run.path)}
        row.update({key: run.value(key) for key in keys})
        row["num_seeds"] = int(run.config["num_seeds"])
        row["env_steps"] = max((int(r["env_steps"]) for r in run.rows), default=None)
        # the seconds the run's closing line reports (summary.json); a run that has not ended: its last row's
        row["wall_s"] = run.summary.get("wall_s") or max(
            (float(r["wall_s"]) for r in run.rows if r.get("wall_s") is not None), default=None
        )
        finals = [curve.y[-1] for curve in seed_curves(run, metric, "env_steps")]
        row[metric] = float(np.mean(finals)) if finals else None
        row[f"{metric} std"] = float(np.std(finals)) if finals else None
        for kind in ("eval", "train"):
            last = _last_mean_row(run, kind)
            for name, value in (last or {}).items():
                if name not in ("kind", "seed", "env_steps", "wall_s"):
                    row.setdefault(f"{kind}/{name}", value)
        table.append(row)
    return table


def write_csv(table: Sequence[dict[str, Any]], path: Path) -> Path:
    """The table as CSV, whole or not at all (``write_atomic``): a sweep's run is complete once its table is there."""
    columns = list(dict.fromkeys(name for row in table for name in row))
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=columns)
    writer.writeheader()
    writer.writerows(table)
    write_atomic(path, text.getvalue().encode())
    return path


def load_runs(paths: Sequence[Path]) -> list[Run]:
    return [load_run(path) for path in find_runs(paths)]
