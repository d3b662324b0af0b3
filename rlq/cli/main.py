"""The `rlq` command: `rlq train [overrides]`, `rlq eval|render|export|resume run=<dir> [...]`, `rlq compare <dirs>`.

`rlq train` composes conf/ with Hydra's compose API and checks the config (rlq.run.checks.validate)
before Hydra makes a run directory, so a bad input ends with one line on stderr, exit code 2, and
nothing on disk. A single run then runs that config; a sweep composes each job again in hydra.main.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import MutableMapping
from typing import NoReturn

from rlq.cli.log_errors import warn_once_on_log_errors
from rlq.cli.quiet import quiet_dependencies
from rlq.errors import RlqError, RunInterrupted
from rlq.lib.registry import load

USAGE = """usage: rlq <command> [hydra overrides]

commands:
  train   train an agent:  rlq train algo=ppo env=cartpole num_seeds=8
          (-m/--multirun sweeps, --cfg job prints the config, --help lists the groups)
  eval    evaluate a run's checkpoint greedily:  rlq eval run=outputs/<date>/<time>_<name> episodes=100
  render  video of one greedy episode:  rlq render run=outputs/<date>/<time>_<name> [seed_index=0]
          (states saved where no OpenGL loaded:  rlq render run=<run dir> states=videos/final_seed0.npz)
  export  one seed's policy network alone (parameters + JSON spec; docs/usage.md: load it and act):
          rlq export run=outputs/<date>/<time>_<name> [checkpoint=<env steps>] [seed_index=0] out=params.msgpack
  resume  continue an unfinished run from its latest checkpoint (trained with checkpoint.every_steps>0),
          or extend a run to a larger budget:  rlq resume run=outputs/<date>/<time>_<name> [budget.env_steps=N]
  compare learning curves (mean ± std over seeds) and final metrics of runs or a sweep:
          rlq compare multirun/<date>/<time> [metric=eval/return] [x=env_steps|wall_s] [out=PATH]

`rlq <command> --help` lists a command's options; `rlq --version` prints rlq's version.
"""


def fail(message: str, code: int = 2) -> NoReturn:
    """The CLI's one error path: one line on stderr, exit code 2 (bad input) unless told."""
    print(f"rlq: error: {message}", file=sys.stderr)
    raise SystemExit(code)


def exit_for(err: RlqError) -> NoReturn:
    """One line for a typed error and its exit code: 2 bad input, 3 diverged, 128+N signal N."""
    if isinstance(err, RunInterrupted):
        print(f"rlq: {err}", file=sys.stderr, flush=True)
        sys.stdout.flush()
        if "jax" in sys.modules:  # a run over several processes: they leave together
            from rlq.run.programs.distributed import leave

            leave()
        # the checkpoint and the run's logs are written; a normal exit would join the worker threads first, and
        # one may still be compiling the evaluation program (on 2 busy CPU cores a LunarLander stop waited 77 s)
        os._exit(err.exit_code)
    if getattr(err, "abandons_threads", False):  # a thread blocked in native code: an orderly exit would wait on it
        print(f"rlq: error: {err}", file=sys.stderr, flush=True)
        sys.stdout.flush()
        os._exit(err.exit_code)
    fail(str(err), err.exit_code)


COMMANDS = {
    "train": "rlq.cli.train",
    "eval": "rlq.cli.eval",
    "render": "rlq.cli.render",
    "resume": "rlq.cli.resume",
    "compare": "rlq.cli.compare",
    "export": "rlq.cli.export",
}


HELP_FLAGS = ("-h", "--help")

#: JAX's switch for taking most of a GPU's memory when its first array is placed there
PREALLOCATE = "XLA_PYTHON_CLIENT_PREALLOCATE"


def gpu_memory_on_demand(environ: MutableMapping[str, str] = os.environ) -> None:
    """Let JAX take GPU memory as the run needs it instead of 75 % of the GPU up front, unless the
    user chose (``XLA_PYTHON_CLIENT_PREALLOCATE`` set either way).

    Taking it up front delayed the first array placed on the GPU, on the path to every GPU run's
    first compile, and the process's end (figures: docs/results.md). It also
    left a second process on the same GPU (a sweep's, an `rlq eval` beside training) a quarter of
    the memory. Read by JAX when its GPU backend starts, so this runs before any command imports
    an env."""
    environ.setdefault(PREALLOCATE, "false")


def stop_at_once(signum: int, frame: object) -> NoReturn:
    """SIGINT/SIGTERM outside training (starting up, composing, evaluating): nothing to save, one line, exit
    128 + N. Training installs its own handlers (rlq.run.stops.signals), which save a checkpoint once there is one."""
    name = signal.Signals(signum).name
    print(f"rlq: stopped by {name}: nothing to save", file=sys.stderr, flush=True)
    sys.stdout.flush()
    # not SystemExit: raised from a handler it can land in a callback that swallows it (JAX's gc callback did)
    os._exit(128 + signum)


def main(argv: list[str] | None = None) -> None:
    """Dispatch to a subcommand (imported on use, so `rlq --help` starts fast).

    ``-h``/``--help`` after a subcommand prints its ``HELP`` (a text, or a function that writes it: train's reads
    conf/; ``rlq train --hydra-help`` is Hydra's)."""
    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {signum: signal.signal(signum, stop_at_once) for signum in (signal.SIGINT, signal.SIGTERM)}
    try:
        dispatch(argv)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def dispatch(argv: list[str] | None) -> None:
    gpu_memory_on_demand()
    quiet_dependencies()
    warn_once_on_log_errors()
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE)
        return
    if argv[0] in ("-V", "--version"):
        from rlq import __version__

        print(f"rlq {__version__}")
        return
    command, args = argv[0], argv[1:]
    if command not in COMMANDS:
        fail(f"unknown command '{command}'; use one of: {', '.join(COMMANDS)} (see `rlq --help`)")
    module = load(COMMANDS, command, "command")
    help_text = getattr(module, "HELP", None)
    if help_text and any(a in HELP_FLAGS for a in args):
        print(help_text() if callable(help_text) else help_text, end="")
        return
    try:
        getattr(module, f"{command}_main")(args)
    except RlqError as err:
        exit_for(err)
    except OSError as err:  # a file the command reads or writes: a read-only run directory, a full disk
        fail(os_problem(err), 1)


def os_problem(err: OSError) -> str:
    """An OSError as one line: what failed, on which path."""
    where = " -> ".join(str(name) for name in (err.filename, err.filename2) if name is not None)
    return f"{err.strerror or err}: {where}" if where else str(err.strerror or err)
