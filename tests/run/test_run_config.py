"""A run directory's saved config, read back for `rlq eval`, `render`, `resume`: run-level options
added to rlq since the run was trained come in at their defaults; the run's own choices stay."""

from omegaconf import OmegaConf

from rlq.run.evaluate import load_run_config
from tests.conftest import compose_config


def test_an_older_run_config_gets_the_new_run_level_options_at_their_defaults(tmp_path):
    cfg = compose_config("env=lunar", "algo=dqn", "return_window=7", "seed=4")
    saved = OmegaConf.to_container(cfg)
    for newer in ("program_cache", "compile_cache", "stop"):
        del saved[newer]
    del saved["video"]["every_steps"]
    (tmp_path / ".hydra").mkdir()
    OmegaConf.save(OmegaConf.create(saved), tmp_path / ".hydra" / "config.yaml")

    loaded = load_run_config(tmp_path)
    assert loaded.program_cache == "auto" and loaded.compile_cache == "user" and loaded.stop.when is None
    assert loaded.video.every_steps == 0
    assert loaded.return_window == 7 and loaded.seed == 4
    assert loaded.env == cfg.env and loaded.algo == cfg.algo
