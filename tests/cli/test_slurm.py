"""The SLURM path: the sweep goes through submitit (hydra-submitit-launcher's local executor in CI, the
same code path as hydra/launcher=slurm bar the scheduler), the slurm preset composes, and without the
plugin the error says which extra to install."""

import csv
import sys

import pytest

from rlq.cli.main import main
from tests.cli.test_sweep import JOBS, SWEEP_TINY
from tests.helpers import run_cli

pytestmark = pytest.mark.slow


def test_a_2x2_sweep_through_submitit_local_writes_its_summary(workdir):
    proc = run_cli(
        "train", "-m", "hydra/launcher=submitit_local", "hydra.launcher.gpus_per_node=0",
        "algo=dqn,ppo", "seed=0,1", *SWEEP_TINY, cwd=workdir,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    (sweep_dir,) = (workdir / "multirun").glob("*/*")
    with open(sweep_dir / "sweep_summary.csv") as file:
        table = list(csv.DictReader(file))
    assert {r["run"] for r in table} == JOBS
    assert all(float(r["eval/return"]) >= 1 for r in table)
    assert list((sweep_dir / ".submitit").iterdir()), "the jobs did not go through submitit"


def test_the_slurm_preset_composes(workdir):
    proc = run_cli("train", "hydra/launcher=slurm", "--cfg", "hydra", cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "hydra_plugins.hydra_submitit_launcher.submitit_launcher.SlurmLauncher" in proc.stdout
    assert "gpus_per_node: 1" in proc.stdout


def test_without_the_plugin_the_error_names_the_extra(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "hydra_plugins.hydra_submitit_launcher", None)
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "-m", "hydra/launcher=slurm", "seed=0,1"])
    assert exit_info.value.code == 2
    assert 'pip install -e ".[slurm]"' in capsys.readouterr().err


def test_without_slurm_commands_the_error_says_where_to_run(monkeypatch, capsys):
    monkeypatch.setattr("rlq.tools.sweep.shutil.which", lambda command: None)
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "-m", "hydra/launcher=slurm", "seed=0,1"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "whose sbatch and srun this machine's PATH does not have" in err
    assert "hydra/launcher=submitit_local" in err
