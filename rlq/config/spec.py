"""A run as a command resolved it: frozen dataclasses of the run-level settings, read-only mappings of the env,
controller and algorithm sections (until each declares its own typed config), and the composed config that the
runner still reads."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from omegaconf import DictConfig, OmegaConf


def frozen(value: Any) -> Any:
    """``value`` (a plain container) read-only all the way down: mappings as MappingProxyType, lists as tuples."""
    if isinstance(value, dict):
        return MappingProxyType({key: frozen(item) for key, item in value.items()})
    if isinstance(value, list):
        return tuple(frozen(item) for item in value)
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


@dataclass(frozen=True)
class Checkpoints:
    every_steps: int  # 0: only the final checkpoint
    keep_last: int
    keep_best: bool


@dataclass(frozen=True)
class Devices:
    platform: str | None  # null (JAX's default) | cpu | gpu
    devices: Any  # null | all | a count | indices
    distributed: Mapping[str, Any]


@dataclass(frozen=True)
class Outputs:
    dir_key: str  # hydra.run.dir, or hydra.sweep.dir for a sweep's job
    dir: str  # the run (or sweep) directory still to be made; "" when the config names none
    run_name: str
    logger: Mapping[str, Any]
    video: Mapping[str, Any]


@dataclass(frozen=True)
class RunSpec:
    """What `rlq train <overrides>` runs. ``overrides`` are the command's as checked (integer keys given in float
    notation rewritten as integers); ``choices`` are Hydra's group choices (``algo: ppo``); ``config`` is the run's
    composed config without Hydra's node and ``composed`` the one with it (None where an override was rewritten or
    for a sweep's job, whose config Hydra composes again)."""

    seeds: Seeds
    budget: Budget
    evaluation: Evaluation
    checkpoints: Checkpoints
    devices: Devices
    outputs: Outputs
    env: Mapping[str, Any]
    controller: Mapping[str, Any]
    algorithm: Mapping[str, Any]
    choices: Mapping[str, str | None]
    overrides: tuple[str, ...]
    config: DictConfig
    composed: DictConfig | None


def run_spec(
    cfg: DictConfig,
    overrides: list[str],
    choices: dict[str, str | None],
    out: tuple[str, str],
    composed: DictConfig | None,
) -> RunSpec:
    """The RunSpec of a composed and checked run config ``cfg`` (without Hydra's node); ``out``: the output
    directory's key and value."""
    plain = OmegaConf.to_container(cfg, resolve=True)
    assert isinstance(plain, dict)
    section = {key: frozen(value) for key, value in plain.items()}
    return RunSpec(
        seeds=Seeds(seed=plain["seed"], count=plain["num_seeds"]),
        budget=Budget(
            env_steps=plain["budget"]["env_steps"],
            log_every_steps=plain["log_every_steps"],
            stop_when=plain["stop"]["when"],
        ),
        evaluation=Evaluation(
            every_steps=plain["eval"]["every_steps"], episodes=plain["eval"]["episodes"], env=section["eval"]["env"]
        ),
        checkpoints=Checkpoints(
            every_steps=plain["checkpoint"]["every_steps"],
            keep_last=plain["checkpoint"]["keep_last"],
            keep_best=plain["checkpoint"]["keep_best"],
        ),
        devices=Devices(platform=plain["platform"], devices=section["devices"], distributed=section["distributed"]),
        outputs=Outputs(
            dir_key=out[0], dir=out[1], run_name=plain["run_name"], logger=section["logger"], video=section["video"]
        ),
        env=section["env"],
        controller=section["controller"],
        algorithm=section["algo"],
        choices=MappingProxyType(dict(choices)),
        overrides=tuple(overrides),
        config=cfg,
        composed=composed,
    )
