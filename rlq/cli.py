"""The `rlq` command: `rlq train [overrides]`, `rlq eval run=<dir> [...]`, `rlq resume run=<dir>`.

`rlq train` composes conf/ with Hydra. Before Hydra makes a run directory, the overrides are
composed once more with Hydra's compose API and checked (rlq.validate), so a bad input ends
with one line on stderr, exit code 2, and nothing on disk.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

from omegaconf import OmegaConf

CONF_DIR = Path(__file__).resolve().parent.parent / "conf"
USAGE = """usage: rlq <command> [hydra overrides]

commands:
  train   train an agent:  rlq train algo=ppo env=cartpole num_seeds=8
          (-m/--multirun sweeps, --cfg job prints the config, --help lists the groups)
  eval    evaluate a run's checkpoint greedily:  rlq eval run=outputs/<date>/<time>_<name> episodes=100
  render  video of one greedy episode:  rlq render run=outputs/<date>/<time>_<name> [seed_index=0]
          (states saved where no OpenGL loaded:  rlq render run=<run dir> states=videos/final_seed0.npz)
  resume  continue an unfinished run from its latest checkpoint (trained with checkpoint.every_steps>0):
          rlq resume run=outputs/<date>/<time>_<name>
"""
HYDRA_FLAGS = {"--help", "-h", "--hydra-help", "--cfg", "-c", "--info", "-i", "--resolve", "--package", "-p"}
MULTIRUN_FLAGS = {"-m", "--multirun"}


def fail(message: str) -> None:
    print(f"rlq: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def _explain_hydra_error(err: Exception) -> str:
    text = str(err)
    missing = re.search(r"Could not find '([\w/]+)/(\w+)'", text)
    if missing:
        group, option = missing.groups()
        options = sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml"))
        return f"unknown {group} '{option}'; choose one of: {', '.join(options)} (e.g. {group}={options[0]})"
    unknown_key = re.search(r"Key '([\w.]+)' is not in struct", text) or re.search(
        r"Could not override '([\w.]+)'", text
    )
    if unknown_key:
        append = re.search(r"To append to your config use (\S+)", text)
        hint = f" (a new key, e.g. in compiler_options, is added with {append.group(1)})" if append else ""
        return f"unknown config key '{unknown_key.group(1)}'; `rlq train --cfg job` lists the keys{hint}"
    first = next((line for line in text.splitlines() if line.strip()), type(err).__name__)
    return first.strip()


def compose(overrides: list[str]):
    """Compose the run config as Hydra will, without making a run directory."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            return hydra_compose(config_name="config", overrides=overrides)
    finally:
        GlobalHydra.instance().clear()


def _group_override(item: str) -> bool:
    key = item.split("=", 1)[0].lstrip("+~")
    return key.split("/")[0] in ("env", "controller", "algo", "logger", "experiment", "hydra")


def check_overrides(overrides: list[str]) -> list[str]:
    """Compose and validate; exits with a one-line message on any problem.

    Returns the overrides with integer keys written in float notation (``budget.env_steps=1e6``)
    rewritten as integers.
    """
    from rlq.validate import ConfigError, check_run_config, check_types, integral_floats

    for item in overrides:
        if "=" not in item:
            fail(f"'{item}' is not an override; write key=value (e.g. algo=ppo)")
    try:
        cfg = compose(overrides)
        defaults = compose([o for o in overrides if _group_override(o)])
    except Exception as err:
        fail(_explain_hydra_error(err))
    value_keys = [o.split("=", 1)[0].lstrip("+") for o in overrides if not _group_override(o)]
    value_keys = [k for k in value_keys if not k.startswith("~")]
    fixed = integral_floats(defaults, cfg, value_keys)
    for key, value in fixed.items():
        OmegaConf.update(cfg, key, value)
    overrides = [
        f"{o.split('=', 1)[0]}={fixed[o.split('=', 1)[0].lstrip('+')]}"
        if o.split("=", 1)[0].lstrip("+") in fixed
        else o
        for o in overrides
    ]
    try:
        check_types(defaults, cfg, value_keys)
        check_run_config(cfg)
    except ConfigError as err:
        fail(str(err))
    return overrides


def _train_task(cfg) -> None:
    import shutil

    from hydra.core.hydra_config import HydraConfig

    from rlq.train import train
    from rlq.validate import ConfigError, check_run_config

    run_dir = Path(HydraConfig.get().runtime.output_dir)
    try:
        check_run_config(cfg)
    except ConfigError as err:
        shutil.rmtree(run_dir, ignore_errors=True)
        fail(str(err))
    result = train(cfg, run_dir)
    print(result.line(), flush=True)


def train_main(args: list[str]) -> None:
    import hydra

    passthrough = any(a in HYDRA_FLAGS or a.startswith("--cfg") for a in args)
    multirun = any(a in MULTIRUN_FLAGS for a in args)
    if not passthrough and not multirun:
        args = check_overrides(args)
    os.environ.setdefault("HYDRA_FULL_ERROR", "0")
    task = hydra.main(config_path=str(CONF_DIR), config_name="config", version_base="1.3")(_train_task)
    sys.argv = ["rlq train", *args]
    task()


def main(argv: list[str] | None = None) -> None:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE)
        return
    command, args = argv[0], argv[1:]
    if command == "train":
        train_main(args)
    elif command == "eval":
        from rlq.evaluate import eval_main

        eval_main(args)
    elif command == "render":
        from rlq.render_cli import render_main

        render_main(args)
    elif command == "resume":
        from rlq.resume_cli import resume_main

        resume_main(args)
    else:
        fail(
            f"unknown command '{command}'; use `rlq train`, `rlq eval`, `rlq render` or `rlq resume` (see `rlq --help`)"
        )


if __name__ == "__main__":
    main()
