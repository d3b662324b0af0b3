"""How many bad inputs and faults the tests hold to the rule of docs/reliability.md (one `rlq: error:` line, exit 2,
3 for divergence, nothing written outside the run directory, no directory left by a refusal), counted from the
tables themselves; docs/reliability.md states the number. `python -m tests.cli.test_probe_count` prints the count
of each source.

A probe is one command on one state of the disk: table entries with the same command line on the same files (made by
their ``make``, compared byte for byte) count once, however many fragments of the line they check."""

from __future__ import annotations

import importlib
import os
import re
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.helpers import REPO

#: the tables every entry of which runs through ``check_bad_input`` (tests/cli/test_bad_inputs.py): module, table
#: name, and how an entry gives (argv, make, a fragment of the line the user sees)
TABLES: list[tuple[str, str, Callable[[tuple], tuple[list[str], Callable | None, str]]]] = [
    ("tests.cli.test_bad_inputs", "CASES", lambda case: case),
    ("tests.cli.test_bad_inputs_more", "CASES", lambda case: case),
    ("tests.cli.test_bad_inputs_third", "CASES", lambda case: case),
    ("tests.config.test_choices", "CASES", lambda case: (case[0], None, case[1])),
    ("tests.config.test_ignored", "CASES", lambda case: (["train", *case[0]], None, case[1])),
    ("tests.run.test_memory", "POPULATIONS", lambda case: (["train", *case[0]], None, case[1])),
]

#: probes outside the tables, held to the same rule by a test of their own: (module, test, argv, the state it runs
#: on, a fragment of the line the user sees). A test of the installed command whose input a table runs in-process
#: does not count again.
SINGLE = [
    (
        "tests.cli.test_bad_inputs",
        "test_a_run_dir_in_use_is_refused",
        ["resume", "run={run}"],
        "locked",
        "is in use by another rlq process (pid ",
    ),
    (
        "tests.cli.test_bad_inputs",
        "test_a_run_dir_in_use_is_refused",
        ["train", "hydra.run.dir={tmp}/fresh"],
        "locked",
        "is in use by another rlq process (pid ",
    ),
    (
        "tests.cli.test_concurrent_start",
        "test_a_start_refused_by_the_lock_does_not_overwrite_the_running_jobs_record",
        ["train", "hydra.run.dir={run}"],
        "a second process past the early check",
        "is in use by another rlq process",
    ),
    (
        "tests.cli.test_bad_inputs_third",
        "test_what_a_killed_checkpoint_write_left_is_removed_by_the_next_command",
        ["resume", "run={run}"],
        "kill -9 during the first checkpoint: its temporary left",
        "nothing to resume (a note first: the temporary removed)",
    ),
    (
        "tests.cli.test_bad_inputs_more",
        "test_the_installed_command_prints_only_the_error_line",
        ["train", "algo=dqn", "env=humanoid", "allow_untuned=true"],
        "installed command",
        "algo=dqn needs a discrete action",
    ),
    (
        "tests.config.test_ignored",
        "test_a_sweep_names_the_job_whose_variant_ignores_the_key",
        ["train", "-m", "algo=random_search", "algo.variant=hill_climb,ars", "algo.population=64"],
        "",
        "job 1 of 2 (algo.variant=ars): algo.population is not read",
    ),
    (
        "tests.run.test_memory",
        "test_a_gpus_free_memory_refuses_what_the_host_would_take",
        ["train", "algo=es", "algo.population=100000"],
        "a GPU with 1 GiB free",
        "GiB of device memory, 1.0 GiB is free; lower algo.population",
    ),
    (
        "tests.run.test_distributed",
        "test_a_missing_process_is_named_after_the_timeout",
        ["train", "distributed.process_id=0", "distributed.num_processes=2"],
        "no other process",
        "distributed: process 0 waited 2 s (distributed.timeout_s) at ... for process 1 of 2",
    ),
    (
        "tests.run.test_distributed",
        "test_a_missing_process_is_named_after_the_timeout",
        ["train", "distributed.process_id=1", "distributed.num_processes=2"],
        "no coordinator",
        "distributed: process 1 waited 2 s (distributed.timeout_s) for process 0 at ..., which did not answer",
    ),
    (
        "tests.run.test_guard",
        "test_diverging_run_exits_3_and_keeps_the_last_good_checkpoint",
        ["train", "algo=dqn", "algo.lr=1e30"],
        "diverges: exit 3",
        "training diverged: params_norm is NaN/Inf ...; stopped, last good checkpoint: .../step_1024.msgpack",
    ),
    (
        "tests.run.test_guard",
        "test_ppo_at_a_huge_learning_rate_is_stopped_by_the_bound",
        ["train", "algo=ppo", "algo.lr=1e9"],
        "past guard.max_abs_loss: exit 3",
        "training diverged: ... beyond guard.max_...",
    ),
]

#: where docs/reliability.md states the count, and the bounds of its list of every probe (``--write`` rewrites it)
STATED = re.compile(r"\*\*(\d+) bad inputs and faults\*\*")
BEGIN = "<!-- every probe: written by `python -m tests.cli.test_probe_count --write` -->"
END = "<!-- end of the probes -->"
DOC = REPO / "docs" / "reliability.md"


def disk_state(make: Callable | None) -> str:
    """What ``make`` leaves in an empty directory, as text: each path, its kind, its bytes (a symlink's target)."""
    if make is None:
        return ""
    with tempfile.TemporaryDirectory() as root:
        make(Path(root))
        lines = []
        for path in sorted(Path(root).rglob("*")):
            mode = os.lstat(path).st_mode
            name = path.relative_to(root)
            if stat.S_ISLNK(mode):
                lines.append(f"{name} -> {os.readlink(path).replace(root, '{tmp}')}")
            elif stat.S_ISREG(mode):
                lines.append(f"{name}: {path.read_bytes().replace(root.encode(), b'{tmp}')!r}")
            else:
                lines.append(f"{name}: mode {stat.S_IFMT(mode):o}")
        return "\n".join(lines)


#: a probe: where it is tested, its command line, the files it runs on, the fragments of the line the user sees
Probe = tuple[str, tuple[str, ...], str, list[str]]


def probes() -> list[Probe]:
    """Every probe once (tables first, in TABLES' order, then SINGLE), with the fragments its entries check."""
    found: dict[tuple[tuple[str, ...], str], Probe] = {}
    for module_name, table, entry in TABLES:
        for case in getattr(importlib.import_module(module_name), table):
            argv, make, fragment = entry(case)
            key = (tuple(argv), disk_state(make))
            found.setdefault(key, (module_name.replace(".", "/") + ".py", *key, []))[3].append(fragment)
    for module_name, test, argv, state, fragment in SINGLE:
        assert callable(getattr(importlib.import_module(module_name), test)), (module_name, test)
        key = (tuple(argv), state)
        found.setdefault(key, (f"{module_name.replace('.', '/')}.py::{test}", *key, []))[3].append(fragment)
    return list(found.values())


def count() -> dict[str, int]:
    """How many probes each test (a table's module, or a test outside the tables) holds."""
    counts: dict[str, int] = {}
    for where, *_ in probes():
        counts[where] = counts.get(where, 0) + 1
    return counts


def code(text: str) -> str:
    """``text`` as inline Markdown code (a long run of one character shortened)."""
    text = re.sub(r"(\w)\1{19,}", lambda run: f"<{len(run.group(0))} x {run.group(1)}>", text)
    return f"`` {text} ``" if "`" in text else f"`{text}`"


def listing() -> str:
    """docs/reliability.md's list of every probe: the command, what the user sees (fragments of the line), its test."""
    lines = [BEGIN, ""]
    where_before = None
    for where, argv, _, fragments in probes():
        if where != where_before:
            lines += ["", f"`{where}`:", ""] if where_before is not None else [f"`{where}`:", ""]
            where_before = where
        shown = {"run": "{run}", "tmp": "{tmp}"}  # the tables' placeholders, their doubled braces single
        seen = " / ".join(code(f.format(**shown)) for f in dict.fromkeys(fragments))
        lines.append(f"- {code('rlq ' + ' '.join(a.format(**shown) for a in argv))}: {seen}")
    return "\n".join([*lines, "", END])


@pytest.mark.slow  # makes every probe's state on disk (6 s)
def test_the_tests_hold_at_least_150_bad_inputs_and_faults_to_the_rule_and_the_docs_say_how_many():
    total = sum(count().values())
    assert total >= 150
    text = DOC.read_text()
    assert STATED.findall(text) == [str(total)], f"docs/reliability.md should say **{total} bad inputs and faults**"
    assert text[text.index(BEGIN) : text.index(END) + len(END)] == listing(), (
        "python -m tests.cli.test_probe_count --write"
    )


def test_entries_with_one_command_on_the_same_files_count_once():
    from tests.cli.test_bad_inputs import run_dir_case

    assert disk_state(run_dir_case()) == disk_state(run_dir_case())
    assert disk_state(run_dir_case(final=False)) != disk_state(run_dir_case())
    assert disk_state(run_dir_case(lambda d: (d / "metrics.jsonl").write_text("x"))) != disk_state(run_dir_case())


if __name__ == "__main__":
    import sys

    if "--write" in sys.argv:
        text = DOC.read_text()
        DOC.write_text(text[: text.index(BEGIN)] + listing() + text[text.index(END) + len(END) :])
    counts = count()
    for name, added in counts.items():
        print(f"{added:4d}  {name}")
    print(f"{sum(counts.values()):4d}  in all")
