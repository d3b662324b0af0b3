"""The `rlq` entry point's process set-up."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from rlq.cli.main import PREALLOCATE, gpu_memory_on_demand, main


def test_jax_takes_gpu_memory_as_the_run_needs_it_unless_the_user_chose() -> None:
    unset: dict[str, str] = {}
    gpu_memory_on_demand(unset)
    assert unset == {PREALLOCATE: "false"}
    for chosen in ("true", "false"):
        environ = {PREALLOCATE: chosen}
        gpu_memory_on_demand(environ)
        assert environ == {PREALLOCATE: chosen}


def test_every_command_sets_it_before_it_runs() -> None:
    env = {k: v for k, v in os.environ.items() if k != PREALLOCATE}
    code = "import os; from rlq.cli.main import main; main(['--help']); print(os.environ.get('" + PREALLOCATE + "'))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "false"


def test_a_file_the_command_cannot_write_is_one_line_and_exit_1(monkeypatch, capsys) -> None:
    def read_only(args: list[str]) -> None:
        raise PermissionError(13, "Permission denied", "/runs/a/compare_eval_return.png")

    monkeypatch.setattr("rlq.cli.compare.compare_main", read_only)
    with pytest.raises(SystemExit) as exit_info:
        main(["compare", "/runs/a"])
    err = capsys.readouterr().err
    assert exit_info.value.code == 1 and "Traceback" not in err
    assert err.strip().splitlines() == ["rlq: error: Permission denied: /runs/a/compare_eval_return.png"]


def test_a_signal_outside_training_ends_the_command_with_one_line(capsys, monkeypatch):
    import signal

    from rlq.cli.main import stop_at_once

    exits = []
    monkeypatch.setattr(os, "_exit", exits.append)  # the process would end here
    stop_at_once(signal.SIGTERM, None)
    assert exits == [128 + signal.SIGTERM]
    assert capsys.readouterr().err == "rlq: stopped by SIGTERM: nothing to save\n"
    main(["--version"])  # main puts the handlers back when it returns
    assert signal.getsignal(signal.SIGINT) is not stop_at_once and signal.getsignal(signal.SIGTERM) is not stop_at_once
