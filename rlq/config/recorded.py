"""Recorded runs read back as RunSpecs (``<run dir>/.hydra/config.yaml``): with the options added since they were
written at their defaults, and changed as `rlq eval`, `rlq render` and `rlq resume` change them (another env, the
``env.<key>=<value>`` overrides, a key set)."""

from __future__ import annotations

import copy
from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast

from omegaconf import DictConfig, OmegaConf

from rlq.config.choices import group_options
from rlq.config.compose import WITHOUT_TUNED, compose, explain_hydra_error
from rlq.config.conf_dir import CONF_DIR
from rlq.config.spec import RunSpec, evaluation_spec, run_spec, with_env
from rlq.config.types import check_types, integer_key, integers_written
from rlq.errors import ConfigError, RunDirError, UsageError

#: top-level keys every run config has; one without them was truncated
RUN_KEYS = ("seed", "num_seeds", "budget", "env", "controller", "algo", "logger", "eval", "checkpoint")

#: the config groups a run chose; everything else at the top level is a run-level option
COMPONENT_KEYS = ("env", "controller", "algo", "logger")

#: the config groups whose options added since a run was written come in at their defaults: those
#: whose configs name themselves (``name:``), so the run's choice can be read back (not the logger's)
OPTION_GROUPS = ("env", "algo", "controller")


def _over_defaults(defaults: DictConfig, cfg: DictConfig) -> DictConfig:
    """``cfg`` merged over a plain (unstructured, unflagged) copy of ``defaults``: ``cfg`` wins."""
    return cast(DictConfig, OmegaConf.merge(OmegaConf.create(OmegaConf.to_container(defaults)), cfg))


def with_current_run_defaults(cfg: DictConfig) -> DictConfig:
    """``cfg`` with the options added since it was written, at their defaults: run-level ones (e.g.
    ``program_cache`` for a run trained before it existed) and those of the env, algo and
    controller it chose (e.g. ``env.solver.sweep_layout``). The run's own choices and values win."""
    defaults = compose(WITHOUT_TUNED)
    run_level = OmegaConf.masked_copy(defaults, [str(k) for k in defaults if k not in COMPONENT_KEYS])
    merged = _over_defaults(run_level, cfg)
    chosen = {
        group: name
        for group in OPTION_GROUPS
        if isinstance(cfg.get(group), DictConfig)
        and isinstance(name := cfg[group].get("name"), str)
        and (CONF_DIR / group / f"{name}.yaml").exists()
    }
    if chosen:
        current = compose([*(f"{group}={name}" for group, name in chosen.items()), *WITHOUT_TUNED])
        for group in chosen:
            merged[group] = _over_defaults(current[group], merged[group])
    return merged


def recorded_spec(path: Path) -> RunSpec:
    """The RunSpec of a run's recorded ``config.yaml`` at ``path``, with the options added since at their defaults;
    RunDirError where it is unreadable or truncated, or where a key deeper down was cut off."""
    try:
        cfg = OmegaConf.load(path)
    except Exception as err:
        raise RunDirError(f"{path} is unreadable (truncated or corrupt): {str(err).splitlines()[0]}") from None
    missing = [k for k in RUN_KEYS if not isinstance(cfg, DictConfig) or k not in cfg]
    if missing:
        raise RunDirError(f"{path} is truncated or corrupt: no {', '.join(missing)}")
    current = with_current_run_defaults(cast(DictConfig, cfg))
    try:
        return run_spec(current)
    except Exception as err:  # a key deeper down that was cut off, or an interpolation that no longer resolves
        raise RunDirError(f"{path} is truncated or corrupt: {type(err).__name__}: {str(err).splitlines()[0]}") from None


def env_choice(spec: RunSpec, env_name: str | None) -> RunSpec:
    """``spec`` with the env `rlq eval`/`rlq render` step: the run's evaluation env (``eval.env`` over its env), or
    ``env_name`` with its defaults."""
    env_cfg = copy.deepcopy(evaluation_spec(spec).config.env)  # the run's evaluation env (eval.env)
    if env_name:
        path = CONF_DIR / "env" / f"{env_name}.yaml"
        if not path.exists():
            options = group_options("env")
            raise ConfigError(f"unknown env '{env_name}'; choose one of: {', '.join(options)}")
        env_cfg = compose([f"env={env_name}", *WITHOUT_TUNED]).env  # with its own defaults (env/physics)
    return with_env(spec, env_cfg)


#: what ``OmegaConf.select`` returns for a key the config has not
_ABSENT = object()


def _unknown_env_key(cfg: DictConfig, key: str) -> str:
    """The line for an ``env.<key>`` the env has not, in the style of `rlq train`'s, with the keys it has."""
    parent = OmegaConf.select(cfg, key.rsplit(".", 1)[0], default=None)
    node = parent if isinstance(parent, DictConfig) else cfg.env
    keys = [str(k) for k in node if not (node is cfg.env and k == "name")]
    return f"unknown config key '{key}' of env={cfg.env.name}; its keys are {', '.join(keys)}"


def env_overridden(spec: RunSpec, overrides: list[str]) -> RunSpec:
    """``spec`` with the ``env.<key>=<value>`` overrides of `rlq eval` and `rlq render`, read and checked as
    `rlq train` reads and checks its own: the key must be one of the env's, the value keeps its default's type
    (the ranges: rlq.tools.env_overrides). Raises ConfigError or UsageError."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parser = OverridesParser.create()
    cfg = spec.config
    out = copy.deepcopy(cfg)
    # an untyped env (a composed one is its schema's typed node): the values are read and checked as written below
    out.env = OmegaConf.create(OmegaConf.to_container(cfg.env))
    keys = []
    for item in integers_written(overrides, lambda key: integer_key(key, cfg), sweeps=False):
        try:
            (override,) = parser.parse_overrides([item])
        except Exception as err:
            raise ConfigError(explain_hydra_error(err)) from None
        key = override.key_or_group
        if override.is_sweep_override():
            raise UsageError(f"{item} gives several values; eval and render take one value per key")
        if key == "env.name":
            raise UsageError(f"{item}: choose the env with env=NAME")
        if OmegaConf.select(cfg, key, default=_ABSENT, throw_on_missing=False) is _ABSENT:
            raise ConfigError(_unknown_env_key(cfg, key))
        OmegaConf.update(out, key, override.value(), force_add=True)
        keys.append(key)
    check_types(cfg, out, keys)
    return run_spec(out, spec.overrides, spec.choices, (spec.outputs.dir_key, spec.outputs.dir))


def extend_recorded(path: Path, values: Mapping[str, Any]) -> None:
    """The run's recorded ``config.yaml`` at ``path`` with the dotted keys of ``values`` set (`rlq resume`'s new
    budget), the rest as written."""
    recorded = OmegaConf.load(path)
    for key, value in values.items():
        OmegaConf.update(recorded, key, value)
    OmegaConf.save(recorded, path)


def yaml_text(value: Any) -> str:
    """``value`` (plain values) as the yaml a run's record holds."""
    return OmegaConf.to_yaml(OmegaConf.create(value))


def parsed_yaml(text: str) -> Any:
    """One yaml value given on the command line (``devices=[0,1]``) as Hydra reads it."""
    return OmegaConf.create(f"value: {text}").value


def job_spec(cfg: Mapping[str, Any], choices: Mapping[str, str | None]) -> RunSpec:
    """The RunSpec of a job's config as Hydra composed it (its ``hydra`` node left out), ``choices``: the job's
    group choices."""
    job = cast(DictConfig, cfg)
    if "hydra" in job:
        job = OmegaConf.masked_copy(job, [str(key) for key in job if key != "hydra"])
    return run_spec(job, (), choices)
