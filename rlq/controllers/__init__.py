"""Controller registry: ``controller.name`` selects a module of ``CONTROLLERS`` (imported: an editor follows it).

A controller is an env wrapper: it turns the agent's action into the env's action (identity for
``direct``) and may keep its own state inside ``EnvState.inner``. Each module exposes
``wrap(env, controller_cfg, env_cfg) -> Env`` and optionally ``check(controller_cfg,
env_cfg)`` returning an error message for an unsupported combination; its keys are declared in rlq/declared/controllers/
(``CONTROLLER_CONFIGS``). Both take the typed configs:
the controller's (``controller_settings``; ``check_controller`` and ``wrap_controller`` also take its composed
section) and the env's (rlq.envs.env_settings).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import ModuleType
from typing import Any

from rlq.controllers import cpg, direct
from rlq.declared.controllers import CONTROLLER_CONFIGS
from rlq.lib.env_api import Env
from rlq.lib.registry import choose
from rlq.lib.settings import typed

CONTROLLERS: dict[str, ModuleType] = {"direct": direct, "cpg": cpg}


def _module(controller_cfg: Mapping[str, Any] | Any) -> ModuleType:
    name = controller_cfg["name"] if isinstance(controller_cfg, Mapping) else controller_cfg.name
    return choose(CONTROLLERS, name, "controller.name")


def controller_config(controller_cfg: Mapping[str, Any] | Any) -> type:
    """The declaration of the chosen controller's keys."""
    name = controller_cfg["name"] if isinstance(controller_cfg, Mapping) else controller_cfg.name
    return choose(CONTROLLER_CONFIGS, name, "controller.name")


def controller_settings(controller_cfg: Mapping[str, Any] | Any) -> Any:
    """The named controller's ``Config`` with the values of the ``controller`` section (a ``Config``: itself)."""
    return typed(controller_config(controller_cfg), controller_cfg, "controller")


def check_controller(controller_cfg: Mapping[str, Any] | Any, env_cfg: Any) -> str | None:
    """An error message if this controller cannot drive this env, else None."""
    check = getattr(_module(controller_cfg), "check", None)
    return check(controller_settings(controller_cfg), env_cfg) if check else None


def wrap_controller(env: Env, controller_cfg: Mapping[str, Any] | Any, env_cfg: Any) -> Env:
    return _module(controller_cfg).wrap(env, controller_settings(controller_cfg), env_cfg)
