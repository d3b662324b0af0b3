"""`rlq eval`'s choice of env for a finished run."""

from rlq.run.evaluate import eval_env_config
from tests.conftest import compose_config


def test_rlq_eval_steps_the_run_s_evaluation_env_unless_told_another():
    cfg = compose_config("env=lunar", "+eval.env.max_episode_steps=300")
    assert eval_env_config(cfg, None, []).env.max_episode_steps == 300
    assert eval_env_config(cfg, None, ["env.max_episode_steps=200"]).env.max_episode_steps == 200
    other = eval_env_config(cfg, "lunar_box2d", [])
    assert other.env.name == "lunar_box2d" and other.env.max_episode_steps == 1000
