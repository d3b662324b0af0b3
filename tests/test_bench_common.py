"""scripts/bench_common.py: what a result file says of the code that made it."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import shutil
import subprocess
from pathlib import Path

from tests.helpers import script_module

SCRIPT = Path(__file__).parents[1] / "scripts" / "bench_common.py"


def git(cwd: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True, text=True).stdout.strip()


def test_the_commit_says_modified_when_tracked_files_differ_from_it(tmp_path) -> None:
    """A copy of a tree can carry an older commit's .git beside newer files: the result must not name that commit."""
    scripts = tmp_path / "scripts"
    scripts.mkdir()
    shutil.copy(SCRIPT, scripts / "bench_common.py")
    git(tmp_path, "init", "-q")
    git(tmp_path, "add", ".")
    git(tmp_path, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "one")
    spec = importlib.util.spec_from_file_location("copied_bench_common", scripts / "bench_common.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    head = git(tmp_path, "rev-parse", "--short", "HEAD")
    assert module.rlq_commit() == head
    (tmp_path / "untracked.txt").write_text("an untracked file is not code the result ran\n")
    assert module.rlq_commit() == head
    with open(scripts / "bench_common.py", "a") as f:
        f.write("\n# changed\n")
    assert module.rlq_commit() == f"{head}+modified"


def test_a_result_names_the_versions_that_decide_its_physics() -> None:
    """warp-lang's version (None: absent) says whether env.mjx_impl=auto could step MJX envs on MuJoCo Warp."""
    with script_module("bench_common") as module:
        found = module.package_versions()
    assert set(found) == {"jax", "jaxlib", "mujoco-mjx", "warp-lang"}
    assert found["jax"] == importlib.metadata.version("jax")
