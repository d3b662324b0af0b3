"""Checks of a composed config, run once before anything is compiled.

Every problem becomes one line that names the fix; the CLI prints it and exits with code 2.
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rlq.config.spec import RunSpec, as_spec, evaluation_spec, member_spec
from rlq.config.types import compatible, type_name
from rlq.errors import ConfigError
from rlq.store.lock import locked_by
from rlq.store.outputs import check_not_nested, check_run_dir

if TYPE_CHECKING:
    from rlq.lib.env_api import Env, HostEnv

GROUPS = ("env", "controller", "algo", "logger", "experiment")


def cannot_create(path: Path) -> str | None:
    """Why directory ``path`` cannot be made and written (None: it can): its nearest existing
    ancestor is a file, or not writable."""
    parent = Path(path)
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        return f"{parent} is a file"
    try:  # os.access says yes to root on read-only or virtual file systems; a real write does not
        with tempfile.TemporaryFile(dir=parent):
            pass
    except OSError as err:
        return f"{parent} is not writable ({err.strerror})"
    return None


def check_output_dir(path: Path | str, key: str) -> None:
    """``path`` (a run or sweep directory still to be made) can be created and written, and holds
    no checkpoint of an earlier run (a run that died before its first checkpoint is started over,
    as a requeued SLURM job does); a directory holding finished runs is a sweep's (its multirun.yaml), whose
    finished jobs are kept and stopped ones go on from their checkpoints when the sweep runs again."""
    if not str(path).strip():
        raise ConfigError(f"{key} is empty (an unset shell variable?); give a directory")
    path = Path(path)
    if key == "hydra.run.dir":
        check_run_dir(path, key)
    else:  # a sweep run again holds its jobs' directories
        check_not_nested(path, key)
    if path.exists():
        if not path.is_dir():
            raise ConfigError(f"{key}={path} is a file; give a directory")
        holder = locked_by(path)
        if holder:
            raise ConfigError(f"{key}={path} is in use by another rlq process ({holder}); choose another directory")
        if (path / "checkpoints" / "final.msgpack").exists() and (path / "summary.json").exists():
            raise ConfigError(f"{key}={path} already holds a finished rlq run; choose another directory")
        if any((path / "checkpoints").glob("*.msgpack")):
            raise ConfigError(
                f"{key}={path} already holds an rlq run; continue it with `rlq resume run={path}` or choose another directory"
            )
        # a sweep run again (its multirun.yaml there): finished jobs are kept, stopped ones go on from their
        # checkpoints; finished runs in any other directory are not a sweep's
        finished = next(path.glob("*/checkpoints/final.msgpack"), None) if key == "hydra.sweep.dir" else None
        if finished is not None and not (path / "multirun.yaml").exists():
            raise ConfigError(
                f"{key}={path} already holds finished jobs of an earlier sweep ({finished.parent.parent.name}); "
                "choose another directory"
            )
    problem = cannot_create(path)
    if problem:
        raise ConfigError(f"{key}={path} cannot be created: {problem}")


def check_compile_cache(spec: RunSpec) -> None:
    """``compile_cache`` names a directory that can be made and written (or is off)."""
    from rlq.run.programs.compile_cache import cache_dir

    path = cache_dir(spec.compilation.compile_cache)
    if path is None:
        return
    if path.exists() and not path.is_dir():
        raise ConfigError(f"compile_cache={path} is a file; give a directory, or compile_cache=null for no cache")
    problem = cannot_create(path)
    if problem:
        raise ConfigError(f"compile_cache={path} cannot be created: {problem}; or compile_cache=null for no cache")


def no_time_limit(label: str, key: str) -> ConfigError:
    """The error for a JAX env without a time limit: each evaluation runs a fixed number of steps at
    most, so an episode that never ends would hold it forever."""
    return ConfigError(
        f"{label}: {key}=null (no time limit) cannot be evaluated: rlq evaluates a JAX env for at most "
        f"its time limit's steps; give an integer >= 1, e.g. {key}=1000 (Gymnasium's LunarLander-v3 limit), "
        "or evaluate without a limit on Box2D: `rlq eval run=<dir> env=lunar_box2d env.max_episode_steps=null`"
    )


def check_time_limit(env: Env | HostEnv, label: str) -> None:
    """``env`` has a time limit where rlq's evaluation needs one (a JAX env; a host env may have none)."""
    if env.jittable and env.max_episode_steps is None:
        raise no_time_limit(label, "env.max_episode_steps")


def check_eval_env(spec: RunSpec) -> None:
    """``eval.env`` names options of the run's env (not another env), each of its type and range."""
    from rlq.run.checks.constraints import problems

    options = spec.evaluation.env
    if not options:
        return
    if not isinstance(options, Mapping):
        raise ConfigError(
            f"eval.env must be a group of env options (on the command line: +eval.env.<option>=<value>); got {options!r}"
        )
    for option, value in options.items():
        key = str(option)
        if key == "name" or key not in spec.env:
            raise ConfigError(
                f"eval.env.{key} is not an option of env={spec.env['name']}; eval.env changes the run's own env's "
                "options for its evaluations (evaluate another env after training: `rlq eval run=<dir> env=<name>`)"
            )
        default = spec.env[key]
        if not compatible(default, value):
            raise ConfigError(f"eval.env.{key} must be {type_name(default)}, as env.{key} is; got {value!r}")
        if key == "max_episode_steps" and value is None:
            raise no_time_limit(f"env={spec.env['name']}", "eval.env.max_episode_steps")
    problem = problems(evaluation_spec(spec))  # the run's own values passed: only eval.env's can fail here
    if problem:
        raise ConfigError(f"eval.{problem}")


#: bytes of a run directory's name: file systems allow 255, and Hydra's time prefix and a sweep's suffixes take more
RUN_NAME_BYTES = 200


def check_run_name(name: object) -> None:
    """``run_name`` is one directory name: no path separator or ``..`` (which would write outside outputs/), and short
    enough for the file system."""
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(f"run_name must be a non-empty name, got {name!r} (e.g. run_name=my-run)")
    if "/" in name or "\\" in name or name in (".", ".."):
        raise ConfigError(
            f"run_name={name} is not one directory name: it would write outside outputs/; to choose the directory "
            "itself use hydra.run.dir=<path>"
        )
    if len(name.encode()) > RUN_NAME_BYTES:
        raise ConfigError(f"run_name is {len(name.encode())} bytes long; give at most {RUN_NAME_BYTES}")


def check_run_config(run: RunSpec | Mapping[str, Any], memory: bool = True) -> None:
    """Values, sizes, combinations and algorithm requirements; raises ConfigError. ``memory``: also its sizes
    against this machine's free memory (not for a recorded run read to be evaluated: eval takes one seed at a time,
    perhaps on a smaller machine than it trained on)."""
    from rlq.algos import algo_settings, algorithm_spec, check_algo
    from rlq.controllers import check_controller
    from rlq.envs import env_settings
    from rlq.run.checks.constraints import problems
    from rlq.run.checks.memory import check_search_sizes, check_training_sizes, free_bytes
    from rlq.run.programs import members
    from rlq.run.programs.compiler import check_options, options_from_config
    from rlq.run.programs.devices import placement
    from rlq.run.programs.distributed import settings
    from rlq.run.programs.env_stack import checked_env, evaluation_metrics
    from rlq.run.stops.stop import parse_stop
    from rlq.store.objective import parse_objective

    spec = as_spec(run)
    problem = problems(spec)
    if problem:
        raise ConfigError(problem)
    settings(spec.devices.distributed)
    members.check(spec, algorithm_spec(spec.algorithm).sweepable)
    for member in members.members(spec) if members.sweeping(spec) else []:
        problem = problems(member_spec(spec, member))
        if problem:
            raise ConfigError(f"sweep member {members.member_dirname(member)}: {problem}")
    check_run_name(spec.outputs.run_name)
    stop_when = spec.budget.stop_when
    rule = parse_stop(stop_when) if stop_when is not None else None
    objective = parse_objective(spec.training.objective)
    if spec.outputs.video.at_end not in (None, True, False):
        raise ConfigError(
            f"video.at_end must be true, false or null (a single run's, when cheap), got {spec.outputs.video.at_end!r}"
        )
    check_eval_env(spec)
    check_compile_cache(spec)
    problem = check_controller(spec.controller, env_settings(spec.env))
    if problem:
        raise ConfigError(problem)
    try:
        problem = check_options(options_from_config(spec))
    except ValueError as err:
        raise ConfigError(str(err)) from err
    if problem:
        raise ConfigError(problem)
    env_label = f"env={spec.env['name']}"
    env = checked_env(spec, env_label)
    if not env.jittable:
        raise ConfigError(f"{env_label} runs on the host and is for `rlq eval` only; train on a JAX env")
    check_time_limit(env, env_label)
    problem = check_algo(spec.algorithm, env)
    if problem:
        raise ConfigError(problem)
    free = free_bytes() if memory else None
    check_search_sizes(spec, env, free)  # first: a population's genotypes are the most a search holds
    check_training_sizes(spec, env, *algorithm_spec(spec.algorithm).env_batch(algo_settings(spec.algorithm)), free)
    if rule is not None and rule.kind == "eval":  # train/ metrics are the update's: known once it is traced
        names = evaluation_metrics(spec, env)
        if rule.metric not in names:
            raise ConfigError(
                f"stop.when={stop_when!r}: eval rows have no {rule.metric!r}; they have: {', '.join(names)}"
            )
    if objective[0] == "eval" and objective[1] not in ("return", "length"):  # the env's own: traced to be known
        names = evaluation_metrics(spec, env)
        if objective[1] not in names:
            raise ConfigError(
                f"objective={spec.training.objective}: eval rows have no {objective[1]!r}; they have: {', '.join(names)}"
            )
    placement(members.program_config(spec))
