"""`rlq train [overrides]`: validate the overrides, then hand them to Hydra (single run or -m sweep)."""

from __future__ import annotations

import os
import re
import shutil
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from rlq.cli.checked import check_sweep, checked_run
from rlq.cli.follower import as_follower, follower_dir
from rlq.cli.main import exit_for, fail, os_problem
from rlq.cli.resume import continue_run
from rlq.config.choices import group_options
from rlq.config.compose import check_composes, check_package, compose
from rlq.config.recorded import job_spec
from rlq.config.resolve import check_written
from rlq.config.spec import RunSpec
from rlq.config.store import hydra_conf_dir
from rlq.config.tuned import machine_choice, tuned_algos, tuned_line
from rlq.config.types import integer_key, integers_written
from rlq.errors import ConfigError, RlqError, UsageError
from rlq.run.checks.expected import expected_line, shortfall_line
from rlq.run.checks.validate import check_run_config
from rlq.store import checkpoint
from rlq.store.files import remove_temporaries
from rlq.store.jsonfiles import SUMMARY_FIX, read_json_object
from rlq.store.lock import run_lock
from rlq.store.record import write_record
from rlq.store.sidecar import check_sidecar
from rlq.tools.sweep import check_launcher, dirname_overrides, job_dirname, sweeper_overrides

HYDRA_FLAGS = {"--help", "-h", "--hydra-help", "--cfg", "-c", "--info", "-i", "--resolve", "--package", "-p"}
MULTIRUN_FLAGS = {"-m", "--multirun"}
#: Hydra's flags that take a value (``--cfg job``, ``--package algo``), and those whose value is optional
#: (``--info defaults``) with the values they take
VALUE_FLAGS = {"--cfg", "-c", "--package", "-p"}
INFO_FLAGS = {"--info", "-i"}
INFO_CHOICES = {"all", "config", "defaults", "defaults-tree", "plugins", "searchpath"}
#: what ``--cfg`` prints: the run's config, Hydra's node, both
CFG_CHOICES = ("job", "hydra", "all")

#: `rlq train --help` (rlq.cli.main prints it; --hydra-help is Hydra's, which rebuilds its config repository once per
#: config group, 125 times with its own, and lists the structured configs' *_schema entries: 5.7 s on a laptop's
#: core against 2.1 s): the groups a user chooses, in the order shown, with what each chooses
HELP_GROUPS = (
    ("algo", "the algorithm"),
    ("env", "the environment"),
    ("controller", "what the policy drives (the brittle stars: cpg unless told)"),
    ("machine", "the recipe's shape: gpu where JAX sees an NVIDIA GPU, else cpu"),
    ("experiment", "a named preset (conf/experiment/)"),
    ("logger", "console, JSONL and W&B (offline) logging"),
    ("env/physics", "the brittle stars' physics"),
)

HELP_KEYS = """keys (key=value; each key's type, default and meaning: docs/configuration.md):
  seed=S num_seeds=N                 the first seed, and how many seeds train in one program
  budget.env_steps=N                 env steps per seed
  algo.<key>=V env.<key>=V           the algorithm's and the env's keys (e.g. algo.lr=3e-4)
  eval.every_steps=N eval.episodes=N periodic greedy evaluations, episodes per seed
  eval.keep=last|best                end with the last state or each seed's best evaluated one
  stop.when="eval/return>=475"       stop once a rule holds
  checkpoint.every_steps=N           checkpoints to resume from (rlq resume run=<dir>)
  video.at_end=true|false            an mp4 of a greedy episode at the end
  logger.wandb.mode=offline|online|disabled
  'sweep.algo.lr=[1e-3,3e-4]'        an in-program sweep: every value's seeds in one program
  allow_untuned=true                 run a pair without a tuned recipe on the algorithm's defaults
"""

HELP_FLAGS = """flags:
  -m, --multirun     one job per combination of comma-separated values (hydra/launcher=slurm on a cluster)
  --cfg job          print the composed config and exit (hydra, all: with Hydra's); --package KEY: a part of it
  --info             Hydra's information about the composition
  --hydra-help       Hydra's own help
"""


def train_help() -> str:
    """The text `rlq train --help` prints."""
    tuned = {env: tuned_algos(env) for env in group_options("env")}
    eval_only = [env for env, algos in tuned.items() if not algos]  # lunar_box2d: Gymnasium's env, for rlq eval
    width = max(len(group) for group, _ in HELP_GROUPS) + 2
    indent = " " * (width + 2)
    groups = []
    for group, what in HELP_GROUPS:
        options = ", ".join(o for o in group_options(group) if group != "env" or o not in eval_only)
        if group == "env" and eval_only:
            options += f" ({', '.join(eval_only)}: rlq eval only)"
        wrapped = textwrap.fill(options, 110, initial_indent=indent, subsequent_indent=indent, break_on_hyphens=False)
        groups.append(f"  {group:<{width}}{what}:\n{wrapped}")
    pairs = [f"  {env + ':':<{width + 12}}{', '.join(algos)}" for env, algos in tuned.items() if algos]
    return "\n".join(
        [
            "usage: rlq train [group=option ...] [key=value ...] [-m] [--cfg job] [--hydra-help]",
            "",
            "Train one run from the composed config (no arguments: PPO on CartPole), or with -m one run per",
            "combination of the values given (a Hydra sweep). `rlq train algo=A env=E` runs that pair's tuned",
            "recipe, shaped for the machine; keys you pass win (docs/matrix.md).",
            "",
            "config groups (group=option):",
            *groups,
            "",
            "tuned pairs (env: algo):",
            *pairs,
            "",
            HELP_KEYS,
            HELP_FLAGS,
        ]
    )


HELP = train_help

# at import, not in train_main: a launcher that runs jobs in other processes (submitit) unpickles
# _train_task, which imports this module, before the job resolves its directory (hydra.sweep.subdir)
OmegaConf.register_new_resolver("rlq_job_dir", job_dirname, replace=True)


def _train_task(cfg) -> float:
    """One job; returns the run's ``objective`` (the final greedy return by default) for Hydra's sweepers."""
    import functools
    import shutil

    from hydra.core.hydra_config import HydraConfig

    from rlq.lib.sharding import is_writer
    from rlq.run.train import train
    from rlq.store.objective import objective_value
    from rlq.tools.warm_start import check_init_from, warm_state

    runtime = HydraConfig.get().runtime
    run_dir = Path(runtime.output_dir)
    spec = job_spec(cfg, dict(runtime.choices))
    writer = is_writer()  # over several processes only process 0 prints (and writes) the run
    if writer:
        print(tuned_line(dict(runtime.choices)), flush=True)
        for said in (expected_line(spec, dict(runtime.choices)), shortfall_line(spec, dict(runtime.choices))):
            if said:
                print(said, flush=True)
    try:
        if not checked_before_launch():
            check_run_config(spec)
        if (
            spec.training.init_from
        ):  # not in check_run_config: a warm-started run stays readable once its source is gone
            check_init_from(spec.values)
    except ConfigError as err:
        shutil.rmtree(run_dir, ignore_errors=True)
        exit_for(err)
    try:
        with run_lock(run_dir):
            remove_temporaries(run_dir)
            kept = finished_job(run_dir, spec)
            if kept is not None:  # a sweep run again: its finished jobs stay as they are
                if writer:
                    print(f"rlq: {run_dir} finished in an earlier run of this sweep: kept", flush=True)
                return objective_value(spec.training.objective, kept, run_dir)
            write_record(run_dir, cfg, HydraConfig.get())
            requeued = requeued_checkpoint(run_dir, spec)
            warm = functools.partial(warm_state, spec.values) if spec.training.init_from else None
            result = continue_run(spec, run_dir, *requeued) if requeued else train(spec, run_dir, warm=warm)
        if writer:
            print(result.line(), flush=True)
        return objective_value(spec.training.objective, result.final_eval, run_dir)
    except RlqError as err:  # out of Hydra's job runner, which would print a traceback and exit 1
        exit_for(err)
    except OSError as err:  # a full disk: one line naming the file, not Hydra's "Error executing job" and traceback
        fail(os_problem(err), 1)


def checked_before_launch() -> bool:
    """Whether this job's config was validated before Hydra ran it, so the job need not check it again: a single
    run's (``checked_run``) and each job's of a basic sweep (``check_sweep`` checks them all first) were; a job whose
    values a sweeper chose as it went (Optuna, between the interval ends checked up front) was not."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    hydra = HydraConfig.get()
    return hydra.mode == RunMode.RUN or str(hydra.sweeper["_target_"]).endswith("BasicSweeper")


def requeued_checkpoint(run_dir: Path, spec: RunSpec | None = None) -> tuple[Path, list[str], bool] | None:
    """The checkpoint a job goes on from when it runs again in its own directory (a sweep job that SLURM preempted
    and submitit requeued, or any job of a sweep run again with its ``hydra.sweep.dir``), the damaged ones skipped,
    and whether it is the final checkpoint of a run killed before its summary (``continue_run``'s ``finish``).
    A fresh job's directory has none (`rlq train` refuses output directories holding a run); one without
    intermediate checkpoints starts over."""
    cfg = spec.values if spec is not None else None
    final = checkpoint.final_without_summary(run_dir, cfg)
    if final is not None:
        return final, [], True
    if not checkpoint.intermediate(run_dir / "checkpoints"):
        return None
    return (*checkpoint.resumable(run_dir, cfg), False)


def finished_job(run_dir: Path, spec: RunSpec) -> dict[str, Any] | None:
    """The final evaluation (per seed) of a job that finished in an earlier run of its sweep (its ``summary.json``
    and intact final checkpoint, of this job's config: CheckpointError otherwise); None for a job to train."""
    final = run_dir / "checkpoints" / "final.msgpack"
    if not (final.exists() and (run_dir / "summary.json").exists()):
        return None
    check_sidecar(final, checkpoint.verify(final), spec.values)
    found = read_json_object(run_dir / "summary.json", SUMMARY_FIX).get("final_eval")
    return dict(found) if isinstance(found, dict) else {}


def run_composed(cfg: DictConfig, task: Callable[[DictConfig], object]) -> None:
    """Run one job of ``cfg`` (composed with Hydra's node: ``RunSpec.composed``) as ``hydra.main`` runs
    a single job: Hydra's logging, the run directory with its .hydra/ record, the callbacks, the
    job's ``env_set``; but without composing the config a second time, which would add a noticeable
    share of a short CartPole run. Exceptions of the task propagate."""
    from hydra._internal.callbacks import Callbacks  # what hydra.main uses; hydra-core is pinned to 1.3
    from hydra.core.utils import JobRuntime, configure_log, run_job
    from hydra.types import HydraContext

    configure_log(cfg.hydra.hydra_logging, cfg.hydra.verbose)
    JobRuntime.instance().set("name", cfg.hydra.job.name)
    callbacks = Callbacks(cfg)
    callbacks.on_run_start(config=cfg, config_name="config")
    # run_job reads only the callbacks; the config loader is for launchers and sweepers, which a single run has none of
    context = HydraContext(config_loader=None, callbacks=callbacks)  # type: ignore[arg-type]
    done = run_job(task, cfg, job_dir_key="hydra.run.dir", job_subdir_key=None, hydra_context=context)
    callbacks.on_run_end(config=cfg, config_name="config", job_return=done)
    done.return_value  # noqa: B018 (raises the task's exception)


def given_overrides(args: list[str]) -> list[str]:
    """The overrides among the arguments of `rlq train --cfg job ...` (``--info``, ``--resolve``): every argument
    that is neither one of Hydra's flags nor a flag's value (``job`` of ``--cfg job``), ``=`` or not."""
    given: list[str] = []
    value_next = False
    for arg, following in zip(args, [*args[1:], None], strict=True):
        if value_next:
            value_next = False
        elif arg.startswith("-"):
            value_next = arg in VALUE_FLAGS or (arg in INFO_FLAGS and following in INFO_CHOICES)
        else:
            given.append(arg)
    return given


def flag_value(args: list[str], *names: str) -> str | None:
    """The value given to a flag (``--cfg job``, ``-c job`` or ``--cfg=job``); None if absent."""
    for i, arg in enumerate(args):
        if arg in names:
            return args[i + 1] if i + 1 < len(args) else ""
        for name in names:
            if name.startswith("--") and arg.startswith(name + "="):
                return arg.split("=", 1)[1]
    return None


#: Hydra's line for ``+key=value`` where the config has the key already
APPEND_EXISTING = re.compile(r"Could not append to config\. An item is already at '([\w.]+)'\.?")


def drop_the_plus(err: ConfigError) -> ConfigError:
    """``+algo.lr=1e-3``: Hydra says it cannot append; the line says to drop the ``+`` (which adds a new key)."""
    found = APPEND_EXISTING.search(str(err))
    if found is None:
        return err
    key = found.group(1)
    hint = f"+{key}: the config has {key} already (+ adds a new key); drop the + to set it: {key}=..."
    return ConfigError(APPEND_EXISTING.sub(lambda _: hint, str(err)))


def train_main(args: list[str]) -> None:
    try:
        _train(args)
    except ConfigError as err:
        raise drop_the_plus(err) from None


def _train(args: list[str]) -> None:
    passthrough = any(a in HYDRA_FLAGS or a.startswith(("--cfg=", "--package=")) for a in args)
    multirun = any(a in MULTIRUN_FLAGS for a in args)
    check_launcher(args, launching=multirun and not passthrough)
    asks_help = any(a in ("--help", "-h", "--hydra-help") for a in args)
    machine = machine_choice([a for a in args if "=" in a and not a.startswith("-")])
    if machine and not asks_help:
        args = [machine, *args]  # before the flags: Hydra reads its overrides as one positional list
    if passthrough and not asks_help:
        if multirun:
            raise UsageError("-m and --cfg/--info do not combine; print one job's config without -m")
        # refused as a run refuses them (resolve): Hydra would print the config of ``~tuned`` or ``~seed`` deleted (the
        # tuned line naming files it had not applied), or fail on ``algo.lr`` after that line
        check_written(given_overrides(args))
        overrides = [a for a in args if "=" in a and not a.startswith("-")]
        typed = check_composes(overrides)  # an integer key given as 1e6 written as the integer Hydra's typed node takes
        rewritten = dict(zip(overrides, typed, strict=True))
        args, overrides = [rewritten.get(a, a) for a in args], typed
        printed, package = flag_value(args, "--cfg", "-c"), flag_value(args, "--package", "-p")
        if printed is not None and printed not in CFG_CHOICES:
            given = f"--cfg {printed} is not" if printed else "--cfg takes"
            raise UsageError(f"{given} one of {', '.join(CFG_CHOICES)} (e.g. rlq train --cfg job)")
        if package is not None and printed is None:
            raise UsageError(f"--package {package} picks the part of the config that --cfg prints: add --cfg job")
        if package and printed in ("job", "hydra", "all"):
            check_package(overrides, printed, package)
        if printed in ("job", "all") and not package:  # YAML comments: the printed config stays loadable
            job = compose(overrides, with_hydra=True)
            choices = dict(job.hydra.runtime.choices)
            print("# " + tuned_line(choices).removeprefix("rlq: "))
            spec = job_spec(job, choices)
            for said in (expected_line(spec, choices), shortfall_line(spec, choices)):
                if said:
                    print("# " + said.removeprefix("rlq: "))
    if multirun and not passthrough:
        # composing every job to check it takes a while before Hydra says anything: say so first
        print("rlq: sweep: checking every job's config before the first starts", flush=True)
        args = integers_written([*args, *sweeper_overrides(args)], integer_key)  # the run's keys
        check_sweep([a for a in args if a not in MULTIRUN_FLAGS])
    elif not passthrough:
        spec = checked_run(args)
        args = list(spec.overrides)
        scratch = follower_dir()
        if scratch is not None:
            args, spec = as_follower(args, spec, scratch)
        composed = spec.composed
        try:
            if composed is not None:
                return run_composed(composed, _train_task)
            return run_hydra(args, multirun)
        finally:
            if scratch is not None:
                shutil.rmtree(scratch, ignore_errors=True)
    return run_hydra(args, multirun)


def run_hydra(args: list[str], multirun: bool) -> None:
    """Hand the overrides to ``hydra.main``: a sweep, or a run whose config Hydra composes again."""
    import hydra

    if multirun:  # Hydra's parser takes its flags before the overrides only
        flags = [a for a in args if a in MULTIRUN_FLAGS]
        args = [*flags, *(a for a in args if a not in MULTIRUN_FLAGS), *dirname_overrides(args)]
    os.environ.setdefault("HYDRA_FULL_ERROR", "0")
    task = hydra.main(config_path=hydra_conf_dir(), config_name="config", version_base="1.3")(_train_task)
    sys.argv = ["rlq train", *args]
    task()
