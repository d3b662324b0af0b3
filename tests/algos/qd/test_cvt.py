"""The CVT archive: nearest-centroid cells on a hand case, k-means centroids from the seed alone,
insertion, named cells and its heatmap."""

import re

import jax.numpy as jnp
import numpy as np
import pytest

from rlq.algos.qd import archive as qa
from rlq.algos.qd.cvt import Cvt, nearest
from rlq.algos.qd.heatmap import heatmap


def test_a_descriptor_falls_into_the_cell_of_its_nearest_centroid():
    centroids = jnp.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    descriptors = jnp.array([[0.1, 0.1], [0.9, 0.2], [0.2, 0.7], [0.6, 0.45], [5.0, -3.0], [jnp.nan, 0.0]])
    assert nearest(centroids, descriptors).tolist() == [0, 1, 2, 1, 1, 0]


def test_centroids_are_kmeans_of_uniform_samples_fixed_by_the_seed():
    cvt = Cvt(50, (-1.0, 0.0), (1.0, 4.0), samples=5000, seed=3)
    centroids = cvt.centroids
    assert centroids.shape == (50, 2) and centroids.dtype == np.float32
    assert (centroids >= [-1.0, 0.0]).all() and (centroids <= [1.0, 4.0]).all()
    np.testing.assert_array_equal(centroids, Cvt(50, (-1.0, 0.0), (1.0, 4.0), samples=5000, seed=3).centroids)
    assert not np.array_equal(centroids, Cvt(50, (-1.0, 0.0), (1.0, 4.0), samples=5000, seed=4).centroids)
    # k-means spreads the cells: new uniform points fill every cell, none with more than 3x its share
    points = np.random.default_rng(0).uniform([-1.0, 0.0], [1.0, 4.0], size=(20000, 2))
    counts = np.bincount(np.asarray(cvt.cell_index(jnp.asarray(points))), minlength=50)
    assert counts.min() > 0 and counts.max() < 3 * 20000 / 50


def test_insertion_keeps_the_best_elite_per_centroid():
    cvt = Cvt(3, (0.0, 0.0), (1.0, 1.0), samples=3, seed=0)  # one sample per cell: the centroids are the samples
    centroids = cvt.centroids
    archive = qa.insert(
        qa.empty(cvt, 1),
        cvt,
        jnp.array([[1.0], [2.0], [3.0]]),
        jnp.array([1.0, 2.0, 0.5]),
        jnp.asarray(centroids[[2, 2, 0]] + 1e-3),
    )
    assert np.asarray(archive.filled).tolist() == [True, False, True]
    assert float(archive.genotypes[2, 0]) == 2.0 and float(archive.genotypes[0, 0]) == 3.0
    assert float(qa.metrics(archive)["archive-occupancy"]) == pytest.approx(2 / 3)
    assert qa.chosen_cell(archive, cvt, "best") == 2 and qa.chosen_cell(archive, cvt, "0") == 0
    for spec, fragment in [("1", "holds no elite"), ("3", "outside the archive's CVT cells (0..2)"), ("1,2", "index")]:
        with pytest.raises(ValueError, match=re.escape(fragment)):
            qa.chosen_cell(archive, cvt, spec)
    image = heatmap(cvt, archive.fitness, archive.filled, "cvt", ("x", "y"))
    assert image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8


@pytest.mark.parametrize(
    ("cells", "low", "high", "samples", "fragment"),
    [
        (10, (0.0,), (1.0,), 5, "cvt_samples=5 is below algo.archive.cells=10"),
        (10, (1.0,), (0.0,), 100, "low must be below high"),
        (10, (0.0, 0.0), (1.0,), 100, "one entry per descriptor"),
    ],
)
def test_bad_cvt_settings_name_the_fix(cells, low, high, samples, fragment):
    with pytest.raises(ValueError, match=re.escape(fragment)):
        Cvt(cells, low, high, samples)
