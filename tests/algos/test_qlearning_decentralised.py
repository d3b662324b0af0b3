"""Tabular Q beyond one agent and one pass: a table shared by the agents (decentralised control) and
replay of past transitions (rlq/algos/qtable_batch.py)."""

import jax
import jax.numpy as jnp
import numpy as np
from omegaconf import OmegaConf

from rlq.algos import algo_settings, check_algo, qlearning, qtable_batch
from rlq.envs.wrappers import AutoReset, EpisodeStats
from rlq.lib.learning import replay
from rlq.lib.rollout import Transition
from rlq.lib.spaces import AgentsDiscrete, Discrete
from tests.fakes import Arms, SpacesOnly
from tests.helpers import compose_config

TABLE = jnp.array([[0.0, 1.0], [2.0, 4.0], [-1.0, 3.0]])


def learn_with(rule, alpha=0.5, gamma=0.9):
    return lambda *batch: rule(*batch, alpha, gamma)


def decentralised_step() -> Transition:
    """One env, two agents in states 0 and 2 taking actions 1 and 0; reward 1; next states 1 and 0."""
    return Transition(
        obs=jnp.array([[0, 2]]),
        action=jnp.array([[1, 0]]),
        reward=jnp.array([1.0]),
        terminated=jnp.array([False]),
        truncated=jnp.array([False]),
        next_obs=jnp.array([[1, 0]]),
        info={},
        aux={},
    )


def test_flat_transitions_give_one_per_agent_with_the_shared_reward():
    flat = qtable_batch.flat_transitions(decentralised_step())
    np.testing.assert_array_equal(flat.s, [0, 2])
    np.testing.assert_array_equal(flat.a, [1, 0])
    np.testing.assert_array_equal(flat.r, [1.0, 1.0])
    np.testing.assert_array_equal(flat.s_next, [1, 0])
    np.testing.assert_array_equal(flat.terminated, [False, False])


def test_flat_transitions_of_single_agent_envs_are_as_they_are():
    single = decentralised_step().replace(obs=jnp.array([2]), action=jnp.array([1]), next_obs=jnp.array([0]))
    flat = qtable_batch.flat_transitions(single)
    assert (int(flat.s[0]), int(flat.a[0]), int(flat.s_next[0])) == (2, 1, 0)


def test_every_agent_updates_the_one_table_by_hand():
    batch = qtable_batch.flat_transitions(decentralised_step())
    learn = learn_with(qlearning.sequential_q_update)
    table, visits = qtable_batch.apply(learn, TABLE, jnp.zeros_like(TABLE), batch)
    # agent 0: Q(0,1) <- 0.5 * 1 + 0.5 * (1 + 0.9 * max(2, 4)) = 2.8
    # agent 1 bootstraps from the row agent 0 just moved: Q(2,0) <- 0.5 * -1 + 0.5 * (1 + 0.9 * 2.8) = 1.26
    np.testing.assert_allclose(table, [[0.0, 2.8], [2.0, 4.0], [1.26, 3.0]], rtol=1e-6)
    np.testing.assert_allclose(visits, [[0, 1], [0, 0], [1, 0]])


def one_transition_buffer() -> replay.ReplayState:
    """Capacity 4 with one transition written (0, 1, r=1, terminal); slots 1..3 hold zeros, which
    would move Q(0,0) = 5 towards 0.9 * 5 if they were ever drawn."""
    item = qtable_batch.QTransition(
        s=jnp.array([0]), a=jnp.array([1]), r=jnp.array([1.0]), s_next=jnp.array([1]), terminated=jnp.array([True])
    )
    return replay.add(qtable_batch.empty_buffer(4), item)


def test_replay_updates_by_hand_sequential():
    table = jnp.array([[5.0, 0.0], [0.0, 0.0]])
    learn = learn_with(qlearning.sequential_q_update)
    new, visits = qtable_batch.replay_updates(
        learn, table, jnp.zeros_like(table), one_transition_buffer(), jax.random.PRNGKey(0), 3, 2
    )
    # 2 batches x 3 draws of the one transition, each halfway to its target 1: 1 - 0.5**6
    np.testing.assert_allclose(new, [[5.0, 0.984375], [0.0, 0.0]], rtol=1e-6)
    np.testing.assert_allclose(visits, [[0, 6], [0, 0]])


def test_replay_updates_by_hand_mean():
    table = jnp.array([[5.0, 0.0], [0.0, 0.0]])
    learn = learn_with(qlearning.mean_q_update)
    new, visits = qtable_batch.replay_updates(
        learn, table, jnp.zeros_like(table), one_transition_buffer(), jax.random.PRNGKey(0), 3, 2
    )
    # each batch moves the pair once, halfway to the mean target 1: 0 -> 0.5 -> 0.75
    np.testing.assert_allclose(new, [[5.0, 0.75], [0.0, 0.0]], rtol=1e-6)
    np.testing.assert_allclose(visits, [[0, 6], [0, 0]])


def algo_cfg(**overrides):
    cfg = compose_config("algo=qlearning").algo
    return algo_settings(
        OmegaConf.merge(cfg, {"num_envs": 4, "num_steps": 5, "epsilon": {"duration": 400}, **overrides})
    )


def test_agents_share_the_table_and_learn_their_own_best_actions():
    env = AutoReset(EpisodeStats(Arms()))
    algo = qlearning.make(algo_cfg(), env, budget_env_steps=400)
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    assert state.table.shape == (3, 2) and state.replay is None
    update = jax.jit(lambda s: algo.update(s, algo.hyperparams))
    for _ in range(algo.num_updates):
        state, metrics = update(state)
    assert int(metrics["env_steps"]) == 400
    assert float(state.visits.sum()) == 400 * 3  # every agent's transition, one table
    greedy = algo.policy(state)(jnp.arange(3), jax.random.PRNGKey(1))
    np.testing.assert_array_equal(greedy, [0, 1, 0])


def test_replay_adds_its_updates_to_each_step():
    env = AutoReset(EpisodeStats(Arms()))
    algo = qlearning.make(algo_cfg(replay_size=64, replay_batch=8, replay_updates=2), env, budget_env_steps=20)
    state, _ = jax.jit(lambda s: algo.update(s, algo.hyperparams))(algo.init(jax.random.PRNGKey(0), algo.hyperparams))
    # 5 steps x (4 envs x 3 agents fresh + 2 x 8 replayed)
    assert float(state.visits.sum()) == 5 * (12 + 16)
    assert int(state.replay.size) == 5 * 12 and np.all(np.isfinite(state.table))


def test_check_pairs_per_agent_states_with_per_agent_actions():
    cfg = algo_cfg()
    agents_obs, agents_act = AgentsDiscrete(10, 5), AgentsDiscrete(4, 5)
    assert qlearning.check(cfg, SpacesOnly(agents_obs, agents_act)) is None
    assert "controller.mode=decentralised" in qlearning.check(cfg, SpacesOnly(agents_obs, Discrete(5)))
    assert "env.observation=arm_sectors" in qlearning.check(cfg, SpacesOnly(Discrete(5), agents_act))
    assert "5 agents but the action 3" in qlearning.check(cfg, SpacesOnly(agents_obs, AgentsDiscrete(4, 3)))


def test_check_replay_holds_one_steps_transitions():
    spaces = SpacesOnly(AgentsDiscrete(10, 5), AgentsDiscrete(4, 5))
    problem = qlearning.check(algo_cfg(replay_size=19), spaces)
    assert problem == (
        "algo.replay_size=19 cannot hold one step's 20 transitions (algo.num_envs x agents); "
        "give 0 (no replay) or >= 20"
    )
    assert qlearning.check(algo_cfg(replay_size=20), spaces) is None


def test_other_algorithms_refuse_per_agent_spaces_in_one_line():
    spaces = SpacesOnly(AgentsDiscrete(10, 5), AgentsDiscrete(4, 5))
    problem = check_algo(compose_config("algo=reinforce").algo, spaces)
    assert problem.startswith("algo=reinforce cannot learn one observation and action per arm")
    assert problem.endswith("use algo=dqn|ppo|pqn|qlearning, which shares one learner over the arms")
    assert check_algo(compose_config("algo=qlearning").algo, spaces) is None
