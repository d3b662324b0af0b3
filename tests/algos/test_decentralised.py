"""PPO, DQN and PQN in decentralised control (``AgentsDiscrete``): one network shared by the agents,
each agent's own observation and action, the env's one reward (rlq/lib/agents.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from omegaconf import OmegaConf

from rlq.algos import algo_settings, check_algo, dqn, ppo, pqn
from rlq.envs.wrappers import AutoReset, EpisodeStats
from rlq.lib.rollout import evaluate
from rlq.lib.spaces import AgentsDiscrete, Discrete
from tests.fakes import Arms, SpacesOnly
from tests.helpers import compose_config, run_cli_in_process, run_dirs

pytestmark = pytest.mark.slow


def test_ppos_joint_value_is_the_mean_of_the_agents():
    logits, values = jnp.zeros((2, 3, 4)), jnp.array([[1.0, 2.0, 6.0], [0.0, 0.0, 3.0]])
    out = ppo.joint_value((logits, None, values))
    assert out[0] is logits and out[1] is None
    np.testing.assert_allclose(out[2], [3.0, 1.0])


def test_dqn_target_of_each_agent_by_hand():
    """Two envs of two agents: each agent bootstraps from its own next Q-values, with its env's reward
    and discount (0 after a termination)."""
    reward, discount = jnp.array([1.0, 0.5]), jnp.array([0.9, 0.0])
    next_q = jnp.array([[[2.0, 4.0], [3.0, -1.0]], [[7.0, 8.0], [0.0, 0.0]]])  # (env, agent, action)
    target = dqn.td_target(reward, discount, next_q, None, double=False)
    np.testing.assert_allclose(target, [[1.0 + 0.9 * 4.0, 1.0 + 0.9 * 3.0], [0.5, 0.5]])
    online = jnp.array([[[9.0, 0.0], [0.0, 9.0]], [[0.0, 0.0], [0.0, 0.0]]])  # Double DQN: online argmax
    target = dqn.td_target(reward, discount, next_q, online, double=True)
    np.testing.assert_allclose(target, [[1.0 + 0.9 * 2.0, 1.0 - 0.9 * 1.0], [0.5, 0.5]], rtol=1e-6)


def test_pqn_targets_of_each_agent_by_hand():
    """Two steps of one env with two agents, γ = 0.5, λ = 0.5: the last step bootstraps from each
    agent's max Q alone; the first mixes it with the agent's own return of the next step."""
    reward = jnp.array([[1.0], [2.0]])  # (time, env)
    next_q = jnp.array([[[[4.0, 0.0], [0.0, 2.0]]], [[[6.0, 1.0], [1.0, 8.0]]]])  # (time, env, agent, action)
    no = jnp.zeros((2, 1), bool)
    targets = pqn.q_lambda_targets(reward, next_q, no, no, 0.5, 0.5)
    last = [2.0 + 0.5 * 6.0, 2.0 + 0.5 * 8.0]
    first = [1.0 + 0.5 * (0.5 * 4.0 + 0.5 * last[0]), 1.0 + 0.5 * (0.5 * 2.0 + 0.5 * last[1])]
    np.testing.assert_allclose(targets[:, 0], [first, last])
    ended = pqn.q_lambda_targets(reward, next_q, jnp.array([[True], [False]]), jnp.array([[True], [False]]), 0.5, 0.5)
    np.testing.assert_allclose(ended[0, 0], [1.0, 1.0])  # a termination: the shared reward alone


@pytest.mark.parametrize("name", ["ppo", "dqn", "pqn"])
def test_per_agent_spaces_are_admitted_in_pairs(name):
    cfg = compose_config(f"algo={name}").algo
    pair = SpacesOnly(AgentsDiscrete(10, 5), AgentsDiscrete(4, 5))
    assert check_algo(cfg, pair) is None
    problem = check_algo(cfg, SpacesOnly(AgentsDiscrete(10, 5), Discrete(5)))
    assert problem.startswith(f"algo={name}: one state per arm") and "controller.mode=decentralised" in problem


def test_dqn_stores_joint_transitions_in_its_one_buffer():
    algo = dqn.make(algo_cfg("dqn"), AutoReset(EpisodeStats(Arms())), budget_env_steps=16)
    state, _ = jax.jit(lambda s: algo.update(s, algo.hyperparams))(algo.init(jax.random.PRNGKey(0), algo.hyperparams))
    stored = state.buffer.storage
    assert stored["obs"].shape[1:] == (3,) and stored["action"].shape[1:] == (3,) and stored["reward"].ndim == 1
    np.testing.assert_array_equal(stored["obs"][0], [0, 1, 2])


#: tiny learners for Arms: 8 envs, 8 steps per update (64 one-step episodes)
SETTINGS = {
    "ppo": {"num_minibatches": 2, "lr": 0.01, "anneal_lr": False},
    "dqn": {"learning_starts": 64, "buffer_size": 512, "batch_size": 32, "lr": 0.01, "epsilon": {"duration": 400}},
    "pqn": {"num_minibatches": 2, "lr": 0.01, "hidden": [32, 32], "reward_scaling": 1.0, "epsilon": {"duration": 400}},
}


def algo_cfg(name: str, **overrides):
    cfg = compose_config(f"algo={name}").algo
    return algo_settings(OmegaConf.merge(cfg, {"num_envs": 8, "num_steps": 8, **SETTINGS[name], **overrides}))


@pytest.mark.parametrize("name", ["ppo", "dqn", "pqn"])
def test_agents_sharing_one_network_learn_their_own_best_actions(name):
    """Arms: agents in the states 0, 1, 2 are paid together for each picking its state's parity; the
    shared network must tell the states apart to reach the greedy return 1 (random play: 0.5)."""
    env = AutoReset(EpisodeStats(Arms()))
    algo = {"ppo": ppo, "dqn": dqn, "pqn": pqn}[name].make(algo_cfg(name), env, budget_env_steps=1280)
    state = algo.init(jax.random.PRNGKey(0), algo.hyperparams)
    update = jax.jit(lambda s: algo.update(s, algo.hyperparams))
    for _ in range(algo.num_updates):
        state, _ = update(state)
    greedy = algo.policy(state)
    np.testing.assert_array_equal(greedy(jnp.arange(3), jax.random.PRNGKey(1)), [0, 1, 0])
    returns = evaluate(env, greedy, jax.random.PRNGKey(2), 4)["episode_return"]
    np.testing.assert_allclose(returns, 1.0)


#: the brittle star at its smallest (as tests/envs/brittle_star/test_presets.py): 1 segment per arm,
#: 3 decisions of 2 control steps per episode
TINY_BRITTLE_STAR = (
    "env.segments_per_arm=1",
    "env.simulation_time=0.12",
    "env.action_repeat=2",
    "eval.episodes=1",
    "video.at_end=false",
    "log_every_steps=4",
)


@pytest.mark.slow
def test_decentralised_ppo_trains_on_the_brittle_star_through_the_cli(workdir):
    """About 2 min on 2 CPU cores, 70 s of it compiling the MJX rollout."""
    proc = run_cli_in_process(
        "train",
        "env=brittle_star",
        "algo=ppo",
        "env.observation=arm_sectors",
        "controller.mode=decentralised",
        "algo.normalize_obs=false",
        "algo.num_envs=2",
        "algo.num_steps=2",
        "algo.num_minibatches=1",
        "budget.env_steps=4",
        "logger=quiet",
        *TINY_BRITTLE_STAR,
        cwd=workdir,
    )
    assert proc.returncode == 0, proc.stderr
    assert "4 env steps x 1 seed(s)" in proc.stdout + proc.stderr
    (run,) = run_dirs(workdir)
    assert (run / "checkpoints" / "final.msgpack").exists()
