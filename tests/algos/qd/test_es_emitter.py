"""MAP-Elites' ES emitter: candidates in the search frame and the bounds, the objectives, and an ES that
moves its mean toward what its objective rewards."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos.qd.es_emitter import EsEmitter, objective_values
from tests.helpers import leaf_types

LOW, HIGH = jnp.array([0.0, -1.0, 0.0]), jnp.array([1.0, 1.0, 3.0])
CENTRE, SCALE = (LOW + HIGH) / 2, (HIGH - LOW) / 2


def mean_genotype(state) -> np.ndarray:
    """The search distribution's mean as a genotype."""
    return np.clip(np.asarray(CENTRE) + np.asarray(SCALE) * np.asarray(state.mean), LOW, HIGH)


def emitter(objective: str = "distance", sigma: float = 0.1, lr: float = 0.05) -> EsEmitter:
    return EsEmitter(8, sigma, lr, objective, CENTRE, SCALE, LOW, HIGH)


def test_candidates_are_the_frame_mapped_to_the_bounds_and_clipped():
    es = emitter(sigma=3.0)
    state = es.init(jax.random.PRNGKey(0))
    candidates, genotypes = es.ask(state, jax.random.PRNGKey(1))
    assert candidates.shape == genotypes.shape == (8, 3)
    expected = np.clip(np.asarray(CENTRE) + np.asarray(SCALE) * np.asarray(candidates), LOW, HIGH)
    np.testing.assert_allclose(genotypes, expected, rtol=1e-6)
    assert (genotypes == LOW).any() and (genotypes == HIGH).any()  # sigma 3 reaches past the box
    np.testing.assert_allclose(candidates[:4], -candidates[4:], rtol=1e-6)  # antithetic pairs
    np.testing.assert_allclose(mean_genotype(state), CENTRE)  # it starts at the box's centre


def test_objectives_are_the_descriptor_norm_or_the_fitness_and_non_finite_ranks_last():
    fitness = jnp.array([1.0, -2.0, jnp.nan])
    descriptors = jnp.array([[3.0, 4.0], [0.0, -1.0], [1.0, 0.0]])
    np.testing.assert_allclose(objective_values("distance", fitness, descriptors), [5.0, 1.0, 1.0])
    np.testing.assert_allclose(objective_values("fitness", fitness, descriptors), [1.0, -2.0, -np.inf])
    with pytest.raises(ValueError, match="objective must be one of distance, fitness"):
        emitter("novelty")


@pytest.mark.parametrize(("objective", "index"), [("distance", 0), ("fitness", 2)])
def test_the_mean_climbs_its_objective(objective: str, index: int):
    """Descriptor = the genotype's first two numbers, fitness = its third: each objective moves the mean
    up its own coordinate (from the centre, whose distance is 0.5 and fitness 1.5)."""
    es = emitter(objective, sigma=0.2, lr=0.1)
    state = es.init(jax.random.PRNGKey(0))

    @jax.jit
    def step(state, key):
        ask_key, tell_key = jax.random.split(key)
        candidates, genotypes = es.ask(state, ask_key)
        return es.tell(state, tell_key, candidates, genotypes[:, 2], genotypes[:, :2])

    for key in jax.random.split(jax.random.PRNGKey(1), 20):
        state = step(state, key)
    start, mean = np.asarray(CENTRE), np.asarray(mean_genotype(state))
    np.testing.assert_allclose(es.mean(state), mean, rtol=1e-6)  # the mean as a genotype (a champion's candidate)
    if objective == "distance":
        assert np.linalg.norm(mean[:2]) > np.linalg.norm(start[:2]) + 0.3
    else:
        assert mean[index] > start[index] + 0.5


def test_it_starts_at_the_width_it_is_made_at():
    """MAP-Elites' init makes the emitter's state ``at`` its hyperparameters: a sweep's member starts at its own
    width."""
    state = jax.jit(lambda sigma: emitter(sigma=0.1).at(sigma, 0.05).init(jax.random.PRNGKey(0)))(np.float32(0.4))
    np.testing.assert_allclose(np.asarray(state.std), 0.4, rtol=1e-7)


def test_its_state_keeps_its_types_through_a_step_so_a_jitted_update_compiles_once():
    es = emitter()
    state = es.init(jax.random.PRNGKey(0))
    candidates, genotypes = es.ask(state, jax.random.PRNGKey(1))
    told = es.tell(state, jax.random.PRNGKey(2), candidates, genotypes[:, 0], genotypes[:, 1:])
    assert leaf_types(told) == leaf_types(state)
