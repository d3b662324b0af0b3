"""The CLI end to end, as a user runs it: a run directory, bad inputs, eval of a checkpoint. The installed command's
exit path and --help run as processes of their own (``run_cli``); the other commands run through rlq's entry point
in the test process (``run_cli_in_process``: the same exit codes and output, without a cold start each)."""

import json
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from tests.helpers import run_cli, run_cli_in_process, run_dirs

pytestmark = pytest.mark.slow

TINY = ["budget.env_steps=4096", "log_every_steps=2048", "eval.episodes=4"]


@pytest.fixture(scope="module")
def default_run(tmp_path_factory) -> tuple[Path, str]:
    workdir = tmp_path_factory.mktemp("cli")
    proc = run_cli_in_process("train", *TINY, "num_seeds=2", cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    return run_dir, proc.stdout


def test_train_leaves_a_complete_run_dir(default_run):
    run_dir, stdout = default_run
    assert (run_dir / ".hydra" / "config.yaml").exists()
    assert (run_dir / "checkpoints" / "final.msgpack").exists()
    assert list((run_dir / "wandb").glob("offline-run-*")), "no offline W&B run"
    # a final video would cost over 10 % of this short CPU run: skipped with one line (tests/run/test_final_video.py)
    assert not (run_dir / "videos").exists()
    assert (run_dir / "rlq.log").read_text().count("rlq: no final video: about") == 1
    assert json.loads((run_dir / "summary.json").read_text())["num_seeds"] == 2
    rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    assert {r["seed"] for r in rows} == {0, 1, "mean"}
    assert any(r["kind"] == "eval" and r["seed"] == "mean" for r in rows)
    summary = stdout.strip().splitlines()[-1]
    assert summary.startswith("rlq: ") and "env steps" in summary and "final greedy eval return" in summary


def test_eval_command_reads_the_checkpoint(default_run):
    run_dir, _ = default_run
    proc = run_cli_in_process("eval", f"run={run_dir}", "episodes=3", cwd=run_dir.parent)
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads((run_dir / "eval_cartpole.json").read_text())
    assert len(result["per_seed_return"]) == 2
    assert all(1 <= r <= 500 for r in result["per_seed_return"])
    assert [len(seed) for seed in result["episode_returns"]] == [3, 3]
    assert np.allclose([np.mean(seed) for seed in result["episode_returns"]], result["per_seed_return"])


def test_eval_records_the_env_overrides_it_evaluated_with(default_run):
    run_dir, _ = default_run
    proc = run_cli_in_process(
        "eval", f"run={run_dir}", "episodes=2", "seed=3", "env.max_episode_steps=20", cwd=run_dir.parent
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads((run_dir / "eval_cartpole.json").read_text())
    assert result["env_overrides"] == ["env.max_episode_steps=20"] and result["seed"] == 3
    assert all(r <= 20 for r in result["per_seed_return"])


def test_eval_on_an_env_with_other_spaces_names_both(default_run):
    run_dir, _ = default_run
    proc = run_cli_in_process("eval", f"run={run_dir}", "env=lunar", cwd=run_dir.parent)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "rlq: error: env=lunar gives observations of shape (8,) and actions Discrete(4); this run's policy was "
        "trained on env=cartpole: observations of shape (4,) and actions Discrete(2); choose an env with them "
        "(or leave env=lunar out)"
    ]


def test_eval_in_a_read_only_run_dir_prints_its_result_and_says_what_it_could_not_write(
    default_run, monkeypatch, capsys
):
    from rlq.cli.main import main

    run_dir, _ = default_run
    import rlq.cli.eval

    write_atomic = rlq.cli.eval.write_atomic

    def read_only(path: Path, data: bytes) -> None:
        if path.name.startswith("eval_"):
            raise OSError(30, "Read-only file system", str(path))
        write_atomic(path, data)

    monkeypatch.setattr(rlq.cli.eval, "write_atomic", read_only)
    main(["eval", f"run={run_dir}", "episodes=2", "seed=5"])
    out, err = capsys.readouterr()
    assert "mean greedy return" in out and "->" not in out
    assert f"rlq: warning: {run_dir / 'eval_cartpole.json'} could not be written (Read-only file system)" in err


def test_render_command_writes_a_video(default_run):
    import imageio_ffmpeg

    run_dir, _ = default_run
    out = run_dir / "videos" / "seed1.mp4"
    proc = run_cli_in_process("render", f"run={run_dir}", "seed_index=1", f"out={out}", cwd=run_dir.parent)
    assert proc.returncode == 0, proc.stderr[-3000:]
    frames = imageio_ffmpeg.read_frames(str(out))
    meta = next(frames)
    assert meta["size"] == (600, 400)
    assert sum(1 for _ in frames) >= 2


def test_bad_input_exits_2_with_one_line(workdir):
    """The installed command's exit path (the full table of bad inputs: tests/cli/test_bad_inputs.py)."""
    proc = run_cli("train", "algo.gamma=1.5", cwd=workdir)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == ["rlq: error: algo.gamma must be a number in [0, 1], got 1.5"]
    assert not (workdir / "outputs").exists()


def test_a_run_on_another_device_kind_than_its_preset_starts_with_a_warning(workdir):
    proc = run_cli_in_process(
        "train",
        *TINY,
        "logger=quiet",
        "video.at_end=false",
        "shaped_for.platform=gpu",
        "shaped_for.note='on a CPU use experiment=cartpole_ppo'",
        cwd=workdir,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    warning = (
        "rlq: warning: this config is shaped for a gpu (shaped_for.platform) and runs on the cpu here, "
        "which is slow; on a CPU use experiment=cartpole_ppo"
    )
    assert warning in proc.stderr.splitlines(), proc.stderr[-3000:]


def test_a_budget_below_one_update_and_a_run_started_over_are_said_at_the_start(workdir):
    died = workdir / "died"  # a run killed before its first checkpoint: rlq train starts it over in place
    died.mkdir()
    (died / "metrics.jsonl").write_text('{"kind": "train", "seed": 0, "env_steps": 737280}\n')
    diverged = "rlq: error: training diverged: params_norm is NaN/Inf at env step 5,000 (seed 0)"
    (died / "rlq.log").write_text(diverged + "\n")  # the earlier attempt's record is kept, the new run's appended
    proc = run_cli_in_process(
        "train", "budget.env_steps=100", "eval.episodes=2", "video.at_end=false", f"hydra.run.dir={died}", cwd=workdir
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stderr.splitlines()
    assert "rlq: budget.env_steps=100 is below one update (512 env steps per seed): the run takes one update" in lines
    assert f"rlq: {died} held a run that stopped before its first checkpoint: it starts over" in lines
    assert "512 env steps" in proc.stdout.strip().splitlines()[-1]
    assert "737280" not in (died / "metrics.jsonl").read_text()
    log = (died / "rlq.log").read_text().splitlines()
    assert log[0] == diverged and "it starts over" in "\n".join(log[1:])


def test_float_notation_for_integer_budget_is_accepted(workdir):
    proc = run_cli_in_process(
        "train", "budget.env_steps=2.048e3", "log_every_steps=1024", "eval.episodes=2", "logger=quiet", cwd=workdir
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "2,048 env steps" in proc.stdout
    (run_dir,) = run_dirs(workdir)  # the record holds the override as the run used it (Hydra composed the rewrite)
    assert OmegaConf.to_container(OmegaConf.load(run_dir / ".hydra" / "overrides.yaml"))[0] == "budget.env_steps=2048"


def test_help_and_print_config(workdir):
    assert run_cli("--help", cwd=workdir).returncode == 0
    proc = run_cli_in_process("train", "--cfg", "job", "algo=ppo", cwd=workdir)
    assert proc.returncode == 0 and "num_seeds" in proc.stdout
    proc = run_cli_in_process("train", "--cfg", "job", "--package", "algo.lr", "env=lunar", "algo.lr=3e-4", cwd=workdir)
    assert proc.returncode == 0 and proc.stdout.strip() == "0.0003", proc.stderr
