"""A sweep job that runs again in its own directory (SLURM preemption, requeued by submitit) goes
on from its intermediate checkpoint instead of starting over, and ends where the uninterrupted
job ended; a whole sweep killed part way, run again in place with `rlq resume run=<sweep dir>`, keeps its finished
jobs, finishes the others and ends with the uninterrupted sweep's table."""

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from rlq.store import checkpoint
from tests.helpers import run_cli

pytestmark = pytest.mark.slow

JOB = [
    "-m",
    "seed=0",
    "budget.env_steps=4096",
    "log_every_steps=1024",
    "checkpoint.every_steps=1024",
    "checkpoint.keep_last=0",
    "eval.episodes=2",
    "logger=quiet",
    "video.at_end=false",
]


def test_a_requeued_sweep_job_resumes_its_own_checkpoint(tmp_path):
    sweep_dir = tmp_path / "sweep"
    first = run_cli("train", *JOB, f"hydra.sweep.dir={sweep_dir}", cwd=tmp_path)
    assert first.returncode == 0, first.stderr[-3000:]
    (job_dir,) = [p for p in sweep_dir.iterdir() if p.is_dir()]
    finished = tmp_path / "finished"
    shutil.copytree(job_dir / "checkpoints", finished)
    for path in (job_dir / "checkpoints").glob("*"):  # killed after its second checkpoint
        if not path.name.startswith("step_2048."):
            path.unlink()

    again = run_cli("train", *JOB, f"hydra.sweep.dir={sweep_dir}", cwd=tmp_path)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "resuming" in again.stdout and "step_2048.msgpack" in again.stdout
    resumed = checkpoint.leaves(job_dir / "checkpoints/final.msgpack")
    for a, b in zip(resumed, checkpoint.leaves(finished / "final.msgpack"), strict=True):
        np.testing.assert_array_equal(a, b)


def table(sweep_dir: Path) -> list[dict[str, str]]:
    """``sweep_summary.csv`` without its wall-clock columns (a resumed job's clock counts its process too)."""
    with open(sweep_dir / "sweep_summary.csv") as file:
        return [{k: v for k, v in row.items() if "wall" not in k} for row in csv.DictReader(file)]


def rows_of(run_dir: Path) -> list[tuple]:
    lines = (run_dir / "metrics.jsonl").read_text().splitlines()
    return [(r["kind"], r["env_steps"], r["seed"]) for r in map(json.loads, lines)]


def test_a_sweep_killed_part_way_resumes_in_place_to_the_uninterrupted_sweeps_end(tmp_path):
    """kill -9 of `rlq train -m seed=0,1,2,3`: job 0 finished, job 1 between its final checkpoint and its summary,
    job 2 after its first checkpoint, job 3 never started, no sweep_summary.csv. `rlq resume run=<sweep dir>`
    keeps job 0, finishes the others and writes the table the uninterrupted sweep wrote."""
    job = ["-m", "seed=0,1,2,3", "budget.env_steps=2048", *JOB[3:]]
    whole = tmp_path / "whole"
    first = run_cli("train", *job, f"hydra.sweep.dir={whole}", cwd=tmp_path)
    assert first.returncode == 0, first.stderr[-3000:]
    killed = tmp_path / "killed"
    shutil.copytree(whole, killed)
    (killed / "sweep_summary.csv").unlink()
    (killed / "seed=1" / "summary.json").unlink()
    stopped = killed / "seed=2"
    for path in [stopped / "summary.json", *(stopped / "checkpoints").glob("*")]:
        if not path.name.startswith("step_1024."):
            path.unlink()
    rows = (stopped / "metrics.jsonl").read_text().splitlines(keepends=True)
    (stopped / "metrics.jsonl").write_text("".join(r for r in rows if json.loads(r)["env_steps"] <= 1024))
    shutil.rmtree(killed / "seed=3")

    again = run_cli("resume", f"run={killed}", cwd=tmp_path)
    assert again.returncode == 0, again.stderr[-3000:]
    assert f"{killed}/seed=0 finished in an earlier run of this sweep: kept" in again.stdout
    assert f"{killed}/seed=1 trained to its end but was stopped before its summary" in again.stdout
    assert f"resuming {killed}/seed=2 from step_1024.msgpack" in again.stdout
    assert "sweep summary" in again.stdout
    assert table(killed) == table(whole)
    for name in ("seed=1", "seed=2", "seed=3"):
        assert rows_of(killed / name) == rows_of(whole / name)  # none doubled, none missing
        for a, b in zip(
            checkpoint.leaves(killed / name / "checkpoints/final.msgpack"),
            checkpoint.leaves(whole / name / "checkpoints/final.msgpack"),
            strict=True,
        ):
            np.testing.assert_array_equal(a, b)
    done = run_cli("resume", f"run={killed}", cwd=tmp_path)
    assert done.returncode == 2 and "has finished (sweep_summary.csv exists)" in done.stderr
