"""MAP-Elites (Mouret & Clune 2015) in rlq's one loop: one ``update`` is one iteration.

    parents   = uniform draw of elites from the filled cells (random genotypes while it is empty)
    offspring = variation(parents)                       gaussian or iso+line, clipped to bounds
              | improvement emitters' samples            CMA-ME (rlq/algos/qd/emitters.py)
              | both, in the proportion ``improvement_fraction`` (``emitter=mixed``)
              | elites turned by whole arms, then gaussian   ``emitter=rotation``, ``rotation_fraction``
              + an OpenAI-ES's candidates                   ``es_fraction`` > 0 (rlq/algos/qd/es_emitter.py)
    rows      = offspring + the champion's candidates    ``champion.candidates`` > 0: the fittest elites and the
                                                         ES mean, each replicated (rlq/algos/qd/champion.py,
                                                         scoring.score_with_replicas)
    fitness, descriptors, extras = scoring_fn(rows)      every row's episodes, one program
    archive   = insert(archive, offspring)               batched; strictly better replaces
    improvement emitters told their offspring's ranking against the archive; restarted when stalled
    the ES emitter told its candidates' objective (``es_objective``: distance or fitness)
    champion  = the best re-scored candidate so far      the mean of each candidate's rows

The archive (rlq/algos/qd/archive.py: a grid, or a CVT's cells, rlq/algos/qd/cvt.py) and the
emitters' CMA-ES and ES states are part of the state, so checkpoints hold them and resume continues them
exactly; ``num_seeds`` archives train together like any algorithm's seeds. Genotypes
(rlq/algos/qd/genotypes.py), fitness and descriptor (rlq/algos/qd/measures.py) are named in config.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Protocol

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from rlq.algos.base import Algorithm, Hyperparams, updates_for_budget
from rlq.algos.qd import archive as qd_archive
from rlq.algos.qd import champion as qd_champion
from rlq.algos.qd import es_emitter, measures, variation
from rlq.algos.qd.cvt import Cvt
from rlq.algos.qd.emitters import ImprovementEmitter, check_emitter, improvement_count, rotation_count
from rlq.algos.qd.genotypes import GenotypeSettings, genotype_rotations, make_genotype, search_frame
from rlq.algos.qd.genotypes import check as check_genotype
from rlq.algos.qd.heatmap import heatmap
from rlq.algos.qd.scoring import Scored, make_keyed_scoring_fn, score_with_replicas
from rlq.algos.spec import AlgorithmSpec
from rlq.declared.map_elites import ArchiveConfig, Config
from rlq.lib.env_api import Env, info_shapes

ARCHIVE_KINDS = ("grid", "cvt")
#: the numeric keys init and the update read as arguments (``Algorithm.init``'s and ``update``'s ``hp``): the
#: variations' widths and the ES emitter's step size (its state starts from ``es_sigma``) and learning rate. Not
#: ``cma_sigma`` (each restart's CMA-ES is made from it outside the update's arithmetic) nor ``qd_offset`` (the
#: evaluation program's QD score adds it too)
SWEEPABLE = ("sigma", "iso_sigma", "line_sigma", "es_sigma", "es_lr")


class MapElitesState(struct.PyTreeNode):
    archive: qd_archive.Archive
    key: jax.Array
    env_steps: jax.Array
    generation: jax.Array
    emitter: Any = None  # the improvement emitters' state (emitter=improvement or mixed), else None
    es: Any = None  # the ES emitter's state (es_fraction > 0), else None
    champion: qd_champion.Champion | None = None  # the policy kept by re-evaluation (champion.candidates > 0)


class TaskSettings(GenotypeSettings, Protocol):
    """The keys of a search's config (MAP-Elites', random search's) that ``check_task`` and ``grid_of`` read."""

    @property
    def name(self) -> str: ...
    @property
    def fitness(self) -> str: ...
    @property
    def descriptor(self) -> str | None: ...
    @property
    def descriptor_dims(self) -> tuple[int, ...] | None: ...
    @property
    def archive(self) -> ArchiveConfig | None: ...


def grid_of(cfg: TaskSettings) -> qd_archive.Cells:
    """The archive's cells: ``algo.archive.kind`` grid (the default) or cvt."""
    archive = cfg.archive
    assert archive is not None, "a search without an archive has no cells"
    low, high = tuple(float(x) for x in archive.low), tuple(float(x) for x in archive.high)
    if archive.kind == "cvt":
        return Cvt(int(archive.cells), low, high, int(archive.cvt_samples), int(archive.cvt_seed))
    return qd_archive.Grid(tuple(int(n) for n in archive.shape), low, high)


def check_descriptor_dims(cfg: TaskSettings, full: int) -> str | None:
    """``algo.descriptor_dims`` names distinct components of a descriptor of ``full`` components
    (an index past the end would be clamped to the last one inside the compiled program)."""
    if cfg.descriptor_dims is None:
        return None
    dims = [int(d) for d in cfg.descriptor_dims]
    given = f"algo.descriptor_dims=[{','.join(str(d) for d in dims)}]"
    size = f"{full} components" + (" (the observation's size)" if cfg.descriptor == "last_obs" else "")
    allowed = f"indices in 0..{full - 1}"
    outside = [d for d in dims if not 0 <= d < full]
    if outside:
        return f"{given}: algo.descriptor={cfg.descriptor} has {size}, so {outside[0]} is out of range; give {allowed}"
    twice = next((d for d in dims if dims.count(d) > 1), None)
    if twice is not None:
        return f"{given} names component {twice} twice; give distinct {allowed}"
    return None


def check_task(cfg: TaskSettings, env: Env) -> str | None:
    """What MAP-Elites and random search both need: episodes that end, a genotype for this env,
    and (with an archive) a fitness, a descriptor and a grid that fit each other."""
    if not env.max_episode_steps:
        return f"{cfg.name} scores full episodes; give env={type(env.unwrapped).__name__} a time limit"
    problem = check_genotype(cfg, env)
    if problem:
        return problem
    if cfg.archive is None:
        return None
    if cfg.descriptor is None:
        return f"{cfg.name} with an archive needs a descriptor (e.g. algo.descriptor=final_xy)"
    info = info_shapes(env)
    problem = measures.check(cfg.fitness, cfg.descriptor, set(info), env.unwrapped.descriptor_wrappers)
    if problem:
        return problem
    if cfg.archive.kind not in ARCHIVE_KINDS:
        return f"algo.archive.kind must be one of {', '.join(ARCHIVE_KINDS)}, got {cfg.archive.kind!r}"
    try:
        grid = grid_of(cfg)
    except ValueError as err:
        return str(err)
    full = int(np.prod(info[measures.DESCRIPTOR_KEYS[cfg.descriptor]].shape))  # before descriptor_dims picks some
    problem = check_descriptor_dims(cfg, full)
    if problem:
        return problem
    dims = full if cfg.descriptor_dims is None else len(cfg.descriptor_dims)
    if dims != grid.num_descriptors:
        bounds = "low and high have" if isinstance(grid, Cvt) else "shape has"
        keys = "low and high" if isinstance(grid, Cvt) else "shape, low and high"
        return (
            f"algo.descriptor={cfg.descriptor} has {dims} dimensions but algo.archive.{bounds} "
            f"{grid.num_descriptors} (set algo.descriptor_dims or the archive's {keys})"
        )
    return None


def check_rotation(cfg: Config, env: Env) -> str | None:
    """``emitter=rotation`` needs a genotype that knows the body's arms."""
    if cfg.emitter != "rotation" or genotype_rotations(cfg, env) is not None:
        return None
    return (
        "algo.emitter=rotation turns gaits by whole arms: it needs algo.genotype=action on the brittle star "
        "through controller=cpg with controller.mode=parametric or parametric_segment"
    )


def check_champion(cfg: Config) -> str | None:
    """The champion's candidates are the elites of distinct cells: no more than the archive has; each plays its
    episodes as rows of ``algo.episodes`` episodes."""
    archive = cfg.archive
    assert archive is not None, "check() refuses MAP-Elites without an archive first"
    cells = int(archive.cells) if archive.kind == "cvt" else math.prod(int(n) for n in archive.shape)
    count, episodes = int(cfg.champion.candidates), int(cfg.champion.episodes)
    if count > cells:
        return f"algo.champion.candidates={count} is more than the archive's {cells} cells; give at most {cells}"
    if count and episodes % int(cfg.episodes):
        return (
            f"algo.champion.episodes={episodes} is not a multiple of algo.episodes={cfg.episodes} (a candidate plays "
            f"its episodes in groups of algo.episodes, beside the offspring); give a multiple of {cfg.episodes}"
        )
    return None


def champion_rows(cfg: Config) -> int:
    """The rows the champion's candidates add to each iteration's scored batch: the fittest elites and the ES mean
    (when it runs), each ``champion.episodes / episodes`` times."""
    count = int(cfg.champion.candidates)
    if not count:
        return 0
    return (count + bool(es_emitter.es_count(cfg))) * (int(cfg.champion.episodes) // int(cfg.episodes))


def check_env_shards(cfg: Config, shards: int) -> str | None:
    """The champion's rows join the offspring's batch, and ``shards`` devices split the two together."""
    extra, batch = champion_rows(cfg), int(cfg.batch_size)
    if not extra or (batch + extra) % shards == 0:
        return None
    count, replicas = int(cfg.champion.candidates), int(cfg.champion.episodes) // int(cfg.episodes)
    mean = bool(es_emitter.es_count(cfg))
    who = f"{count} candidates" + (" and the ES mean" if mean else "")
    return (
        f"algo.champion's {extra} rows ({who}, {replicas} each) join algo.batch_size={batch}: the {batch + extra} "
        f"rows scored together split over {shards} devices, which does not divide them; set algo.champion.candidates "
        f"so that {batch} + (candidates{' + 1' if mean else ''}) x {replicas} is a multiple of {shards}"
    )


def check(cfg: Config, env: Env) -> str | None:
    if cfg.variation not in variation.VARIATIONS:
        return f"algo.variation must be one of {', '.join(variation.VARIATIONS)}, got {cfg.variation!r}"
    if cfg.archive is None:
        return "algo=map_elites needs an archive (algo.archive.shape, .low, .high)"
    others = improvement_count(cfg) + rotation_count(cfg)
    return (
        check_emitter(cfg)
        or es_emitter.check(cfg, others)
        or check_task(cfg, env)
        or check_rotation(cfg, env)
        or check_champion(cfg)
    )


def eval_metrics(cfg: Config) -> tuple[str, ...]:
    """The metrics ``with_archive``'s ``state_metrics`` add to each evaluation row."""
    return qd_archive.METRIC_NAMES if cfg.archive is not None else ()


def archive_figures(grid: qd_archive.Cells, labels: tuple[str, str]):
    """Host-side heatmap of one seed's archive (2-d archives only; a CVT's as coloured centroids)."""

    def figures(state) -> dict[str, np.ndarray]:
        if grid.num_descriptors != 2:
            return {}
        archive = state.archive
        cover = float(np.mean(archive.filled))
        title = f"generation {int(state.generation)}, coverage {100 * cover:.1f} %"
        return {"heatmap": heatmap(grid, archive.fitness, archive.filled, title, labels)}

    return figures


DESCRIPTOR_LABELS = {
    "final_xy": ("final x (m)", "final y (m)"),
    "landing": ("landing x", "touchdown speed"),
    "feet_contact": ("right foot: share of steps on the floor", "left foot: share of steps on the floor"),
}


def make(cfg: Config, env: Env, budget_env_steps: int) -> Algorithm:
    genotype = make_genotype(cfg, env)
    grid = grid_of(cfg)
    low, high = jnp.asarray(genotype.low), jnp.asarray(genotype.high)
    dims = None if cfg.descriptor_dims is None else tuple(int(d) for d in cfg.descriptor_dims)
    score_rows = make_keyed_scoring_fn(
        env,
        genotype.apply,
        cfg.episodes,
        descriptor_key=measures.DESCRIPTOR_KEYS[cfg.descriptor],
        fitness=cfg.fitness,
        descriptor_dims=dims,
    )
    batch = int(cfg.batch_size)
    improving, turning, searching = improvement_count(cfg), rotation_count(cfg), es_emitter.es_count(cfg)
    contenders = int(cfg.champion.candidates)  # the fittest elites re-scored each iteration, and the ES mean
    extra = champion_rows(cfg)
    replicas = int(cfg.champion.episodes) // int(cfg.episodes)
    assert env.max_episode_steps, "check() admits only envs with a time limit"
    steps_per_update = (batch + extra) * cfg.episodes * env.max_episode_steps
    num_updates = updates_for_budget(budget_env_steps, steps_per_update)
    drawn = batch - improving - turning - searching  # uniform elites + algo.variation
    rotations = jnp.asarray(genotype_rotations(cfg, env)) if turning else None
    emitter = (
        ImprovementEmitter(int(cfg.cma_emitters), improving // int(cfg.cma_emitters), float(cfg.cma_sigma), low, high)
        if improving
        else None
    )
    if searching:
        centre, scale = search_frame(cfg, genotype.low, genotype.high)
        es = es_emitter.EsEmitter(
            searching, float(cfg.es_sigma), float(cfg.es_lr), str(cfg.es_objective), centre, scale, low, high
        )

    def init(key: jax.Array, hp: Hyperparams) -> MapElitesState:
        """An empty archive; the ES emitter's search at ``hp``'s width."""
        zero = jnp.zeros((), jnp.int32)
        state = MapElitesState(qd_archive.empty(grid, genotype.dim), key, zero, zero)
        if emitter is not None:
            key, emitter_key = jax.random.split(key)
            state = state.replace(key=key, emitter=emitter.init(emitter_key))
        if searching:
            state = state.replace(es=es.at(hp["es_sigma"], hp["es_lr"]).init(jax.random.fold_in(key, 2)))
        if contenders:
            state = state.replace(champion=qd_champion.empty(genotype.dim))
        return state

    operator = cfg.emitter if cfg.emitter in variation.VARIATIONS else cfg.variation
    defaults = {name: float(getattr(cfg, name)) for name in SWEEPABLE}

    def varied(
        archive: qd_archive.Archive, key: jax.Array, count: int, hp: Hyperparams, how: str = operator
    ) -> jax.Array:
        """``count`` offspring of uniformly drawn elites and the variation ``how`` (``operator``, or
        ``turned``: each turned by a random whole number of arms before the gaussian mutation), at ``hp``'s widths."""
        select_key, partner_key, vary_key, random_key = jax.random.split(key, 4)
        parents = qd_archive.select(archive, select_key, count)
        if how == "turned":
            assert rotations is not None, "check_rotation admits emitter=rotation only with the genotype's rotations"
            children = variation.turned(vary_key, parents, rotations, hp["sigma"], low, high)
        elif how == "iso_line":
            partners = qd_archive.select(archive, partner_key, count)
            children = variation.iso_line(vary_key, parents, partners, hp["iso_sigma"], hp["line_sigma"], low, high)
        else:
            children = variation.gaussian(vary_key, parents, hp["sigma"], low, high)
        return jnp.where(jnp.any(archive.filled), children, variation.uniform(random_key, count, low, high))

    def scored(state: MapElitesState, offspring: jax.Array, result: Scored) -> tuple[MapElitesState, dict]:
        """The iteration's one scoring call, ``result``: the ``offspring`` inserted and in the metrics, every row's
        episodes (the champion's too) counted in the env steps."""
        fitness, descriptors, extras = result.fitness, result.descriptors, result.extras
        archive = qd_archive.insert(state.archive, grid, offspring, fitness, descriptors)
        env_steps = state.env_steps + extras["env_steps"]
        generation = state.generation + 1
        metrics = {
            **qd_archive.metrics(archive, cfg.qd_offset),
            "evaluations": generation * batch * cfg.episodes,
            "offspring-max-fitness": jnp.max(fitness),
            "episode_return": extras["episode_return"].mean(),
            "episode_length": extras["episode_length"].mean(),
            "env_steps": env_steps,
        }
        return state.replace(archive=archive, env_steps=env_steps, generation=generation), metrics

    def update(state: MapElitesState, hp: Hyperparams) -> tuple[MapElitesState, dict]:
        """One iteration at ``hp``'s values. Offspring in the order: uniform elites varied, turned elites, ES
        candidates, improvement emitters'; then the champion's candidates' rows."""
        es_at = es.at(hp["es_sigma"], hp["es_lr"]) if searching else None
        key, vary_key, score_key = jax.random.split(state.key, 3)
        var_key = vary_key
        if emitter is not None:
            var_key, ask_key, tell_key = jax.random.split(vary_key, 3)
        parts = [varied(state.archive, var_key, drawn, hp)] if drawn else []
        if turning:
            parts.append(varied(state.archive, jax.random.fold_in(vary_key, 1), turning, hp, how="turned"))
        if es_at is not None:
            es_ask_key, es_tell_key = jax.random.split(jax.random.fold_in(vary_key, 2))
            candidates, es_children = es_at.ask(state.es, es_ask_key)
            parts.append(es_children)
        if emitter is not None:
            asked = emitter.ask(state.emitter, ask_key)
            parts.append(asked)
        rows, keys = jnp.concatenate(parts), jax.random.split(score_key, batch)
        genotypes, valid = champion_candidates(state) if contenders else (None, None)
        result = score_with_replicas(score_rows, rows, keys, genotypes, replicas, jax.random.fold_in(vary_key, 3))
        fitness, descriptors = result.fitness, result.descriptors
        new, metrics = scored(state, rows, result)
        new = new.replace(key=key)
        if es_at is not None:
            own = slice(drawn + turning, drawn + turning + searching)
            told = es_at.tell(state.es, es_tell_key, candidates, fitness[own], descriptors[own])
            objective = es_emitter.objective_values(es.objective, fitness[own], descriptors[own])
            new = new.replace(es=told)
            metrics = {**metrics, "es-objective-max": jnp.max(objective), "es-objective-mean": jnp.mean(objective)}
        if emitter is not None:
            own = slice(batch - improving, batch)  # the improvement emitters' offspring come last
            restarted = emitter.tell(
                state.emitter, tell_key, asked, fitness[own], descriptors[own], grid, state.archive, new.archive
            )
            new = new.replace(emitter=restarted)
            metrics = {**metrics, "emitter-restarts": restarted.restarts}
        if contenders:
            assert state.champion is not None, "init makes a champion when champion.candidates > 0"
            assert genotypes is not None and valid is not None and result.replica_fitness is not None
            kept = qd_champion.kept(state.champion, genotypes, valid, result.replica_fitness)
            new = new.replace(champion=kept)
            metrics = {**metrics, "champion-fitness": kept.fitness}
        return new, metrics

    def champion_candidates(state: MapElitesState) -> tuple[jax.Array, jax.Array]:
        """The champion's candidates, known before the iteration's scoring: the fittest elites of the archive as the
        iteration finds it, and the mean its ES candidates are drawn around (when the ES emitter runs)."""
        mean = es.mean(state.es) if searching else None
        return qd_champion.contenders(state.archive, contenders, mean)

    def policy(state: MapElitesState):
        elite = state.archive.genotypes[qd_archive.best_cell(state.archive)]
        return genotype.policy(elite if state.champion is None else qd_champion.chosen(state.champion, elite))

    algo = Algorithm(init, update, policy, num_updates, steps_per_update, iterations=True, hyperparams=defaults)
    return with_archive(algo, cfg, grid)


class ArchiveSettings(TaskSettings, Protocol):
    """The keys of a search's config that its archive's figures and metrics read."""

    @property
    def heatmap_every(self) -> int: ...
    @property
    def qd_offset(self) -> float: ...


def with_archive(algo: Algorithm, cfg: ArchiveSettings, grid: qd_archive.Cells) -> Algorithm:
    """``algo`` with the archive's heatmaps and QD metrics (its state has an ``archive`` field)."""
    labels = DESCRIPTOR_LABELS.get(cfg.descriptor or "", ("descriptor 1", "descriptor 2"))
    return dataclasses.replace(
        algo,
        figures=archive_figures(grid, labels),
        figures_every=int(cfg.heatmap_every),
        state_metrics=lambda state: qd_archive.metrics(state.archive, cfg.qd_offset),
    )


SPEC = AlgorithmSpec(
    config=Config,
    make=make,
    check=check,
    env_axis="batch_size",
    check_env_shards=check_env_shards,
    eval_metrics=eval_metrics,
    sweepable=SWEEPABLE,
    unroll_axis=None,
)
