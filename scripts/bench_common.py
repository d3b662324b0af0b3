"""Helpers shared by the benchmark scripts: run `rlq train` as a user would and read its outputs."""

from __future__ import annotations

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


def run_rlq(overrides: list[str]) -> dict:
    """One `rlq train` process: its wall time, summary.json and metrics rows."""
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp) / "run"
        cmd = [sys.executable, "-m", "rlq.cli", "train", *overrides, f"hydra.run.dir={run_dir}"]
        start = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - start
        if proc.returncode != 0:
            raise SystemExit(f"rlq train {' '.join(overrides)} failed:\n{proc.stderr[-3000:]}")
        summary = json.loads((run_dir / "summary.json").read_text())
        rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    return {"process_wall_s": round(wall, 2), "summary": summary, "rows": rows}


def time_to_threshold(rows: list[dict], threshold: float) -> dict | None:
    """First evaluation whose mean greedy return over seeds reaches ``threshold``."""
    for row in rows:
        if row["kind"] == "eval" and row["seed"] == "mean" and (row.get("return") or -1e30) >= threshold:
            return {"env_steps": row["env_steps"], "train_wall_s": row.get("wall_s")}
    return None
