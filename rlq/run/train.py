"""THE training loop: one compiled program per chunk of updates, for every algorithm.

    state = jit(vmap(algo.init))(seed keys, hyperparams)    # all seeds in one program
    loop:  state, metrics = jit(vmap(scan(algo.update, K)))(state, hyperparams)
           hooks on the host (rlq/run/hooks.py): log, figures, evaluate, checkpoint

Metrics leave the device once per chunk of K updates; algorithms never do I/O. The programs
(rlq/run/programs/build.py) are compiled as rlq/run/programs/compiling.py says; training starts once init and chunk
are compiled. Every program runs on the run's mesh (rlq/run/programs/devices.py): its inputs and outputs are
split along the seed axis, and the programs split each seed's envs over the mesh's env devices.

A run goes in three steps, each handing the next a typed state: ``prepare`` (rlq/run/prepare.py: the plan, then
the programs compiled and the first state: ``Plan``, ``Ready``), ``loop`` (rlq/run/loop.py: the chunks, to
``Trained``) and ``finish`` (rlq/run/finish.py: final evaluation, checkpoint, video, the ``RunResult``).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import jax

from rlq.config.spec import RunSpec, as_spec
from rlq.errors import DivergedError, RunInterrupted
from rlq.lib.sharding import is_writer
from rlq.run.finish import finish, write_summary
from rlq.run.loop import loop
from rlq.run.prepare import prepare, start
from rlq.run.programs import members
from rlq.run.programs.devices import Placement, placement
from rlq.run.programs.distributed import peer_stops
from rlq.run.result import RunResult
from rlq.run.stops.signals import StopRequest
from rlq.store.sidecar import config_hash


def _warn(text: str) -> None:
    print(f"rlq: warning: {text}", file=sys.stderr, flush=True)


def train(
    run: RunSpec | Mapping[str, Any],
    run_dir: Path,
    resume: Path | None = None,
    warm: Callable[[Any], Any] | None = None,
    finish: bool = False,
) -> RunResult:
    """Train the ``num_seeds`` seeds of one run (a RunSpec, or a composed config read as one); write metrics and checkpoints to ``run_dir``.

    ``resume``: a checkpoint of this run written at the end of a chunk; training goes on from it
    to the budget (the state holds every PRNG key, so it continues exactly as the run would have).
    SIGINT/SIGTERM end the run after the slice of a chunk in flight with a resumable checkpoint,
    skipping an evaluation or a video in flight (RunInterrupted); NaN/Inf in parameters, losses or returns end
    it at once (DivergedError).
    ``warm``: maps a fresh run's initial state (on the host) to the one it starts from (``init_from``).
    ``finish``: ``resume`` is the final checkpoint of a run killed before its summary.json; the run makes
    what follows that checkpoint (final evaluation, figures, video, summary, members) and trains nothing."""
    # eager operations (keys, checkpoints) go to the run's kind of device too (config key ``platform``)
    spec = as_spec(run)
    state_hash = config_hash(spec.values)
    program = members.program_config(spec)  # an in-program sweep trains every member's seeds
    where = placement(program)
    with StopRequest(_warn, peer_stops()) as stop, jax.default_device(where.local_device):
        result = _train(program, where, Path(run_dir), resume, stop, state_hash, warm, finish)
    if members.sweeping(spec) and is_writer():
        written = members.write_members(spec, Path(run_dir))
        print(members.summary_lines(Path(run_dir), written), flush=True)
    return result


def _train(
    spec: RunSpec,
    where: Placement,
    run_dir: Path,
    resume: Path | None,
    stop: StopRequest,
    state_hash: str,
    warm: Callable[[Any], Any] | None = None,
    finishing: bool = False,
) -> RunResult:
    """``train`` on ``where`` with ``stop`` listening: prepare, loop, finish, then ``summary.json``. A stop or
    a divergence ends rlq.log with the line the CLI prints."""
    plan = prepare(spec, where, run_dir, resume, stop, state_hash, finishing)
    try:
        ready = start(plan, warm)
        result, final_error = finish(plan, ready, loop(plan, ready))
    except (DivergedError, RunInterrupted) as ended:  # the line the CLI prints ends rlq.log too
        plan.logger.record(f"rlq: {ended}" if isinstance(ended, RunInterrupted) else f"rlq: error: {ended}")
        raise
    finally:
        plan.evaluator.shutdown(wait=False, cancel_futures=True)  # an abandoned evaluation ends with the process
        plan.logger.close()
    recorded: dict[str, Any] = dict(result.as_dict())
    if final_error is not None:
        recorded["final_checkpoint_error"] = f"{final_error.strerror}: {final_error.filename}"
    write_summary(run_dir, recorded)
    if final_error is not None:
        raise final_error
    return result
