"""The run's own keys (``seed``, ``num_seeds``, ``budget.env_steps``, ``eval.*``, ``checkpoint.*``, ``guard.*``,
``video.*``, ``logger.*``, ...): a frozen dataclass ``Config`` whose fields give each key's type, default, allowed
values (``rlq.lib.settings.setting``) and meaning (its comment). The one home of a run key's type, default and range:
rlq/config/store.py registers it as the primary config's schema ``run_schema``, which conf/config.yaml's defaults list
composes first (conf/config.yaml, conf/logger/ and conf/machine/ write no default of their own:
tests/config/test_run_keys.py), and rlq's check of the run's values (rlq/run/checks/constraints.py) reads its ranges.

Keys whose values are free-form stay so: a group of options (``eval.env``, ``sweep``, ``compiler_options``) is a
``dict``, and a key that takes several kinds of value (``devices``, ``compile_cache``) is ``Any``, checked by the code
that reads it (rlq/run/programs/); ``distributed.enabled`` takes a name or a boolean, which its choices say. Checks
that relate several keys or need the machine (a device JAX finds, SLURM's variables) are the runner's
(rlq/run/checks/validate.py, rlq/run/programs/devices.py and distributed.py). Apart from the runner so that composing a
config imports no JAX."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from rlq.lib.settings import BUDGET, COUNT, POSITIVE_INT, SEED, OneOf, Range, setting

#: values of ``chunk_loop`` (rlq.run.programs.cadences)
CHUNK_LOOPS = ("scan", "calls")
#: device kinds a run may be placed on or shaped for (``platform``, ``shaped_for.platform``; rlq.run.programs.devices)
PLATFORMS = ("cpu", "gpu")
#: values of ``distributed.enabled`` (rlq.run.programs.distributed)
DISTRIBUTED = ("auto", True, False)
#: what null means for ``distributed.num_processes`` and ``distributed.process_id``
FROM_SLURM = "null (read from SLURM)"
#: values of ``program_cache`` (rlq.run.programs.program_cache)
PROGRAM_CACHE_MODES = ("auto", "always", "never")
#: W&B modes rlq passes to ``wandb.init``
WANDB_MODES = ("offline", "online", "disabled")
#: ``eval.keep``: the last state's policy (the default), or each seed's best evaluated one (rlq/run/kept.py)
KEEP_CHOICES = ("last", "best")


def _options() -> Any:
    """A group of free-form options, empty by default (one dict per instance)."""
    return dataclasses.field(default_factory=dict)


@dataclass(frozen=True)
class ShapedFor:
    """``shaped_for``: the device kind a preset's sizes are chosen for; a run on another kind starts with a warning."""

    #: null (any) | cpu | gpu
    platform: str | None = setting(None, OneOf(PLATFORMS))
    #: what to run there instead, e.g. "on a CPU use experiment=lunar_ppo"
    note: str = setting("")


@dataclass(frozen=True)
class Distributed:
    """``distributed``: one run over several processes (JAX's multi-process runtime; README "Running on a
    cluster"); rlq.run.programs.distributed reads these keys and checks what the declaration cannot say (host:port,
    a process index below the count, SLURM's variables where a key is null)."""

    #: auto (when num_processes > 1 or srun started several tasks) | true | false
    enabled: Any = setting("auto", OneOf(DISTRIBUTED))
    #: host:port of process 0; null: read from SLURM (under srun)
    coordinator_address: str | None = setting(None)
    #: null: SLURM's task count
    num_processes: int | None = setting(None, Range(1, integer=True, null=FROM_SLURM))
    #: this process's index, 0..num_processes-1; null: SLURM's task id
    process_id: int | None = setting(None, Range(0, integer=True, null=FROM_SLURM))
    #: seconds to wait for every process to join; then one line naming who is missing, exit 2
    timeout_s: int = setting(300, Range(1, integer=True))


@dataclass(frozen=True)
class Budget:
    """``budget``: how long the run trains."""

    #: env steps per seed (the run's step and update counters are 32-bit integers on the device)
    env_steps: int = setting(500000, BUDGET)


@dataclass(frozen=True)
class Eval:
    """``eval``: the greedy evaluations."""

    #: greedy evaluation cadence (0: only at the end)
    every_steps: int = setting(100000, COUNT)
    #: episodes per seed and evaluation
    episodes: int = setting(32, POSITIVE_INT)
    #: the policy a run ends with: last (the final state's) | best (per seed, the state of its best greedy evaluation,
    #: the final one included, scored again at the end on fresh episodes: rlq/run/kept.py)
    keep: str = setting("last", OneOf(KEEP_CHOICES))
    #: env options of the evaluation program over the run's own, e.g. {unroll_physics: none} (humanoid_ppo: the same
    #: physics traced in loops, a shorter compile); each an option of the run's env, of its type and range
    env: dict[str, Any] = _options()


@dataclass(frozen=True)
class Checkpoint:
    """``checkpoint``: what the run keeps of its learner state."""

    #: 0: only the final checkpoint
    every_steps: int = setting(0, COUNT)
    #: periodic step_* checkpoints kept, the newest (0: all)
    keep_last: int = setting(3, COUNT)
    #: true: checkpoints/best.msgpack holds the state of the best greedy eval return
    keep_best: bool = setting(False)


@dataclass(frozen=True)
class Guard:
    """``guard``: the divergence guard stops a run (exit 3, the last good checkpoint kept) once a loss or return is
    NaN/Inf, the parameters' norm is not finite, or one of these is passed (null: no bound)."""

    #: |any loss|: finite blow-ups (PPO at lr=1e9 reaches a value loss of 5e17 with no NaN)
    max_abs_loss: float | None = setting(1.0e12, Range(0, low_open=True))
    #: global L2 norm of the policy's parameters (a trained network's is below 1e3)
    max_params_norm: float | None = setting(1.0e8, Range(0, low_open=True))


@dataclass(frozen=True)
class Stop:
    """``stop``: ending a run before its budget."""

    #: end early once met, e.g. "eval/return>=200" (mean over seeds; eval/ or train/ metrics; >=, >, <=, <); the final
    #: evaluation and checkpoint are written as at the budget's end (rlq.run.stops.stop reads it)
    when: str | None = setting(None)


@dataclass(frozen=True)
class Video:
    """``video``: the greedy episodes recorded."""

    #: <run dir>/videos/final_seed0.mp4 when the env has a renderer: true | false | null (a single run's, unless on a
    #: CPU it would cost over 10 % of the run; a sweep job: none)
    at_end: bool | None = setting(None)
    #: seed 0's greedy episode every N env steps: videos/step_<N>_seed0.mp4 and W&B (0: off)
    every_steps: int = setting(0, COUNT)
    #: episode cap for the video (null: the env's time limit)
    max_steps: int | None = setting(None, Range(1, integer=True))


@dataclass(frozen=True)
class Wandb:
    """``logger.wandb``: the W&B run."""

    #: offline (`wandb sync <run dir>/wandb/...` uploads later) | online | disabled
    mode: str = setting("offline", OneOf(WANDB_MODES))
    project: str = setting("rlq")
    entity: str | None = setting(None)
    #: null: a multirun job joins its sweep's group (<date>_<time>), a single run none
    group: str | None = setting(None)
    tags: tuple[str, ...] = setting(())


@dataclass(frozen=True)
class Logger:
    """``logger`` (conf/logger/: default | quiet): metrics always go to <run dir>/metrics.jsonl; these switch the
    console bar and W&B."""

    console: bool = setting(True)
    wandb: Wandb = setting(Wandb())


@dataclass(frozen=True)
class Machine:
    """``machine`` (conf/machine/: cpu | gpu): the machine the run is shaped for, which picks
    conf/tuned/machine/<env>_<algo>_<machine>.yaml where one exists."""

    #: cpu | gpu, the group's choice (`rlq train` picks gpu where JAX will see an NVIDIA GPU: rlq/config/tuned.py)
    name: str = setting("cpu")


@dataclass(frozen=True)
class Config:
    """The run's own keys: type, default, allowed values and meaning. The ``algo``, ``env`` and ``controller`` groups
    are their components' (rlq/declared/); ``hydra`` is Hydra's."""

    #: true: run an env x algo pair that has no tuned settings, on the algorithm's own defaults
    allow_untuned: bool = setting(False)
    #: base seed; seed i of a run uses fold_in(PRNGKey(seed), i) (JAX's PRNG takes an unsigned 32-bit seed)
    seed: int = setting(0, SEED)
    #: independent seeds trained together in one compiled program (vmap)
    num_seeds: int = setting(1, POSITIVE_INT)
    #: which kind of device runs the programs: null (JAX's default: the GPU when there is one) | cpu | gpu; presets
    #: that step few envs at a time choose cpu (rlq.run.programs.devices says so of one this machine lacks)
    platform: str | None = setting(None, OneOf(PLATFORMS, null="null (JAX's default)"))
    shaped_for: ShapedFor = setting(ShapedFor())
    #: local devices the run spreads over: null (as many as split the seeds evenly), all, a count (the first N) or
    #: indices [0,2] (rlq/run/programs/devices.py reads and checks it)
    devices: Any = setting(None)
    distributed: Distributed = setting(Distributed())
    budget: Budget = setting(Budget())
    #: env steps between host syncs (metrics leave the device once per chunk)
    log_every_steps: int = setting(25000, POSITIVE_INT)
    #: train rows' return_window: mean return of each seed's last N finished episodes (0: off)
    return_window: int = setting(100, COUNT)
    #: how a chunk's updates run: scan (one program loops over them; best for short updates) | calls (the host queues
    #: one-update programs back to back; humanoid_ppo's choice)
    chunk_loop: str = setting("scan", OneOf(CHUNK_LOOPS))
    eval: Eval = setting(Eval())
    checkpoint: Checkpoint = setting(Checkpoint())
    guard: Guard = setting(Guard())
    stop: Stop = setting(Stop())
    #: <run dir>[:final|:<env steps>]: start the policy from that run's checkpoint (same algo and network sizes)
    init_from: str | None = setting(None)
    #: in-program sweep: 'sweep.algo.lr=[1e-4,3e-4,1e-3]' trains one member per value in one compiled program
    #: (rlq/run/programs/members.py, README "Sweeps in one program")
    sweep: dict[str, Any] = _options()
    #: what the run returns to Hydra's sweepers: eval/<name> of the final greedy evaluation or train/<name> of the
    #: last train row, mean over seeds (rlq.store.objective reads it)
    objective: str = setting("eval/return")
    video: Video = setting(Video())
    #: the run directory's suffix; each preset (experiment=) sets its own name (rlq.run.checks.validate checks it)
    run_name: str = setting("${env.name}-${algo.name}")
    #: JAX's persistent compilation cache: user ($XDG_CACHE_HOME/rlq/jax, else ~/.cache/rlq/jax) | a directory | null
    #: or false (off)
    compile_cache: Any = setting("user")
    #: also keep a one-device run's compiled programs whole in <compile_cache dir>/programs: auto (on a GPU, and on a
    #: CPU for env=cartpole and env=lunar) | always | never
    program_cache: str = setting("auto", OneOf(PROGRAM_CACHE_MODES))
    #: XLA options for every program of the run, e.g. +compiler_options={xla_gpu_command_buffer_scheduling_mode:...}
    compiler_options: dict[str, Any] = _options()
    machine: Machine = setting(Machine())
    logger: Logger = setting(Logger())
