"""Whole compiled programs kept on disk (config keys ``program_cache`` and ``compile_cache``).

JAX's persistent cache (rlq.run.programs.compile_cache) skips XLA's compile on a second run, but every
program is still traced and lowered first: for the MJX humanoid that is most of a warm start
(tens of seconds: MJX's physics is traced once per program). This cache keeps a run's compiled
``init``, ``chunk`` and ``evaluate`` programs as JAX's serialized executables
(``jax.experimental.serialize_executable``); a later run whose key matches loads them without
tracing anything.

The key is a digest of everything that shapes the programs: the run config without the keys that
only steer the host (``IGNORED_KEYS``: seed, logging, checkpoints, videos, stop rule), without the
algorithm's numeric hyperparameters (``AlgorithmSpec.sweepable``: the init and chunk programs take them as an
argument, so a sweep over a learning rate loads the programs its first job compiled) and with an in-program
sweep's keys and counts of values but not its values (``sweep_shape``: the same argument), the source
of the rlq package, the versions of the packages that trace into the programs (``PACKAGES``), the
device kind and ids, the Python version, ``XLA_FLAGS`` and JAX's x64 and matmul-precision flags.
Runs spread over more than one device use JAX's cache only, and so do CPU runs of envs whose programs
XLA's CPU runtime cannot reload (the MJX envs), unless ``program_cache=always`` (see ``CPU_RELOADS``;
the key's values are declared in rlq/declared/run.py). A file that cannot be read back is deleted and the
programs compiled again. Like JAX's cache, loading runs code from the cache directory: keep it
private.

The process also keeps the last few program sets it stored or loaded (``KEPT_SETS``), each as long as its file
stands as it was: the later jobs of a sweep that runs in one process (Hydra's basic and Optuna sweepers) take
their programs from memory instead of deserialising them again (DQN LunarLander on 2 CPU cores: 1.6-2.1 s per job).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import pickle
import sys
import threading
from collections import OrderedDict
from collections.abc import Iterable, Iterator, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any, cast

import jax
from jax.experimental import serialize_executable

from rlq.algos import algorithm_spec
from rlq.config.plain import plain
from rlq.config.spec import RunSpec, as_spec
from rlq.lib.versions import installed_versions
from rlq.run.programs import compile_cache
from rlq.run.programs.devices import Placement
from rlq.store.files import write_atomic

#: top-level config keys that never reach a compiled program
IGNORED_KEYS = (
    "seed",
    "logger",
    "run_name",
    "video",
    "checkpoint",
    "stop",
    "compile_cache",
    "program_cache",
    "shaped_for",
    "machine",
    "allow_untuned",
    "hydra",
)
#: the envs whose programs ``program_cache=auto`` keeps on a CPU (on a GPU: every env's), as XLA's CPU runtime reloads
#: them (tests/run/test_program_cache.py; not every program: the MJX humanoid's crash the process that loads them), but
#: for programs that call a custom call (``Declined``): a sweep's later job on a CPU loads them whole instead of
#: tracing them for JAX's cache (CartPole PPO, 2 cores at load 3-7: 0.4-1.4 s instead of 1.0-2.8 s,
#: scripts/bench_sweep_compile.py)
CPU_RELOADS = ("cartpole", "lunar")
#: what marks a custom call in a compiled program's text
CUSTOM_CALL = "custom_call_target="


class Declined(str):
    """Why ``program_cache=auto`` leaves a CPU program to JAX's cache, said nowhere: it calls a custom call (LAPACK's
    eigendecomposition in CMA-ES), and XLA's CPU runtime crashes the process that runs such a program reloaded."""


#: a serialised program: its bytes and its input and output tree structures
Packed = tuple[bytes, Any, Any]
#: the programs a run needs before its first chunk: loaded before the others (``ProgramCache.load_first``)
FIRST = ("init", "chunk")
#: how many program sets the process keeps in memory (``ProgramCache.load`` takes them from there)
KEPT_SETS = 4
#: what identifies a cache file's contents: its inode, modification time (ns) and size
Stamp = tuple[int, int, int]
#: the program sets the process stored or loaded, by file, with the stamp of the file they came with
_KEPT: OrderedDict[Path, tuple[Stamp, dict[str, jax.stages.Compiled]]] = OrderedDict()
_KEPT_LOCK = threading.Lock()
#: packages whose code is traced into rlq's programs
PACKAGES = ("jax", "jaxlib", "flax", "optax", "mujoco", "mujoco-mjx", "brax", "gymnax", "biorobot")


#: the installed rlq package (this file is rlq/run/programs/program_cache.py)
PACKAGE_ROOT = Path(__file__).resolve().parents[2]


def source_files() -> list[Path]:
    """Every file of the rlq package (code, configs, assets), in a fixed order."""
    return sorted(p for p in PACKAGE_ROOT.rglob("*") if p.is_file() and "__pycache__" not in p.parts)


@functools.cache
def source_digest() -> str:
    """sha256 of every file of the installed rlq package: a change anywhere in rlq (an algorithm, an env, the
    rollout) names new programs."""
    digest = hashlib.sha256()
    for path in source_files():
        digest.update(str(path.relative_to(PACKAGE_ROOT)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def package_versions() -> dict[str, str | None]:
    return installed_versions(PACKAGES)


def sweep_shape(spec: RunSpec) -> dict[str, int]:
    """What of an in-program sweep shapes its programs: each swept key and its number of values. The values enter
    init and the chunk as their hyperparameter argument (rlq.run.programs.build.hyper_values), so a sweep over other
    values of the same keys runs the same programs."""
    return {name: len(values) for name, values in spec.training.sweep.items()}


def program_config(run: RunSpec | Mapping[str, Any]) -> dict[str, Any]:
    """The part of the run's config that shapes the programs: without ``IGNORED_KEYS``, without the
    algorithm's numeric hyperparameters (``AlgorithmSpec.sweepable``), which init and the chunk take as an
    argument, and with an in-program sweep's shape for its values (``sweep_shape``)."""
    spec = as_spec(run)
    shaping = plain({key: value for key, value in spec.values.items() if key not in IGNORED_KEYS})
    if "sweep" in shaping:
        shaping["sweep"] = sweep_shape(spec)
    if "eval" in shaping:
        shaping["eval"].pop("keep", None)  # which evaluated state the run ends with: the host's choice
    if "algo" in shaping:
        for name in algorithm_spec(spec.algorithm).sweepable:
            *parents, leaf = name.split(".")
            node = shaping["algo"]
            for parent in parents:
                node = node[parent]  # a sweepable key's group: declared by the algorithm
            node.pop(leaf, None)
    return cast(dict[str, Any], shaping)


def program_key(run: RunSpec | Mapping[str, Any], devices: Iterable[jax.Device]) -> str:
    """The digest that names a run's programs in the cache (see the module docstring)."""
    parts = {
        "config": program_config(run),
        "source": source_digest(),
        "packages": package_versions(),
        "devices": [(d.platform, d.device_kind, d.id) for d in devices],
        "python": list(sys.version_info[:2]),
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "jax_flags": [jax.config.values["jax_enable_x64"], str(jax.config.values["jax_default_matmul_precision"])],
    }
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()


#: the event JAX records when its persistent cache supplies a compiled program
CACHE_HIT_EVENT = "/jax/compilation_cache/cache_hits"


#: the name of the program a thread compiles (``compiling(name)``), which a cache hit is reported under
_COMPILING = threading.local()


@contextlib.contextmanager
def compiling(name: str) -> Iterator[None]:
    """Marks the calling thread as compiling program ``name`` (for ``watch_cache_hits``)."""
    _COMPILING.name = name
    try:
        yield
    finally:
        _COMPILING.name = None


@contextlib.contextmanager
def watch_cache_hits() -> Iterator[list[str]]:
    """Collects JAX's persistent-cache hits while active (compiles in any thread): the names of the programs
    (``compiling``) JAX's cache supplied, in the order it did (``""`` for a compile not marked)."""
    hits: list[str] = []

    def listener(event: str, **kwargs: Any) -> None:
        if event == CACHE_HIT_EVENT:
            hits.append(getattr(_COMPILING, "name", None) or "")

    jax.monitoring.register_event_listener(listener)
    try:
        yield hits
    finally:
        jax.monitoring.unregister_event_listener(listener)


class ProgramCache:
    """The compiled programs of one run key, together in one file ``<dir>/<key>.bin``.

    Only programs XLA has just compiled are stored, as one set: an executable that JAX's own cache
    supplied does not survive a second serialisation on XLA's CPU runtime (it loads, then fails to
    dispatch), so ``rlq.run.programs.compiling.compile_programs`` keeps nothing when JAX's cache was hit."""

    def __init__(self, directory: Path, key: str, devices: list[jax.Device], custom_calls: bool = True):
        """``custom_calls``: keep programs that call custom calls (not on a CPU under ``program_cache=auto``)."""
        self.path = directory / f"{key}.bin"
        self.devices = devices
        self.custom_calls = custom_calls
        #: the programs loaded from the file kept once all are (``load_first``)
        self._keeping: Future[None] = finished(None)

    @classmethod
    def for_run(cls, run: RunSpec | Mapping[str, Any], where: Placement) -> ProgramCache | None:
        """The run's cache, or None when ``compile_cache`` is off, ``program_cache`` does not apply to
        the run's device and env, or the run spans several devices."""
        spec = as_spec(run)
        base = compile_cache.cache_dir(spec.compilation.compile_cache)
        devices = list(where.mesh.devices.flat)
        mode = spec.compilation.program_cache
        reloads = devices[0].platform != "cpu" or spec.env["name"] in CPU_RELOADS
        if base is None or len(devices) != 1 or mode == "never" or (mode == "auto" and not reloads):
            return None
        cpu_auto = mode == "auto" and devices[0].platform == "cpu"
        return cls(base / "programs", program_key(spec, devices), devices, custom_calls=not cpu_auto)

    def load(self) -> dict[str, jax.stages.Compiled] | None:
        """The stored programs by name (``load_first``, all of them waited for); None when absent or unreadable
        (then the file goes)."""
        loading = self.load_first()
        if loading is None:
            return None
        try:
            loaded = {name: future.result() for name, future in loading.items()}
        except Exception:  # ``load_first`` has deleted the file
            return None
        self._keeping.result()
        return loaded

    def load_first(self) -> dict[str, Future[jax.stages.Compiled]] | None:
        """The stored programs by name, as futures: those the process kept while the file stands as it was, else
        loaded from the file, ``FIRST`` side by side and done when this returns, the others (the evaluation, a
        chunk's last block) after them, while the run trains; None when absent or ``FIRST`` cannot be read (then
        the file goes, as it does when a later one cannot)."""
        kept = self._kept()
        if kept is not None:
            return {name: finished(program) for name, program in kept.items()}
        if not self.path.exists():
            return None
        pool = ThreadPoolExecutor(max_workers=max(1, len(FIRST)))
        try:
            stamp = _stamp(self.path)
            stored = pickle.loads(self.path.read_bytes())
            first = {name: pool.submit(self._deserialize, stored[name]) for name in FIRST if name in stored}
            loading = {name: finished(future.result()) for name, future in first.items()}
        except Exception:  # a truncated file or one jax can no longer read: compile again
            pool.shutdown(wait=False)
            self.path.unlink(missing_ok=True)
            return None
        loading.update(
            {name: pool.submit(self._deserialize, parts) for name, parts in stored.items() if name not in first}
        )
        self._keeping = pool.submit(self._keep_when_loaded, loading, stamp)
        pool.shutdown(wait=False)
        return loading

    def _keep_when_loaded(self, loading: Mapping[str, Future[jax.stages.Compiled]], stamp: Stamp | None) -> None:
        """Keep the programs once all are loaded; delete the file if one cannot be."""
        try:
            programs = {name: future.result() for name, future in loading.items()}
        except Exception:
            self.path.unlink(missing_ok=True)
            return
        self._keep(programs, stamp)

    def _kept(self) -> dict[str, jax.stages.Compiled] | None:
        """The programs the process kept for this file, if the file is still the one they came with."""
        with _KEPT_LOCK:
            entry = _KEPT.get(self.path)
            if entry is None:
                return None
            if entry[0] != _stamp(self.path):  # replaced or gone: its programs may differ
                del _KEPT[self.path]
                return None
            _KEPT.move_to_end(self.path)
            return dict(entry[1])

    def _keep(self, programs: Mapping[str, jax.stages.Compiled], stamp: Stamp | None) -> None:
        """Keep ``programs``, which the file of ``stamp`` holds, for the process's later runs."""
        if stamp is None:
            return
        with _KEPT_LOCK:
            _KEPT[self.path] = (stamp, dict(programs))
            _KEPT.move_to_end(self.path)
            while len(_KEPT) > KEPT_SETS:
                _KEPT.popitem(last=False)

    def _deserialize(self, parts: Packed) -> jax.stages.Compiled:
        serialized, in_tree, out_tree = parts
        return serialize_executable.deserialize_and_load(serialized, in_tree, out_tree, execution_devices=self.devices)

    def load_soon(self) -> Future[dict[str, Future[jax.stages.Compiled]] | None]:
        """``load_first`` in a worker thread, so that the run builds its env meanwhile."""
        pool = ThreadPoolExecutor(max_workers=1)
        future = pool.submit(self.load_first)
        pool.shutdown(wait=False)
        return future

    def pack(self, program: jax.stages.Compiled) -> Packed | str:
        """``program`` as bytes for ``store``, or why it cannot be (``Declined``: why it is not to be). Call it
        before the program first runs: once run, an executable of XLA's CPU runtime may hold parts it cannot
        serialise."""
        if not self.custom_calls and CUSTOM_CALL in (program.as_text() or ""):
            return Declined("a program calls a custom call")
        try:
            return serialize_executable.serialize(program)
        except Exception as error:  # XLA raises its runtime error type (e.g. an op it cannot serialise)
            return str(error)

    def store(
        self, packed: Mapping[str, Packed | str], programs: Mapping[str, jax.stages.Compiled] | None = None
    ) -> str | None:
        """Write the ``pack``-ed programs (atomically); returns why they could not be, or None (also when one was
        ``Declined``: nothing is written). ``programs``: the compiled programs themselves, kept in memory for the
        process's later runs once written."""
        if any(isinstance(value, Declined) for value in packed.values()):
            return None
        problems = [value for value in packed.values() if isinstance(value, str)]
        if problems:
            return problems[0]
        try:
            blob = pickle.dumps(dict(packed))
        except (pickle.PicklingError, TypeError) as error:
            return str(error)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(self.path, blob)
        except OSError as error:
            return str(error)
        if programs is not None:
            self._keep(programs, _stamp(self.path))
        return None


def finished(value: Any) -> Future:
    """A future that already holds ``value``."""
    future: Future = Future()
    future.set_result(value)
    return future


def _stamp(path: Path) -> Stamp | None:
    """What identifies the file at ``path`` as written (None: there is none)."""
    try:
        stat = path.stat()
    except OSError:
        return None
    return (stat.st_ino, stat.st_mtime_ns, stat.st_size)
