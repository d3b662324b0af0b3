"""The direct controller: the agent's action goes to the env unchanged."""

from __future__ import annotations

from dataclasses import dataclass

from omegaconf import DictConfig

from rlq.lib.env_api import Env
from rlq.lib.settings import setting


@dataclass(frozen=True)
class Config:
    """``controller=direct`` has no settings of its own."""

    name: str = setting("direct")


def wrap(env: Env, controller_cfg: DictConfig, env_cfg: DictConfig) -> Env:
    return env
