"""The grid archive: batched insertion against a one-by-one reference, its rules, and metrics."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rlq.algos.qd import archive as qa

GRID = qa.Grid((4, 3), (-1.0, 0.0), (1.0, 3.0))


def reference_insert(arch: dict, grid: qa.Grid, genotypes, fitness, descriptors) -> dict:
    """One offspring at a time: the cell from the clipped bins, replaced only by a strictly better one."""
    arch = {k: np.array(v, copy=True) for k, v in arch.items()}
    for g, f, d in zip(genotypes, fitness, descriptors, strict=True):
        if not (np.isfinite(f) and np.all(np.isfinite(d))):
            continue
        coords = [
            min(max(int(math.floor((x - lo) / (hi - lo) * n)), 0), n - 1)
            for x, lo, hi, n in zip(d, grid.low, grid.high, grid.shape, strict=True)
        ]
        cell = int(np.ravel_multi_index(coords, grid.shape))
        if f > arch["fitness"][cell]:
            arch["genotypes"][cell], arch["fitness"][cell] = g, f
            arch["descriptors"][cell], arch["filled"][cell] = d, True
    return arch


def as_dict(archive: qa.Archive) -> dict:
    return {k: np.asarray(getattr(archive, k)) for k in ("genotypes", "fitness", "descriptors", "filled")}


def assert_same(batched: qa.Archive, reference: dict) -> None:
    got = as_dict(batched)
    np.testing.assert_array_equal(got["filled"], reference["filled"])
    np.testing.assert_array_equal(got["fitness"], reference["fitness"])
    np.testing.assert_array_equal(got["genotypes"], reference["genotypes"])
    np.testing.assert_array_equal(got["descriptors"], reference["descriptors"])


insert = jax.jit(qa.insert, static_argnums=1)

# few distinct fitness values, so that ties are common; descriptors reach outside the bounds
fitness_values = st.sampled_from([-1.0, 0.0, 0.5, 1.0, 2.0, float("nan"), float("-inf")])
descriptor = st.tuples(st.floats(-2.0, 2.0, width=32), st.floats(-1.0, 4.0, width=32))


@settings(max_examples=60, deadline=None)
@given(
    batches=st.lists(st.lists(st.tuples(fitness_values, descriptor), min_size=1, max_size=24), min_size=1, max_size=3)
)
def test_batched_insertion_equals_one_by_one_reference(batches):
    archive = qa.empty(GRID, genotype_dim=2)
    reference = as_dict(archive)
    counter = 0
    for batch in batches:
        n = len(batch)
        genotypes = np.arange(counter, counter + 2 * n, dtype=np.float32).reshape(n, 2)  # each offspring unique
        counter += 2 * n
        fitness = np.array([f for f, _ in batch], np.float32)
        descriptors = np.array([d for _, d in batch], np.float32)
        archive = insert(archive, GRID, jnp.asarray(genotypes), jnp.asarray(fitness), jnp.asarray(descriptors))
        reference = reference_insert(reference, GRID, genotypes, fitness, descriptors)
        assert_same(archive, reference)


def test_several_offspring_in_one_cell_the_best_wins():
    genotypes = jnp.array([[1.0], [2.0], [3.0]])
    desc = jnp.full((3, 2), 0.1)
    archive = qa.insert(qa.empty(GRID, 1), GRID, genotypes, jnp.array([0.5, 2.0, 1.0]), desc)
    cell = int(qa.cell_index(GRID, desc[0]))
    assert int(archive.filled.sum()) == 1
    assert float(archive.fitness[cell]) == 2.0 and float(archive.genotypes[cell, 0]) == 2.0


def test_ties_keep_the_first_and_never_replace_an_elite():
    desc = jnp.full((2, 2), 0.1)
    archive = qa.insert(qa.empty(GRID, 1), GRID, jnp.array([[1.0], [2.0]]), jnp.array([1.0, 1.0]), desc)
    cell = int(qa.cell_index(GRID, desc[0]))
    assert float(archive.genotypes[cell, 0]) == 1.0  # first of equals
    tied = qa.insert(archive, GRID, jnp.array([[9.0]]), jnp.array([1.0]), desc[:1])
    worse = qa.insert(archive, GRID, jnp.array([[9.0]]), jnp.array([0.5]), desc[:1])
    for after in (tied, worse):
        assert_same(after, as_dict(archive))
    better = qa.insert(archive, GRID, jnp.array([[9.0]]), jnp.array([1.5]), desc[:1])
    assert float(better.genotypes[cell, 0]) == 9.0


def test_out_of_bounds_descriptors_go_to_border_cells_and_nan_is_never_inserted():
    far = jnp.array([[-50.0, -50.0], [50.0, 50.0], [0.0, 1e9]])
    coords = np.asarray(qa.cell_coordinates(GRID, far))
    np.testing.assert_array_equal(coords, [[0, 0], [3, 2], [2, 2]])
    archive = qa.insert(
        qa.empty(GRID, 1),
        GRID,
        jnp.zeros((3, 1)),
        jnp.array([1.0, jnp.nan, 1.0]),
        jnp.array([[0.0, 0.0], [0.5, 0.5], [jnp.nan, 1.0]]),
    )
    assert int(archive.filled.sum()) == 1


def test_cell_index_is_row_major_x_then_y():
    grid = qa.Grid((30, 30), (-3.0, -3.0), (3.0, 3.0))
    # x bin 29 (right edge), y bin 0 (bottom)
    assert int(qa.cell_index(grid, jnp.array([2.99, -2.99]))) == 29 * 30 + 0
    assert int(qa.cell_index(grid, jnp.array([-3.0, -2.8]))) == 1  # [-2.8 - (-3)] / 0.2 = 1 -> bin 1


def test_metrics_of_a_hand_built_archive():
    filled = jnp.array([True, False, True, False] + [False] * 8)
    fitness = jnp.where(filled, jnp.array([-1.0, 0, -3.0, 0] + [0] * 8), -jnp.inf)
    descriptors = jnp.zeros((12, 2)).at[0].set(jnp.array([3.0, 4.0])).at[2].set(jnp.array([0.0, 1.0]))
    archive = qa.Archive(jnp.zeros((12, 1)), fitness, descriptors, filled)
    m = {k: float(v) for k, v in qa.metrics(archive, qd_offset=5.0).items()}
    assert m["archive-occupancy"] == pytest.approx(2 / 12)
    assert m["qd-score"] == pytest.approx((-1 + 5) + (-3 + 5))
    assert m["minimum-fitness"] == -3.0 and m["maximum-fitness"] == -1.0
    assert m["average-fitness"] == pytest.approx(-2.0)
    assert m["furthest-distance-travelled"] == pytest.approx(5.0)
    assert set(m) == set(qa.METRIC_NAMES)
    empty = qa.metrics(qa.empty(GRID, 1))
    assert float(empty["archive-occupancy"]) == 0.0 and float(empty["qd-score"]) == 0.0
    assert np.isnan(float(empty["maximum-fitness"]))


def test_selection_draws_only_filled_cells():
    archive = qa.insert(
        qa.empty(GRID, 1), GRID, jnp.array([[7.0], [8.0]]), jnp.array([1.0, 1.0]), jnp.array([[0.9, 2.9], [-0.9, 0.1]])
    )
    drawn = np.asarray(qa.select(archive, jax.random.PRNGKey(0), 200))
    assert set(drawn[:, 0].tolist()) == {7.0, 8.0}


def test_selection_is_uniform_over_filled_cells():
    archive = qa.insert(
        qa.empty(GRID, 1),
        GRID,
        jnp.array([[1.0], [2.0], [3.0]]),
        jnp.array([1.0, 9.0, -4.0]),
        jnp.array([[0.9, 2.9], [-0.9, 0.1], [0.0, 1.5]]),
    )
    drawn = np.asarray(qa.select(archive, jax.random.PRNGKey(3), 30_000))[:, 0]
    counts = np.array([(drawn == v).sum() for v in (1.0, 2.0, 3.0)])
    assert counts.sum() == 30_000
    np.testing.assert_allclose(counts / 30_000, 1 / 3, atol=0.02)


def test_selection_from_an_empty_archive_gives_zeros():
    drawn = np.asarray(qa.select(qa.empty(GRID, 2), jax.random.PRNGKey(0), 5))
    assert drawn.shape == (5, 2) and not drawn.any()


def test_best_and_furthest_cells():
    archive = qa.insert(
        qa.empty(GRID, 1),
        GRID,
        jnp.array([[1.0], [2.0]]),
        jnp.array([5.0, 1.0]),
        jnp.array([[0.0, 0.5], [0.9, 2.9]]),
    )
    assert float(archive.genotypes[qa.best_cell(archive), 0]) == 1.0
    assert float(archive.genotypes[qa.furthest_cell(archive), 0]) == 2.0


@pytest.mark.parametrize(
    ("shape", "low", "high"),
    [((3,), (0.0, 0.0), (1.0, 1.0)), ((0, 3), (0.0, 0.0), (1.0, 1.0)), ((3, 3), (0.0, 1.0), (1.0, 1.0))],
)
def test_bad_grids_are_refused(shape, low, high):
    with pytest.raises(ValueError, match="archive"):
        qa.Grid(shape, low, high)


def test_chosen_cell_by_name_and_coordinates():
    archive = qa.insert(
        qa.empty(GRID, 1), GRID, jnp.array([[1.0], [2.0]]), jnp.array([5.0, 1.0]), jnp.array([[0.0, 0.5], [0.9, 2.9]])
    )
    assert float(archive.genotypes[qa.chosen_cell(archive, GRID, "best"), 0]) == 1.0
    assert float(archive.genotypes[qa.chosen_cell(archive, GRID, "furthest"), 0]) == 2.0
    assert qa.chosen_cell(archive, GRID, "3,2") == int(qa.cell_index(GRID, jnp.array([0.9, 2.9])))
    for spec, message in (("0,0", "holds no elite"), ("4,0", "outside"), ("top", "best, furthest"), ("1", "outside")):
        with pytest.raises(ValueError, match=message):
            qa.chosen_cell(archive, GRID, spec)
    with pytest.raises(ValueError, match="empty"):
        qa.chosen_cell(qa.empty(GRID, 1), GRID, "best")
