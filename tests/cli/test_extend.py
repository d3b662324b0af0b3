"""Extending runs: `rlq resume run=<dir> budget.env_steps=N` trains a finished run on to a larger budget (only
budget keys may change), and `rlq train ... init_from=<run dir>[:checkpoint]` starts a new run from a trained
run's policy parameters. The commands run through rlq's entry point in the test process (``run_cli_in_process``)."""

import shutil

import jax
import numpy as np
import pytest
from omegaconf import OmegaConf

from rlq.errors import ConfigError
from rlq.run.programs.build import build
from rlq.run.programs.cadences import Cadences, chunk_plan
from rlq.run.programs.keys import seed_keys
from rlq.store import checkpoint
from rlq.tools.evaluate import restore_run
from rlq.tools.warm_start import check_init_from, parse_init_from, warm_state
from tests.helpers import compose_config, run_cli_in_process, run_dirs

pytestmark = pytest.mark.slow

#: chunks of 1024 env steps whatever the budget, and no learning-rate schedule: an extended run then ends
#: exactly where a run given the larger budget from the start ends
TINY = [
    "log_every_steps=1024",
    "eval.every_steps=0",
    "eval.episodes=2",
    "algo.anneal_lr=false",
    "video.at_end=false",
    "logger.wandb.mode=disabled",
]


def trained(workdir, budget):
    workdir.mkdir(exist_ok=True)
    proc = run_cli_in_process("train", f"budget.env_steps={budget}", *TINY, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    return run_dir


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    return trained(tmp_path_factory.mktemp("short"), 2048)


@pytest.fixture(scope="module")
def longer_run(tmp_path_factory):
    return trained(tmp_path_factory.mktemp("longer"), 4096)


def assert_same_state(extended, longer):
    got = checkpoint.leaves(extended / "checkpoints/final.msgpack")
    want = checkpoint.leaves(longer / "checkpoints/final.msgpack")
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)


def test_a_stopped_run_extended_ends_as_the_longer_run(longer_run, tmp_path):
    workdir = tmp_path / "stopped"
    workdir.mkdir()
    proc = run_cli_in_process("train", "budget.env_steps=2048", "checkpoint.every_steps=1024", *TINY, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (stopped,) = run_dirs(workdir)
    for path in (stopped / "checkpoints").glob("final.*"):
        path.unlink()  # as if it had been stopped after its first chunk
    proc = run_cli_in_process("resume", f"run={stopped}", "budget.env_steps=4096", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "from step_1024" in proc.stdout and "4,096 env steps (resumed at 1,024)" in proc.stdout
    assert_same_state(stopped, longer_run)


def test_a_finished_run_extended_ends_as_the_longer_run(short_run, longer_run, tmp_path):
    extended = tmp_path / "extended"
    shutil.copytree(short_run, extended)
    proc = run_cli_in_process("resume", f"run={extended}", "budget.env_steps=4096", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "extending" in proc.stdout and "4,096 env steps (resumed at 2,048)" in proc.stdout
    assert OmegaConf.load(extended / ".hydra/config.yaml").budget.env_steps == 4096
    assert_same_state(extended, longer_run)


def test_an_extension_whose_chunks_differ_ends_at_its_budget(tmp_path):
    """A run of one 2048-step chunk extended to 4096 steps, whose own plan is one 4096-step chunk: the
    extension trains in chunks that divide the steps done, ends at its budget, and is a valid source."""
    workdir = tmp_path / "one_chunk"
    workdir.mkdir()
    plain = [t for t in TINY if not t.startswith("log_every_steps")]
    proc = run_cli_in_process("train", "budget.env_steps=2048", *plain, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    proc = run_cli_in_process("resume", f"run={run_dir}", "budget.env_steps=4096", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "4,096 env steps (resumed at 2,048)" in proc.stdout
    assert checkpoint.env_steps(run_dir / "checkpoints" / "final.msgpack") == 4096
    cfg = compose_config(*TINY, "budget.env_steps=1024", f"init_from={run_dir}")
    check_init_from(cfg)


def test_chunks_of_an_extension_divide_the_updates_done():
    cadences = Cadences(log=25_000, eval=0, checkpoint=0)
    assert chunk_plan(16, 512, cadences) == (16, 1)
    assert chunk_plan(16, 512, cadences, done=8) == (8, 2)
    assert chunk_plan(30, 512, cadences, done=12) == (6, 5)  # none wasted, then the nearest to the cadence


def test_resume_changes_only_the_budget(short_run, tmp_path):
    proc = run_cli_in_process("resume", f"run={short_run}", "algo.lr=1e-3", cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "algo.lr is not a budget key" in proc.stderr and "init_from" in proc.stderr
    proc = run_cli_in_process("resume", f"run={short_run}", "budget.env_steps=1000", cwd=tmp_path)
    assert proc.returncode == 2 and "not beyond the 2,048 env steps" in proc.stderr
    proc = run_cli_in_process("resume", f"run={short_run}", cwd=tmp_path)
    assert proc.returncode == 2 and "budget.env_steps=N" in proc.stderr  # the hint that extends it


def test_init_from_deals_the_trained_policy_to_every_seed(short_run):
    cfg = compose_config(*TINY, "budget.env_steps=1024", "num_seeds=3", f"init_from={short_run}:final")
    check_init_from(cfg)
    programs = build(cfg)
    fresh = jax.device_get(programs.init(seed_keys(cfg.seed, 3), programs.hyper))
    warm = warm_state(cfg, fresh)
    source = jax.device_get(restore_run(short_run, "final")[2])
    for got, want in zip(jax.tree.leaves(warm.params), jax.tree.leaves(source.params), strict=True):
        assert got.shape[0] == 3
        for seed in range(3):
            np.testing.assert_array_equal(got[seed], want[0])
    for got, kept in zip(jax.tree.leaves(warm.opt_state), jax.tree.leaves(fresh.opt_state), strict=True):
        np.testing.assert_array_equal(got, kept)  # the optimiser starts fresh


def test_init_from_refuses_another_algorithm_or_network(short_run):
    with pytest.raises(ConfigError, match="trained algo=ppo, this one is algo=dqn"):
        check_init_from(compose_config("algo=dqn", f"init_from={short_run}"))
    cfg = compose_config(*TINY, "budget.env_steps=1024", "algo.hidden=[8]", f"init_from={short_run}")
    programs = build(cfg)
    fresh = jax.device_get(programs.init(seed_keys(cfg.seed, 1), programs.hyper))
    with pytest.raises(ConfigError, match="does not fit this run's"):
        warm_state(cfg, fresh)
    assert parse_init_from("runs/a:40000") == (parse_init_from("runs/a")[0], "40000")


def test_train_init_from_on_the_command_line(short_run, tmp_path):
    proc = run_cli_in_process("train", "budget.env_steps=1024", *TINY, f"init_from={short_run}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert f"policy from {short_run}/checkpoints/final.msgpack (2,048 env steps)" in proc.stdout
    proc = run_cli_in_process("train", "algo=dqn", f"init_from={tmp_path}", cwd=tmp_path)
    assert proc.returncode == 2 and "not an rlq run directory" in proc.stderr and not run_dirs(tmp_path)[1:]
