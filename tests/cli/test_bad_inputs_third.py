"""A third table of bad inputs and faults (docs/reliability.md, "Outputs, torn files and advice"), held to
tests/cli/test_bad_inputs.py's rule: one line, exit 2, no traceback, nothing compiled, nothing left behind. Output
paths that are no regular file (a device, a FIFO, a symlink to elsewhere) or a run inside another run; damaged
metrics and summaries; refusals whose advice must fit the case."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import pytest

from rlq.cli.main import main
from tests.cli.test_bad_inputs import check_bad_input, make_run, run_dir_case
from tests.helpers import refuse_to_train

EVAL_ROWS = "".join(
    json.dumps({"kind": "eval", "env_steps": 4096, "seed": seed, "return": 20.0}) + "\n" for seed in (0, "mean")
)


def fifo(name: str):
    """A FIFO ``name`` in the run directory (a path rlq would write)."""
    return lambda run_dir: os.mkfifo(run_dir / name)


def beside(make):
    """``make`` applied to the test's directory (the run's parent) instead of the run."""
    return lambda run_dir: make(run_dir.parent)


def symlink_elsewhere(name: str):
    def make(root: Path) -> None:
        (root / "elsewhere").mkdir()
        (root / "elsewhere" / "precious").write_text("keep")
        (root / name).symlink_to(root / "elsewhere" / "precious")

    return make


def write(name: str, text: str):
    return lambda run_dir: (run_dir / name).write_text(text)


def both(*mutations):
    def mutate(run_dir: Path) -> None:
        for mutation in mutations:
            mutation(run_dir)

    return mutate


def foreign_files(root: Path) -> None:
    (root / "home").mkdir()
    (root / "home" / "thesis.tex").write_text("mine")


def sweep_dir(files: dict[str, str]):
    """A `rlq train -m` sweep's directory holding ``files`` (name -> text)."""

    def make(root: Path) -> Path:
        (root / "sweep").mkdir()
        for name, text in files.items():
            (root / "sweep" / name).write_text(text)
        return root / "sweep"

    return make


MULTIRUN = {"multirun.yaml": "hydra:\n  overrides:\n    task: [seed=0,1]\n"}


DAMAGED = "is damaged (line 2 is not JSON: Expecting value); restore it from a copy, or move it away"

#: (argv with {run} / {tmp} placeholders, how to make {run}, a fragment of the error line)
CASES = [
    # outputs: a device, a FIFO, a symlink to elsewhere, a directory
    (["export", "run={run}", "out=/dev/null"], run_dir_case(), "out=/dev/null is a character device, not a regular"),
    (["export", "run={run}", "out=/dev/full"], run_dir_case(), "out=/dev/full is a character device"),
    (["export", "run={run}", "out={tmp}/pipe"], run_dir_case(beside(lambda r: os.mkfifo(r / "pipe"))), "is a FIFO"),
    (["export", "run={run}", "out={tmp}/p.msgpack"], run_dir_case(beside(lambda r: os.mkfifo(r / "p.json"))), "p.json"),
    (["export", "run={run}", "out={tmp}/link"], run_dir_case(beside(symlink_elsewhere("link"))), "link is a symlink"),
    (["eval", "run={run}"], run_dir_case(fifo("eval_cartpole.json")), "eval_cartpole.json is a FIFO, not a regular"),
    (["eval", "run={run}", "env=lunar"], run_dir_case(fifo("eval_lunar.json")), "eval_lunar.json is a FIFO"),
    (["render", "run={run}", "out=/dev/null"], run_dir_case(), "out=/dev/null is a character device"),
    (["render", "run={run}", "out={tmp}/v.mp4"], run_dir_case(beside(lambda r: os.mkfifo(r / "v.npz"))), "v.npz is a"),
    (["render", "run={run}", "out={tmp}/link"], run_dir_case(beside(symlink_elsewhere("link"))), "link is a symlink"),
    (
        ["compare", "{run}", "out={tmp}/cmp"],
        run_dir_case(both(write("metrics.jsonl", EVAL_ROWS), beside(lambda r: os.mkfifo(r / "cmp.png")))),
        "out={tmp}/cmp.png is a FIFO",
    ),
    (
        ["compare", "{run}", "out={tmp}/cmp"],
        run_dir_case(both(write("metrics.jsonl", EVAL_ROWS), beside(symlink_elsewhere("cmp.csv")))),
        "out={tmp}/cmp.csv is a symlink",
    ),
    # a run directory that is no directory, not rlq's, or inside another run
    (["train", "hydra.run.dir=/dev/null"], None, "hydra.run.dir=/dev/null is a character device; give a directory"),
    (["train", "hydra.run.dir={tmp}/pipe"], run_dir_case(beside(lambda r: os.mkfifo(r / "pipe"))), "is a FIFO; give"),
    (["train", "hydra.run.dir={tmp}/link"], run_dir_case(beside(symlink_elsewhere("link"))), "link is a symlink"),
    (["train", "hydra.run.dir={tmp}/home"], run_dir_case(beside(foreign_files)), "holds files rlq did not write"),
    (["train", "hydra.run.dir={run}/checkpoints"], run_dir_case(), "checkpoints is inside the run {run}; runs do not"),
    (["train", "hydra.run.dir={run}/checkpoints/again"], run_dir_case(), "is inside the run {run}"),
    (["train", "hydra.run.dir={run}/.hydra"], run_dir_case(), "is inside the run {run}"),
    (["train", "hydra.run.dir={run}/videos"], run_dir_case(steps=(2048,), final=False), "is inside the run {run}"),
    (
        ["train", "-m", "seed=0,1", "hydra.sweep.dir={run}/sweep"],
        run_dir_case(),
        "hydra.sweep.dir={run}/sweep is inside",
    ),
    # damaged metrics and summaries: one line naming the file and what to do
    (["resume", "run={run}"], run_dir_case(write("metrics.jsonl", '{"a": 1}\ngarbage\n'), final=False), DAMAGED),
    (
        ["compare", "{run}"],
        run_dir_case(write("metrics.jsonl", EVAL_ROWS[:70] + "\ngarbage\n")),
        "metrics.jsonl is dam",
    ),
    (["compare", "{run}"], run_dir_case(write("metrics.jsonl", EVAL_ROWS + "[1]\n")), "line 3 is not a JSON object"),
    (
        ["compare", "{run}"],
        run_dir_case(both(write("metrics.jsonl", EVAL_ROWS), write("summary.json", "{'wall_s': 1"))),
        "summary.json is damaged (not JSON: Expecting property name enclosed in double quotes, line 1)",
    ),
    # advice that fits the case
    (["resume", "run={run}", "budget.env_steps=-5"], run_dir_case(), "budget.env_steps=-5 is not a positive number"),
    (["resume", "run={run}", "budget.env_steps=0"], run_dir_case(), "budget.env_steps=0 is not a positive number"),
    (
        ["resume", "run={run}"],
        run_dir_case(final=False),  # trained with checkpoint.every_steps=2048, killed during its first checkpoint
        "the run stopped before its first one (at 2,048 env steps) was written whole, so there is nothing to resume",
    ),
    (
        ["resume", "run={run}"],
        run_dir_case(final=False, overrides=("checkpoint.every_steps=0",)),
        "train with checkpoint.every_steps>0 to make runs resumable",
    ),
    # a -m sweep's directory: run again in place unless finished, as it was run, its record readable
    (
        ["resume", "run={run}"],
        sweep_dir({**MULTIRUN, "sweep_summary.csv": "run,seed\n"}),
        "has finished (sweep_summary.csv exists): nothing to resume",
    ),
    (["resume", "run={run}", "budget.env_steps=5000"], sweep_dir(MULTIRUN), "a sweep directory resumes as it was run"),
    (["resume", "run={run}"], sweep_dir({"multirun.yaml": "hydra: [\n"}), "multirun.yaml is unreadable (ParserError)"),
    # ranges of keys the table did not have
    (["train", "algo=es", "algo.mean_episodes=0"], None, "algo.mean_episodes must be an integer >= 1, got 0"),
    (["train", "algo=dqn", "algo.n_step=0"], None, "algo.n_step must be an integer >= 1, got 0"),
    (["train", "algo=qlearning", "algo.alpha=0"], None, "algo.alpha must be a number in (0, 1], got 0"),
    (["train", "algo=dqn", "algo.epsilon.decay=nan"], None, "algo.epsilon.decay must be a number in [0, 1], got nan"),
    (["train", "algo=es", "algo.low=inf"], None, "algo.low must be a number, got inf"),
    (
        ["train", "algo=map_elites", "algo.champion.candidates=-1"],
        None,
        "algo.champion.candidates must be an integer >= 0, got -1",
    ),
    (
        ["train", "algo=map_elites", "algo.champion.candidates=2.5"],
        None,
        "algo.champion.candidates must be an integer >= 0, got 2.5",
    ),
    (
        ["train", "algo=map_elites", "algo.champion.candidates=4", "algo.champion.episodes=0"],
        None,
        "algo.champion.episodes must be an integer >= 1, got 0",
    ),
    (
        ["train", "algo=map_elites", "algo.champion.candidates=401"],
        None,
        "algo.champion.candidates=401 is more than the archive's 400 cells; give at most 400",
    ),
    (
        ["train", "algo=map_elites", "algo.champion.candidates=4", "algo.champion.episodes=24"],
        None,
        "algo.champion.episodes=24 is not a multiple of algo.episodes=16 (a candidate plays its episodes in groups",
    ),
    (
        ["train", "algo=es", "algo.keep=mean", "algo.mean_episodes=6"],
        None,
        "algo.mean_episodes=6 is not a multiple of algo.episodes=16 (algo.keep=mean plays the mean's episodes in",
    ),
    # sizes that would crash late: refused before the run directory is made, or before anything is compiled
    (["train", "algo.num_envs=1000000000"], None, "one update would take 128,000,000,000 env steps per seed, beyond"),
    (["train", "algo=pqn", "algo.num_envs=1000000000"], None, "beyond the 32-bit step counter (2,147,483,647); lower"),
    (["train", "eval.episodes=100000000"], None, "eval.episodes=100,000,000 x 500 steps (the evaluation's keys) needs"),
    (["eval", "run={run}", "episodes=100000000"], run_dir_case(), "episodes=100,000,000 x 500 steps needs at least"),
    (["train", "+algo.lr=1e-3"], None, "+algo.lr: the config has algo.lr already (+ adds a new key); drop the +"),
    (["train", "-m", "seed=0,1", "+algo.gamma=0.9"], None, "job 0 of 2 (seed=0): +algo.gamma: the config has"),
]


@pytest.mark.slow  # the full tables run in the full suite; the quick tier keeps the first (tests/cli/test_bad_inputs.py)
@pytest.mark.parametrize("argv, make, fragment", CASES, ids=[" ".join(c[0]) for c in CASES])
def test_bad_input_is_one_line_and_exit_2(argv, make, fragment, tmp_path, monkeypatch, capsys):
    check_bad_input(argv, make, fragment, tmp_path, monkeypatch, capsys)
    for device in ("/dev/null", "/dev/full"):
        assert stat.S_ISCHR(os.lstat(device).st_mode)
    for path in tmp_path.rglob("*"):
        if path.name in ("pipe", "p.json", "v.npz", "cmp.png", "eval_cartpole.json", "eval_lunar.json"):
            assert stat.S_ISFIFO(os.lstat(path).st_mode)
    if (tmp_path / "elsewhere").exists():
        assert (tmp_path / "elsewhere" / "precious").read_text() == "keep"


def test_the_third_table_covers_every_writer_and_reader():
    assert {argv[0] for argv, _, _ in CASES} == {"export", "eval", "render", "compare", "train", "resume"}


def test_what_a_killed_checkpoint_write_left_is_removed_by_the_next_command(tmp_path, monkeypatch, capsys):
    """kill -9 during the first periodic checkpoint leaves its temporary: `rlq resume` removes it (the run's lock is
    free) and says why it cannot resume; the run's own files stay."""
    monkeypatch.chdir(tmp_path)
    refuse_to_train(monkeypatch)
    run_dir = make_run(tmp_path, final=False)
    (run_dir / "rlq.lock").write_text("4242")
    (run_dir / "checkpoints").mkdir()
    leftover = run_dir / "checkpoints" / ".step_2048.msgpack.tmp-4242"
    leftover.write_bytes(b"\0" * 4096)
    with pytest.raises(SystemExit) as exit_info:
        main(["resume", f"run={run_dir}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_info.value.code == 2
    assert err[0] == f"rlq: note: removed what a stopped write left in {run_dir}: checkpoints/{leftover.name}"
    assert "nothing to resume" in err[-1] and "checkpoint.every_steps>0" not in err[-1]
    assert not leftover.exists() and (run_dir / ".hydra" / "config.yaml").exists()


def test_compare_reads_a_run_whose_last_metrics_line_was_cut(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    run_dir = make_run(tmp_path)
    (run_dir / "metrics.jsonl").write_text(EVAL_ROWS + '{"kind": "eval", "env_steps": 81')
    main(["compare", str(run_dir), f"out={tmp_path / 'cmp'}"])
    captured = capsys.readouterr()
    assert captured.err.strip().splitlines() == [
        f"rlq: note: {run_dir / 'metrics.jsonl'}: skipped its last line, cut short (32 characters; a write stopped "
        "midway)"
    ]
    assert "20" in captured.out and (tmp_path / "cmp.png").is_file() and (tmp_path / "cmp.csv").is_file()
