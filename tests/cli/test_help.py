"""`rlq <command> --help` (and -h) prints the command's usage with every option it accepts and exits 0."""

import pytest

from rlq.cli.args import EVAL_KEYS
from rlq.cli.main import COMMANDS
from tests.helpers import run_cli

#: what each command's help must name: its key=value options, or for train Hydra's config groups
NAMED = {
    "train": ["algo", "env", "controller", "logger", "experiment"],
    "eval": [f"{key}=" for key in EVAL_KEYS],
    "render": ["run=", "seed_index=", "seed=", "steps=", "out=", "checkpoint=", "env=", "states=", "cell="],
    "resume": ["run="],
    "compare": ["metric=", "x=", "out=", "threshold=", "env_steps", "wall_s"],
    "export": ["run=", "checkpoint=", "seed_index=", "out="],
}


def test_every_command_has_its_help_listed():
    assert set(NAMED) == set(COMMANDS)


@pytest.mark.slow
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_help_exits_zero_and_lists_the_options(command, workdir):
    for flag in ("--help", "-h"):
        proc = run_cli(command, flag, cwd=workdir)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert proc.stderr == "" or "error" not in proc.stderr
        for name in NAMED[command]:
            assert name in proc.stdout, f"`rlq {command} {flag}` does not name {name}"
    assert not (workdir / "outputs").exists()


def test_render_help_names_every_option_it_accepts():
    from rlq.cli.render import HELP, RENDER_KEYS

    assert all(f"{key}=" in HELP for key in RENDER_KEYS)


@pytest.mark.parametrize("flag", ["--version", "-V"])
def test_version_prints_the_installed_version(flag, capsys):
    from importlib.metadata import version

    from rlq.cli.main import main

    main([flag])
    assert capsys.readouterr().out.strip() == f"rlq {version('rlq')}"
