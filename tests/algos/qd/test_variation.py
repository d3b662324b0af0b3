"""MAP-Elites' variation operators stay in bounds and do what their formulas say."""

import jax
import jax.numpy as jnp
import numpy as np

from rlq.algos.qd import variation

LOW, HIGH = jnp.array([0.0, -1.0, 0.0]), jnp.array([1.0, 1.0, 3.0])


def test_gaussian_is_centred_on_the_parent_with_sigma_and_clipped():
    parents = jnp.broadcast_to(jnp.array([0.5, 0.0, 1.5]), (20000, 3))
    children = np.asarray(variation.gaussian(jax.random.PRNGKey(0), parents, 0.1, LOW, HIGH))
    np.testing.assert_allclose(children.mean(axis=0), [0.5, 0.0, 1.5], atol=0.01)
    np.testing.assert_allclose(children.std(axis=0), 0.1, atol=0.01)
    edge = np.asarray(variation.gaussian(jax.random.PRNGKey(1), jnp.zeros((1000, 3)), 1.0, LOW, HIGH))
    assert (edge >= np.asarray(LOW)).all() and (edge <= np.asarray(HIGH)).all()


def test_iso_line_moves_along_the_line_between_elites():
    x, y = jnp.array([[0.2, 0.0, 1.0]]), jnp.array([[0.6, 0.4, 2.0]])
    wide_low, wide_high = jnp.full(3, -10.0), jnp.full(3, 10.0)
    children = np.asarray(
        variation.iso_line(
            jax.random.PRNGKey(2), jnp.repeat(x, 500, 0), jnp.repeat(y, 500, 0), 0.0, 0.5, wide_low, wide_high
        )
    )
    steps = (children - np.asarray(x)) / (np.asarray(y) - np.asarray(x))  # one scalar per child, same on all axes
    np.testing.assert_allclose(steps, steps[:, :1].repeat(3, 1), atol=1e-5)
    assert 0.4 < steps[:, 0].std() < 0.6
    same = variation.iso_line(jax.random.PRNGKey(3), x, y, 0.0, 0.0, LOW, HIGH)
    np.testing.assert_allclose(same, x)


def test_uniform_fills_the_bounds():
    samples = np.asarray(variation.uniform(jax.random.PRNGKey(4), 5000, LOW, HIGH))
    assert samples.shape == (5000, 3)
    np.testing.assert_allclose(samples.min(axis=0), LOW, atol=0.01)
    np.testing.assert_allclose(samples.max(axis=0), HIGH, atol=0.01)
