"""``algo=random_search``'s keys: random policy search (T1), sample a population of parameter vectors per generation,
score each by its mean return over full episodes, keep the best. Defaults are the textbook CartPole search;
``variant=ars`` reads the ``ars`` group (rlq/algos/ars.py)."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.declared.map_elites import ArchiveConfig
from rlq.lib.learning.declared import ACTIVATION_NAMES
from rlq.lib.settings import COUNT, FINITE, NON_NEGATIVE, POSITIVE, POSITIVE_INT, OneOf, Sizes, setting


@dataclass(frozen=True)
class ArsConfig:
    """The ``ars`` group of ``algo=random_search``, read with ``algo.variant=ars`` (Mania et al. 2018, V2-t): 2 x
    directions candidates w +- noise * delta per iteration, each over `episodes` full episodes; the `top` directions
    step w by step_size / (top * std of their returns). Starts at w = 0; population, sampling, low, high and sigma
    do not apply (top <= directions: ``rlq.algos.ars.check``)."""

    #: Gaussian directions per iteration (each scored in both signs)
    directions: int = setting(32, POSITIVE_INT)
    #: directions that step the policy (by their better sign's return)
    top: int = setting(16, POSITIVE_INT)
    #: alpha
    step_size: float = setting(0.02, POSITIVE)
    #: nu: the exploration noise on the weights
    noise: float = setting(0.03, POSITIVE)
    #: V2: observations normalised by the running statistics of every state seen
    normalize: bool = setting(True)
    #: subtracted from the training return per step played: Mania et al.'s removal of a survival bonus (5 on the
    #: humanoid), so standing still stops being the easy optimum
    reward_shift: float = setting(0.0, NON_NEGATIVE)
    #: false: the linear policy's raw outputs go to the env, as Mania et al.'s did (the env clamps them and charges
    #: its control cost on them); only envs that clamp Box actions themselves take that (``Env.clamps_actions``)
    clip_actions: bool = setting(True)


@dataclass(frozen=True)
class Config:
    """``algo=random_search``'s keys: type, default, allowed values and meaning. Rules across keys and the env:
    ``rlq.algos.random_search.check``."""

    name: str = setting("random_search")
    #: hill_climb: the keys below (T1's search) | ars: augmented random search, the ars: keys (VARIANTS: check)
    variant: str = setting("hill_climb")
    #: candidates per generation (one update = one generation)
    population: int = setting(20, POSITIVE_INT)
    #: full episodes per candidate; fitness = mean return
    episodes: int = setting(20, POSITIVE_INT)
    #: uniform: every candidate uniform in [low, high] | gaussian: best + sigma * N(0, I), clipped (check)
    sampling: str = setting("uniform")
    #: parameter bounds (low below high: the genotype's check)
    low: float = setting(-2.0, FINITE)
    high: float = setting(2.0, FINITE)
    #: step size of gaussian sampling
    sigma: float = setting(0.1, POSITIVE)
    #: [] = linear policy (2 actions: a = 1 if w·obs (+ b) >= 0); e.g. [16] for an MLP
    hidden: tuple[int, ...] = setting((), Sizes())
    #: linear policy only: add a bias term
    bias: bool = setting(False)
    #: MLP only
    activation: str = setting("tanh", OneOf(ACTIVATION_NAMES))
    #: policy: the weights above | action: one constant action, e.g. an open-loop CPG modulation (GENOTYPES: the
    #: genotype's check)
    genotype: str = setting("policy")
    #: return | energy (minus the mean |joint actuator force|, brittle star) | distance (from the start, undirected
    #: brittle star) (the scoring's check)
    fitness: str = setting("return")
    #: an optional archive: every candidate is also inserted into a MAP-Elites grid (QD metrics and heatmaps of random
    #: search, the baseline of experiment=brittle_star_random_search). final_xy | landing | feet_contact | last_obs (see algo=
    #: map_elites; with an archive: MAP-Elites' check)
    descriptor: str | None = setting(None)
    descriptor_dims: tuple[int, ...] | None = setting(None, Sizes(low=0, example="[0,2]"))
    #: null: no archive
    archive: ArchiveConfig | None = setting(None)
    qd_offset: float = setting(0.0, FINITE)
    #: generations between archive heatmaps (with an archive)
    heatmap_every: int = setting(10, COUNT)
    ars: ArsConfig = setting(ArsConfig())
