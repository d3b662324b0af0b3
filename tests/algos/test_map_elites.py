"""MAP-Elites in rlq's loop on CartPole (linear policies): archive rules over real updates, a
learning threshold, resume, `rlq eval`'s QD metrics, and the config checks."""

import json
from dataclasses import replace

import numpy as np
import pytest

from rlq.algos import algo_settings, map_elites
from rlq.errors import ConfigError
from rlq.run.checks.validate import check_run_config
from tests.helpers import (
    compose_config,
    run_cli_in_process,
    run_dirs,
    stopped_at,
    train_run,
    updates_that_only_improve_elites,
)


@pytest.mark.slow  # four updates of a 32-candidate batch, checked one by one (about 20 s of CPU): the full suite
def test_elites_only_improve_and_coverage_never_drops():
    cfg = compose_config("algo=map_elites", "algo.episodes=1", "algo.batch_size=32", "algo.variation=iso_line")
    state, metrics = updates_that_only_improve_elites(cfg, 4)
    fitness = np.asarray(state.archive.fitness)
    assert float(metrics["archive-occupancy"]) == pytest.approx(np.isfinite(fitness).mean())
    assert int(metrics["evaluations"]) == 4 * 32
    assert 0 < float(metrics["archive-occupancy"]) < 1


@pytest.mark.slow
def test_map_elites_finds_balancing_policies_across_the_archive(tmp_path):
    """Learning threshold: a fifth of the 20 x 20 archive filled, an elite scoring 500 on its 4 episodes
    that also balances on fresh episodes."""
    result = train_run(
        tmp_path, "algo=map_elites", "algo.episodes=4", "budget.env_steps=4000000", "num_seeds=2", "video.at_end=false"
    )
    assert result.final_eval["maximum-fitness"].min() == 500.0
    assert result.final_eval["archive-occupancy"].min() >= 0.2
    assert result.eval_return.min() >= 400.0  # 32 fresh episodes of the 4-episode elite (424, 475 seen)


@pytest.mark.slow
def test_run_writes_heatmaps_and_eval_reports_qd_metrics(workdir):
    proc = run_cli_in_process(
        "train",
        "algo=map_elites",
        "algo.episodes=1",  # conf/tuned/cartpole_map_elites.yaml scores each offspring over 16
        "algo.batch_size=16",
        "algo.heatmap_every=2",
        "budget.env_steps=32000",  # 4 iterations of 16 x 500 steps
        "log_every_steps=8000",
        "eval.episodes=2",
        "video.at_end=false",
        "logger=quiet",
        cwd=workdir,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "archive coverage" in proc.stdout.splitlines()[-1]
    (run_dir,) = run_dirs(workdir)
    pngs = sorted(p.name for p in (run_dir / "figures").glob("*.png"))
    # 4 iterations, a heatmap every 2: after the second (named by its true env steps), then the final one
    assert len(pngs) == 2 and pngs[0] == "heatmap_seed0_final.png" and pngs[1].startswith("heatmap_seed0_step_")
    rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    train_rows = [r for r in rows if r["kind"] == "train" and r["seed"] == 0]
    assert all("qd-score" in r and "archive-occupancy" in r for r in train_rows)
    proc = run_cli_in_process("eval", f"run={run_dir}", "episodes=2", cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    final = [r for r in rows if r["kind"] == "eval" and r["seed"] == 0][-1]
    assert f"archive-occupancy {final['archive-occupancy']:.4g}" in proc.stdout
    report = json.loads((run_dir / "eval_cartpole.json").read_text())
    assert report["state_metrics"]["qd-score"] == [pytest.approx(final["qd-score"], rel=1e-6)]
    for cell in ("best", "furthest"):
        proc = run_cli_in_process("render", f"run={run_dir}", f"cell={cell}", cwd=workdir)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert f"elite of cell {cell}" in proc.stdout
        assert (run_dir / "videos" / f"final_seed0_cell_{cell}_episode0.mp4").stat().st_size > 1000
    proc = run_cli_in_process("render", f"run={run_dir}", "cell=99,0", cwd=workdir)
    assert proc.returncode == 2 and "outside the archive's grid (0..19, 0..19)" in proc.stderr


@pytest.mark.parametrize(
    ("overrides", "fragment"),
    [
        (["algo.fitness=energy"], "algo.fitness=energy needs an env that reports 'energy'"),
        (["algo.descriptor=final_xy"], "algo.descriptor=final_xy is not reported by this env"),
        (["algo.descriptor=landing"], "algo.descriptor=landing is not reported by this env; it reports last_obs"),
        (["algo.descriptor_dims=[0,1,2]"], "has 3 dimensions but algo.archive.shape has 2"),
        (
            ["algo.descriptor_dims=[0,9]"],
            "algo.descriptor_dims=[0,9]: algo.descriptor=last_obs has 4 components (the observation's size), "
            "so 9 is out of range; give indices in 0..3",
        ),
        (["algo.descriptor_dims=[2,2]"], "algo.descriptor_dims=[2,2] names component 2 twice; give distinct"),
        (["algo.descriptor_dims=[-1,2]"], "algo.descriptor_dims must be null or a list of integers >= 0"),
        (["algo.archive.low=[1.0,1.0]", "algo.archive.high=[0.0,0.0]"], "archive low must be below high"),
        (["algo.variation=crossover"], "algo.variation must be one of gaussian, iso_line"),
        (["algo.genotype=action"], "algo.genotype=action needs a bounded Box action space"),
        (["algo.batch_size=0"], "algo.batch_size must be an integer >= 1"),
    ],
)
def test_bad_configs_name_the_fix(overrides, fragment):
    with pytest.raises(ConfigError, match=None) as err:
        check_run_config(compose_config("algo=map_elites", *overrides))
    assert fragment in str(err.value)


def test_descriptor_dims_are_distinct_components_of_the_descriptor():
    cfg = algo_settings(compose_config("algo=map_elites").algo)
    assert map_elites.check_descriptor_dims(cfg, 4) is None
    cfg = replace(cfg, descriptor_dims=(0, 4))
    assert "has 4 components (the observation's size), so 4 is out of range" in map_elites.check_descriptor_dims(cfg, 4)
    cfg = replace(cfg, descriptor="landing", descriptor_dims=(1, 0))
    assert map_elites.check_descriptor_dims(cfg, 2) is None
    cfg = replace(cfg, descriptor_dims=(1, 1))
    assert "names component 1 twice" in map_elites.check_descriptor_dims(cfg, 2)
    cfg = replace(cfg, descriptor_dims=None)
    assert map_elites.check_descriptor_dims(cfg, 2) is None


@pytest.mark.parametrize("preset", ["lunar_map_elites", "brittle_star_map_elites", "brittle_star_random_search"])
def test_presets_validate(preset):
    check_run_config(compose_config(f"experiment={preset}"))


@pytest.mark.slow
def test_resume_continues_the_archive_exactly(workdir, tmp_path):

    from rlq.store import checkpoint

    args = [
        "algo=map_elites",
        "algo.episodes=1",  # conf/tuned/cartpole_map_elites.yaml scores each offspring over 16
        "algo.batch_size=16",
        "budget.env_steps=32000",
        "log_every_steps=8000",
        "checkpoint.every_steps=1",  # a checkpoint after every chunk but the last
        "eval.episodes=2",
        "video.at_end=false",
        "logger=quiet",
    ]
    proc = run_cli_in_process("train", *args, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    stopped = stopped_at(run_dir, tmp_path, -1)  # resume from an archive two iterations before the end
    proc = run_cli_in_process("resume", f"run={stopped}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    resumed = checkpoint.leaves(stopped / "checkpoints/final.msgpack")
    original = checkpoint.leaves(run_dir / "checkpoints/final.msgpack")
    for a, b in zip(resumed, original, strict=True):
        np.testing.assert_array_equal(a, b)
