"""The brittle star QD preset end to end on CPU, tiny (a few evaluations of 5-step episodes; nearly
all of its minute is MJX compilation): heatmaps in the run dir and in the offline W&B run."""

import json

import pytest

from tests.helpers import run_cli_in_process, run_dirs

pytest.importorskip("biorobot")

pytestmark = pytest.mark.slow

TINY = [
    "env.segments_per_arm=1",
    "env.simulation_time=0.2",  # 5 control steps per episode
    "algo.heatmap_every=1",
    "budget.env_steps=40",
    "video.at_end=false",
    "logger.console=false",
]


@pytest.mark.parametrize("preset", ["brittle_star_map_elites", "brittle_star_random_search"])
def test_preset_writes_metrics_heatmaps_and_a_wandb_run_holding_them(workdir, preset):
    size = "algo.batch_size=4" if preset.endswith("map_elites") else "algo.population=4"
    proc = run_cli_in_process("train", f"experiment={preset}", size, *TINY, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    train = [r for r in rows if r["kind"] == "train" and r["seed"] == 0]
    assert [r["evaluations"] for r in train] == [4, 8]
    for row in train:
        assert 0 < row["archive-occupancy"] <= 8 / 900
        assert -3.75 <= row["minimum-fitness"] <= row["maximum-fitness"] <= 0  # minus the energy
        assert row["qd-score"] >= 0  # qd_offset 3.75 = the actuator force limit
    pngs = sorted(p.name for p in (run_dir / "figures").glob("heatmap_*.png"))
    assert pngs == ["heatmap_seed0_final.png", "heatmap_seed0_step_20.png"]
    (wandb_run,) = (run_dir / "wandb").glob("offline-run-*")
    images = list((wandb_run / "files" / "media" / "images").rglob("*.png"))
    assert len(images) == 2, sorted(p.name for p in images)
    assert all(p.name.startswith("figures_heatmap_seed0_") or "heatmap" in str(p) for p in images)


def test_rotation_emitter_turns_brittle_star_elites_by_whole_arms():
    """Two iterations of algo.emitter=rotation at a negligible sigma: the second batch is the first's elites,
    half of them copied and half turned by whole arms, so every elite is a turn (or copy) of a first elite;
    on a grid of millimetre cells the turned gaits land in cells of their own."""
    import jax
    import numpy as np

    from rlq.algos import make_algo
    from rlq.controllers import oscillators
    from rlq.run.programs.env_stack import make_env
    from tests.helpers import compose_config

    cfg = compose_config(
        "experiment=brittle_star_map_elites",
        "algo.batch_size=8",
        "algo.emitter=rotation",
        "algo.sigma=1e-6",
        *TINY[:2],
        "algo.archive.low=[-0.01,-0.01]",
        "algo.archive.high=[0.01,0.01]",
    )
    algo = make_algo(cfg.algo, make_env(cfg), budget_env_steps=10**9)
    update = jax.jit(lambda s: algo.update(s, algo.hyperparams))
    first, _ = update(jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0)))
    second, metrics = update(first)
    assert int(metrics["evaluations"]) == 16
    elites = np.asarray(first.archive.genotypes)[np.asarray(first.archive.filled)]
    turns = np.concatenate([elites[:, row] for row in oscillators.parametric_rotations(5)])
    gap = lambda genotype, candidates: np.abs(candidates - genotype).max(axis=1).min()  # noqa: E731
    kept = np.asarray(second.archive.genotypes)[np.asarray(second.archive.filled)]
    assert all(gap(genotype, turns) < 1e-4 for genotype in kept)
    assert any(gap(genotype, elites) > 1e-2 for genotype in kept)  # a turned gait, not a copy


def test_es_preset_is_the_tutorials_task_with_the_rotation_and_es_emitters():
    from rlq.run.checks.validate import check_run_config
    from tests.helpers import compose_config

    cfg = compose_config("experiment=brittle_star_map_elites_es")
    tutorial = compose_config("experiment=brittle_star_map_elites")
    check_run_config(cfg)
    for key in ("genotype", "fitness", "descriptor", "archive", "sigma", "episodes", "qd_offset"):
        assert cfg.algo[key] == tutorial.algo[key], key
    assert (cfg.env, cfg.controller, cfg.budget) == (tutorial.env, tutorial.controller, tutorial.budget)
    assert (cfg.algo.emitter, cfg.algo.rotation_fraction) == ("rotation", 0.5)
    assert (cfg.algo.es_fraction, cfg.algo.es_sigma) == (0.5, 0.05)
    assert (cfg.algo.es_objective, cfg.algo.batch_size, tutorial.algo.batch_size) == ("distance", 640, 1280)
