"""``controller=direct``'s keys: the policy's action goes to the environment unchanged."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.settings import setting


@dataclass(frozen=True)
class Config:
    """``controller=direct`` has no settings of its own."""

    name: str = setting("direct")
