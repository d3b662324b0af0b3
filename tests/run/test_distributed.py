"""One `rlq train` run over two processes (JAX's multi-process runtime, CPU devices talking through
gloo) gives the numbers of the same run in one process on as many devices, and only process 0
writes the run directory. Each process forces 2 CPU devices; the single process forces 4."""

from __future__ import annotations

import glob
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rlq.errors import ConfigError
from rlq.run.programs.distributed import settings
from rlq.store import checkpoint
from rlq.tools.evaluate import load_run_config
from tests.helpers import REPO, compose_config, run_cli
from tests.run.sharded_runs import FAST_COMPILE
from tests.run.test_devices import assert_same_rows, assert_same_state, metric_rows

pytestmark = pytest.mark.slow

TRAIN = (
    "env=cartpole",
    "algo=ppo",
    "num_seeds=4",
    "algo.num_envs=8",
    "algo.num_steps=32",
    "algo.hidden=[16]",
    "budget.env_steps=512",
    "log_every_steps=256",
    "checkpoint.every_steps=256",  # a periodic checkpoint: its host copy gathers across the processes too
    "eval.episodes=4",
    "video.at_end=false",
    "logger=quiet",
    "compile_cache=null",
)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def launch(
    run_dir: Path,
    devices: int,
    tmp: Path,
    *overrides: str,
    resume: bool = False,
    slurm: dict[str, str] | None = None,
    module: str = "rlq.cli",
) -> subprocess.Popen:
    """``rlq train`` (``rlq resume``) in a process of its own (``slurm``: as srun starts a task; ``module``: the
    one ``python -m`` runs); its stdout and stderr go to files in ``tmp``'s parent (a pipe nobody drains while
    the test waits on another process could fill and stall a collective)."""
    tmp.mkdir(parents=True, exist_ok=True)
    name = tmp.parent / tmp.name
    env = {
        **os.environ,
        "XLA_FLAGS": f"{FAST_COMPILE} --xla_force_host_platform_device_count={devices}",
        "JAX_PLATFORMS": "cpu",
        "WANDB_MODE": "disabled",
        "TMPDIR": str(tmp),  # a follower's scratch run directory goes here
        **(slurm or {}),
    }
    command = ["resume", f"run={run_dir}"] if resume else ["train", *TRAIN, f"hydra.run.dir={run_dir}", *overrides]
    with name.with_suffix(".out").open("w") as stdout, name.with_suffix(".err").open("w") as stderr:
        return subprocess.Popen(
            [sys.executable, "-m", module, *command],
            cwd=REPO,
            env=env,
            stdout=stdout,
            stderr=stderr,
        )


def finish(out: Path, procs: dict[str, subprocess.Popen], tmp: dict[str, str]) -> None:
    for name, proc in procs.items():
        proc.wait(timeout=300)
        assert proc.returncode == 0, (name, (out / f"{tmp[name]}.err").read_text()[-3000:])


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("distributed")
    address = f"127.0.0.1:{free_port()}"
    joined = ("distributed.num_processes=2", f"distributed.coordinator_address={address}")
    procs = {
        "process1": launch(out / "two", 2, out / "tmp1", *joined, "distributed.process_id=1"),
        "process0": launch(out / "two", 2, out / "tmp0", *joined, "distributed.process_id=0"),
        "one": launch(out / "one", 4, out / "tmp"),
    }
    finish(out, procs, {"process1": "tmp1", "process0": "tmp0", "one": "tmp"})
    return out


def test_two_processes_train_as_one_process_on_as_many_devices(runs):
    assert_same_rows(metric_rows(runs / "two"), metric_rows(runs / "one"))
    for name in ("step_256", "final"):
        assert_same_state(runs / f"two/checkpoints/{name}.msgpack", runs / f"one/checkpoints/{name}.msgpack")


def test_only_process_0_writes_the_run_and_prints_its_line(runs):
    def files(run_dir: Path) -> set[str]:
        return {p.relative_to(run_dir).as_posix() for p in run_dir.rglob("*")}

    assert files(runs / "two") == files(runs / "one")
    assert list((runs / "tmp1").iterdir()) == []  # the follower's scratch run directory is gone
    assert "final greedy eval return" in (runs / "tmp0.out").read_text()
    assert "final greedy eval return" not in (runs / "tmp1.out").read_text()
    assert json.loads((runs / "two/summary.json").read_text())["env_steps"] == 512


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (
            ["distributed.num_processes=2", "distributed.process_id=2", "distributed.coordinator_address=h:1"],
            "distributed.process_id=2 must be below distributed.num_processes=2",
        ),
        (
            ["distributed.num_processes=0"],
            "distributed.num_processes must be null (read from SLURM) or an integer >= 1",
        ),
        (["distributed.enabled=maybe"], "distributed.enabled must be one of auto, true, false, got 'maybe'"),
        (["distributed.enabled=1"], "distributed.enabled must be one of auto, true, false, got 1"),
        (["distributed.process_id=-1"], "distributed.process_id must be null (read from SLURM) or an integer >= 0"),
        (["distributed.timeout_s=0"], "distributed.timeout_s must be an integer >= 1, got 0"),
        (["distributed.coordinator_address=node1"], "distributed.coordinator_address must be host:port"),
        (["distributed.num_processes=2"], "outside SLURM give distributed.coordinator_address"),
        (["distributed.enabled=true"], "outside SLURM give distributed.coordinator_address"),
    ],
)
def test_bad_distributed_settings_are_config_errors(overrides, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        settings(compose_config(*overrides).distributed, environ={})


def test_auto_joins_processes_only_where_srun_started_several():
    cfg = compose_config().distributed
    assert not settings(cfg, environ={}).enabled
    assert not settings(cfg, environ={"SLURM_JOB_ID": "7", "SLURM_STEP_NUM_TASKS": "1"}).enabled
    assert settings(cfg, environ={"SLURM_JOB_ID": "7", "SLURM_STEP_NUM_TASKS": "8"}).enabled
    assert not settings(
        compose_config("distributed.enabled=false").distributed, environ={"SLURM_STEP_NUM_TASKS": "8"}
    ).enabled


def srun_task(index: int, port: int) -> dict[str, str]:
    """The variables srun gives task ``index`` of a two-task step on this machine (JAX reads them)."""
    return {
        "SLURM_JOB_ID": "58",
        "SLURM_STEP_NODELIST": "127.0.0.1",
        "SLURM_NTASKS": "2",
        "SLURM_STEP_NUM_TASKS": "2",
        "SLURM_PROCID": str(index),
        "SLURM_LOCALID": str(index),
        "JAX_COORDINATOR_PORT": str(port),
    }


def stopped_copy(runs: Path, name: str) -> Path:
    """The two-process run as if its job had stopped after its intermediate checkpoint."""
    stopped = runs / name
    shutil.copytree(runs / "two", stopped)
    for path in (stopped / "checkpoints").glob("final.*"):
        path.unlink()
    return stopped


def test_a_run_of_two_processes_resumes_on_two(runs):
    """`rlq resume` takes its processes from srun's variables, not from the run's record."""
    stopped = stopped_copy(runs, "resumed")
    port = free_port()
    procs = {
        "task1": launch(stopped, 2, runs / "task1", resume=True, slurm=srun_task(1, port)),
        "task0": launch(stopped, 2, runs / "task0", resume=True, slurm=srun_task(0, port)),
    }
    finish(runs, procs, {name: name for name in procs})
    assert json.loads((stopped / "summary.json").read_text())["resumed_from_env_steps"] == 256
    assert_same_state(stopped / "checkpoints/final.msgpack", runs / "one/checkpoints/final.msgpack")
    assert_same_rows(metric_rows(stopped), metric_rows(runs / "one"))
    assert list((runs / "task1").iterdir()) == []


def test_a_stop_of_one_process_during_an_evaluation_ends_both_and_resume_goes_on(tmp_path):
    """Process 0's SIGTERM during the evaluation after the first chunk, which never ends on its own: neither
    process waits for it (each wait ends as the first process to claim it says, rlq.run.stops.waiting.Agreed), the
    checkpoint after the chunk is saved with the evaluation skipped, and a resume on two processes makes it."""
    run_dir, address = tmp_path / "run", f"127.0.0.1:{free_port()}"
    joined = ("distributed.num_processes=2", f"distributed.coordinator_address={address}", "eval.every_steps=256")
    procs = {
        "tmp1": launch(run_dir, 2, tmp_path / "tmp1", *joined, "distributed.process_id=1"),
        "tmp0": launch(
            run_dir, 2, tmp_path / "tmp0", *joined, "distributed.process_id=0", module="tests.run.stop_in_evaluation"
        ),
    }
    for name, proc in procs.items():
        proc.wait(timeout=300)  # an evaluation waited for in full never ends
        err = (tmp_path / f"{name}.err").read_text()
        assert proc.returncode == 128 + signal.SIGTERM, (name, err[-3000:])
        assert "stopped by SIGTERM at env step 256, skipping its evaluation" in err, (name, err[-3000:])
    saved = run_dir / "checkpoints" / "step_256.msgpack"
    assert checkpoint.meta(saved)["eval_skipped"] is True
    assert not (run_dir / "checkpoints" / "final.msgpack").exists()

    port = free_port()
    procs = {
        name: launch(run_dir, 2, tmp_path / name, resume=True, slurm=srun_task(index, port))
        for index, name in ((1, "task1"), (0, "task0"))
    }
    finish(tmp_path, procs, {name: name for name in procs})
    assert json.loads((run_dir / "summary.json").read_text())["resumed_from_env_steps"] == 256
    assert ("eval", 256) in {(row["kind"], row["env_steps"]) for row in metric_rows(run_dir)}


def test_a_stop_of_one_process_before_training_ends_both_with_their_line(tmp_path):
    """Process 0's SIGTERM while the programs compile: both processes end with the line that nothing was saved
    (process 1 reads the stop in JAX's coordination service), and neither is aborted by JAX for the other's end."""
    run_dir, address = tmp_path / "run", f"127.0.0.1:{free_port()}"
    joined = ("distributed.num_processes=2", f"distributed.coordinator_address={address}")
    procs = {
        "tmp1": launch(run_dir, 2, tmp_path / "tmp1", *joined, "distributed.process_id=1"),
        "tmp0": launch(run_dir, 2, tmp_path / "tmp0", *joined, "distributed.process_id=0"),
    }
    logs = [run_dir / "metrics.jsonl", tmp_path / "tmp1" / "rlq-process1-*" / "metrics.jsonl"]
    deadline = time.monotonic() + 300  # each process's log is opened once its signal handlers are in place
    while not all(glob.glob(str(log)) for log in logs) and time.monotonic() < deadline:
        assert all(proc.poll() is None for proc in procs.values())
        time.sleep(0.05)
    procs["tmp0"].send_signal(signal.SIGTERM)
    for name, proc in procs.items():
        proc.wait(timeout=120)
        err = (tmp_path / f"{name}.err").read_text()
        assert proc.returncode == 128 + signal.SIGTERM, (name, err[-3000:])
        assert "rlq: stopped by SIGTERM before training began: nothing to save" in err, (name, err[-3000:])


def test_the_record_of_a_run_of_two_processes_rebuilds_in_one(runs):
    """Its processes' settings (coordinator, process ids) are the training's, not the reader's: `rlq eval`,
    `render` and a resume on one process (tests/run/test_devices.py resumes 4 devices' checkpoint on 1) ignore them."""
    distributed = load_run_config(runs / "two").devices.distributed
    assert distributed["num_processes"] == 2 and distributed["process_id"] == 0


def test_a_sweep_does_not_join_processes(tmp_path):
    joined = ["distributed.num_processes=2", "distributed.process_id=0", "distributed.coordinator_address=h:1"]
    proc = run_cli("train", "-m", "seed=0,1", *joined, cwd=tmp_path, timeout=120)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "distributed: a sweep's jobs run in one process each" in proc.stderr


@pytest.mark.parametrize(
    "process_id, line",
    [
        ("0", "process 0 waited 2 s (distributed.timeout_s) at {address} for process 1 of 2, which did not all join"),
        ("1", "process 1 waited 2 s (distributed.timeout_s) for process 0 at {address}, which did not answer"),
    ],
    ids=["coordinator alone", "follower alone"],
)
def test_a_missing_process_is_named_after_the_timeout(process_id, line, tmp_path):
    """A run of two processes started alone: one line naming who is missing, exit 2, no run directory."""
    address = f"127.0.0.1:{free_port()}"
    run_dir = tmp_path / "run"
    overrides = [f"distributed.{k}={v}" for k, v in (("num_processes", 2), ("process_id", process_id))]
    proc = run_cli(
        "train",
        "distributed.enabled=true",
        f"distributed.coordinator_address={address}",
        "distributed.timeout_s=2",
        *overrides,
        f"hydra.run.dir={run_dir}",
        cwd=tmp_path,
        env={"JAX_PLATFORMS": "cpu"},
    )
    assert proc.returncode == 2, proc.stderr[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"rlq: error: distributed: {line.format(address=address)}"), lines
    assert not run_dir.exists()
