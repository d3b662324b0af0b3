"""Environment registry: ``env.name`` selects one of the modules in ``ENVS``.

Each env module exposes ``make(env_cfg) -> Env`` returning the bare environment;
``rlq.run.build.make_env`` adds the controller and the standard wrappers.
"""

from __future__ import annotations

import importlib

from omegaconf import DictConfig

from rlq.errors import ConfigError
from rlq.lib.env_api import Env, EnvState, Wrapper

__all__ = ["ENVS", "Env", "EnvState", "Wrapper", "make_base_env"]

ENVS = {
    "cartpole": "rlq.envs.cartpole",
    "lunar": "rlq.envs.lunar.env",
    "lunar_box2d": "rlq.envs.lunar.box2d_reference",
    "humanoid": "rlq.envs.humanoid.env",
    "brittle_star": "rlq.envs.brittle_star.env",
    "brittle_star_undirected": "rlq.envs.brittle_star.undirected",
}


def make_base_env(env_cfg: DictConfig) -> Env:
    """The bare environment named by ``env_cfg.name`` (no controller, no wrappers)."""
    if env_cfg.name not in ENVS:
        raise ConfigError(f"env.name={env_cfg.name!r} is not an rlq env; choose one of: {', '.join(ENVS)}")
    module = importlib.import_module(ENVS[env_cfg.name])
    return module.make(env_cfg)
