"""The Q-table as a picture (drawn on the host with matplotlib's Agg backend): states along x,
actions along y, colour = Q(s, a), each visited state's greedy action marked with a red dot;
states never visited are left blank (their values are still the random initial ones)."""

from __future__ import annotations

import numpy as np


def greedy_marks(table: np.ndarray, visits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(states, greedy actions) of the states visited at least once."""
    visited = np.flatnonzero(np.asarray(visits).sum(axis=1) > 0)
    return visited, np.argmax(np.asarray(table)[visited], axis=1)


def qtable_image(table: np.ndarray, visits: np.ndarray, title: str = "") -> np.ndarray:
    """RGB image (H, W, 3) uint8 of a Q-table [num_states, num_actions] and its visit counts."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    table, visits = np.asarray(table, np.float64), np.asarray(visits)
    num_states, num_actions = table.shape
    values = np.where(visits.sum(axis=1, keepdims=True) > 0, table, np.nan)
    width = float(np.clip(2.0 + 0.02 * num_states, 6.0, 16.0))
    fig = Figure(figsize=(width, 1.6 + 0.45 * num_actions), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="white")
    image = ax.imshow(
        np.ma.masked_invalid(values.T),
        origin="lower",
        aspect="auto",
        interpolation="nearest",
        cmap=cmap,
        extent=(-0.5, num_states - 0.5, -0.5, num_actions - 0.5),
    )
    states, actions = greedy_marks(table, visits)
    cell_points = 72.0 * (width - 2.0) / num_states  # a cell's width in points, roughly
    ax.scatter(states, actions, s=float(np.clip(0.5 * cell_points, 3.0, 8.0)) ** 2, c="red", marker="o", lw=0)
    fig.colorbar(image, ax=ax, label="Q(s, a)", pad=0.01)
    ax.set_xlabel(f"state ({num_states}; blank: never visited)")
    ax.set_ylabel("action")
    ax.set_yticks(range(num_actions))
    ax.set_title(title or "Q-table, greedy action marked (red)")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
