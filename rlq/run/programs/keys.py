"""The PRNG keys of a run's seeds and of their evaluations: one jitted derivation from the config's seed."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np


def seed_keys(seed: int, num_seeds: int, members: int = 1) -> jax.Array:
    """Key of seed i is fold_in(PRNGKey(seed), i): a seed's run does not depend on num_seeds.

    ``members``: the program trains that many runs of ``num_seeds / members`` seeds each (an
    in-program sweep, rlq/run/programs/members.py), and each member's seeds get the keys its own run would.

    Jitted, as ``eval_keys``: run eagerly, its PRNG operations compile one small program each
    (before the run's own compile starts). The seed's key enters the program as an argument, so a
    sweep over seeds compiles it once."""
    return _seed_keys(jax.random.PRNGKey(seed), num_seeds, members)


def eval_keys(seed: int, tag: jax.Array | np.integer, num_seeds: int, members: int = 1) -> jax.Array:
    """The keys of the evaluation tagged ``tag`` (one per seed): every evaluation of a run with the same
    tag draws the same episodes (``members`` as for ``seed_keys``)."""
    return _eval_keys(jax.random.PRNGKey(seed), tag, num_seeds, members)


@functools.partial(jax.jit, static_argnums=(1, 2))
def _seed_keys(base: jax.Array, num_seeds: int, members: int) -> jax.Array:
    keys = jax.vmap(lambda i: jax.random.fold_in(base, i))(jnp.arange(num_seeds // members))
    return jnp.tile(keys, (members, 1))


@functools.partial(jax.jit, static_argnums=(2, 3))
def _eval_keys(base: jax.Array, tag: jax.Array, num_seeds: int, members: int) -> jax.Array:
    base = jax.random.fold_in(jax.random.fold_in(base, 10_007), tag)
    return jnp.tile(jax.random.split(base, num_seeds // members), (members, 1))
