"""Environment registry: ``env.name`` selects one of the modules in ``ENVS`` (imported on demand: a CartPole run
imports no MuJoCo) and its declaration in ``ENV_CONFIGS`` (rlq/declared/envs/).

Each env module exposes ``make(env_cfg) -> Env`` returning the bare environment, from the env's typed ``Config``
(``env_settings`` builds it from the composed ``env`` section);
``rlq.run.programs.env_stack.make_env`` adds the controller and the standard wrappers.

A process keeps the last few bare envs it built, by their config: a run builds its env while its
config is checked and again to train, and the MJX envs take a second or more each (parsing the
model and uploading it). Envs hold no state between calls.
"""

from __future__ import annotations

import dataclasses
import json
from collections import OrderedDict
from collections.abc import Mapping
from typing import Any

from rlq.declared.envs import ENV_CONFIGS
from rlq.lib.env_api import Env, EnvState, Wrapper
from rlq.lib.registry import choose, load
from rlq.lib.settings import typed

__all__ = ["ENVS", "ENV_CONFIGS", "Env", "EnvState", "Wrapper", "env_config", "env_settings", "make_base_env"]

ENVS = {
    "cartpole": "rlq.envs.cartpole",
    "lunar": "rlq.envs.lunar.env",
    "lunar_box2d": "rlq.envs.lunar.box2d_reference",
    "humanoid": "rlq.envs.humanoid.env",
    "brittle_star": "rlq.envs.brittle_star.env",
    "brittle_star_undirected": "rlq.envs.brittle_star.undirected",
}


def env_config(env_cfg: Mapping[str, Any] | Any) -> type:
    """The declaration of the chosen env's keys (``env_cfg``: the ``env`` section or an env's ``Config``)."""
    name = env_cfg["name"] if isinstance(env_cfg, Mapping) else env_cfg.name
    return choose(ENV_CONFIGS, name, "env.name")


def env_settings(env_cfg: Mapping[str, Any] | Any) -> Any:
    """The named env's ``Config`` with the values of the ``env`` section (a ``Config`` already: itself)."""
    return typed(env_config(env_cfg), env_cfg, "env")


#: bare envs built in this process, by their config (the newest last)
_BUILT: OrderedDict[str, Env] = OrderedDict()
KEEP_BUILT = 4


def make_base_env(env_cfg: Mapping[str, Any] | Any) -> Env:
    """The bare environment named by ``env_cfg.name`` (no controller, no wrappers; ``env_cfg``: the env's ``Config``
    or its section)."""
    env_cfg = env_settings(env_cfg)
    module = load(ENVS, env_cfg.name, "env.name")
    key = json.dumps(dataclasses.asdict(env_cfg), sort_keys=True, default=str)
    if key in _BUILT:
        _BUILT.move_to_end(key)
        return _BUILT[key]
    env = module.make(env_cfg)
    _BUILT[key] = env
    if len(_BUILT) > KEEP_BUILT:
        _BUILT.popitem(last=False)
    return env
