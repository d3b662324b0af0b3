"""What `rlq train` says: no "snaps to" note for a default cadence nobody set (one for a cadence the command
set), one `[eval @ N steps]` line where `stop.when` ends a run at an evaluation, and none of MuJoCo's, MJX's
or brax's noise (filtered by the CLI, the dependencies untouched)."""

import json
import subprocess
import sys

import pytest

from rlq.run.programs.cadences import Cadences
from tests.helpers import REPO, run_cli, run_dirs

pytestmark = pytest.mark.slow

MJX_PLACES_A_MODEL = """
import logging, sys, warnings
if sys.argv[1] == "quiet":
    from rlq.cli.quiet import quiet_dependencies
    quiet_dependencies()
logging.basicConfig(level=logging.INFO, format="%(message)s")
import mujoco
from mujoco import mjx
mjx.put_model(mujoco.MjModel.from_xml_string("<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>"))
warnings.warn("Brax System, piplines and environments are not actively being maintained. Please see MJX", UserWarning)
print("placed")
"""


def test_defaults_snap_quietly_and_a_stopped_run_evaluates_once(tmp_path):
    proc = run_cli(
        "train",
        "budget.env_steps=300000",
        "checkpoint.every_steps=30000",  # set by the command, and missed by the chunks (23,040 env steps)
        'stop.when="eval/return>=1"',
        "eval.episodes=2",
        "video.at_end=false",
        "logger.wandb.mode=disabled",
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    console = proc.stdout + proc.stderr
    assert "log_every_steps=" not in console and "eval.every_steps=" not in console  # defaults nobody set
    assert "checkpoint.every_steps=30000 snaps to 23,040" in console
    assert console.count("[eval @ 92,160 steps]") == 1 and "stop.when eval/return>=1 met at 92,160" in console
    (run_dir,) = run_dirs(tmp_path)
    rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    assert [r["env_steps"] for r in rows if r["kind"] == "eval" and r["seed"] == "mean"] == [92160]
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["env_steps"] == 92160 and summary["eval_return_mean"] == rows[-1]["return"]


def test_only_the_cadences_asked_for_get_a_note():
    cadences = Cadences(log=25_000, eval=100_000, checkpoint=30_000)
    notes = cadences.snap_notes(23_040, 300_000, asked={"checkpoint.every_steps", "seed"})
    assert notes == ["checkpoint.every_steps=30000 snaps to 23,040 (every 1 chunk of 23,040 env steps)"]
    assert len(cadences.snap_notes(23_040, 300_000)) == 3  # outside a Hydra job every cadence counts as asked


def test_mjx_and_brax_noise_is_filtered(tmp_path):
    fake = tmp_path / "warp"  # a warp that fails to import, as on a machine without MuJoCo Warp
    fake.mkdir()
    (fake / "__init__.py").write_text("raise ImportError('no warp here')\n")
    env = {"PYTHONPATH": f"{tmp_path}:{REPO}", "PATH": "/usr/bin:/bin"}

    def run(mode: str) -> str:
        proc = subprocess.run(
            [sys.executable, "-c", MJX_PLACES_A_MODEL, mode], env=env, capture_output=True, text=True, timeout=300
        )
        assert proc.returncode == 0 and "placed" in proc.stdout, proc.stderr[-3000:]
        return proc.stdout + proc.stderr

    loud = run("loud")  # what the dependencies print unfiltered
    assert "Failed to import warp" in loud and "Using JAX default device" in loud and "Brax System" in loud
    quiet = run("quiet")
    assert "Failed to import" not in quiet and "Using JAX default device" not in quiet and "Brax System" not in quiet
