"""`rlq train -m algo=dqn,ppo seed=0,1` then `rlq compare <sweep dir>`: job directories named by the
swept overrides, sweep_summary.csv at the sweep's end, a PNG of four curves in two groups and a CSV,
and no JAX INFO line on the console."""

import csv
from pathlib import Path

import pytest

from rlq.tools.compare import compare
from tests.helpers import run_cli

pytestmark = pytest.mark.slow

SWEEP_TINY = [
    "budget.env_steps=2000",
    "log_every_steps=1000",
    "eval.every_steps=1000",
    "eval.episodes=2",
    "logger=quiet",
    "video.at_end=false",
]
JOBS = {"algo=dqn,seed=0", "algo=dqn,seed=1", "algo=ppo,seed=0", "algo=ppo,seed=1"}


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path) as file:
        return list(csv.DictReader(file))


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    workdir = tmp_path_factory.mktemp("sweep")
    proc = run_cli("train", "algo=dqn,ppo", "-m", "seed=0,1", *SWEEP_TINY, cwd=workdir)  # -m may come anywhere
    assert proc.returncode == 0, proc.stderr[-3000:]
    (sweep_dir,) = (workdir / "multirun").glob("*/*")
    return sweep_dir, proc


def test_jobs_are_named_by_their_swept_overrides(sweep):
    sweep_dir, _ = sweep
    assert {p.name for p in sweep_dir.iterdir() if p.is_dir()} == JOBS


def test_the_sweep_ends_with_its_summary_table(sweep):
    sweep_dir, proc = sweep
    table = read_csv(sweep_dir / "sweep_summary.csv")
    assert {(r["run"], r["algo"], r["seed"]) for r in table} == {(j, j[5:8], j[-1]) for j in JOBS}
    assert all(float(r["eval/return"]) >= 1 and int(r["env_steps"]) > 0 for r in table)
    assert "sweep_summary.csv" in proc.stdout


def test_no_jax_info_line_on_the_console(sweep):
    _, proc = sweep
    assert "libtpu" not in proc.stderr + proc.stdout
    assert "[jax" not in proc.stderr + proc.stdout


def test_compare_draws_four_curves_in_two_groups(sweep):
    sweep_dir, _ = sweep
    proc = run_cli("compare", str(sweep_dir), cwd=sweep_dir.parent)
    assert proc.returncode == 0, proc.stderr[-3000:]
    png, table = sweep_dir / "compare_eval_return.png", read_csv(sweep_dir / "compare_eval_return.csv")
    assert png.stat().st_size > 10_000
    assert len(table) == 4 and {r["algo"] for r in table} == {"dqn", "ppo"}
    assert [line.split()[:2] for line in proc.stdout.splitlines()[1:3]] == [["algo=dqn", "2"], ["algo=ppo", "2"]]
    result = compare([sweep_dir], out=sweep_dir / "again")
    assert {label: len(curves) for label, curves in result.groups.items()} == {"algo=dqn": 2, "algo=ppo": 2}
    assert all(len(curve.x) == 2 for curves in result.groups.values() for curve in curves)  # evals at 1024, 1536
