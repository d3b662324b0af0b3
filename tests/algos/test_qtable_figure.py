"""The tabular Q-table picture: the drawing itself, and its PNGs at each evaluation of a run."""

import numpy as np
import pytest

from rlq.algos.qtable_figure import greedy_marks, qtable_image
from tests.helpers import train_run


def red_runs(image: np.ndarray) -> list[float]:
    """Mean row of each horizontal run of columns holding marker red, left to right."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    red = (r > 200) & (g < 60) & (b < 60)
    columns = np.flatnonzero(red.any(axis=0))
    runs = np.split(columns, np.flatnonzero(np.diff(columns) > 1) + 1)
    return [float(np.mean(np.nonzero(red[:, run])[0])) for run in runs]


def test_qtable_image_marks_the_greedy_action_of_each_visited_state():
    table = np.array([[3.0, 1.0, 0.0], [0.0, 1.0, 2.0], [0.0, 5.0, 1.0], [9.0, 0.0, 0.0]])
    visits = np.array([[1, 0, 0], [2, 1, 1], [0, 4, 0], [0, 0, 0]])  # state 3 never visited
    states, actions = greedy_marks(table, visits)
    np.testing.assert_array_equal(states, [0, 1, 2])
    np.testing.assert_array_equal(actions, [0, 2, 1])
    image = qtable_image(table, visits)
    assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3 and image.shape[1] > image.shape[0]
    rows = red_runs(image)
    assert len(rows) == 3  # one mark per visited state, none for state 3
    # action 0 at the bottom (largest row index), action 2 at the top
    assert rows[0] > rows[2] > rows[1]


@pytest.mark.slow  # a CLI run with its figures (5 s)
def test_cartpole_qlearning_draws_the_qtable_at_each_evaluation(tmp_path):
    train_run(
        tmp_path,
        "experiment=cartpole_qlearning",
        "budget.env_steps=8192",
        "log_every_steps=2048",
        "eval.every_steps=4096",
        "eval.episodes=2",
        "video.at_end=false",
    )
    names = sorted(p.name for p in (tmp_path / "figures").glob("*.png"))
    assert names == ["qtable_seed0_final.png", "qtable_seed0_step_4096.png"]
