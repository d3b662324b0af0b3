"""A run directory's saved config, read back for `rlq eval`, `render`, `resume`: options added to
rlq since the run was trained come in at their defaults; the run's own choices stay."""

import pytest
from omegaconf import OmegaConf

from rlq.tools.evaluate import load_run_config
from tests.helpers import compose_config


def test_an_older_run_config_gets_the_new_run_level_options_at_their_defaults(tmp_path):
    cfg = compose_config("env=lunar", "algo=dqn", "return_window=7", "seed=4")
    saved = OmegaConf.to_container(cfg)
    for newer in ("program_cache", "compile_cache", "stop"):
        del saved[newer]
    del saved["video"]["every_steps"]
    (tmp_path / ".hydra").mkdir()
    OmegaConf.save(OmegaConf.create(saved), tmp_path / ".hydra" / "config.yaml")

    loaded = load_run_config(tmp_path)
    assert loaded.compilation.program_cache == "auto" and loaded.compilation.compile_cache == "user"
    assert loaded.budget.stop_when is None and loaded.outputs.video.every_steps == 0
    assert loaded.training.return_window == 7 and loaded.seeds.seed == 4
    assert loaded.config.env == cfg.env and loaded.config.algo == cfg.algo


def test_an_older_run_config_gets_the_new_options_of_its_env_and_algo_at_their_defaults(tmp_path):
    cfg = compose_config("experiment=lunar_ppo_gpu", "seed=3")
    saved = OmegaConf.to_container(cfg)
    del saved["env"]["solver"]["sweep_layout"]
    del saved["algo"]["recompute_gae"]
    (tmp_path / ".hydra").mkdir()
    OmegaConf.save(OmegaConf.create(saved), tmp_path / ".hydra" / "config.yaml")

    loaded = load_run_config(tmp_path)
    assert loaded.env["solver"]["sweep_layout"] == "auto" and loaded.algorithm["recompute_gae"] is False
    assert loaded.env["solver"]["velocity_iterations"] == 30 and loaded.algorithm["num_envs"] == 8192  # the preset's
    assert loaded.config.env == cfg.env and loaded.config.algo == cfg.algo and loaded.seeds.seed == 3


@pytest.mark.slow  # composes every preset (6 s)
def test_a_preset_names_its_run_directory_unless_the_user_does():
    """Two presets of one env and algorithm (lunar_ppo, lunar_ppo_gpu) leave directories that tell them apart."""
    from rlq.config.conf_dir import CONF_DIR

    presets = sorted((CONF_DIR / "experiment").glob("*.yaml"))
    assert len(presets) > 10
    for path in presets:
        assert compose_config(f"experiment={path.stem}").run_name == path.stem, path.name
    assert compose_config("env=lunar", "algo=ppo").run_name == "lunar-ppo"
    assert compose_config("experiment=lunar_ppo_gpu", "run_name=mine").run_name == "mine"
