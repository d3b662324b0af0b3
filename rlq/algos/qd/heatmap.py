"""The archive's fitness heatmap (descriptor 1 to the right, descriptor 2 up, empty cells blank,
with a colour bar), drawn with matplotlib's Agg backend on the host. A CVT archive is drawn as its
centroids, coloured by their elite's fitness (empty cells as small grey dots)."""

from __future__ import annotations

import numpy as np

from rlq.algos.qd.archive import Cells, Grid
from rlq.algos.qd.cvt import Cvt


def heatmap(
    grid: Cells, fitness: np.ndarray, filled: np.ndarray, title: str = "", labels: tuple[str, str] = ("x", "y")
) -> np.ndarray:
    """RGB image (H, W, 3) uint8 of a 2-d archive's elite fitness."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if grid.num_descriptors != 2:
        raise ValueError(f"a heatmap needs a 2-d archive, this one has {grid.num_descriptors} descriptors")
    fig = Figure(figsize=(6.0, 5.0), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="white")
    if isinstance(grid, Cvt):
        image = _centroids(ax, grid, np.asarray(fitness, np.float64), np.asarray(filled, bool), cmap)
    else:
        image = _grid(ax, grid, np.asarray(fitness, np.float64), np.asarray(filled, bool), cmap)
    fig.colorbar(image, ax=ax, label="fitness")
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    if title:
        ax.set_title(title)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _grid(ax, grid: Grid, fitness: np.ndarray, filled: np.ndarray, cmap):
    values = np.where(filled, fitness, np.nan).reshape(grid.shape)
    return ax.imshow(
        np.ma.masked_invalid(values.T),
        origin="lower",
        extent=(grid.low[0], grid.high[0], grid.low[1], grid.high[1]),
        cmap=cmap,
        aspect="auto",
        interpolation="nearest",
    )


def _centroids(ax, cvt: Cvt, fitness: np.ndarray, filled: np.ndarray, cmap):
    points = cvt.centroids
    ax.scatter(points[~filled, 0], points[~filled, 1], s=2, c="lightgrey")
    image = ax.scatter(points[filled, 0], points[filled, 1], s=12, c=fitness[filled], cmap=cmap)
    ax.set_xlim(cvt.low[0], cvt.high[0])
    ax.set_ylim(cvt.low[1], cvt.high[1])
    return image
