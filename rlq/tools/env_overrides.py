"""The ``env.<key>=<value>`` overrides of `rlq eval` and `rlq render`, read and checked as `rlq train` reads and
checks its own."""

from __future__ import annotations

import copy

from omegaconf import DictConfig, OmegaConf

from rlq.config.compose import explain_hydra_error
from rlq.config.types import check_types, integral_floats
from rlq.errors import ConfigError, UsageError

#: what ``OmegaConf.select`` returns for a key the config has not
_ABSENT = object()


def _unknown_env_key(cfg: DictConfig, key: str) -> str:
    """The line for an ``env.<key>`` the env has not, in the style of `rlq train`'s, with the keys it has."""
    parent = OmegaConf.select(cfg, key.rsplit(".", 1)[0], default=None)
    node = parent if isinstance(parent, DictConfig) else cfg.env
    keys = [str(k) for k in node if not (node is cfg.env and k == "name")]
    return f"unknown config key '{key}' of env={cfg.env.name}; its keys are {', '.join(keys)}"


def with_env_overrides(cfg: DictConfig, overrides: list[str]) -> DictConfig:
    """``cfg`` with the ``env.<key>=<value>`` overrides of `rlq eval` and `rlq render`, read and checked
    as `rlq train` reads and checks its own: the key must be one of ``cfg.env``'s, the value keeps its
    default's type and lies in its range (rlq.run.checks.constraints). Raises ConfigError or UsageError."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from rlq.run.checks.constraints import problems

    parser = OverridesParser.create()
    out = copy.deepcopy(cfg)
    keys = []
    for item in overrides:
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
    for key, value in integral_floats(cfg, out, keys).items():
        OmegaConf.update(out, key, value)
    check_types(cfg, out, keys)
    problem = problems(out)
    if problem:
        raise ConfigError(problem)
    return out
