"""The direct controller: the agent's action goes to the env unchanged."""

from __future__ import annotations

from rlq.declared.controllers.direct import Config
from rlq.lib.env_api import Env


def wrap(env: Env, controller_cfg: Config, env_cfg: object) -> Env:
    return env
