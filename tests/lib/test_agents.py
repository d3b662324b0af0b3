"""Parameter sharing over agents (rlq/lib/agents.py): one network applied to each agent's own input."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.errors import ExportError
from rlq.lib.agents import agent_space, agents_problem, per_agent
from rlq.lib.learning.distributions import categorical_log_prob, make_action_dist
from rlq.lib.learning.networks import MLP, ActorCritic, encode_obs
from rlq.lib.policy_export import mlp_policy
from rlq.lib.spaces import AgentsDiscrete, Box, Discrete

OBS = AgentsDiscrete(4, 3)
ACTIONS = AgentsDiscrete(2, 3)


def test_each_agent_reads_its_own_one_hot_and_optionally_its_index():
    obs = jnp.array([[3, 0, 3], [1, 2, 0]])  # 2 envs x 3 agents
    x = encode_obs(obs, OBS)
    assert x.shape == (2, 3, 4)
    np.testing.assert_array_equal(x[1, 1], [0, 0, 1, 0])
    with_id = encode_obs(obs, OBS, agent_id=True)
    assert with_id.shape == (2, 3, 4 + 3)
    np.testing.assert_array_equal(with_id[1, 2], [1, 0, 0, 0, 0, 0, 1])  # state 0, agent 2


def test_the_shared_network_gives_one_output_per_agent_and_permutes_with_them():
    net = MLP((16,), ACTIONS.n)
    obs = jnp.array([[3, 0, 2], [1, 1, 0]])
    params = net.init(jax.random.PRNGKey(0), encode_obs(obs[0], OBS))
    q = net.apply(params, encode_obs(obs, OBS))
    assert q.shape == (2, 3, 2)
    perm = jnp.array([2, 0, 1])
    np.testing.assert_allclose(net.apply(params, encode_obs(obs[:, perm], OBS)), q[:, perm], rtol=1e-6)
    np.testing.assert_allclose(q[1, 0], q[1, 1])  # same state, same parameters: same output


def test_the_agents_index_breaks_the_symmetry():
    net = MLP((16,), ACTIONS.n)
    obs = jnp.array([1, 1, 1])
    params = net.init(jax.random.PRNGKey(0), encode_obs(obs, OBS, agent_id=True))
    q = net.apply(params, encode_obs(obs, OBS, agent_id=True))
    assert not np.allclose(q[0], q[1])


def test_actor_critic_for_one_agents_action_gives_per_agent_logits_and_values():
    net = ActorCritic(agent_space(ACTIONS), (8,))
    x = encode_obs(jnp.array([[0, 1, 2]]), OBS)
    logits, log_std, value = net.apply(net.init(jax.random.PRNGKey(0), x), x)
    assert logits.shape == (1, 3, 2) and log_std is None and value.shape == (1, 3)


def test_joint_log_prob_and_entropy_are_the_sums_of_the_agents():
    logits = jnp.log(jnp.array([[0.5, 0.5], [0.9, 0.1], [0.2, 0.8]]))
    action = jnp.array([1, 0, 1])
    joint = make_action_dist(ACTIONS)
    np.testing.assert_allclose(joint.log_prob((logits, None), action), np.log(0.5 * 0.9 * 0.8), rtol=1e-6)
    np.testing.assert_allclose(joint.log_prob((logits, None), action), categorical_log_prob(logits, action).sum())
    entropy = -sum(p * np.log(p) for p in (0.5, 0.5, 0.9, 0.1, 0.2, 0.8))
    np.testing.assert_allclose(joint.entropy((logits, None), None), entropy, rtol=1e-6)
    np.testing.assert_array_equal(joint.mode((logits, None)), [0, 0, 1])
    assert joint.sample(jax.random.PRNGKey(0), (jnp.stack([logits] * 5), None)).shape == (5, 3)


def test_per_agent_broadcasts_the_shared_reward_and_leaves_single_agents_alone():
    reward, q = jnp.array([1.0, 2.0]), jnp.zeros((2, 3))
    np.testing.assert_array_equal(per_agent(reward, q), [[1.0] * 3, [2.0] * 3])
    np.testing.assert_array_equal(per_agent(reward, jnp.zeros(2)), reward)


def test_per_agent_observations_need_per_agent_actions():
    assert agents_problem("ppo", OBS, ACTIONS) is None
    assert agents_problem("ppo", Discrete(3), Discrete(2)) is None
    assert "controller.mode=decentralised" in agents_problem("ppo", OBS, Box.uniform(-1, 1, 2))
    assert "env.observation=arm_sectors" in agents_problem("dqn", Box.uniform(-1, 1, 2), ACTIONS)
    assert agents_problem("pqn", OBS, AgentsDiscrete(2, 5)) == "algo=pqn: the observation has 3 agents but the action 5"


def test_a_shared_per_agent_policy_refuses_export_in_one_line():
    with pytest.raises(ExportError, match="has no export format yet"):
        mlp_policy({}, OBS, ACTIONS, (8,), 2, "tanh", "argmax")
