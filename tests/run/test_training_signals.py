"""Training signals of the loop: the return window of every seed, the stop rule."""

import json
import re

import numpy as np
import pytest

from rlq.errors import ConfigError
from rlq.run.checks.validate import check_run_config
from rlq.run.stops.stop import parse_stop
from tests.helpers import compose_config, run_cli, run_dirs, train_run


@pytest.mark.slow
def test_train_rows_carry_the_return_window(tmp_path):
    train_run(
        tmp_path,
        "budget.env_steps=4096",
        "log_every_steps=1024",
        "num_seeds=2",
        "eval.every_steps=0",
        "video.at_end=false",
        "return_window=10",
    )
    rows = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    train = [r for r in rows if r["kind"] == "train"]
    assert len(train) == 12 and all("return_window" in r for r in train)
    windows = [r["return_window"] for r in train if r["seed"] != "mean"]
    assert all(w is not None and 5 < w < 500 for w in windows)  # CartPole episodes of an untrained policy
    means = [r for r in train if r["seed"] == "mean"]
    per_seed = {(r["env_steps"], r["seed"]): r["return_window"] for r in train if r["seed"] != "mean"}
    for row in means:
        assert np.isclose(row["return_window"], np.mean([per_seed[(row["env_steps"], s)] for s in (0, 1)]))


@pytest.mark.slow
def test_stop_when_ends_a_cartpole_run_once_solved(tmp_path):
    budget = 300_000
    result = train_run(
        tmp_path,
        f"budget.env_steps={budget}",
        "log_every_steps=4096",
        "eval.every_steps=4096",
        "eval.episodes=8",
        "video.at_end=false",
        "stop.when='eval/return>=100'",
    )
    assert result.env_steps < budget
    assert "stop.when eval/return>=100 met" in result.stopped
    rows = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    evals = [r for r in rows if r["kind"] == "eval" and r["seed"] == "mean"]
    # the evaluation that met it is the run's final one (not evaluated again: one eval row, one console line)
    assert evals[-1]["return"] >= 100 and evals[-1]["env_steps"] == result.env_steps
    assert float(result.eval_return.mean()) == evals[-1]["return"]
    assert max(r["env_steps"] for r in rows) == result.env_steps
    assert (tmp_path / "checkpoints" / "final.msgpack").exists()
    assert json.loads((tmp_path / "summary.json").read_text())["stopped"] == result.stopped


@pytest.mark.parametrize(
    "when, message",
    [
        ("eval/return=>100", "is not <eval|train>/<metric><op><number>"),
        ("score/return>=100", "must start with eval/ or train/"),
        ("eval/return>=lots", "the threshold 'lots' is not a number"),
    ],
)
def test_stop_when_rejects_bad_expressions(when, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        parse_stop(when)


def test_stop_rule_reads_the_comparison():
    rule = parse_stop("train/episode_length < 20.5")
    assert (rule.kind, rule.metric, rule.op, rule.threshold) == ("train", "episode_length", "<", 20.5)
    assert rule.met(20.0) and not rule.met(20.5) and not rule.met(float("nan"))
    assert parse_stop("eval/return>=200").met(200.0)


@pytest.mark.slow
def test_bad_stop_when_is_one_line_before_anything_runs(workdir):
    proc = run_cli("train", "stop.when=eval/return", cwd=workdir)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "rlq: error: stop.when='eval/return' is not <eval|train>/<metric><op><number> with op one of >=, <=, >, <"
        """ (e.g. 'stop.when="eval/return>=200"' in a shell)"""
    ]
    assert run_dirs(workdir) == []


def test_an_eval_metric_no_evaluation_logs_is_refused_with_the_names_they_log():
    with pytest.raises(ConfigError) as err:
        check_run_config(compose_config("stop.when='eval/nosuch>=1'"))
    assert str(err.value) == "stop.when='eval/nosuch>=1': eval rows have no 'nosuch'; they have: length, return"
    with pytest.raises(ConfigError, match="they have: archive-occupancy, average-fitness, "):
        check_run_config(compose_config("algo=map_elites", "stop.when='eval/return_window>=1'"))
    check_run_config(compose_config("algo=map_elites", "stop.when='eval/qd-score>=1'"))
    check_run_config(compose_config("stop.when='train/nosuch>=1'"))  # the update's metrics: known once traced


@pytest.mark.slow
def test_an_eval_rule_no_evaluation_checks_is_said_at_the_start(tmp_path):
    train_run(
        tmp_path,
        "budget.env_steps=2048",
        "eval.every_steps=0",
        "stop.when='eval/return>=1'",
        "eval.episodes=2",
        "video.at_end=false",
    )
    note = (
        "rlq: stop.when='eval/return>=1' is never checked: eval.every_steps=0 evaluates only at the end of the "
        "run's 2,048 env steps; give eval.every_steps (and log_every_steps, the chunk evaluations fall between) "
        "below that"
    )
    assert note in (tmp_path / "rlq.log").read_text().splitlines()
