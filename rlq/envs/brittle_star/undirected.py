"""Undirected locomotion of the brittle star (``env=brittle_star_undirected``); see brittle_star.py."""

from __future__ import annotations

from rlq.declared.envs.brittle_star import UndirectedConfig
from rlq.envs.brittle_star.env import BrittleStar, config_from


def make(env_cfg: UndirectedConfig) -> BrittleStar:
    return BrittleStar(config_from(env_cfg, directed=False))
