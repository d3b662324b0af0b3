"""Composed and recorded configs as the layers above read them, without knowing OmegaConf: resolved plain values,
a dotted key's value, and the yaml of a run's record (``.hydra/``) written and read back."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

from rlq.errors import RunDirError


def plain(cfg: Mapping[str, Any]) -> dict[str, Any]:
    """``cfg`` (a composed config or a plain mapping) as plain dicts and lists, interpolations resolved."""
    if isinstance(cfg, DictConfig):
        whole = OmegaConf.to_container(cfg, resolve=True)
        assert isinstance(whole, dict)
        return {str(key): value for key, value in whole.items()}
    return {str(key): _plain_value(value) for key, value in cfg.items()}


def _plain_value(value: Any) -> Any:
    if isinstance(value, DictConfig | ListConfig):
        return OmegaConf.to_container(value, resolve=True)
    if isinstance(value, Mapping):
        return plain(value)
    if isinstance(value, list | tuple):
        return [_plain_value(item) for item in value]
    return value


#: ``select``'s answer for a key a config has not, where None (a null value) would not tell them apart
MISSING = object()


def select(cfg: Mapping[str, Any], key: str, absent: Any = None) -> Any:
    """The value of the dotted ``key`` (``checkpoint.every_steps``) in ``cfg``; ``absent`` where it has none."""
    if isinstance(cfg, DictConfig):
        return OmegaConf.select(cfg, key, default=absent, throw_on_missing=False)
    node: Any = cfg
    for part in key.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return absent
        node = node[part]
    return node


def record_texts(cfg: Mapping[str, Any], hydra_cfg: Any) -> dict[str, str]:
    """The yaml of a run's record, by file name: ``config.yaml`` (the job's config), ``hydra.yaml`` and
    ``overrides.yaml``, as Hydra writes them (``hydra_cfg``: Hydra's node of the job)."""
    nodes = {
        "config.yaml": cfg,
        "hydra.yaml": OmegaConf.create({"hydra": hydra_cfg}),
        "overrides.yaml": hydra_cfg.overrides.task,
    }
    return {name: OmegaConf.to_yaml(node) for name, node in nodes.items()}


def read_recorded(path: Path) -> Any:
    """A yaml file of a run's record as plain values (interpolations left as written)."""
    return OmegaConf.to_container(OmegaConf.load(path), resolve=False)


def read_recorded_config(path: Path) -> Mapping[str, Any]:
    """A run's recorded ``config.yaml``: a mapping whose interpolations resolve when read (``select``)."""
    config = OmegaConf.load(path)
    if not isinstance(config, DictConfig):
        raise RunDirError(f"{path} holds no run config (a list, not a mapping of keys)")
    return config
