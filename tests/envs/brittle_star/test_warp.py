"""The brittle star on MuJoCo Warp (env.mjx_impl=warp) through rlq's wrappers, against MJX's JAX
implementation of the same model.

Warp also runs its kernels on the CPU, so this checks the integration (Warp's data template and
constraint buffers, the shared contact buffer, auto-reset merging) without a GPU. The first run
compiles Warp's kernels (about a minute on a CPU; cached in ~/.cache/warp afterwards).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("biorobot")
pytest.importorskip("warp")

from rlq.envs import make_base_env  # noqa: E402
from rlq.lib.rollout import evaluate  # noqa: E402
from rlq.run.programs.env_stack import make_env  # noqa: E402
from tests.helpers import compose_config, train_run  # noqa: E402

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::UserWarning")]

#: a small pruned model; 3 control steps per episode, so the fourth step auto-resets
SMALL = ("env=brittle_star", "env.segments_per_arm=2", "env.physics.wall_contacts=false", "env.simulation_time=0.12")
STEPS = 4


def rollout(impl: str) -> list:
    env = make_env(compose_config(*SMALL, f"env.mjx_impl={impl}", "env.warp_contacts=256"))
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    states = [reset(jax.random.split(jax.random.PRNGKey(0), 2))]
    for k in jax.random.split(jax.random.PRNGKey(1), STEPS):
        states.append(step(states[-1], jax.vmap(env.action_space.sample)(jax.random.split(k, 2))))
    return states


@pytest.fixture(scope="module")
def both():
    return rollout("jax"), rollout("warp")


def test_warp_steps_the_same_model_as_mjx_jax(both):
    on_jax, on_warp = both
    for a, b in zip(on_jax[:3], on_warp[:3], strict=True):
        np.testing.assert_allclose(a.obs, b.obs, atol=2e-3)  # two solvers of one model: float-level drift
        np.testing.assert_allclose(a.info["distance_to_target"], b.info["distance_to_target"], atol=1e-4)
    assert not np.allclose(on_warp[3].obs, on_warp[0].obs)  # the body moved


def test_the_episode_ends_and_warp_data_restarts_from_the_reset(both):
    _, on_warp = both
    ended = on_warp[3]
    assert bool(ended.truncated.all())
    restarted = on_warp[4]
    np.testing.assert_array_equal(restarted.info["episode_length"], [1, 1])
    assert np.all(np.isfinite(restarted.obs))


def test_auto_is_the_jax_implementation_on_a_cpu():
    assert make_base_env(compose_config(*SMALL, "env.mjx_impl=auto").env).mjx_impl == "jax"


@pytest.mark.parametrize(
    ("override", "message"),
    [("env.mjx_impl=bullet", "env.mjx_impl must be one of"), ("env.warp_contacts=0", "env.warp_contacts must be")],
)
def test_bad_warp_settings_raise(override, message):
    with pytest.raises(ValueError, match=message):
        make_base_env(compose_config(*SMALL, "env.mjx_impl=warp", override).env)


def test_warp_evaluates_under_a_vmap_over_seeds():
    """The run's evaluation program vmaps rlq's evaluate (a while_loop that stops once every
    episode ended) over seeds; the stopping test then differs per seed, which batches the loop's
    whole carry, Warp's batch-shared buffers included."""
    env = make_env(compose_config(*SMALL, "env.mjx_impl=warp", "env.warp_contacts=256"))
    policy = lambda obs, key: jnp.zeros(env.action_space.shape)  # noqa: E731
    keys = jax.random.split(jax.random.PRNGKey(2), 2)
    record = jax.jit(jax.vmap(lambda k: evaluate(env, policy, k, 2)))(keys)
    assert record["finished"].shape == (2, 2) and bool(record["finished"].all())
    np.testing.assert_array_equal(record["episode_length"], 3)


def test_a_run_on_warp_trains_evaluates_and_saves_its_video(tmp_path):
    """A whole run: its state holds Warp's batch-shared buffers once for all seeds, and the final
    evaluation and the video take seed 0's entry of it (rlq.lib.batch.seed_entry)."""
    result = train_run(
        tmp_path,
        *SMALL,
        "env.mjx_impl=warp",
        "env.warp_contacts=256",
        "algo=ppo",
        "algo.num_envs=2",
        "algo.num_steps=3",
        "algo.num_minibatches=1",
        "algo.update_epochs=1",
        "budget.env_steps=12",
        "eval.episodes=2",
        "video.at_end=true",
    )
    assert np.isfinite(result.as_dict()["eval_return_mean"])
    assert list((tmp_path / "videos").glob("final_seed0.*"))
