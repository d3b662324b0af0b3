import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.lib.learning.initializers import orthogonal, orthonormal_columns
from rlq.lib.learning.networks import ActorCritic
from rlq.lib.spaces import Discrete


@pytest.mark.parametrize("shape", [(8, 64), (64, 64), (64, 4), (3, 5, 7)])
def test_orthogonal_rows_or_columns_scaled(shape):
    w = np.asarray(orthogonal(2.0)(jax.random.PRNGKey(0), shape)).reshape(-1, shape[-1])
    gram = w.T @ w if w.shape[0] >= w.shape[1] else w @ w.T
    np.testing.assert_allclose(gram, 4.0 * np.eye(gram.shape[0]), atol=1e-4)


def test_orthonormal_columns_is_the_qr_factor_with_positive_diagonal():
    a = jnp.array([[3.0, 1.0], [4.0, 2.0], [0.0, 2.0]])
    q = np.asarray(orthonormal_columns(a))
    np.testing.assert_allclose(q[:, 0], [0.6, 0.8, 0.0], atol=1e-6)
    r = q.T @ np.asarray(a)
    np.testing.assert_allclose(np.tril(r, -1), 0.0, atol=1e-6)
    assert (np.diag(r) > 0).all()


def test_seed_batched_network_init_uses_no_lapack():
    """vmap(init) over seeds must not lower to LAPACK QR (it deadlocks XLA's CPU pool)."""
    net = ActorCritic(Discrete(4), hidden=(64, 64))
    keys = jax.random.split(jax.random.PRNGKey(0), 8)
    text = jax.jit(jax.vmap(lambda k: net.init(k, jnp.zeros(8)))).lower(keys).as_text()
    assert "lapack" not in text.lower() and "geqrf" not in text.lower()
