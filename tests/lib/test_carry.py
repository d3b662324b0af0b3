"""rlq.lib.carry: zeros that vmap batches like their input, so a loop carry starts batched."""

import jax
import jax.numpy as jnp

from rlq.lib.carry import batched_zeros, strongly_typed


def test_batched_zeros_are_zeros_that_vmap_batches_as_their_input() -> None:
    seen = {}

    def per_env(x):
        seen["plain zeros batched"] = isinstance(jnp.zeros((2, 3)), jax.core.Tracer)
        zeros = batched_zeros(x, (2, 3), jnp.int32)
        seen["batched_zeros batched"] = isinstance(zeros, jax.core.Tracer)
        return zeros

    out = jax.vmap(per_env)(jnp.array([0.0, -1.5, jnp.nan, jnp.inf]))
    assert seen == {"plain zeros batched": False, "batched_zeros batched": True}
    assert out.shape == (4, 2, 3) and out.dtype == jnp.int32 and not out.any()


def test_a_loop_started_from_them_computes_what_it_computes_from_plain_zeros() -> None:
    def count_down(x, start):
        def body(carry):
            i, y = carry
            return i + 1, y - 1.0

        return jax.lax.while_loop(lambda carry: carry[1] > 0, body, (start(x), x))

    xs = jnp.array([0.0, 1.0, 2.5, 7.0])
    plain = jax.vmap(lambda x: count_down(x, lambda _: jnp.zeros((), jnp.int32)))(xs)
    batched = jax.vmap(lambda x: count_down(x, lambda v: batched_zeros(v, dtype=jnp.int32)))(xs)
    assert [b.tolist() for b in batched] == [p.tolist() for p in plain] == [[0, 1, 3, 7], [0.0, 0.0, -0.5, 0.0]]


def test_strongly_typed_makes_weak_arrays_strong_and_keeps_values_and_dtypes() -> None:
    tree = {"weak": jnp.asarray(jnp.inf), "strong": jnp.zeros(3, jnp.int32), "weak_half": jnp.asarray(0.5) * 1}
    assert tree["weak"].weak_type and not tree["strong"].weak_type
    typed = strongly_typed(tree)
    for name, leaf in typed.items():
        assert not leaf.weak_type
        assert leaf.dtype == tree[name].dtype and leaf.shape == tree[name].shape
        assert bool(jnp.all(leaf == tree[name]))
