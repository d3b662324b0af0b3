"""The final video (``video.at_end``): a single run's by default, unless on a CPU it would cost over 10 % of the run
(skipped with one line); none in a sweep's job unless asked; always when asked."""

from pathlib import Path

import pytest

from rlq.run.videos import VIDEO_SHARE, cpu_video_skip, video_estimate_s, wants_final_video
from tests.helpers import run_cli, train_run

TINY = ["budget.env_steps=2048", "log_every_steps=1024", "eval.every_steps=0", "eval.episodes=2"]


def test_a_sweep_job_renders_none_unless_asked():
    assert wants_final_video(None, sweep_job=False) and not wants_final_video(None, sweep_job=True)
    assert wants_final_video(True, sweep_job=True) and not wants_final_video(False, sweep_job=False)


def test_the_estimate_and_the_ten_percent_rule():
    estimate = video_estimate_s(compile_s=4.0, frames=500, draws_on_host_gl=False)
    assert estimate == 2.0 + 500 * 0.004
    assert video_estimate_s(4.0, 500, draws_on_host_gl=True) > estimate  # MuJoCo frames are drawn with OpenGL
    assert cpu_video_skip(4.0, 4.0 / VIDEO_SHARE, Path("run")) is None  # 10 % of the run: rendered
    line = cpu_video_skip(4.0, 20.0, Path("run"))
    assert line is not None and "about 4 s" in line and "20 s" in line and "video.at_end=true" in line


@pytest.mark.slow  # two runs, one encoding a video
def test_a_short_cpu_run_skips_its_default_video_with_one_line(tmp_path):
    train_run(tmp_path, *TINY)
    assert not (tmp_path / "videos").exists()
    log = (tmp_path / "rlq.log").read_text()
    assert log.count("rlq: no final video: about") == 1 and f"rlq render run={tmp_path}" in log
    asked = tmp_path / "asked"
    asked.mkdir()
    train_run(asked, *TINY, "video.at_end=true")
    assert (asked / "videos" / "final_seed0.mp4").stat().st_size > 1000


@pytest.mark.slow
def test_a_sweep_job_writes_no_video_and_says_nothing_of_it(tmp_path):
    proc = run_cli("train", "-m", "seed=0,1", *TINY, "logger=quiet", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (sweep_dir,) = (tmp_path / "multirun").glob("*/*")
    jobs = [p for p in sweep_dir.iterdir() if (p / "summary.json").exists()]
    assert len(jobs) == 2 and not any((job / "videos").exists() for job in jobs)
    assert "no final video" not in proc.stdout + proc.stderr
