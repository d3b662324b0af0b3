"""The archive's fitness heatmap (descriptor 1 to the right, descriptor 2 up, empty cells blank,
with a colour bar), drawn with matplotlib's Agg backend on the host."""

from __future__ import annotations

import numpy as np

from rlq.algos.qd.archive import Grid


def heatmap(
    grid: Grid, fitness: np.ndarray, filled: np.ndarray, title: str = "", labels: tuple[str, str] = ("x", "y")
) -> np.ndarray:
    """RGB image (H, W, 3) uint8 of a 2-d grid archive's elite fitness."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if grid.num_descriptors != 2:
        raise ValueError(f"a heatmap needs a 2-d archive, this one has {grid.num_descriptors} descriptors")
    values = np.where(np.asarray(filled), np.asarray(fitness, np.float64), np.nan).reshape(grid.shape)
    fig = Figure(figsize=(6.0, 5.0), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    cmap = matplotlib.colormaps["viridis"].copy()
    cmap.set_bad(color="white")
    image = ax.imshow(
        np.ma.masked_invalid(values.T),
        origin="lower",
        extent=(grid.low[0], grid.high[0], grid.low[1], grid.high[1]),
        cmap=cmap,
        aspect="auto",
        interpolation="nearest",
    )
    fig.colorbar(image, ax=ax, label="fitness")
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    if title:
        ax.set_title(title)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
