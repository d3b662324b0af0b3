"""Sweep helpers: job directory names, the W&B group of a sweep's jobs, the directory-name overrides."""

import pytest
from omegaconf import OmegaConf

from rlq.errors import ConfigError
from rlq.store.logging import ConsoleSink, WandbSink
from rlq.store.record import sweep_group
from rlq.tools.sweep import check_launcher, dirname_overrides, job_dirname
from tests.helpers import compose_config


def test_job_dirnames_are_one_safe_path_component():
    assert job_dirname("algo=dqn,seed=1", 3) == "algo=dqn,seed=1"
    assert job_dirname("env/physics=fast,seed=0", 0) == "env.physics=fast,seed=0"
    assert job_dirname("", 7) == "7"
    long = job_dirname("algo.lr=" + "1" * 400, 0)
    assert len(long.encode()) <= 200 and "/" not in long and long != job_dirname("algo.lr=" + "1" * 401, 0)


def test_a_sweeps_jobs_share_its_wandb_group(tmp_path):
    sweep = tmp_path / "multirun" / "2026-01-02" / "10-20-30"
    (sweep / "algo=dqn,seed=0").mkdir(parents=True)
    (sweep / "multirun.yaml").write_text("{}\n")
    assert sweep_group(sweep / "algo=dqn,seed=0") == "2026-01-02_10-20-30"
    assert sweep_group(tmp_path / "multirun") is None


def test_wandb_runs_of_a_sweep_join_its_group(tmp_path, monkeypatch):
    monkeypatch.setenv("WANDB_SILENT", "true")
    sweep = tmp_path / "multirun" / "2026-01-02" / "10-20-30"
    run_dir = sweep / "algo=ppo,seed=0"
    run_dir.mkdir(parents=True)
    (sweep / "multirun.yaml").write_text("{}\n")
    cfg = compose_config("logger=quiet", "logger.wandb.mode=offline")
    sink = WandbSink(cfg, run_dir, ConsoleSink(1, 1, enabled=False))
    try:
        assert sink._run is not None and sink._run.group == "2026-01-02_10-20-30"
    finally:
        sink.close()
    OmegaConf.update(cfg, "logger.wandb.group", "mine")
    sink = WandbSink(cfg, run_dir, ConsoleSink(1, 1, enabled=False))
    try:
        assert sink._run is not None and sink._run.group == "mine"
    finally:
        sink.close()


def test_only_swept_overrides_name_the_job_directories():
    (override,) = dirname_overrides(["algo=dqn,ppo", "seed=0,1", "budget.env_steps=2000", "hydra/launcher=basic"])
    assert override == "hydra.job.config.override_dirname.exclude_keys=['budget.env_steps']"
    assert dirname_overrides(["algo=dqn,ppo", "seed=0,1"]) == []
    assert dirname_overrides(["algo=dqn"]) == []  # nothing swept: the one job is named by all its overrides


@pytest.mark.parametrize("launcher", ["slurm", "submitit_local"])
def test_a_launcher_without_any_hydra_plugin_installed_is_one_line(launcher, monkeypatch):
    """On a fresh `pip install -e .` no package provides ``hydra_plugins``: finding the submitit plugin must not
    raise ModuleNotFoundError from its parent."""

    def find_spec(name, *args):
        raise ModuleNotFoundError(f"No module named '{name.split('.')[0]}'")

    monkeypatch.setattr("rlq.tools.sweep.importlib.util.find_spec", find_spec)
    with pytest.raises(ConfigError, match=r'needs hydra-submitit-launcher: pip install -e "\.\[slurm\]"'):
        check_launcher(["-m", f"hydra/launcher={launcher}", "seed=0,1"], launching=True)
