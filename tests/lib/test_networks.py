"""The network module's compute dtype: bfloat16 hidden layers, float32 parameters and outputs."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.lib.learning.networks import ActorCritic, compute_dtype
from rlq.lib.spaces import Box


def dot_operand_dtypes(net: ActorCritic, params, x: jax.Array) -> list[str]:
    """The operand dtype of every matrix product in the network's forward pass, in order."""
    jaxpr = jax.make_jaxpr(lambda p: net.apply(p, x))(params)
    return [str(eqn.invars[0].aval.dtype) for eqn in jaxpr.eqns if eqn.primitive.name == "dot_general"]


@pytest.mark.slow  # 10-20 s on 2 cores: the full suite runs it
def test_bfloat16_network_keeps_float32_parameters_and_outputs():
    space = Box.uniform(-1.0, 1.0, 3)
    x = jax.random.normal(jax.random.PRNGKey(1), (16, 5))
    full = ActorCritic(space, (32, 32), "swish", (64, 64, 64), state_std=True)
    half = full.clone(dtype=jnp.bfloat16)
    params = full.init(jax.random.PRNGKey(0), x)
    jax.tree.map(np.testing.assert_array_equal, half.init(jax.random.PRNGKey(0), x), params)
    assert all(leaf.dtype == jnp.float32 for leaf in jax.tree.leaves(params))

    # critic: 3 hidden layers and an output layer, actor: 2 and 1; the hidden ones run in bfloat16
    # (the observations are cast on the way in), the output layers in float32 ...
    dtypes = dot_operand_dtypes(half, params, x)
    assert dtypes == ["bfloat16"] * 3 + ["float32"] + ["bfloat16"] * 2 + ["float32"], dtypes
    assert dot_operand_dtypes(full, params, x) == ["float32"] * 7

    # ... and every head comes out float32, close to the float32 network's.
    for out_half, out_full in zip(half.apply(params, x), full.apply(params, x), strict=True):
        assert out_half.dtype == jnp.float32
        np.testing.assert_allclose(out_half, out_full, rtol=0.05, atol=0.05)


def test_unknown_compute_dtype_names_the_choices():
    assert compute_dtype("bfloat16") == jnp.bfloat16
    with pytest.raises(ValueError, match="bfloat16"):
        compute_dtype("float16")
