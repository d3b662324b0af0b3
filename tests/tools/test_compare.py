"""rlq.tools.compare on hand-made run directories: grouping by distinguishing overrides (seed left out),
seeds of num_seeds>1 runs and of seed= runs as curves of one band, the band's figures, the table."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from rlq.errors import RunDirError, UsageError
from rlq.store.runs import find_runs, load_run
from rlq.tools.compare import band, compare, draw, stats_label, summary_lines


def make_run(path: Path, overrides: list[str], returns: dict[int, list[float]], num_seeds: int = 1) -> Path:
    """A run directory as `rlq train` leaves it: eval rows of each seed at 100, 200, ... env steps."""
    (path / ".hydra").mkdir(parents=True)
    OmegaConf.save(
        OmegaConf.create({"seed": 0, "num_seeds": num_seeds, "run_name": "cartpole-ppo"}), path / ".hydra/config.yaml"
    )
    OmegaConf.save(OmegaConf.create(overrides), path / ".hydra/overrides.yaml")
    OmegaConf.save(
        OmegaConf.create({"hydra": {"runtime": {"choices": {"algo": "ppo", "env": "cartpole"}}}}),
        path / ".hydra/hydra.yaml",
    )
    rows = []
    for step in range(len(next(iter(returns.values())))):
        for seed, values in returns.items():
            rows.append(
                {
                    "kind": "eval",
                    "env_steps": 100 * (step + 1),
                    "seed": seed,
                    "return": values[step],
                    "wall_s": 1.5 * (step + 1) + seed,
                }
            )
        rows.append(
            {
                "kind": "eval",
                "env_steps": 100 * (step + 1),
                "seed": "mean",
                "return": float(np.mean([v[step] for v in returns.values()])),
            }
        )
    (path / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return path


def test_seed_runs_and_num_seeds_runs_make_one_band_per_config(tmp_path):
    sweep = tmp_path / "sweep"
    make_run(sweep / "a", ["algo=dqn", "seed=0"], {0: [1.0, 3.0]})
    make_run(sweep / "b", ["algo=dqn", "seed=1"], {0: [3.0, 5.0]})
    make_run(sweep / "c", ["algo=ppo", "seed=0"], {0: [10.0, 20.0], 1: [30.0, 40.0], 2: [20.0, 30.0]}, num_seeds=3)
    result = compare([sweep])
    assert {label: len(curves) for label, curves in result.groups.items()} == {"algo=dqn": 2, "algo=ppo": 3}
    grid, mean, std = band(result.groups["algo=dqn"])
    np.testing.assert_allclose(grid, [100, 200])
    np.testing.assert_allclose(mean, [2.0, 4.0])
    np.testing.assert_allclose(std, [1.0, 1.0])
    assert result.png == sweep / "compare_eval_return.png" and result.png.stat().st_size > 5000
    with open(result.csv) as file:
        table = list(csv.DictReader(file))
    assert [(r["run"], r["algo"], r["seed"], r["eval/return"]) for r in table] == [
        ("a", "dqn", "0", "3.0"),
        ("b", "dqn", "1", "5.0"),
        ("c", "ppo", "0", "30.0"),  # the mean over its three seeds' final returns
    ]
    assert float(table[2]["eval/return std"]) == pytest.approx(np.std([20.0, 40.0, 30.0]))


def test_a_key_one_run_leaves_at_its_default_still_distinguishes(tmp_path):
    make_run(tmp_path / "a", [], {0: [1.0]})
    make_run(tmp_path / "b", ["algo=dqn"], {0: [2.0]})
    result = compare([tmp_path / "a", tmp_path / "b"], out=tmp_path / "out" / "cmp")
    assert set(result.groups) == {"algo=ppo", "algo=dqn"}
    assert result.png == tmp_path / "out" / "cmp.png" and result.csv.exists()


def test_wall_time_curves_are_averaged_where_they_overlap(tmp_path):
    make_run(tmp_path / "a", ["seed=0"], {0: [1.0, 2.0, 3.0], 1: [3.0, 4.0, 5.0]}, num_seeds=2)
    result = compare([tmp_path / "a"], x="wall_s")
    (curves,) = result.groups.values()
    grid, mean, _ = band(curves)
    assert grid[0] == 2.5 and grid[-1] == 4.5  # seed 1's first wall time, seed 0's last
    assert np.all(np.diff(grid) > 0) and len(mean) == len(grid)


def test_bad_input_is_a_typed_error(tmp_path):
    make_run(tmp_path / "a", [], {0: [1.0]})
    with pytest.raises(UsageError, match="eval/return"):
        compare([tmp_path / "a"], metric="train/episode_return")
    with pytest.raises(UsageError, match="x="):
        compare([tmp_path / "a"], x="time")
    with pytest.raises(RunDirError, match="no rlq run"):
        find_runs([tmp_path / "a" / ".hydra"])
    assert load_run(tmp_path / "a").value("algo") == "ppo"


def test_the_table_wall_time_is_the_one_the_run_ended_with(tmp_path):
    """wall_s in the table (and a sweep's sweep_summary.csv) is the figure of the run's closing line
    (summary.json: the final evaluation, checkpoint and video included); a run still going has its last
    row's."""
    ended = make_run(tmp_path / "a", [], {0: [1.0, 2.0]})
    make_run(tmp_path / "b", ["seed=1"], {0: [1.0, 2.0]})
    (ended / "summary.json").write_text(json.dumps({"wall_s": 9.25, "env_steps": 200}))
    with open(compare([tmp_path]).csv) as file:
        table = {row["run"]: row for row in csv.DictReader(file)}
    assert float(table["a"]["wall_s"]) == 9.25
    assert float(table["b"]["wall_s"]) == 3.0  # its last row's


def test_each_group_reports_its_iqm_interval_and_seeds_over_a_threshold(tmp_path):
    finals = [500.0, 500.0, 143.0, 480.0, 490.0, 500.0, 208.0, 499.0]
    make_run(tmp_path / "a", ["algo=dqn"], {seed: [10.0, v] for seed, v in enumerate(finals)}, num_seeds=8)
    make_run(tmp_path / "b", ["algo=ppo"], {0: [5.0, 500.0], 1: [6.0, 470.0]}, num_seeds=2)
    result = compare([tmp_path], threshold=475.0)
    dqn, ppo = result.stats["algo=dqn"], result.stats["algo=ppo"]
    assert dqn.iqm == pytest.approx(np.mean(sorted(finals)[2:6])) and dqn.iqm_low <= dqn.iqm <= dqn.iqm_high
    assert (dqn.over, dqn.n, ppo.over, ppo.n) == (6, 8, 1, 2)
    lines = summary_lines(result)
    assert "IQM [95 % CI]" in lines[0] and "seeds ≥ 475" in lines[0]
    assert "6/8 (75%)" in lines[1] and f"{dqn.iqm:.4g} [{dqn.iqm_low:.4g}, {dqn.iqm_high:.4g}]" in lines[1]
    assert "1/2 (50%)" in lines[2]
    axes = draw(result).axes[0]
    iqms = [c for c in axes.containers if c.get_label().startswith("algo=")]
    assert [c.get_label() for c in iqms] == [f"algo=dqn: {stats_label(dqn)}", f"algo=ppo: {stats_label(ppo)}"]
    assert float(iqms[0].lines[0].get_ydata()[0]) == pytest.approx(dqn.iqm)
    assert any(line.get_gid() == "threshold" and line.get_ydata()[0] == 475.0 for line in axes.get_lines())


def test_without_a_threshold_no_seeds_are_counted_and_a_bad_one_is_refused(tmp_path):
    make_run(tmp_path / "a", [], {0: [1.0], 1: [3.0]}, num_seeds=2)
    result = compare([tmp_path / "a"])
    (stats,) = result.stats.values()
    assert stats.over is None and stats.iqm == 2.0
    assert "seeds ≥" not in summary_lines(result)[0]
    with pytest.raises(UsageError, match="threshold=inf"):
        compare([tmp_path / "a"], threshold=float("inf"))
