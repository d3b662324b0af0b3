"""Which local devices a run uses and how its batch axes are laid over them (config key ``devices``).

The devices form a mesh of two axes (rlq.lib.sharding): ``seed``, as many devices as divide
``num_seeds`` (all of them when there are at least as many seeds and they divide evenly), and
``env``, the rest, which split each seed's batch of envs or scored candidates (the algorithm
names that batch in its ``AlgorithmSpec.env_axis``). One device is the same programs on a 1 x 1 mesh.

By default (``devices: null``) a run splits its seeds only: a seed's envs never span devices, because
that does not pay for the humanoid on 2 GPUs (1.01x with ``algo.minibatch_shuffle=per_shard``, 0.86x before):
a GPU is far from full with 2048 of them (``scripts/bench_devices.py --scale bound``).
``devices=all``, a count or a list of indices ask for the env split too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from rlq.config.spec import RunSpec, as_spec
from rlq.errors import ConfigError
from rlq.lib.sharding import ENV, SEED


def local_devices(platform: object = None) -> list[jax.Device]:
    """This machine's devices of ``platform`` (config key ``platform``, whose values rlq/declared/run.py declares):
    null for JAX's default kind (the accelerator when there is one), ``cpu`` or ``gpu``; a ConfigError where this
    machine has none of that kind."""
    if platform is None:
        return jax.local_devices()
    try:
        return jax.local_devices(backend=str(platform))
    except RuntimeError:
        raise ConfigError(f"platform={platform} but JAX finds no {platform} device here; use platform=null") from None


def keep_to_the_cpu() -> None:
    """Keep JAX to the CPU for the rest of the process, before it starts its backends: a
    ``platform=cpu`` run on a GPU node then neither starts the GPU nor reserves its memory (JAX
    takes most of it by default), so several such runs share the node. Called by `rlq train` for
    a single run; once JAX's backends have started it changes nothing."""
    jax.config.update("jax_platforms", "cpu")


def select_devices(spec: object, platform: object = None) -> list[jax.Device]:
    """The local devices of ``platform`` named by ``devices``: null or ``all`` (all of them; ``placement`` uses
    fewer for null), a count (the first N) or a list of indices. A run over several processes
    (rlq/run/programs/distributed.py) takes every process's devices, so only null or ``all``."""
    local = local_devices(platform)
    if jax.process_count() > 1:
        if spec is not None and spec != "all":
            raise ConfigError(
                f"devices={spec!r} over {jax.process_count()} processes: use devices=null or all (every process's devices)"
            )
        return list(jax.devices(local[0].platform))
    if spec is None or spec == "all":
        return local
    if isinstance(spec, int) and not isinstance(spec, bool):
        if not 1 <= spec <= len(local):
            raise ConfigError(f"devices={spec} but this machine has {len(local)} local device(s); use 1..{len(local)}")
        return local[:spec]
    if isinstance(spec, (list, tuple)) and spec:
        indices = list(spec)
        if not all(isinstance(i, int) and not isinstance(i, bool) and 0 <= i < len(local) for i in indices):
            raise ConfigError(f"devices={indices}: indices must be integers in 0..{len(local) - 1}")
        if len(set(indices)) != len(indices):
            raise ConfigError(f"devices={indices} names a device twice")
        return [local[i] for i in indices]
    raise ConfigError(f"devices must be null (split the seeds), all, a count or a list of indices, got {spec!r}")


@dataclass(frozen=True)
class Placement:
    """The run's mesh: ``seed_shards`` x ``env_shards`` devices."""

    mesh: Mesh
    #: the one console line a run with idle local devices starts with (None: every device is used)
    note: str | None = None

    @property
    def platform(self) -> str:
        """The kind of the mesh's devices: ``cpu``, ``gpu``, ..."""
        return str(self.mesh.devices.flat[0].platform)

    @property
    def local_device(self) -> jax.Device:
        """This process's first device of the mesh: where its eager operations run."""
        return next(d for d in self.mesh.devices.flat if d.process_index == jax.process_index())

    @property
    def seed_shards(self) -> int:
        return int(self.mesh.shape[SEED])

    @property
    def env_shards(self) -> int:
        return int(self.mesh.shape[ENV])

    @property
    def seeds(self) -> NamedSharding:
        """Every leaf of a run's state, keys and metrics: split along its leading (seed) axis."""
        return NamedSharding(self.mesh, PartitionSpec(SEED))

    def describe(self) -> str:
        count = self.seed_shards * self.env_shards
        return f"{count} device(s): seeds over {self.seed_shards}, envs over {self.env_shards}"


def shape_note(run: RunSpec | Mapping[str, Any], platform: str) -> str | None:
    """The warning a run starts with when its device kind is not the one its preset's sizes are chosen
    for (``shaped_for``): a GPU preset's thousands of envs take minutes per million steps on a CPU."""
    shaped_for = as_spec(run).devices.shaped_for
    wanted = shaped_for.platform
    if wanted is None or wanted == platform:
        return None
    text = f"this config is shaped for a {wanted} (shaped_for.platform) and runs on the {platform} here, which is slow"
    return f"{text}; {shaped_for.note}" if shaped_for.note else text


def placement(run: RunSpec | Mapping[str, Any]) -> Placement:
    """Lay the selected devices over the seed and env axes; a device count that does not divide the
    axis it must split is a ConfigError, raised before anything compiles."""
    from rlq.algos import algo_settings, algorithm_spec

    run_spec = as_spec(run)
    spec, platform = run_spec.devices.devices, run_spec.devices.platform
    devices = select_devices(spec, platform)
    count, num_seeds = len(devices), int(run_spec.seeds.count)
    note = None
    if spec is None and math.gcd(count, num_seeds) < count:
        used = math.gcd(count, num_seeds)
        note = (
            f"{count} {'local ' if jax.process_count() == 1 else ''}devices: num_seeds={num_seeds} runs on {used} (seeds split over devices, never one "
            f"seed's envs, which is slower for most runs); devices=all also splits each seed's envs"
        )
        devices, count = devices[:used], used
    processes = {d.process_index for d in devices}
    if len(processes) < jax.process_count():
        raise ConfigError(
            f"num_seeds={num_seeds} uses {count} of the {len(select_devices(spec, platform))} devices of "
            f"{jax.process_count()} processes, leaving a process none; set num_seeds to a multiple of the device "
            "count, or devices=all"
        )
    seed_shards = math.gcd(count, num_seeds)
    env_shards = count // seed_shards
    if env_shards > 1:
        fix = f"set devices={seed_shards} or num_seeds to a multiple of {count}"
        algo_spec, algo_cfg = algorithm_spec(run_spec.algorithm), algo_settings(run_spec.algorithm)
        key, size = algo_spec.env_batch(algo_cfg)
        if size % env_shards:
            raise ConfigError(
                f"{count} devices with num_seeds={num_seeds} split {key}={size} over {env_shards} devices, "
                f"which does not divide it; {fix}, or {key} to a multiple of {env_shards}"
            )
        problem = algo_spec.check_env_shards(algo_cfg, env_shards)
        if problem:
            raise ConfigError(f"{problem}, or {fix}")
    grid = np.array(devices, dtype=object).reshape(seed_shards, env_shards)
    return Placement(Mesh(grid, (SEED, ENV)), note)
