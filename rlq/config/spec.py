"""A run as a command resolved it: frozen dataclasses of the run-level settings, one typed field per key the runner
reads (its default is declared in rlq/declared/run.py), read-only mappings of the env, controller and algorithm
sections (each component reads its own typed config from them), and the changed copies the runner needs (an
in-program sweep's members and program, the evaluation env's run, a run with some keys set), made here by
re-resolving the composed config so that nothing above rlq.config reads OmegaConf."""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, cast

from omegaconf import DictConfig, OmegaConf


class FrozenList(tuple):
    """A list of a config read-only: a tuple that prints as the list it was (``[64, 64]``), as error lines show it."""

    __slots__ = ()

    def __repr__(self) -> str:
        return repr(list(self))


def frozen(value: Any) -> Any:
    """``value`` (a plain container) read-only all the way down: mappings as MappingProxyType, lists as
    FrozenLists."""
    if isinstance(value, dict):
        return MappingProxyType({key: frozen(item) for key, item in value.items()})
    if isinstance(value, list):
        return FrozenList(frozen(item) for item in value)
    return value


@dataclass(frozen=True)
class Seeds:
    seed: int  # base seed; seed i of the run uses fold_in(PRNGKey(seed), i)
    count: int  # num_seeds, trained together in one program


@dataclass(frozen=True)
class Budget:
    env_steps: int  # per seed
    log_every_steps: int  # env steps between host syncs
    stop_when: str | None  # an early stop rule, e.g. "eval/return>=200"


@dataclass(frozen=True)
class Evaluation:
    every_steps: int  # 0: only at the end
    episodes: int  # per seed and evaluation
    env: Mapping[str, Any]  # env options of the evaluation program over the run's own
    keep: str = "last"  # last | best: the policy the run ends with (rlq/run/kept.py)


@dataclass(frozen=True)
class Checkpoints:
    every_steps: int  # 0: only the final checkpoint
    keep_last: int
    keep_best: bool


@dataclass(frozen=True)
class ShapedFor:
    platform: str | None  # the device kind a preset's sizes are chosen for (null: any)
    note: str  # what to run there instead


@dataclass(frozen=True)
class Devices:
    platform: str | None  # null (JAX's default) | cpu | gpu
    devices: Any  # null | all | a count | indices
    distributed: Mapping[str, Any]
    shaped_for: ShapedFor


@dataclass(frozen=True)
class Video:
    at_end: Any  # true | false | null (a single run's, when cheap); checked by rlq/run/checks/validate.py
    every_steps: int  # 0: off
    max_steps: int | None  # null: the env's time limit


@dataclass(frozen=True)
class Outputs:
    dir_key: str  # hydra.run.dir, or hydra.sweep.dir for a sweep's job
    dir: str  # the run (or sweep) directory still to be made; "" when the config names none
    run_name: str
    logger: Mapping[str, Any]
    video: Video


@dataclass(frozen=True)
class Training:
    return_window: int  # train rows' mean return of each seed's last N episodes (0: off)
    chunk_loop: str  # scan | calls
    guard: Mapping[str, Any]  # the divergence guard's bounds
    init_from: str | None  # <run dir>[:final|:<env steps>]
    objective: str  # what the run returns to Hydra's sweepers
    sweep: Mapping[str, Any]  # an in-program sweep: each swept key (algo.lr) and its values, in the order given


@dataclass(frozen=True)
class Compilation:
    compile_cache: Any  # user | a directory | null or false (off)
    program_cache: str  # auto | always | never
    compiler_options: Mapping[str, Any]  # XLA options of every program of the run


@dataclass(frozen=True)
class RunSpec:
    """What `rlq train <overrides>` runs. ``values`` is the whole resolved config as read-only plain values (the
    config hash, W&B's config, the program cache's key and the run's range check read it); ``overrides`` are
    the command's as checked (integer keys given in float notation rewritten as integers); ``choices`` are Hydra's
    group choices (``algo: ppo``); ``config`` is the run's composed config without Hydra's node (rlq.config and the
    CLI read it, never the runner) and ``composed`` the one with it (None where an override was rewritten or for a
    sweep's job, whose config Hydra composes again)."""

    seeds: Seeds
    budget: Budget
    evaluation: Evaluation
    checkpoints: Checkpoints
    devices: Devices
    outputs: Outputs
    training: Training
    compilation: Compilation
    env: Mapping[str, Any]
    controller: Mapping[str, Any]
    algorithm: Mapping[str, Any]
    values: Mapping[str, Any]
    choices: Mapping[str, str | None]
    overrides: tuple[str, ...]
    config: DictConfig
    composed: DictConfig | None


def _swept(node: Any, prefix: str = "") -> dict[str, Any]:
    """The swept keys of ``sweep`` (``algo.lr``) and their values as given, in the order given."""
    flat: dict[str, Any] = {}
    for key, value in (node or {}).items():
        if isinstance(value, Mapping):
            flat.update(_swept(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def run_spec(
    cfg: DictConfig,
    overrides: list[str] | tuple[str, ...] = (),
    choices: Mapping[str, str | None] | None = None,
    out: tuple[str, str] = ("", ""),
    composed: DictConfig | None = None,
) -> RunSpec:
    """The RunSpec of a composed and checked run config ``cfg`` (without Hydra's node); ``out``: the output
    directory's key and value."""
    plain = OmegaConf.to_container(cfg, resolve=True)
    assert isinstance(plain, dict)
    section = {str(key): frozen(value) for key, value in plain.items()}
    video = plain["video"]
    return RunSpec(
        seeds=Seeds(seed=plain["seed"], count=plain["num_seeds"]),
        budget=Budget(
            env_steps=plain["budget"]["env_steps"],
            log_every_steps=plain["log_every_steps"],
            stop_when=plain["stop"]["when"],
        ),
        evaluation=Evaluation(
            every_steps=plain["eval"]["every_steps"],
            episodes=plain["eval"]["episodes"],
            env=section["eval"]["env"],
            keep=plain["eval"]["keep"],
        ),
        checkpoints=Checkpoints(
            every_steps=plain["checkpoint"]["every_steps"],
            keep_last=plain["checkpoint"]["keep_last"],
            keep_best=plain["checkpoint"]["keep_best"],
        ),
        devices=Devices(
            platform=plain["platform"],
            devices=section["devices"],
            distributed=section["distributed"],
            shaped_for=ShapedFor(platform=plain["shaped_for"]["platform"], note=plain["shaped_for"]["note"]),
        ),
        outputs=Outputs(
            dir_key=out[0],
            dir=out[1],
            run_name=plain["run_name"],
            logger=section["logger"],
            video=Video(at_end=video["at_end"], every_steps=video["every_steps"], max_steps=video["max_steps"]),
        ),
        training=Training(
            return_window=plain["return_window"],
            chunk_loop=plain["chunk_loop"],
            guard=section["guard"],
            init_from=plain["init_from"],
            objective=plain["objective"],
            sweep=MappingProxyType({key: frozen(value) for key, value in _swept(plain["sweep"]).items()}),
        ),
        compilation=Compilation(
            compile_cache=plain["compile_cache"],
            program_cache=plain["program_cache"],
            compiler_options=section["compiler_options"] or MappingProxyType({}),
        ),
        env=section["env"],
        controller=section["controller"],
        algorithm=section["algo"],
        values=MappingProxyType(section),
        choices=MappingProxyType(dict(choices or {})),
        overrides=tuple(overrides),
        config=cfg,
        composed=composed,
    )


def as_spec(run: RunSpec | Mapping[str, Any]) -> RunSpec:
    """``run``, or the RunSpec of a composed config (or plain mapping of one) given in its place."""
    if isinstance(run, RunSpec):
        return run
    cfg = run if isinstance(run, DictConfig) else OmegaConf.create(dict(run))
    return run_spec(cast(DictConfig, cfg))


def _respec(spec: RunSpec, cfg: DictConfig, composed: DictConfig | None = None) -> RunSpec:
    return run_spec(cfg, spec.overrides, spec.choices, (spec.outputs.dir_key, spec.outputs.dir), composed)


def with_values(spec: RunSpec, values: Mapping[str, Any]) -> RunSpec:
    """``spec`` with the dotted keys of ``values`` set (``{"devices": 1}``), interpolations read again; a key of
    Hydra's node (``hydra.run.dir``) is set in the composed config only."""
    cfg = copy.deepcopy(spec.config)
    composed = copy.deepcopy(spec.composed)
    for key, value in values.items():
        if not key.startswith("hydra."):
            OmegaConf.update(cfg, key, value, force_add=True)
        if composed is not None:
            OmegaConf.update(composed, key, value, force_add=True)
    return _respec(spec, cfg, composed)


def _unresolved_copy(spec: RunSpec) -> DictConfig:
    """A copy of ``spec``'s config with its interpolations as written, free of the composed config's flags."""
    return cast(DictConfig, OmegaConf.create(OmegaConf.to_container(spec.config, resolve=False)))


def member_spec(spec: RunSpec, member: Mapping[str, float]) -> RunSpec:
    """The spec of the separate run an in-program sweep's member stands for: the sweep's values set, no sweep."""
    one = _unresolved_copy(spec)
    one.sweep = {}
    for name, value in member.items():
        OmegaConf.update(one, name, value)
    return _respec(spec, one)


def program_spec(spec: RunSpec, count: int) -> RunSpec:
    """The spec an in-program sweep's program is built from: ``num_seeds`` counts the seeds of its ``count``
    members."""
    program = _unresolved_copy(spec)
    program.num_seeds = int(spec.seeds.count) * count
    return _respec(spec, program)


def evaluation_spec(spec: RunSpec) -> RunSpec:
    """``spec`` with ``eval.env``'s options over its env's: what the evaluation env is built from."""
    options = spec.config.eval.get("env")
    if not options:
        return spec
    merged = OmegaConf.merge(spec.config, {"env": OmegaConf.to_container(options, resolve=True)})
    return _respec(spec, cast(DictConfig, merged))


def with_env(spec: RunSpec, env: Mapping[str, Any]) -> RunSpec:
    """``spec`` whose env section is ``env`` (a composed env section or a plain mapping of one)."""
    cfg = spec.config.copy()
    cfg.env = copy.deepcopy(env) if isinstance(env, DictConfig) else OmegaConf.create(dict(env))
    return _respec(spec, cfg)


def config_yaml(spec: RunSpec) -> str:
    """The yaml of ``spec``'s config as a run records it (``.hydra/config.yaml``, interpolations as written)."""
    return OmegaConf.to_yaml(spec.config)
