"""The direct controller: the agent's action goes to the env unchanged."""

from __future__ import annotations

from omegaconf import DictConfig

from rlq.lib.env_api import Env


def wrap(env: Env, controller_cfg: DictConfig, env_cfg: DictConfig) -> Env:
    return env
