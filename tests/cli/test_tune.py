"""`rlq train -m hydra/sweeper=optuna ...`: each job returns its final greedy return (config key ``objective``), so
Optuna samples ``interval(...)`` and ``choice(...)`` values over two trials and reports the best one."""

import json

import pytest
from omegaconf import OmegaConf

from tests.helpers import run_cli

pytestmark = pytest.mark.slow

TINY = ["budget.env_steps=1000", "log_every_steps=1000", "eval.episodes=2", "logger=quiet", "video.at_end=false"]


@pytest.fixture(scope="module")
def optuna_sweep(tmp_path_factory):
    workdir = tmp_path_factory.mktemp("tune")
    proc = run_cli(
        "train",
        "-m",
        "hydra/sweeper=optuna",
        "hydra.sweeper.n_trials=2",
        "hydra.sweeper.sampler.seed=0",
        "algo.lr=tag(log,interval(1e-4,1e-2))",
        "algo.update_epochs=choice(1,2)",
        *TINY,
        cwd=workdir,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (sweep_dir,) = (workdir / "multirun").glob("*/*")
    return sweep_dir, proc


def test_two_trials_run_and_optuna_reports_the_best_return(optuna_sweep):
    sweep_dir, proc = optuna_sweep
    jobs = [p for p in sweep_dir.iterdir() if (p / "summary.json").exists()]
    assert len(jobs) == 2
    returns = [json.loads((job / "summary.json").read_text())["eval_return_mean"] for job in jobs]
    results = OmegaConf.load(sweep_dir / "optimization_results.yaml")
    assert results.best_value == pytest.approx(max(returns))  # maximised: rlq sets direction=maximize
    assert 1e-4 <= results.best_params["algo.lr"] <= 1e-2
    assert results.best_params["algo.update_epochs"] in (1, 2)
    assert "setup plugin" not in proc.stdout + proc.stderr  # alembic's INFO lines stay out of the console
    assert (sweep_dir / "sweep_summary.csv").exists()
