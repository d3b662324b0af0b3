"""The non-finite guard: NaN/Inf in parameters, losses or returns stops the run with exit 3."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from rlq.cli.main import main
from rlq.run.stops import guard
from rlq.store import checkpoint
from tests.helpers import run_cli, run_dirs


def test_flags_check_params_losses_and_returns_only():
    metrics = {
        "loss": jnp.asarray(1.0),
        "value_loss": jnp.asarray(jnp.inf),
        "episode_return": jnp.asarray(jnp.nan),  # no episode ended: no value, not a divergence
        "archive-min-fitness": jnp.asarray(-jnp.inf),  # an empty archive cell, by design
    }
    flags = guard.flags({"w": jnp.ones(3)}, metrics)
    assert {k: bool(v) for k, v in flags.items()} == {
        "finite/loss": True,
        "finite/value_loss": False,
        "finite/episode_return": True,
        "finite/params_norm": True,
    }
    assert not bool(guard.flags({"w": jnp.asarray([1.0, jnp.nan])}, {})["finite/params_norm"])
    assert not bool(guard.flags({"w": jnp.full(4, 3e19)}, {})["finite/params_norm"])  # the norm overflows


def test_first_failure_is_the_earliest_update_of_any_seed():
    steps = np.array([[100, 200, 300], [100, 200, 300]])
    checks = {"loss": np.array([[True, True, False], [True, True, True]])}
    checks["params_norm"] = np.array([[True, True, True], [True, False, False]])
    assert guard.first_failure(checks, steps) == ("params_norm", 1, 200)
    assert guard.first_failure({"loss": np.ones((2, 3), bool)}, steps) is None


#: DQN learns from env step 2048 on; at lr=1e30 its parameters overflow in the first learner steps
DIVERGING = [
    "algo=dqn",
    "algo.lr=1e30",
    "algo.learning_starts=2048",
    "budget.env_steps=8192",
    "log_every_steps=1024",
    "checkpoint.every_steps=1024",
    "eval.every_steps=0",
    "eval.episodes=2",
    "video.at_end=false",
    "logger=quiet",
]


@pytest.mark.slow
def test_diverging_run_exits_3_and_keeps_the_last_good_checkpoint(tmp_path, capsys):
    proc = run_cli("train", *DIVERGING, cwd=tmp_path)
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 3, proc.stderr[-3000:]
    assert len(err) == 1 and "Traceback" not in proc.stderr
    (run_dir,) = run_dirs(tmp_path)
    good = run_dir / "checkpoints" / "step_1024.msgpack"
    assert err[-1] == (
        "rlq: error: training diverged: params_norm is NaN/Inf or beyond guard.max_params_norm=1e+08 at env step 2,048 "
        "(seed 0); "
        f"stopped, last good checkpoint: {good}"
    )
    assert sorted(p.name for p in (run_dir / "checkpoints").glob("*.msgpack")) == ["step_1024.msgpack"]
    assert err[-1] in (run_dir / "rlq.log").read_text().splitlines()
    assert checkpoint.verify(good)["env_steps"] == 1024
    main(["eval", f"run={run_dir}", "episodes=2"])  # the kept checkpoint loads and evaluates
    assert "mean greedy return" in capsys.readouterr().out


def test_bounds_catch_finite_blow_ups_and_leave_nan_alone():
    bounds = guard.Bounds(max_abs_loss=1e6, max_params_norm=10.0)
    metrics = {"value_loss": jnp.asarray(4.8e17), "loss": jnp.asarray(jnp.nan), "episode_return": jnp.asarray(1e9)}
    flags = {k: bool(v) for k, v in guard.flags({"w": jnp.full(4, 6.0)}, metrics, bounds).items()}
    assert flags == {
        "finite/value_loss": False,  # finite, but past guard.max_abs_loss
        "finite/loss": True,  # NaN: no value this update
        "finite/episode_return": True,  # returns have no bound: only Inf stops them
        "finite/params_norm": False,  # norm 12 > 10
    }
    assert all(bool(v) for v in guard.flags({"w": jnp.full(4, 6.0)}, metrics).values())  # no bounds: all finite
    assert bounds.limit("value_loss") == ("guard.max_abs_loss", 1e6) and bounds.limit("episode_return") is None


@pytest.mark.slow
def test_ppo_at_a_huge_learning_rate_is_stopped_by_the_bound(tmp_path):
    """Every number stays finite at lr=1e9 (the value loss reaches ~5e17): only the bound stops it, exit 3."""
    overrides = ["algo=ppo", "algo.lr=1e9", "budget.env_steps=16384", "log_every_steps=2048", "eval.every_steps=0"]
    proc = run_cli("train", *overrides, "eval.episodes=2", "video.at_end=false", "logger=quiet", cwd=tmp_path)
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 3, proc.stderr[-3000:]
    assert len(err) == 1 and err[0].startswith("rlq: error: training diverged: ")
    assert "beyond guard.max_" in err[0], err[0]
