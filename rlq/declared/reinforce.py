"""``algo=reinforce``'s keys: REINFORCE (Monte-Carlo policy gradient); defaults follow T1 on CartPole (MLP 20-20,
undiscounted, no baseline, Adam). Each update: one rollout, one gradient step on every transition whose episode
finished inside it (T1 instead samples 256 of the last 512 transitions)."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.learning.declared import ACTIVATION_NAMES
from rlq.lib.settings import NON_NEGATIVE, POSITIVE, POSITIVE_INT, PROBABILITY, OneOf, Sizes, setting


@dataclass(frozen=True)
class Config:
    """``algo=reinforce``'s keys: type, default, allowed values and meaning. Rules across keys and the env:
    ``rlq.algos.reinforce.check``."""

    name: str = setting("reinforce")
    #: parallel auto-resetting envs
    num_envs: int = setting(10, POSITIVE_INT)
    #: rollout length per update; must cover a full episode (at least the env's time limit: check)
    num_steps: int = setting(500, POSITIVE_INT)
    #: Adam's
    lr: float = setting(1.0e-2, POSITIVE)
    #: decay lr linearly to 0 over the budget
    anneal_lr: bool = setting(False)
    #: discount of the rewards-to-go (T1: undiscounted)
    gamma: float = setting(1.0, PROBABILITY)
    #: none | mean (batch mean of the rewards-to-go) | value (learned critic) (BASELINES: check)
    baseline: str = setting("none")
    #: divide G_t - b by its batch std
    normalize_advantages: bool = setting(False)
    #: entropy bonus
    ent_coef: float = setting(0.0, NON_NEGATIVE)
    #: critic loss weight (baseline=value)
    vf_coef: float = setting(0.5, NON_NEGATIVE)
    max_grad_norm: float | None = setting(10.0, NON_NEGATIVE)
    hidden: tuple[int, ...] = setting((20, 20), Sizes())
    activation: str = setting("relu", OneOf(ACTIVATION_NAMES))
