"""JAX's persistent compilation cache: on by default in the user's cache dir, movable, switchable off."""

import os
from pathlib import Path

import pytest

from rlq.run.programs.compile_cache import cache_dir
from tests.helpers import run_cli, run_dirs


def test_cache_dir_defaults_to_the_user_cache_and_can_move_or_be_off(tmp_path):
    assert cache_dir("user", {"XDG_CACHE_HOME": str(tmp_path)}) == tmp_path / "rlq" / "jax"
    assert cache_dir("user", {"HOME": str(tmp_path)}) == tmp_path / ".cache" / "rlq" / "jax"
    assert cache_dir(str(tmp_path / "c"), {}) == tmp_path / "c"
    assert cache_dir(None, {}) is None and cache_dir(False, {}) is None


def test_the_test_suite_keeps_the_cache_out_of_home():
    assert not str(cache_dir("user")).startswith(str(Path.home() / ".cache"))


def test_the_test_suite_s_own_programs_share_the_cache_its_runs_use():
    """tests/conftest.py names compile_cache=user's directory for JAX before JAX starts (so before this module can be
    imported to ask for it): a run inside a test then neither moves JAX's cache nor resets it."""
    assert os.environ["JAX_COMPILATION_CACHE_DIR"] == str(cache_dir("user"))


@pytest.mark.slow
def test_a_run_fills_the_cache_dir_and_off_leaves_none(workdir):
    tiny = ("budget.env_steps=1024", "log_every_steps=1024", "eval.episodes=2", "video.at_end=false", "logger=quiet")
    env = {"JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0", "XDG_CACHE_HOME": str(workdir / "xdg")}
    proc = run_cli("train", *tiny, f"compile_cache={workdir / 'jax'}", cwd=workdir, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert any((workdir / "jax").iterdir())
    proc = run_cli("train", *tiny, "compile_cache=false", cwd=workdir, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert len(run_dirs(workdir)) == 2 and not (workdir / "xdg" / "rlq").exists()
