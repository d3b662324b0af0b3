import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import qlearning
from rlq.envs import make_env
from rlq.envs.base import Env
from rlq.envs.spaces import Box, Discrete
from tests.conftest import compose_config, run_cli, train_run

TABLE = jnp.array([[0.0, 1.0], [2.0, 4.0], [-1.0, 3.0]])


def test_q_update_by_hand():
    new = qlearning.q_update(TABLE, 0, 1, 1.0, 1, False, alpha=0.5, gamma=0.9)
    # Q(0,1) <- 0.5 * 1 + 0.5 * (1 + 0.9 * max(2, 4)) = 2.8; nothing else moves
    np.testing.assert_allclose(new, [[0.0, 2.8], [2.0, 4.0], [-1.0, 3.0]], rtol=1e-6)


def test_q_update_terminal_has_no_bootstrap():
    new = qlearning.q_update(TABLE, 2, 0, 1.0, 1, True, alpha=0.5, gamma=0.9)
    # target = r = 1: Q(2,0) <- 0.5 * -1 + 0.5 * 1 = 0
    np.testing.assert_allclose(new[2], [0.0, 3.0])


def test_sequential_update_applies_transitions_in_order():
    s, a = jnp.array([0, 0]), jnp.array([1, 1])
    r, s_next, term = jnp.array([3.0, 0.0]), jnp.array([1, 0]), jnp.array([True, False])
    new = qlearning.sequential_q_update(TABLE, s, a, r, s_next, term, alpha=0.5, gamma=0.9)
    # first: Q(0,1) <- 0.5 * 1 + 0.5 * 3 = 2; second bootstraps from the updated row:
    # Q(0,1) <- 0.5 * 2 + 0.5 * (0 + 0.9 * max(0, 2)) = 1.9
    np.testing.assert_allclose(new[0], [0.0, 1.9], rtol=1e-6)


def test_mean_update_moves_a_shared_pair_once_towards_the_mean_target():
    s, a = jnp.array([0, 0, 2]), jnp.array([1, 1, 0])
    r, s_next, term = jnp.array([1.0, 3.0, 0.0]), jnp.array([1, 1, 0]), jnp.array([True, True, False])
    new = qlearning.mean_q_update(TABLE, s, a, r, s_next, term, alpha=0.5, gamma=0.9)
    # (0,1): targets 1 and 3, mean 2: 1 + 0.5 * (2 - 1) = 1.5; (2,0): target 0.9 * max(0, 1) = 0.9
    np.testing.assert_allclose(new, [[0.0, 1.5], [2.0, 4.0], [-0.05, 3.0]], rtol=1e-6)


def _algo(*overrides):
    cfg = compose_config("experiment=cartpole_qlearning", "algo.num_envs=3", "algo.num_steps=5", *overrides)
    return qlearning.make(cfg.algo, make_env(cfg), budget_env_steps=15), cfg


def test_update_counts_env_steps_and_learns():
    algo, _ = _algo()
    state = algo.init(jax.random.PRNGKey(0))
    new, metrics = jax.jit(algo.update)(state)
    assert int(metrics["env_steps"]) == 15
    assert int(jnp.sum(new.table != state.table)) > 0


def test_both_parallel_updates_run():
    algo, _ = _algo("algo.parallel_update=mean")
    state, _ = jax.jit(algo.update)(algo.init(jax.random.PRNGKey(0)))
    assert np.all(np.isfinite(state.table))


class FakeEnv(Env):
    def __init__(self, obs, action):
        self.observation_space, self.action_space = obs, action


def test_check_needs_discrete_observations_and_actions():
    cfg = compose_config("algo=qlearning").algo
    assert qlearning.check(cfg, FakeEnv(Discrete(5), Discrete(5))) is None
    assert "env.discretize" in qlearning.check(cfg, FakeEnv(Box.uniform(-1, 1, 2), Discrete(2)))
    assert "discrete action space" in qlearning.check(cfg, FakeEnv(Discrete(5), Box.uniform(-1, 1, 2)))


def test_cartpole_without_discretisation_fails_through_the_cli(workdir):
    proc = run_cli("train", "algo=qlearning", "env=cartpole", "logger=quiet", cwd=workdir, timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "env.discretize" in lines[0], proc.stderr
    assert not (workdir / "outputs").exists()


def test_four_seeds_in_one_program(tmp_path):
    result = train_run(
        tmp_path,
        "experiment=cartpole_qlearning",
        "num_seeds=4",
        "eval.episodes=4",
        "budget.env_steps=4096",
        "log_every_steps=2048",
    )
    assert result.eval_return.shape == (4,) and np.all(np.isfinite(result.eval_return))
    tables = np.asarray(result.state.table)
    assert tables.shape == (4, 648, 2) and not np.allclose(tables[0], tables[1])


@pytest.mark.slow
def test_qlearning_balances_cartpole(tmp_path):
    result = train_run(tmp_path, "experiment=cartpole_qlearning", "num_seeds=3")
    assert np.mean(result.eval_return) >= 195, result.eval_return
