from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos import algo_settings, qlearning
from rlq.lib.spaces import Box, Discrete
from rlq.run.programs.env_stack import make_env
from tests.fakes import SpacesOnly
from tests.helpers import compose_config, quick_sample, run_cli_in_process, train_run

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
    new, visits = qlearning.sequential_q_update(
        TABLE, jnp.zeros_like(TABLE), s, a, r, s_next, term, alpha=0.5, gamma=0.9
    )
    # first: Q(0,1) <- 0.5 * 1 + 0.5 * 3 = 2; second bootstraps from the updated row:
    # Q(0,1) <- 0.5 * 2 + 0.5 * (0 + 0.9 * max(0, 2)) = 1.9
    np.testing.assert_allclose(new[0], [0.0, 1.9], rtol=1e-6)
    np.testing.assert_allclose(visits, [[0, 2], [0, 0], [0, 0]])


def test_mean_update_moves_a_shared_pair_once_towards_the_mean_target():
    s, a = jnp.array([0, 0, 2]), jnp.array([1, 1, 0])
    r, s_next, term = jnp.array([1.0, 3.0, 0.0]), jnp.array([1, 1, 0]), jnp.array([True, True, False])
    new, visits = qlearning.mean_q_update(TABLE, jnp.zeros_like(TABLE), s, a, r, s_next, term, alpha=0.5, gamma=0.9)
    # (0,1): targets 1 and 3, mean 2: 1 + 0.5 * (2 - 1) = 1.5; (2,0): target 0.9 * max(0, 1) = 0.9
    np.testing.assert_allclose(new, [[0.0, 1.5], [2.0, 4.0], [-0.05, 3.0]], rtol=1e-6)
    np.testing.assert_allclose(visits, [[0, 2], [0, 0], [1, 0]])


def test_sample_average_sequential_update_averages_every_target():
    # a bandit (terminal transitions, so targets are the rewards): the value is their running mean
    table, visits = jnp.zeros((1, 1)), jnp.zeros((1, 1))
    rewards = jnp.array([4.0, 0.0, 2.0, 6.0])
    zeros = jnp.zeros(4, jnp.int32)
    args = (zeros, zeros, rewards, zeros, jnp.ones(4, bool))
    new, visits = qlearning.sequential_q_update(table, visits, *args, alpha=0.01, gamma=0.9, sample_average=True)
    np.testing.assert_allclose(new, [[3.0]], rtol=1e-6)
    assert float(visits[0, 0]) == 4.0
    # a constant alpha of 0.01 would have moved only a few percent of the way
    const, _ = qlearning.sequential_q_update(table, jnp.zeros((1, 1)), *args, alpha=0.01, gamma=0.9)
    assert float(const[0, 0]) < 0.2


def test_sample_average_mean_update_weights_batches_by_visits():
    # 2 earlier visits averaged 1.0; 3 new terminal targets with mean 6: (2 * 1 + 3 * 6) / 5 = 4
    table, visits = jnp.ones((1, 1)), jnp.full((1, 1), 2.0)
    zeros = jnp.zeros(3, jnp.int32)
    new, visits = qlearning.mean_q_update(
        table, visits, zeros, zeros, jnp.array([5.0, 6.0, 7.0]), zeros, jnp.ones(3, bool), 0.01, 0.9, True
    )
    np.testing.assert_allclose(new, [[4.0]], rtol=1e-6)
    assert float(visits[0, 0]) == 5.0
    # after many visits the step size falls to the floor alpha
    new, _ = qlearning.mean_q_update(
        jnp.zeros((1, 1)),
        jnp.full((1, 1), 1e6),
        zeros[:1],
        zeros[:1],
        jnp.ones(1),
        zeros[:1],
        jnp.ones(1, bool),
        0.5,
        0.9,
        True,
    )
    np.testing.assert_allclose(new, [[0.5]])


def _algo(*overrides):
    cfg = compose_config("experiment=cartpole_qlearning", "algo.num_envs=3", "algo.num_steps=5", *overrides)
    return qlearning.make(algo_settings(cfg.algo), make_env(cfg), budget_env_steps=15), cfg


def test_update_counts_env_steps_and_learns():
    algo, _ = _algo()
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    new, metrics = jax.jit(lambda s: algo.update(s, algo.hyperparams))(state)
    assert int(metrics["env_steps"]) == 15
    assert int(jnp.sum(new.table != state.table)) > 0


# the quick tier runs two of the four pairs, between them each rule and each decay
@pytest.mark.parametrize(
    ("update", "decay"), quick_sample([(u, d) for u in ("sequential", "mean") for d in ("none", "visits")], 3)
)
def test_every_update_rule_runs_and_counts_visits(update, decay):
    algo, _ = _algo(f"algo.parallel_update={update}", f"algo.alpha_decay={decay}")
    state, _ = jax.jit(lambda s: algo.update(s, algo.hyperparams))(algo.init(jax.random.PRNGKey(0), algo.hyperparams))
    assert np.all(np.isfinite(state.table))
    assert float(state.visits.sum()) == 15.0


def test_check_needs_discrete_observations_and_actions():
    cfg = algo_settings(compose_config("algo=qlearning").algo)
    assert qlearning.check(cfg, SpacesOnly(Discrete(5), Discrete(5))) is None
    assert "env.discretize" in qlearning.check(cfg, SpacesOnly(Box.uniform(-1, 1, 2), Discrete(2)))
    assert "discrete action space" in qlearning.check(cfg, SpacesOnly(Discrete(5), Box.uniform(-1, 1, 2)))
    both_continuous = qlearning.check(cfg, SpacesOnly(Box.uniform(-1, 1, 2), Box.uniform(-1, 1, 2)))
    assert (
        "SpacesOnly has continuous actions; use algo=ppo" in both_continuous
    )  # names the env; no discretisation fixes it
    cfg = replace(cfg, alpha_decay="harmonic")
    assert "algo.alpha_decay" in qlearning.check(cfg, SpacesOnly(Discrete(5), Discrete(5)))
    cfg = replace(cfg, alpha_decay="visits", alpha=0.0)
    assert "algo.alpha" in qlearning.check(cfg, SpacesOnly(Discrete(5), Discrete(5)))


@pytest.mark.slow
def test_cartpole_without_discretisation_fails_through_the_cli(workdir):
    proc = run_cli_in_process(
        "train", "algo=qlearning", "env=cartpole", "env.discretize=null", "logger=quiet", cwd=workdir
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "env.discretize" in lines[0], proc.stderr
    assert not (workdir / "outputs").exists()


@pytest.mark.slow  # a four-seed run (about 10 s of CPU): the full suite runs it, as test_dqn's and test_train's
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
