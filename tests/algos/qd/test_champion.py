"""The champion kept by re-evaluation: the best re-scored candidate, not the fittest elite; empty cells never win;
only a strictly higher re-evaluated mean replaces it; the policy plays the fittest elite until one is scored."""

import jax
import jax.numpy as jnp
import numpy as np

from rlq.algos.qd import champion
from rlq.algos.qd.archive import Archive

#: six cells: the archive's fitness ranks cell 0 first, but the stub's re-evaluation (a genotype's first number)
#: ranks cell 1 first; the empty cells 3 and 5 hold a genotype the re-evaluation would rank above all
FIRST = jnp.array([1.0, 3.0, 2.0, 9.0, 0.5, 9.0])
ARCHIVE = Archive(
    genotypes=jnp.stack([FIRST, -FIRST], axis=1),
    fitness=jnp.array([10.0, 9.0, 8.0, -jnp.inf, 7.0, -jnp.inf]),
    descriptors=jnp.zeros((6, 2)),
    filled=jnp.array([True, True, True, False, True, False]),
)


def stub_score(genotypes: jax.Array, key: jax.Array):
    """A re-evaluation whose fresh episodes give each genotype its first number; 7 env steps per candidate."""
    count = genotypes.shape[0]
    extras = {
        "episode_return": jnp.zeros((count, 2)),
        "episode_length": jnp.full((count, 2), 3.5),
        "env_steps": jnp.asarray(7 * count, jnp.int32),
    }
    return genotypes[:, 0], jnp.zeros((count, 0)), extras


def test_the_champion_is_the_best_rescored_candidate_not_the_fittest_elite():
    genotypes, valid = champion.fittest(ARCHIVE, 3)
    np.testing.assert_array_equal(genotypes[:, 0], [1.0, 3.0, 2.0])  # cells 0, 1, 2 by the archive's fitness
    kept, env_steps = champion.rescored(
        champion.empty(2), genotypes, valid, stub_score, jax.random.PRNGKey(0), jnp.asarray(100, jnp.int32)
    )
    np.testing.assert_array_equal(kept.genotype, [3.0, -3.0])  # cell 1's elite, while cell 0's is the fittest
    assert float(kept.fitness) == 3.0 and int(env_steps) == 100 + 3 * 7


def test_empty_cells_are_scored_but_never_win():
    genotypes, valid = champion.fittest(ARCHIVE, 5)  # four elites and an empty cell
    assert valid.tolist() == [True, True, True, True, False] and float(genotypes[4, 0]) == 9.0
    kept, _ = champion.rescored(champion.empty(2), genotypes, valid, stub_score, jax.random.PRNGKey(0), 0)
    np.testing.assert_array_equal(kept.genotype, [3.0, -3.0])


def test_only_a_strictly_higher_mean_replaces_the_champion():
    held = champion.Champion(jnp.array([5.0, 5.0]), jnp.asarray(3.0))
    for genotypes, expected in (([[3.0, 0.0], [1.0, 0.0]], [5.0, 5.0]), ([[3.5, 0.0], [1.0, 0.0]], [3.5, 0.0])):
        kept, _ = champion.rescored(held, jnp.array(genotypes), jnp.ones(2, bool), stub_score, jax.random.key(0), 0)
        np.testing.assert_array_equal(kept.genotype, expected)


def test_the_policy_plays_the_fittest_elite_until_a_champion_is_scored():
    elite = jnp.array([1.0, 2.0])
    np.testing.assert_array_equal(champion.chosen(champion.empty(2), elite), elite)
    held = champion.Champion(jnp.array([5.0, 5.0]), jnp.asarray(-40.0))
    np.testing.assert_array_equal(champion.chosen(held, elite), [5.0, 5.0])
