"""``algo=es``'s keys: evolution strategies (evosax), one update = one generation (ask -> score every candidate's full
episodes -> tell). Same genotypes as random_search / map_elites. The policy evaluated is the best candidate scored."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.learning.declared import ACTIVATION_NAMES
from rlq.lib.settings import FINITE, NON_NEGATIVE, POSITIVE, POSITIVE_INT, OneOf, Sizes, setting


@dataclass(frozen=True)
class Config:
    """``algo=es``'s keys: type, default, allowed values and meaning. Rules across keys and the env:
    ``rlq.algos.es.check``."""

    name: str = setting("es")
    #: open_es (OpenAI-ES, Adam on a centered-rank gradient) | cma_es | snes (STRATEGIES: check)
    strategy: str = setting("open_es")
    #: candidates per generation (even for open_es, antithetic pairs: check)
    population: int = setting(32, POSITIVE_INT)
    #: full episodes per candidate; fitness = mean return
    episodes: int = setting(4, POSITIVE_INT)
    #: std of the search distribution (open_es: fixed; cma_es/snes: initial, then adapted); genotype=action: in the
    #: action box mapped to [-1, 1] per dimension, starting at its centre
    sigma: float = setting(0.5, POSITIVE)
    #: open_es only: Adam's learning rate on the mean
    lr: float = setting(0.1, POSITIVE)
    #: genotype bounds: candidates are clipped to [low, high] before scoring (low below high: the genotype's check)
    low: float = setting(-2.0, FINITE)
    high: float = setting(2.0, FINITE)
    #: [] = linear policy; e.g. [16] for an MLP
    hidden: tuple[int, ...] = setting((), Sizes())
    #: linear policy only: add a bias term
    bias: bool = setting(False)
    #: MLP only
    activation: str = setting("tanh", OneOf(ACTIVATION_NAMES))
    #: policy: the weights above | action: one constant action, e.g. an open-loop CPG modulation (GENOTYPES: the
    #: genotype's check)
    genotype: str = setting("policy")
    #: candidate: the best candidate scored (on its own episodes) | mean: the distribution's mean, scored every
    #: generation on mean_episodes episodes, the best-scoring one kept (noisy envs) (KEEPS: check)
    keep: str = setting("candidate")
    #: keep=mean only: a multiple of episodes (the mean plays them as mean_episodes / episodes rows of the
    #: candidates' batch, one rollout program: check)
    mean_episodes: int = setting(32, POSITIVE_INT)
    #: policy genotypes only: the policy reads observations normalised by the running mean and std of every
    #: observation the candidates acted on in earlier generations (OpenAI-ES's and ARS's V2 normalisation); the kept
    #: policy keeps the statistics it was scored with
    normalize: bool = setting(False)
    #: subtracted per step played from the fitness the strategy is told (not from the fitness a policy is kept by, nor
    #: the logged returns): algo=random_search's algo.ars.reward_shift, Mania et al.'s removal of a survival bonus (5
    #: on the humanoid), so that standing until the time limit stops being the easy optimum; fitness=return only.
    #: Part of the program, not one of its inputs: a sweep over it compiles each value
    reward_shift: float = setting(0.0, NON_NEGATIVE)
    #: return | energy (minus the mean |joint actuator force|, brittle star) | distance (from the start, undirected
    #: brittle star) (the scoring's check)
    fitness: str = setting("return")
