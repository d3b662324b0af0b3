"""``algo=map_elites``'s keys: MAP-Elites (Mouret & Clune 2015), a grid archive keeps the fittest genotype per
descriptor cell. One update = one iteration: draw elites uniformly, vary them, score all offspring in one program,
insert the batch. These defaults run on CartPole (linear policies, cart position x pole angle at the episode's end);
experiment=brittle_star_map_elites is the brittle star CPG tutorial. The ``archive`` group is random search's too."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.learning.declared import ACTIVATION_NAMES
from rlq.lib.settings import COUNT, FINITE, NON_NEGATIVE, POSITIVE, POSITIVE_INT, SEED, OneOf, Range, Sizes, setting


@dataclass(frozen=True)
class ArchiveConfig:
    """The ``archive`` group of MAP-Elites (and of random search's optional archive): grid cells per dimension or
    CVT cells, and the descriptor bounds (one per kept descriptor component: MAP-Elites' check)."""

    #: grid: a regular grid of `shape` cells | cvt: `cells` Voronoi cells (CVT-MAP-Elites); map_elites.check names
    #: the choices
    kind: str = setting("grid")
    #: kind=grid: cells per descriptor dimension
    shape: tuple[int, ...] = setting((20, 20), Sizes(example="[20,20]"))
    #: descriptor bounds; descriptors outside fall into the border cells
    low: tuple[float, ...] = setting((-2.4, -0.21))
    high: tuple[float, ...] = setting((2.4, 0.21))
    #: kind=cvt: number of cells, centroids of k-means on cvt_samples uniform points in low..high
    cells: int = setting(400, POSITIVE_INT)
    cvt_samples: int = setting(10000, POSITIVE_INT)
    #: kind=cvt: seed of those points (the same cells for every run seed, resume, eval and render)
    cvt_seed: int = setting(0, SEED)


@dataclass(frozen=True)
class ChampionConfig:
    """The ``champion`` group: the policy a run ends with, kept by re-evaluation instead of the fittest elite
    (rlq/algos/qd/champion.py)."""

    #: the fittest elites scored again each iteration on fresh episodes (with the ES emitter's mean, when it runs);
    #: the best re-scored one so far is the run's policy. 0: none, the policy is the fittest elite
    candidates: int = setting(0, COUNT)
    #: candidates > 0: fresh episodes per candidate each iteration, a multiple of ``episodes`` (they play as rows of
    #: the offspring's batch); its re-evaluated fitness is their mean
    episodes: int = setting(32, POSITIVE_INT)


@dataclass(frozen=True)
class Config:
    """``algo=map_elites``'s keys: type, default, allowed values and meaning. Rules across keys and the env:
    ``rlq.algos.map_elites.check`` (and the emitters' and genotype's)."""

    name: str = setting("map_elites")
    #: policy: a direct policy's weights (below) | action: one constant action, e.g. a CPG modulation latched at reset
    #: (controller=cpg controller.mode=parametric controller.modulate=at_reset) (GENOTYPES: the genotype's check)
    genotype: str = setting("policy")
    #: return | energy (minus the mean |joint actuator force| over the episode, brittle star) | distance (from the
    #: start, undirected brittle star) (the scoring's check)
    fitness: str = setting("return")
    #: final_xy (brittle star disk xy, m) | landing (LunarLander: x, touchdown speed) | feet_contact (humanoid: share of steps each foot is on the floor) | last_obs (check)
    descriptor: str = setting("last_obs")
    #: components of the descriptor to keep (null: all); CartPole: cart position, pole angle
    descriptor_dims: tuple[int, ...] | None = setting((0, 2), Sizes(low=0, example="[0,2]"))
    archive: ArchiveConfig = setting(ArchiveConfig())
    #: offspring per iteration (evaluated in parallel)
    batch_size: int = setting(128, POSITIVE_INT)
    #: episodes per offspring; fitness and descriptor are their means
    episodes: int = setting(1, POSITIVE_INT)
    #: gaussian: parent + sigma N(0, I) | iso_line: Vassiliades & Mouret 2018 (VARIATIONS: the emitters' check)
    variation: str = setting("gaussian")
    sigma: float = setting(0.1, POSITIVE)
    #: iso_line only
    iso_sigma: float = setting(0.005, NON_NEGATIVE)
    line_sigma: float = setting(0.05, NON_NEGATIVE)
    #: who makes the offspring: gaussian | iso_line (uniform elites + that variation; the default is algo.variation's)
    #: | improvement (CMA-ME: CMA-ES emitters ranking offspring by archive improvement, restarting at a random elite
    #: when stalled) | mixed (both, see below) | rotation (uniform elites turned by a random whole number of arms, a
    #: symmetry of the brittle star, then algo.sigma's gaussian; CPG genotypes, see below) (EMITTERS: the emitters'
    #: check)
    emitter: str = setting("${.variation}")
    #: emitter=mixed: share of each batch from the improvement emitters, the rest from algo.variation
    improvement_fraction: float = setting(0.5, Range(0.0, 1.0, low_open=True, high_open=True))
    #: emitter=rotation: share of each batch turned, the rest from algo.variation
    rotation_fraction: float = setting(0.5, Range(0.0, 1.0, low_open=True))
    #: share of each batch from an OpenAI-ES emitter (ME-ES), beside any emitter above; 0: none. Its candidates are
    #: scored and inserted like the others; its mean follows es_objective
    es_fraction: float = setting(0.0, Range(0.0, 1.0, high_open=True))
    #: distance: the descriptor's norm (final_xy: how far from the start) | fitness: algo.fitness (OBJECTIVES: the ES
    #: emitter's check)
    es_objective: str = setting("distance")
    #: the ES's step size, as a share of each genotype dimension's half-range (algo=es's frame)
    es_sigma: float = setting(0.1, POSITIVE)
    #: the ES's Adam learning rate
    es_lr: float = setting(0.05, POSITIVE)
    #: improvement/mixed: independent CMA-ES emitters, sharing those offspring equally (>= 2 each)
    cma_emitters: int = setting(1, POSITIVE_INT)
    #: improvement/mixed: each CMA-ES's initial step size (again at every restart)
    cma_sigma: float = setting(0.5, POSITIVE)
    #: added to each elite's fitness in the QD score (keeps it positive and increasing)
    qd_offset: float = setting(0.0, FINITE)
    champion: ChampionConfig = setting(ChampionConfig())
    #: iterations between heatmaps (figures/heatmap_seed<i>_step_<N>.png, W&B); 0: end only
    heatmap_every: int = setting(10, COUNT)
    #: genotype=policy: the network and the bounds of its weights. [] = linear policy (2 actions: a = 1 if w·obs (+ b)
    #: >= 0); e.g. [16] for an MLP
    hidden: tuple[int, ...] = setting((), Sizes())
    bias: bool = setting(False)
    activation: str = setting("tanh", OneOf(ACTIVATION_NAMES))
    #: below high: the genotype's check
    low: float = setting(-2.0, FINITE)
    high: float = setting(2.0, FINITE)
