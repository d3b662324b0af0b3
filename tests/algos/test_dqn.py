import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import algo_settings, dqn
from rlq.lib.spaces import Box, Discrete
from rlq.run.programs.env_stack import make_env
from tests.fakes import SpacesOnly
from tests.helpers import compose_config, run_cli_in_process, train_run


def test_td_target_bootstraps_with_the_discount():
    reward = jnp.array([1.0, 1.0, 0.5])
    discount = jnp.array([0.5, 0.0, 0.25])  # a one-step transition, a termination, a two-step return
    next_q_target = jnp.array([[2.0, 4.0], [10.0, 20.0], [3.0, 1.0]])
    target = dqn.td_target(reward, discount, next_q_target, None, double=False)
    np.testing.assert_allclose(target, [1.0 + 0.5 * 4.0, 1.0, 0.5 + 0.25 * 3.0])


def test_double_dqn_target_values_the_online_argmax_with_the_target_net():
    next_q_target = jnp.array([[2.0, 4.0]])
    next_q_online = jnp.array([[9.0, 0.0]])  # online net prefers action 0
    target = dqn.td_target(jnp.array([1.0]), jnp.array([0.9]), next_q_target, next_q_online, double=True)
    np.testing.assert_allclose(target, [1.0 + 0.9 * 2.0])


def test_n_step_above_the_block_is_refused():
    cfg = compose_config("algo=dqn", "algo.train_every=2", "algo.num_steps=4", "algo.n_step=3")
    assert "algo.n_step=3 must lie in [1, algo.train_every=2]" in dqn.check(algo_settings(cfg.algo), make_env(cfg))


def test_n_step_learner_runs_and_stores_block_returns():
    algo = _small_algo("algo.train_every=4", "algo.n_step=3", "algo.gamma=0.5")
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.key(0))
    state, metrics = jax.jit(lambda s: algo.update(s, algo.hyperparams))(state)
    stored = state.buffer.storage
    # CartPole pays 1 a step: a block's steps hold 1 + 0.5 + 0.25, then 1.5, then 1 (episodes run on here)
    np.testing.assert_allclose(stored["reward"][:8].reshape(4, 2)[:, 0], [1.75, 1.75, 1.5, 1.0])
    np.testing.assert_allclose(stored["discount"][:8].reshape(4, 2)[:, 0], [0.125, 0.125, 0.25, 0.5])
    assert np.isfinite(metrics["loss"])


def test_polyak():
    target = {"w": jnp.array([0.0, 10.0])}
    online = {"w": jnp.array([1.0, 0.0])}
    np.testing.assert_allclose(dqn.polyak(target, online, 0.1)["w"], [0.1, 9.0])
    np.testing.assert_allclose(dqn.polyak(target, online, 1.0)["w"], [1.0, 0.0])


def _small_algo(*overrides):
    cfg = compose_config(
        "algo=dqn",
        "algo.num_envs=2",
        "algo.num_steps=4",
        "algo.buffer_size=64",
        "algo.batch_size=8",
        "algo.learning_starts=0",
        *overrides,
    )
    env = make_env(cfg)
    return dqn.make(algo_settings(cfg.algo), env, budget_env_steps=64)


def _leaves_equal(a, b):
    return all(np.allclose(x, y) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True))


def test_update_counts_steps_and_hard_copies_the_target():
    algo = _small_algo("algo.target_every=1", "algo.tau=1.0")
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    state, metrics = jax.jit(lambda s: algo.update(s, algo.hyperparams))(state)
    assert int(metrics["env_steps"]) == algo.steps_per_update == 8
    assert int(state.learner.steps) == 4  # one learner step after each of the 4 vectorised steps
    assert int(state.buffer.size) == 8
    assert _leaves_equal(state.learner.target_params, state.learner.params)
    assert np.isfinite(float(metrics["loss"]))


def test_q_network_takes_layer_norm_when_asked():
    """algo.layer_norm=true: PQN's network (LayerNorm before each hidden activation) for the online, target and
    evaluation params alike; off by default."""
    for flag, expected in (("algo.layer_norm=true", True), ("algo.layer_norm=false", False)):
        algo = _small_algo(flag)
        learner = jax.jit(lambda k, algo=algo: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0)).learner
        for params in (learner.params, learner.target_params, learner.ema_params):
            assert any("LayerNorm" in name for name in params["params"]) is expected, flag
    assert compose_config("algo=dqn").algo.layer_norm is False


def test_no_learning_before_learning_starts():
    algo = _small_algo("algo.learning_starts=1000")
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    new, metrics = jax.jit(lambda s: algo.update(s, algo.hyperparams))(state)
    assert int(new.learner.steps) == 0
    assert _leaves_equal(new.learner.params, state.learner.params)
    assert np.isnan(float(metrics["loss"]))


def test_a_learner_that_never_starts_within_the_budget_is_noted():
    cfg = algo_settings(compose_config("algo=dqn", "algo.learning_starts=100000000").algo)
    assert dqn.notes(cfg, 4608) == (
        "algo.learning_starts=100000000 is beyond the budget (4,608 env steps per seed): "
        "the run never updates the network",
    )
    assert dqn.notes(algo_settings(compose_config("algo=dqn").algo), 50_000) == ()
    assert (
        dqn.notes(algo_settings(compose_config("algo=dqn", "algo.learning_starts=4608").algo), 4608) == ()
    )  # its last block learns
    assert "the run never updates" in _small_algo("algo.learning_starts=1000").notes[0]  # make carries them


def test_a_buffer_below_a_batch_is_noted_not_refused():
    """Batches are drawn with replacement (rlq.lib.learning.replay.sample), so a buffer below a batch works,
    repeating transitions; a buffer that holds one block of transitions is all the code needs."""
    cfg = algo_settings(compose_config("algo=dqn", "algo.buffer_size=10", "algo.batch_size=128").algo)
    assert dqn.check(cfg, make_env(compose_config("algo=dqn"))) is None
    assert dqn.notes(cfg, 50_000) == (
        "algo.buffer_size=10 is below algo.batch_size=128: each batch draws its 128 transitions from at most 10 "
        "(with replacement)",
    )


@pytest.mark.slow  # a CLI run (8 s)
def test_notes_are_printed_at_the_start_of_the_run(tmp_path):
    train_run(
        tmp_path,
        "algo=dqn",
        "budget.env_steps=512",
        "algo.learning_starts=600",
        "eval.episodes=2",
        "video.at_end=false",
    )
    note = (
        "rlq: algo.learning_starts=600 is beyond the budget (512 env steps per seed): the run never updates the network"
    )
    assert note in (tmp_path / "rlq.log").read_text().splitlines()


def test_greedy_policy_uses_ema_params_when_enabled():
    algo = _small_algo("algo.ema=0.5")
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    flipped = jax.tree.map(lambda x: -x, state.learner.params)
    state = state.replace(learner=state.learner.replace(ema_params=flipped))
    obs = jnp.array([0.01, 0.2, -0.03, 0.5])
    q_online = algo.policy(state.replace(learner=state.learner.replace(ema_params=state.learner.params)))
    assert int(algo.policy(state)(obs, None)) != int(q_online(obs, None))


def test_check_rejects_continuous_actions():
    cfg = compose_config("algo=dqn")
    message = dqn.check(algo_settings(cfg.algo), SpacesOnly(Box.uniform(-1, 1, 3), Box.uniform(-1, 1, 2)))
    assert "algo=dqn needs a discrete action space" in message and "algo=ppo" in message


def test_check_accepts_discrete_observations():
    env = SpacesOnly(Box.uniform(-1, 1, 3), Box.uniform(-1, 1, 2))
    env.observation_space, env.action_space = Discrete(5), Discrete(3)
    assert dqn.check(algo_settings(compose_config("algo=dqn").algo), env) is None


@pytest.mark.slow
def test_continuous_actions_fail_through_the_cli(workdir):
    proc = run_cli_in_process("train", "algo=dqn", "env=lunar", "env.continuous=true", "logger=quiet", cwd=workdir)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "algo=dqn needs a discrete action space" in lines[0], proc.stderr
    assert not (workdir / "outputs").exists()


@pytest.mark.slow
def test_bad_loss_through_the_cli(workdir):
    proc = run_cli_in_process("train", "algo=dqn", "algo.loss=l1", "logger=quiet", cwd=workdir)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "algo.loss" in proc.stderr
    assert not (workdir / "outputs").exists()


@pytest.mark.slow  # about 12 s of CPU: the full suite runs it; the quick tier trains DQN in test_notes_are_printed_...
def test_four_seeds_in_one_program(tmp_path):
    result = train_run(
        tmp_path,
        "experiment=cartpole_dqn",
        "num_seeds=4",
        "eval.episodes=4",
        "budget.env_steps=2048",
        "algo.learning_starts=512",
        "log_every_steps=1024",
    )
    assert result.eval_return.shape == (4,) and np.all(np.isfinite(result.eval_return))
    assert result.env_steps == 2048
    params = result.state.learner.params
    first_layer = jax.tree.leaves(params)[0]
    assert first_layer.shape[0] == 4 and not np.allclose(first_layer[0], first_layer[1])


@pytest.mark.slow
def test_dqn_solves_cartpole(tmp_path):
    result = train_run(tmp_path, "experiment=cartpole_dqn", "num_seeds=3", "video.at_end=false")
    assert result.env_steps <= 500_000
    assert np.mean(result.eval_return) >= 475, result.eval_return
