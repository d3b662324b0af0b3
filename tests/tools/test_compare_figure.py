"""`rlq compare` of a short 4-seed run (its final evaluation only): the figure has a line per seed and a band (an
error bar at the single x value), the legend sits outside the axes, and without out= the files land beside the
compared runs, not in the working directory."""

import os

import numpy as np
import pytest
from matplotlib.collections import LineCollection, PolyCollection

from rlq.tools.compare import compare, draw
from tests.helpers import run_cli, run_dirs
from tests.tools.test_compare import make_run


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    workdir = tmp_path_factory.mktemp("short4")
    overrides = ["num_seeds=4", "budget.env_steps=1024", "eval.every_steps=0", "eval.episodes=2", "logger=quiet"]
    proc = run_cli("train", *overrides, "video.at_end=false", cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    return run_dir


@pytest.mark.slow  # 10-20 s on 2 cores: the full suite runs it
def test_a_short_four_seed_run_draws_each_seed_and_a_band(short_run):
    result = compare([short_run])
    (curves,) = result.groups.values()
    assert len(curves) == 4 and all(len(curve.x) == 1 for curve in curves)  # the final evaluation alone
    figure = draw(result)
    (axes,) = figure.axes
    seeds = [line for line in axes.get_lines() if line.get_gid() == "seed"]
    assert len(seeds) == 4 and all(line.get_marker() not in (None, "None", "") for line in seeds)  # visible points
    ys = sorted(float(line.get_ydata()[0]) for line in seeds)
    assert ys == sorted(float(curve.y[-1]) for curve in curves)
    bands = [c for c in axes.collections if c.get_gid() == "band" or isinstance(c, LineCollection)]
    assert bands, "no band"
    segments = [seg for c in bands if isinstance(c, LineCollection) for seg in c.get_segments()]
    spread = np.std(ys)
    assert any(np.isclose(abs(seg[1][1] - seg[0][1]), 2 * spread) for seg in segments)  # mean ± std at that x
    figure.canvas.draw()
    legend = axes.get_legend()
    assert legend.get_window_extent().x0 >= axes.get_window_extent().x1  # beside the plot, not over it


def test_longer_curves_get_a_filled_band(tmp_path):
    run = make_run(tmp_path / "r", ["seed=0"], {0: [1.0, 3.0, 5.0], 1: [3.0, 5.0, 9.0]}, num_seeds=2)
    (axes,) = draw(compare([run], out=tmp_path / "x")).axes
    assert [c for c in axes.collections if isinstance(c, PolyCollection) and c.get_gid() == "band"]
    assert len([line for line in axes.get_lines() if line.get_gid() == "seed"]) == 2


def test_without_out_the_files_land_beside_the_compared_runs(tmp_path):
    runs = tmp_path / "outputs" / "day"
    a = make_run(runs / "a", ["algo=dqn"], {0: [1.0, 2.0]})
    b = make_run(runs / "b", ["algo=ppo"], {0: [3.0, 4.0]})
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    cwd = os.getcwd()
    os.chdir(elsewhere)
    try:
        result = compare([a, b])
    finally:
        os.chdir(cwd)
    assert result.png == runs.resolve() / "compare_eval_return.png" and result.png.exists()
    assert not list(elsewhere.iterdir())


def test_a_single_evaluation_is_drawn_on_an_axis_from_zero(tmp_path):
    run = make_run(tmp_path / "r", ["seed=0"], {0: [1.0], 1: [3.0]}, num_seeds=2)
    result = compare([run], out=tmp_path / "x")
    (axes,) = draw(result).axes
    (x,) = {float(curve.x[0]) for curves in result.groups.values() for curve in curves}
    low, high = axes.get_xlim()
    assert low == 0 and x < high <= 1.05 * x + 1e-9  # not a window of ±4 % around the one x
    assert "small points: each seed" in axes.get_title()
