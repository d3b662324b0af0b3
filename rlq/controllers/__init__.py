"""Controller registry: ``controller.name`` selects a module of ``CONTROLLERS`` (imported: an editor follows it).

A controller is an env wrapper: it turns the agent's action into the env's action (identity for
``direct``) and may keep its own state inside ``EnvState.inner``. Each module exposes
``wrap(env, controller_cfg, env_cfg) -> Env``, ``Config`` (the declaration of its keys: type, default and allowed
values, rlq/lib/settings.py; conf/controller/<name>.yaml is its preset) and optionally ``check(controller_cfg,
env_cfg)`` returning an error message for an unsupported combination.
"""

from __future__ import annotations

from types import ModuleType

from omegaconf import DictConfig

from rlq.controllers import cpg, direct
from rlq.lib.env_api import Env
from rlq.lib.registry import choose

CONTROLLERS: dict[str, ModuleType] = {"direct": direct, "cpg": cpg}


def _module(controller_cfg: DictConfig) -> ModuleType:
    return choose(CONTROLLERS, controller_cfg.name, "controller.name")


def controller_config(controller_cfg: DictConfig) -> type:
    """The declaration of the chosen controller's keys."""
    config = _module(controller_cfg).Config
    assert isinstance(config, type)
    return config


def check_controller(controller_cfg: DictConfig, env_cfg: DictConfig) -> str | None:
    """An error message if this controller cannot drive this env, else None."""
    check = getattr(_module(controller_cfg), "check", None)
    return check(controller_cfg, env_cfg) if check else None


def wrap_controller(env: Env, controller_cfg: DictConfig, env_cfg: DictConfig) -> Env:
    return _module(controller_cfg).wrap(env, controller_cfg, env_cfg)
