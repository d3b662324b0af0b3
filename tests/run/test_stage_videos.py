"""Videos at training stages (video.every_steps): in the run directory and in the offline W&B run;
`rlq render checkpoint=<step>` for a kept checkpoint."""

import hashlib
import re

import pytest
from omegaconf import OmegaConf

from rlq.cli.main import main
from tests.helpers import compose_config, train_run

STAGES = (1024, 2048, 3072)  # the last chunk (4096) has the final video instead


def md5(path):
    return hashlib.md5(path.read_bytes()).hexdigest()


OVERRIDES = (
    "logger.wandb.mode=offline",
    "budget.env_steps=4096",
    "log_every_steps=1024",
    "eval.every_steps=0",
    "eval.episodes=2",
    "video.every_steps=1024",
    "checkpoint.every_steps=2048",
    "video.at_end=true",  # asked for: a default final video is skipped where it costs over 10 % of a CPU run
)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("stages")
    train_run(run_dir, *OVERRIDES)
    (run_dir / ".hydra").mkdir()  # the config `rlq train` saves, which `rlq render` reads
    OmegaConf.save(compose_config("logger=quiet", *OVERRIDES), run_dir / ".hydra" / "config.yaml")
    return run_dir


@pytest.mark.slow
def test_one_video_per_stage_in_the_run_and_in_the_offline_wandb_run(run_dir):
    videos = {p.name for p in (run_dir / "videos").glob("*.mp4")}
    assert videos == {f"step_{n}_seed0.mp4" for n in STAGES} | {"final_seed0.mp4"}
    (wandb_run,) = (run_dir / "wandb").glob("offline-run-*")
    logged = {}
    for path in (wandb_run / "files" / "media" / "videos" / "videos").glob("seed0_*.mp4"):
        step = int(re.match(r"seed0_(\d+)_", path.name).group(1))
        logged[step] = md5(path)
    assert logged == {
        **{n: md5(run_dir / "videos" / f"step_{n}_seed0.mp4") for n in STAGES},
        4096: md5(run_dir / "videos" / "final_seed0.mp4"),
    }


@pytest.mark.slow
def test_render_a_kept_checkpoint(run_dir, capsys):
    main(["render", f"run={run_dir}", "checkpoint=2048"])
    video = run_dir / "videos" / "step_2048_seed0_episode0.mp4"
    assert capsys.readouterr().out.strip() == f"rlq render: {video}"
    assert video.stat().st_size > 1000
    with pytest.raises(SystemExit) as stop:
        main(["render", f"run={run_dir}", "checkpoint=1000"])
    assert stop.value.code == 2
    assert capsys.readouterr().err.strip() == (
        f"rlq: error: no checkpoint step_1000.msgpack in {run_dir / 'checkpoints'}; kept: 2048, final "
        "(checkpoint=<env steps>, checkpoint=final or checkpoint=kept)"
    )


@pytest.mark.slow  # a whole run with its video (6 s)
def test_the_video_env_is_built_after_the_final_video_s_rendering_line(tmp_path, monkeypatch):
    """A run's video env (an MJX model's build takes seconds) is built neither between the programs'
    compile and the first chunk (the console's "compiling" line and the summary's compile_s then span
    the same) nor before the final video's "rendering" line (its time is the video's, not the
    evaluation's)."""
    import rlq.run.videos
    import rlq.store.logging

    events = []
    make_env, phase = rlq.run.videos.make_env, rlq.store.logging.ConsoleSink.phase

    def building(cfg, autoreset):
        events.append("video env")
        return make_env(cfg, autoreset)

    def phase_line(self, name):
        events.append(name)
        phase(self, name)

    monkeypatch.setattr(rlq.run.videos, "make_env", building)
    monkeypatch.setattr(rlq.store.logging.ConsoleSink, "phase", phase_line)
    train_run(
        tmp_path,
        "budget.env_steps=2048",
        "log_every_steps=1024",
        "eval.every_steps=0",
        "eval.episodes=2",
        "video.at_end=true",
    )
    assert events == ["compiling", "evaluating", "rendering", "video env"]
    assert (tmp_path / "videos" / "final_seed0.mp4").stat().st_size > 1000


@pytest.mark.slow
def test_a_video_prepared_while_training_steps_the_episode_the_jit_program_steps(tmp_path):
    """``prepare_soon`` (on an accelerator, while the run trains) compiles the episode program ahead;
    the video then runs that program, with the same result as the program compiled at the video."""
    from types import SimpleNamespace

    import jax
    import numpy as np

    import rlq.run.videos
    from rlq.lib.batch import seed_entry
    from rlq.run.programs.build import build
    from rlq.run.programs.keys import seed_keys
    from rlq.store.logging import ConsoleSink

    cfg = compose_config("logger=quiet", "num_seeds=2")
    programs = build(cfg)
    state = programs.init(seed_keys(cfg.seed, 2), programs.hyper)
    logger = SimpleNamespace(console=ConsoleSink(1, 1, enabled=False), video=lambda *args: None)
    video = rlq.run.videos.Seed0Video(cfg, programs.algo, tmp_path, logger, programs.env)
    video.prepare_soon(jax.eval_shape(lambda: state), jax.devices()[0])
    assert isinstance(video._prepared.result(timeout=120), jax.stages.Compiled)
    seed0 = seed_entry(state, 0, 2)
    ahead, at_video = video._episode(seed0), video.program(seed0, video.key)
    assert video._prepared is not None  # the prepared program took the state (no fallback to the jit one)
    jax.tree.map(np.testing.assert_array_equal, ahead, at_video)
    assert video(state, 0, "final_seed0").stat().st_size > 1000
