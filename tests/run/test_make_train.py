"""`from rlq import make_train`: a run's training as one jittable function (rlq/run/make_train.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.errors import ConfigError
from rlq.store import checkpoint
from tests.helpers import train_run

TINY = ("algo=ppo", "env=cartpole", "budget.env_steps=4096", "eval.episodes=4")


@pytest.mark.slow  # the whole training compiles as one program (about 20 s of CPU): the full suite runs it
def test_one_call_trains_and_evaluates():
    from rlq import make_train

    out = jax.jit(make_train(TINY))(jax.random.PRNGKey(0))
    assert out.evaluation["episode_return"].shape == (4,)
    assert out.metrics and {v.shape[0] for v in out.metrics.values()} == {4096 // 512}  # one row per update


@pytest.mark.slow
def test_it_trains_what_the_cli_trains(tmp_path):
    """`rlq train seed=7` ends with the parameters the function ends with given seed 0's key, up to float rounding
    (XLA fuses one scan of every update and the CLI's chunks of updates differently); another key's differ by ~0.1."""
    from rlq import make_train

    train_run(tmp_path, *TINY, "seed=7", "eval.every_steps=0")
    stored = checkpoint.leaves(tmp_path / "checkpoints/final.msgpack")
    mine = jax.tree.leaves(jax.jit(make_train(TINY))(jax.random.fold_in(jax.random.PRNGKey(7), 0)).state)
    assert len(mine) == len(stored)
    for a, b in zip(mine, stored, strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b)[0], rtol=1e-4, atol=1e-6)


def test_bad_overrides_raise_the_clis_error():
    from rlq import make_train

    with pytest.raises(ConfigError, match="algo.lr"):
        make_train(["algo=ppo", "env=cartpole", "algo.lr=-1"])


@pytest.mark.slow
def test_the_plain_recipe_learns_cartpole_on_several_seeds_at_once():
    from rlq import make_train

    keys = jax.random.split(jax.random.PRNGKey(0), 2)
    out = jax.jit(jax.vmap(make_train(["algo=ppo", "env=cartpole"])))(keys)
    assert np.asarray(out.evaluation["episode_return"]).mean(axis=1).min() >= 475


@pytest.mark.slow
def test_a_vmap_over_learning_rates_trains_what_each_ones_call_trains():
    from rlq import make_train

    train = make_train(TINY)
    assert set(train.hyperparams) >= {"lr"}
    key = jax.random.PRNGKey(3)
    swept = jax.jit(jax.vmap(train, in_axes=(None, 0)))(key, {"lr": jnp.array([1e-4, 3e-3], jnp.float32)})
    for i, lr in enumerate((1e-4, 3e-3)):
        alone = jax.jit(train)(key, {"lr": jnp.float32(lr)})
        for a, b in zip(jax.tree.leaves(swept.state), jax.tree.leaves(alone.state), strict=True):
            np.testing.assert_allclose(np.asarray(a)[i], np.asarray(b), rtol=1e-4, atol=1e-6)
    leaves = [np.asarray(leaf) for leaf in jax.tree.leaves(swept.state)]
    assert any(not np.allclose(leaf[0], leaf[1]) for leaf in leaves)  # the two learning rates trained apart


def test_an_unknown_hyperparameter_is_refused_with_the_names_it_takes():
    from rlq import make_train

    with pytest.raises(ConfigError, match="hyperparams gamma_typo: algo=ppo takes .*lr"):
        make_train(TINY)(jax.random.PRNGKey(0), {"gamma_typo": 0.9})
