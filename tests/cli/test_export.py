"""`rlq export` and docs/usage.md's snippet that loads the export and acts: the snippet, executed as
it stands, reproduces `rlq eval`'s greedy return on CartPole (the same reset keys)."""

import re

import jax
import numpy as np
import pytest
from omegaconf import OmegaConf

from rlq.cli.main import main
from rlq.run.programs.env_stack import make_env
from rlq.tools.evaluate import evaluate_run
from tests.helpers import REPO, compose_config, train_run

EPISODES = 3


def readme_snippet() -> str:
    """The python block of docs/usage.md's "Export a policy" section."""
    section = (REPO / "docs" / "usage.md").read_text().split("### Export a policy", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def trained_run(run_dir, *overrides):
    run_dir.mkdir()
    train_run(run_dir, *overrides)
    (run_dir / ".hydra").mkdir()  # the config `rlq train` saves, which the commands read
    OmegaConf.save(compose_config("logger=quiet", *overrides), run_dir / ".hydra" / "config.yaml")
    return run_dir


@pytest.mark.slow  # 10-20 s on 2 cores: the full suite runs it
def test_readme_snippet_reproduces_the_greedy_return_of_rlq_eval(tmp_path, monkeypatch, capsys):
    run_dir = trained_run(
        tmp_path / "run", "budget.env_steps=8192", "log_every_steps=4096", "eval.episodes=2", "video.at_end=false"
    )
    main(["export", f"run={run_dir}", f"out={tmp_path / 'params.msgpack'}"])
    assert capsys.readouterr().out.strip() == f"rlq export: {tmp_path / 'params.msgpack'} (+ params.json)"
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(readme_snippet(), scope)  # noqa: S102  (the documented snippet, as a user runs it)
    act = scope["act"]

    cfg = compose_config("budget.env_steps=8192")
    env = make_env(cfg, autoreset=False)
    step = jax.jit(env.step)
    # rlq eval's keys: evaluate() of seed 0 with PRNGKey(seed=0) folded with the seed index
    reset_key, _ = jax.random.split(jax.random.fold_in(jax.random.PRNGKey(0), 0))
    returns = []
    for key in jax.random.split(reset_key, EPISODES):
        state, total = env.reset(key), 0.0
        while True:
            state = step(state, np.int32(act(state.obs)))
            total += float(state.reward)
            if bool(state.done):
                break
        returns.append(total)
    expected = evaluate_run(run_dir, episodes=EPISODES)["per_seed_return"][0]
    assert np.mean(returns) == pytest.approx(expected)
    assert expected > 30  # a policy that learned something, so the check compares real decisions


@pytest.mark.slow  # trains a run to export (5 s)
def test_tabular_q_is_refused_with_one_line(tmp_path, capsys):
    run_dir = trained_run(
        tmp_path / "run",
        "experiment=cartpole_qlearning",
        "budget.env_steps=4096",
        "log_every_steps=2048",
        "eval.episodes=2",
        "video.at_end=false",
    )
    with pytest.raises(SystemExit) as stop:
        main(["export", f"run={run_dir}"])
    assert stop.value.code == 2
    assert capsys.readouterr().err.strip() == (
        "rlq: error: algo=qlearning has no policy network to export (its greedy policy is its Q-table); "
        f"use rlq eval/render on the run's checkpoint {run_dir / 'checkpoints' / 'final.msgpack'}"
    )
