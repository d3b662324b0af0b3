"""One run over several processes, e.g. one per GPU on several nodes (config key ``distributed``).

Every process runs the same `rlq train` command and the same host code; JAX's multi-process runtime
(``jax.distributed``) joins them, so the run's mesh (rlq/run/programs/devices.py) covers every process's
devices and each compiled program runs as one SPMD program over all of them. Only process 0 writes
the run directory; the others write theirs in a scratch directory (rlq/cli/train.py), but still take
part in every collective: a host copy of a sharded array (``to_host``, rlq.lib.sharding) gathers it from all processes.

``enabled: auto`` joins processes when ``num_processes`` > 1 is given or when ``srun`` started several
tasks; null settings are read by JAX from SLURM's environment. Each key's allowed values are its declaration's
(rlq/declared/run.py's ``Distributed``); ``settings`` holds them to it before anything else checks the run, as it
starts the runtime first.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np

from rlq.declared.run import Distributed
from rlq.errors import ConfigError, PeersMissingError
from rlq.lib.settings import problems

#: the number of tasks of the ``srun`` step a process belongs to
SRUN_TASKS = "SLURM_STEP_NUM_TASKS"
#: how much later than rlq's deadline JAX's own comes (past it, JAX ends the process with a stack trace)
JAX_GRACE_S = 60


@dataclass(frozen=True)
class Settings:
    """What ``jax.distributed.initialize`` is given (None: JAX reads it from the cluster's environment)."""

    enabled: bool
    coordinator_address: str | None = None
    num_processes: int | None = None
    process_id: int | None = None
    #: seconds to wait for every process to join (``distributed.timeout_s``)
    timeout_s: int = 300


def _whole(value: Any) -> int | None:
    """A declared integer key's value (its range admits ``2.0``) as an int, or None."""
    return None if value is None else int(value)


def srun_tasks(environ: Mapping[str, str] = os.environ) -> int:
    """How many tasks the ``srun`` step of this process has (1 outside one)."""
    try:
        return int(environ.get(SRUN_TASKS, "1"))
    except ValueError:
        return 1


def settings(node: Mapping[str, Any], environ: Mapping[str, str] = os.environ) -> Settings:
    """The run's ``distributed`` settings (``node``: its section, ``RunSpec.devices.distributed``), checked against
    their declaration, then what it cannot say; a bad value is a ConfigError."""
    problem = problems(Distributed, node, "distributed")
    if problem:
        raise ConfigError(problem)
    enabled = node["enabled"]
    address = node["coordinator_address"]
    if address is not None and (not isinstance(address, str) or ":" not in address):
        raise ConfigError(f"distributed.coordinator_address must be host:port (e.g. node001:12345), got {address!r}")
    count, index = _whole(node["num_processes"]), _whole(node["process_id"])
    if count is not None and index is not None and index >= count:
        raise ConfigError(
            f"distributed.process_id={index} must be below distributed.num_processes={count} (processes count from 0)"
        )
    if enabled == "auto":
        enabled = (count or srun_tasks(environ)) > 1
    if enabled and "SLURM_JOB_ID" not in environ and None in (address, count, index):
        raise ConfigError(
            "distributed: outside SLURM give distributed.coordinator_address, distributed.num_processes and "
            "distributed.process_id (each process its own), or distributed.enabled=false"
        )
    return Settings(bool(enabled), address, count, index, int(node["timeout_s"]))


def missing(wanted: Settings) -> str:
    """The line of a start that timed out: who waited, for whom, and what to do."""
    where = wanted.coordinator_address or "the address SLURM gives"
    waited = f"waited {wanted.timeout_s} s (distributed.timeout_s)"
    if wanted.process_id in (None, 0) and wanted.num_processes is not None:
        others = ", ".join(str(i) for i in range(1, wanted.num_processes))
        plural = "es" if wanted.num_processes > 2 else ""
        return (
            f"distributed: process 0 {waited} at {where} for process{plural} {others} of {wanted.num_processes}, "
            "which did not all join; start each with the same command and its own distributed.process_id"
        )
    if wanted.process_id is not None:
        return (
            f"distributed: process {wanted.process_id} {waited} for process 0 at {where}, which did not answer; "
            "start process 0 (the coordinator) with the same command"
        )
    return f"distributed: {waited} at {where} for the run's other processes, which did not all join"


def start(node: Mapping[str, Any]) -> bool:
    """Join this process to the run's others (``jax.distributed.initialize``) when the config says so,
    once, before JAX starts its backends; returns whether the run spans several processes. CPU
    devices of several processes talk through gloo (JAX's CPU default has no cross-process collectives)."""
    wanted = settings(node)
    if not wanted.enabled:
        return False
    if jax.distributed.is_initialized():
        return True
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    failed: list[BaseException] = []
    joined = threading.Event()

    def join() -> None:
        try:  # JAX's own deadline comes later: past it, its runtime ends the process with a stack trace
            jax.distributed.initialize(
                coordinator_address=wanted.coordinator_address,
                num_processes=wanted.num_processes,
                process_id=wanted.process_id,
                initialization_timeout=wanted.timeout_s + JAX_GRACE_S,
            )
        except BaseException as err:
            failed.append(err)
        finally:
            joined.set()

    # in a thread, so that the wait has a deadline: the call blocks in native code, deaf to Python
    threading.Thread(target=join, name="rlq-distributed-join", daemon=True).start()
    if not joined.wait(wanted.timeout_s):
        raise PeersMissingError(missing(wanted))
    if failed:
        if isinstance(failed[0], (RuntimeError, ValueError)):
            raise ConfigError(f"distributed: {str(failed[0]).splitlines()[0]}") from None
        raise failed[0]
    return True


#: seconds a process stopping with the others waits for them to leave the run (``leave``)
LEAVE_S = 10


def leave(deadline_s: float = LEAVE_S) -> None:
    """Disconnect from the run's other processes before this one ends at a stop (a barrier in JAX's
    coordination service, ``jax.distributed.shutdown``): JAX aborts a process, stack trace and all, whose
    coordinator (process 0) ended first. A process that does not come within ``deadline_s`` is not waited
    for; a run of one process does nothing."""
    if not jax.distributed.is_initialized():
        return
    left = threading.Event()

    def disconnect() -> None:
        try:
            jax.distributed.shutdown()
        except Exception:  # noqa: BLE001 - the process ends now whatever the others do
            pass
        finally:
            left.set()

    threading.Thread(target=disconnect, name="rlq-distributed-leave", daemon=True).start()
    left.wait(deadline_s)


#: seconds a process that stops before training waits for the others to leave with it (within the 5 s of such a stop)
LEAVE_EARLY_S = 3
#: the coordination service's key of a run's stop: the number of the first signal a process of the run received
STOP_KEY = "rlq/stop"


class PeerStops:
    """A stop of any of a run's processes, as every process sees it (rlq.run.stops.signals.Peers): the first signal one
    receives is published in JAX's coordination service (``client``), which the others read."""

    def __init__(self, client: Any):
        self.client = client

    def publish(self, signum: int) -> None:
        try:
            self.client.key_value_set(STOP_KEY, str(signum))
        except Exception:  # noqa: BLE001 - another process published first
            pass

    def seen(self) -> int | None:
        try:
            return int(self.client.key_value_try_get(STOP_KEY))
        except Exception:  # noqa: BLE001 - no process was stopped
            return None

    def leave(self) -> None:
        leave(LEAVE_EARLY_S)


def peer_stops() -> PeerStops | None:
    """The run's other processes' stops; None in a run of one process."""
    client = coordination_client()
    return None if client is None else PeerStops(client)


def coordination_client() -> Any | None:
    """JAX's client of the coordination service that joins this run's processes (its key-value store is
    host-side: processes agree there without a collective on the devices); None in a run of one process."""
    if jax.process_count() == 1:
        return None
    from jax._src import distributed  # no public name for it (JAX 0.10)

    return distributed.global_state.client


def agreed_signal(signum: int | None) -> int | None:
    """The signal that stops the run, as every process sees it: one process's SIGTERM stops all of
    them after the same chunk (a collective where the run spans processes)."""
    if jax.process_count() == 1:
        return signum
    from jax.experimental import multihost_utils

    seen = multihost_utils.process_allgather(np.int32(signum or 0))
    top = int(np.max(seen))
    return top or None


def agreed_calls(calls: int) -> int:
    """The calls of a chunk's next slice, as every process makes them (the fewest any process asks
    for: each times its own slices, and all must call the same programs)."""
    if jax.process_count() == 1:
        return calls
    from jax.experimental import multihost_utils

    return int(np.min(multihost_utils.process_allgather(np.int32(calls))))
