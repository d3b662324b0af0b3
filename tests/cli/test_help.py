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


def test_train_help_lists_each_group_s_options_the_tuned_pairs_and_keys_the_config_has():
    import re

    from omegaconf import OmegaConf

    from rlq.cli.train import HELP_GROUPS, HELP_KEYS, train_help
    from rlq.config.choices import group_options
    from rlq.config.tuned import tuned_algos
    from tests.helpers import compose_config

    text = train_help()
    assert "_schema" not in text and "tuned/" not in text
    for group, _ in HELP_GROUPS:
        assert group_options(group) and all(option in text for option in group_options(group)), group
    assert "(lunar_box2d: rlq eval only)" in text
    for env in ("cartpole", "lunar", "humanoid", "brittle_star"):
        assert re.search(rf"^  {env}: +{', '.join(tuned_algos(env))}$", text, re.M), env
    cfg = compose_config()
    words = [w.strip("'") for line in HELP_KEYS.splitlines()[1:] for w in line[:37].split() if "=" in w]
    named = [w.split("=", 1)[0] for w in words if "<" not in w]
    missing = object()
    assert len(named) >= 10
    for key in named:
        key = key.removeprefix("sweep.")  # an in-program sweep names the key it sweeps
        assert OmegaConf.select(cfg, key, default=missing) is not missing, key


@pytest.mark.slow
def test_hydra_s_own_help_stays_one_flag_away(workdir):
    proc = run_cli("train", "--hydra-help", cwd=workdir)
    assert proc.returncode == 0 and "Hydra" in proc.stdout, proc.stderr[-2000:]
