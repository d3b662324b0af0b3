"""`rlq eval`'s choice of env for a finished run, and episodes on a host simulator side by side."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.errors import ConfigError, UsageError
from rlq.run.checks.validate import check_time_limit
from rlq.store import checkpoint
from rlq.tools.evaluate import eval_env_config, evaluation_target
from tests.helpers import compose_config, run_cli_in_process, run_dirs


def test_rlq_eval_steps_the_run_s_evaluation_env_unless_told_another():
    cfg = compose_config("env=lunar", "+eval.env.max_episode_steps=300")
    assert eval_env_config(cfg, None, []).env["max_episode_steps"] == 300
    assert eval_env_config(cfg, None, ["env.max_episode_steps=200"]).env["max_episode_steps"] == 200
    other = eval_env_config(cfg, "lunar_box2d", [])
    assert other.env["name"] == "lunar_box2d" and other.env["max_episode_steps"] == 1000


def test_env_overrides_are_read_as_rlq_train_reads_them():
    cfg = compose_config()
    assert eval_env_config(cfg, None, ["env.max_episode_steps=2e2"]).env["max_episode_steps"] == 200
    assert eval_env_config(cfg, None, ["env.max_episode_steps=null"]).env["max_episode_steps"] is None
    bins = "env.discretize={bins:[1,1,6,12],low:[-2.4,-3,-0.21,-3.5],high:[2.4,3,0.21,3.5]}"
    assert list(eval_env_config(cfg, None, [bins]).env["discretize"]["bins"]) == [1, 1, 6, 12]
    assert eval_env_config(cfg, "lunar", ["env.solver.unroll=2"]).env["solver"]["unroll"] == 2


@pytest.mark.parametrize(
    ("env", "override", "error", "message"),
    [
        (None, "env.nosuchkey=1", ConfigError, "unknown config key 'env.nosuchkey' of env=cartpole; its keys are"),
        (None, "env.gravity=-9.8", ConfigError, "unknown config key 'env.gravity' of env=cartpole"),
        (
            "lunar",
            "env.solver.nope=1",
            ConfigError,
            "unknown config key 'env.solver.nope' of env=lunar; its keys are velocity",
        ),
        (None, "env.max_episode_steps=abc", ConfigError, "env.max_episode_steps must be an integer, got 'abc'"),
        (
            None,
            "env.max_episode_steps=-1",
            ConfigError,
            r"env.max_episode_steps must be null or an integer >= 1, got -1",
        ),
        ("lunar", "env.wind_power=-1", ConfigError, r"env.wind_power must be a number >= 0, got -1"),
        (None, "env.max_episode_steps=[1", ConfigError, "cannot read the override 'env.max_episode_steps=\\[1'"),
        (None, "env.max_episode_steps=1,2", UsageError, "gives several values"),
        (None, "env.name=lunar", UsageError, "choose the env with env=NAME"),
    ],
)
def test_env_overrides_are_checked_as_rlq_train_checks_them(env, override, error, message):
    with pytest.raises(error, match=message):
        eval_env_config(compose_config(), env, [override])


def _fits(run_cfg, env_name, overrides=()):
    evaluation_target(run_cfg, env_name, list(overrides))


def test_a_lunar_run_s_policy_acts_in_the_box2d_reference():
    _fits(compose_config("env=lunar"), "lunar_box2d")
    _fits(compose_config("env=lunar", "env.continuous=true"), "lunar_box2d", ["env.continuous=true"])


@pytest.mark.parametrize(
    ("run", "env", "overrides", "message"),
    [
        (
            [],
            "lunar_box2d",
            [],
            "env=lunar_box2d gives observations of shape (8,) and actions Discrete(4); this run's policy was trained "
            "on env=cartpole: observations of shape (4,) and actions Discrete(2); choose an env with them",
        ),
        (["env=lunar"], "lunar_box2d", ["env.continuous=true"], "actions of shape (2,); this run's policy"),
        (
            ["experiment=cartpole_qlearning"],
            None,
            ["env.discretize=null"],
            "observations of shape (4,) and actions Discrete(2); this run's policy was trained on env=cartpole: "
            "observations Discrete(648) and actions Discrete(2); drop the env overrides that change them",
        ),
    ],
)
def test_an_env_with_other_spaces_is_refused_naming_both(run, env, overrides, message):
    with pytest.raises(ConfigError) as err:
        _fits(compose_config(*run), env, overrides)
    assert message in str(err.value)


def test_box2d_evaluates_without_a_time_limit_where_the_jax_env_cannot():
    run = compose_config("env=lunar")
    _, box2d = evaluation_target(run, "lunar_box2d", ["env.max_episode_steps=null"])
    assert box2d.max_episode_steps is None
    check_time_limit(box2d, "env=lunar_box2d")  # a host env's episodes end by themselves
    _, jax_env = evaluation_target(run, None, ["env.max_episode_steps=null"])
    with pytest.raises(ConfigError, match="env.max_episode_steps=null \\(no time limit\\) cannot be evaluated"):
        check_time_limit(jax_env, "env=lunar")


@pytest.mark.slow
def test_eval_export_and_render_fall_back_to_the_newest_intact_checkpoint_and_say_so(tmp_path):
    """A writer stopped between its two renames leaves step_N.msgpack without its sidecar: `rlq eval`,
    `rlq export` and `rlq render` use the checkpoint before it, as `rlq resume` does, with one warning line."""
    overrides = [
        "budget.env_steps=8192",
        "log_every_steps=2048",
        "checkpoint.every_steps=2048",
        "checkpoint.keep_last=0",
    ]
    proc = run_cli_in_process(
        "train", *overrides, "eval.episodes=2", "video.at_end=false", "logger=quiet", cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(tmp_path)
    checkpoints = run_dir / "checkpoints"
    (checkpoints / "final.msgpack").unlink()
    (checkpoints / "final.json").unlink()
    newest = max(checkpoint.intermediate(checkpoints), key=lambda p: int(p.stem.split("_")[1]))
    newest.with_suffix(".json").unlink()
    before = checkpoint.intermediate(checkpoints)[-2]
    proc = run_cli_in_process("eval", f"run={run_dir}", "episodes=2", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (line,) = proc.stderr.strip().splitlines()
    assert (
        line
        == f"rlq: warning: {newest} has no sidecar {newest.with_suffix('.json').name} (its writer was stopped); using {before} instead"
    )
    assert json.loads((run_dir / "eval_cartpole.json").read_text())["checkpoint"] == str(before)
    out = tmp_path / "policy.msgpack"
    proc = run_cli_in_process("export", f"run={run_dir}", f"out={out}", cwd=tmp_path)
    assert proc.returncode == 0 and out.exists(), proc.stderr[-3000:]
    assert proc.stderr.strip().splitlines() == [line]
    video = tmp_path / "episode.mp4"
    proc = run_cli_in_process("render", f"run={run_dir}", "steps=20", f"out={video}", cwd=tmp_path)
    assert proc.returncode == 0 and video.stat().st_size > 0, proc.stderr[-3000:]
    assert proc.stderr.strip().splitlines() == [line]


def _one_by_one(env, policy, seeds, key):
    """What host_episodes computes, one episode after another on one simulator."""
    returns, lengths = [], []
    for i, seed in enumerate(seeds):
        obs, _ = env.reset(seed=seed)
        total, steps, done = 0.0, 0, False
        while not done:
            step_key = jax.random.fold_in(jax.random.fold_in(key, i), steps)
            obs, reward, terminated, truncated, _ = env.step(
                np.asarray(policy(jnp.asarray(obs, jnp.float32), step_key))
            )
            total, steps = total + reward, steps + 1
            done = terminated or truncated
        returns.append(total)
        lengths.append(steps)
    return np.asarray(returns), np.asarray(lengths)


@pytest.mark.slow
@pytest.mark.parametrize("max_steps", [1000, 60])
def test_host_episodes_side_by_side_are_the_episodes_one_by_one(max_steps):
    """A sampling policy (its key matters) on Box2D: the same returns and lengths as episodes run one after
    another with the same keys; a time limit cuts every episode."""
    from rlq.envs.lunar.box2d_reference import LunarBox2D
    from rlq.envs.lunar.heuristic import heuristic
    from rlq.tools.evaluate import host_episodes

    def policy(obs, key):  # the heuristic, a random action one step in five
        return jnp.where(jax.random.uniform(key) < 0.2, jax.random.randint(key, (), 0, 4), heuristic(obs))

    seeds, key = [3, 4, 5, 6], jax.random.PRNGKey(7)
    record = host_episodes(LunarBox2D(max_episode_steps=max_steps), policy, seeds, key)
    returns, lengths = _one_by_one(LunarBox2D(max_episode_steps=max_steps), policy, seeds, key)
    np.testing.assert_array_equal(record["length"], lengths)
    np.testing.assert_allclose(record["return"], returns, rtol=1e-9)
    if max_steps == 60:
        assert (lengths == 60).all()
    else:
        assert (lengths < 1000).all() and len(set(returns.round(3))) == 4
