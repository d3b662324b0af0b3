"""Undirected locomotion of the brittle star (``env=brittle_star_undirected``); see brittle_star.py."""

from __future__ import annotations

from rlq.envs.brittle_star.env import BrittleStar, config_from
from rlq.envs.brittle_star.options import UndirectedConfig


def make(env_cfg: UndirectedConfig) -> BrittleStar:
    return BrittleStar(config_from(env_cfg, directed=False))
