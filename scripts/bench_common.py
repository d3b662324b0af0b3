"""Helpers shared by the benchmark scripts: run `rlq train` as a user would and read its outputs."""

from __future__ import annotations

import datetime
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def device_name() -> str:
    out = subprocess.run(
        [sys.executable, "-c", "import jax; d = jax.devices()[0]; print(d.platform, '|', d.device_kind)"],
        capture_output=True,
        text=True,
        check=True,
    )
    return out.stdout.strip()


def run_rlq(overrides: list[str], keep_dir: Path | None = None) -> dict:
    """One `rlq train` process: its wall time, summary.json and metrics rows.

    The run directory is temporary unless ``keep_dir`` names where to leave it (e.g. for `rlq eval`).
    """
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = keep_dir or Path(tmp) / "run"
        cmd = [sys.executable, "-m", "rlq.cli", "train", *overrides, f"hydra.run.dir={run_dir}"]
        start = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - start
        if proc.returncode != 0:
            raise SystemExit(f"rlq train {' '.join(overrides)} failed:\n{proc.stderr[-3000:]}")
        summary = json.loads((run_dir / "summary.json").read_text())
        rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    return {"process_wall_s": round(wall, 2), "summary": summary, "rows": rows}


def time_to_threshold(rows: list[dict], threshold: float, every_seed: bool = False) -> dict | None:
    """First evaluation whose mean greedy return over seeds (or, with ``every_seed``, each seed's) reaches
    ``threshold``."""
    evals: dict[float, list[dict]] = {}
    for row in rows:
        if row["kind"] == "eval":
            evals.setdefault(row["env_steps"], []).append(row)
    for env_steps, group in evals.items():
        chosen = [r for r in group if (r["seed"] != "mean") == every_seed]
        if chosen and all((r.get("return") or -1e30) >= threshold for r in chosen):
            return {"env_steps": env_steps, "train_wall_s": chosen[0].get("wall_s")}
    return None


def run_figures(run: dict) -> dict:
    """The figures every preset benchmark reports from one `run_rlq` result."""
    summary = run["summary"]
    return {
        "process_wall_s": run["process_wall_s"],
        "compile_s": summary["compile_s"],
        "steady_env_steps_per_s": summary["steady_env_steps_per_s"],
        "env_steps_per_seed": summary["env_steps"],
        "final_eval_return": summary["eval_return"],
    }


def write_report(benchmark: str, results: list[dict], out: Path | None) -> None:
    """The JSON report: benchmark name, date, device and result rows (written only with ``out``)."""
    if out is None:
        return
    report = {
        "benchmark": benchmark,
        "date": datetime.date.today().isoformat(),
        "device": device_name(),
        "results": results,
    }
    out.write_text(json.dumps(report, indent=2))
