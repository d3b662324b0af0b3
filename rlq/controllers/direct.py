"""The direct controller: the agent's action goes to the env unchanged."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.env_api import Env
from rlq.lib.settings import setting


@dataclass(frozen=True)
class Config:
    """``controller=direct`` has no settings of its own."""

    name: str = setting("direct")


def wrap(env: Env, controller_cfg: Config, env_cfg: object) -> Env:
    return env
