"""A non-editable `pip install .` into a fresh venv, then `rlq train` from another directory: the
configs ship inside the package, and the build leaves nothing untracked in the checkout.

The fresh venv reuses the current environment's dependencies through a path file (plain paths: the
current environment's own path files, e.g. an editable install of rlq, are not processed), and
nothing from this checkout is on its path, so rlq can only come from the installed wheel.
"""

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from tests.helpers import REPO

pytestmark = pytest.mark.slow


def _fresh_venv(root: Path) -> Path:
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(root)], check=True)
    (site,) = (root / "lib").glob("python*/site-packages")
    deps = dict.fromkeys([sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]])
    (site / "_rlq_test_deps.pth").write_text("".join(f"{p}\n" for p in deps))
    return root / "bin"


def _committed(source: Path) -> str | None:
    """Make ``source`` a git checkout with everything in it committed, as a clone is; git's path (None: no git)."""
    git = shutil.which("git")
    if git is None:
        return None
    identity = ["-c", "user.name=rlq", "-c", "user.email=rlq@localhost"]
    for args in (["init", "-q"], ["add", "-A"], [*identity, "commit", "-q", "-m", "checkout"]):
        subprocess.run([git, *args], cwd=source, check=True, capture_output=True)
    return git


def test_non_editable_install_trains_from_another_directory(tmp_path):
    source = tmp_path / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(REPO / "rlq", source / "rlq", ignore=ignore)
    shutil.copytree(REPO / "conf", source / "conf", ignore=ignore)
    for name in ("pyproject.toml", "README.md", ".gitignore"):
        shutil.copy(REPO / name, source / name)
    git = _committed(source)
    bin_dir = _fresh_venv(tmp_path / "venv")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(WANDB_MODE="disabled", PIP_NO_INPUT="1", PIP_DISABLE_PIP_VERSION_CHECK="1")
    install = subprocess.run(
        [str(bin_dir / "python"), "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", str(source)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    assert install.returncode == 0, install.stderr[-3000:]
    if git:  # the build leaves nothing untracked in the checkout (setuptools' build/ and rlq.egg-info/ are ignored)
        status = subprocess.run([git, "status", "--porcelain"], cwd=source, capture_output=True, text=True, check=True)
        assert status.stdout == "", status.stdout
    shutil.rmtree(source)  # nothing of the checkout is left to find the configs in

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    where = subprocess.run(
        [str(bin_dir / "python"), "-c", "import rlq; print(rlq.__file__)"],
        cwd=elsewhere,
        env=env,
        capture_output=True,
        text=True,
    )
    assert where.stdout.startswith(str(tmp_path / "venv")), where.stdout + where.stderr
    train = subprocess.run(
        [str(bin_dir / "rlq"), "train", "budget.env_steps=2048", "log_every_steps=1024"]
        + ["eval.every_steps=0", "eval.episodes=2", "logger=quiet", "video.at_end=false"],
        cwd=elsewhere,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert train.returncode == 0, train.stderr[-3000:]
    assert train.stdout.strip().splitlines()[-1].startswith("rlq: ")
    assert list((elsewhere / "outputs").glob("*/*/summary.json"))
