"""CMA-ME's improvement emitter (Fontaine et al. 2020): CMA-ES search distributions that move
toward whatever improves the archive, instead of mutating uniformly drawn elites.

Each of ``emitters`` independent CMA-ES instances (evosax's ``CMA_ES``) samples ``population``
offspring around its mean (clipped to the genotype bounds). After the batch is scored, each
offspring is ranked against the archive as it was before the batch: first those that reach an
empty cell (by fitness), then those that beat their cell's elite (by the improvement), then the
rest (by the improvement, negative), invalid ones last. CMA-ES is told that ranking, so its mean
and covariance follow the improvement. An emitter none of whose offspring improved the archive
restarts: a fresh CMA-ES (step size ``sigma``) around an elite drawn uniformly from the archive
(the bounds' centre while the archive is empty). The state is a pytree carried in the
algorithm's state, so checkpoints hold it and a resumed run continues it exactly.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import jax
import jax.numpy as jnp
from flax import struct

from rlq.algos.qd import archive as qd_archive
from rlq.algos.qd.variation import VARIATIONS

if TYPE_CHECKING:  # evosax's import starts JAX's backend: a run over several processes joins them first
    from evosax.algorithms import CMA_ES

#: ``algo.emitter``: uniform elites + one variation, CMA-ME's improvement emitters, or both, or
#: uniform elites turned by a symmetry of the body beside the variation (``rotation``)
EMITTERS = (*VARIATIONS, "improvement", "mixed", "rotation")
#: status of an offspring against the archive before its batch
NEW_CELL, IMPROVES, NO_GAIN, INVALID = 2, 1, 0, -1


class ImprovementState(struct.PyTreeNode):
    es: Any  # evosax's CMA-ES state, each leaf with a leading axis of one entry per emitter
    restarts: jax.Array  # restarts so far, over all emitters


def improvement_ranks(fitness: jax.Array, cells: jax.Array, archive: qd_archive.Archive) -> tuple[jax.Array, jax.Array]:
    """Rank (0 = best) and status of each offspring of fitness ``(n,)`` in flat cells ``(n,)``,
    against ``archive`` before their batch: new cells first by fitness, then improvements of an
    elite by the gain, then the rest by the (negative) gain; non-finite fitness last."""
    fitness = jnp.asarray(fitness, jnp.float32)
    elite, filled = archive.fitness[cells], archive.filled[cells]
    valid = jnp.isfinite(fitness)
    status = jnp.where(~valid, INVALID, jnp.where(~filled, NEW_CELL, jnp.where(fitness > elite, IMPROVES, NO_GAIN)))
    value = jnp.where(valid, jnp.where(filled, fitness - elite, fitness), -jnp.inf)
    order = jnp.lexsort((-value, -status))  # the last key sorts first
    ranks = jnp.zeros_like(order).at[order].set(jnp.arange(order.shape[0], dtype=order.dtype))
    return ranks, status


@dataclass(frozen=True, eq=False)
class ImprovementEmitter:
    """``emitters`` CMA-ES instances of ``population`` offspring each over genotypes in ``[low, high]``."""

    emitters: int
    population: int
    sigma: float
    low: jax.Array
    high: jax.Array
    _strategy: tuple[CMA_ES, Any] = field(init=False, repr=False)

    @property
    def batch(self) -> int:
        """Offspring per iteration, over all emitters."""
        return self.emitters * self.population

    def __post_init__(self) -> None:
        from evosax.algorithms import CMA_ES  # its import starts JAX's backend (see TYPE_CHECKING above)

        with jax.ensure_compile_time_eval():  # concrete params even when first built inside a trace
            es = CMA_ES(self.population, jnp.zeros(self.low.shape, jnp.float32))
            params = es.default_params.replace(std_init=jnp.asarray(self.sigma, jnp.float32))
        object.__setattr__(self, "_strategy", (es, params))

    def _fresh(self, keys: jax.Array, means: jax.Array) -> Any:
        es, params = self._strategy
        return jax.vmap(lambda key, mean: es.init(key, mean, params))(keys, means)

    def init(self, key: jax.Array) -> ImprovementState:
        centre = jnp.broadcast_to((self.low + self.high) / 2, (self.emitters,) + self.low.shape)
        return ImprovementState(self._fresh(jax.random.split(key, self.emitters), centre), jnp.zeros((), jnp.int32))

    def ask(self, state: ImprovementState, key: jax.Array) -> jax.Array:
        """The batch's offspring ``(emitters * population, dim)``, clipped to the bounds."""
        es, params = self._strategy
        samples, _ = jax.vmap(lambda k, s: es.ask(k, s, params))(jax.random.split(key, self.emitters), state.es)
        return jnp.clip(samples.reshape(self.batch, -1), self.low, self.high)

    def tell(
        self,
        state: ImprovementState,
        key: jax.Array,
        offspring: jax.Array,
        fitness: jax.Array,
        descriptors: jax.Array,
        cells: qd_archive.Cells,
        before: qd_archive.Archive,
        after: qd_archive.Archive,
    ) -> ImprovementState:
        """Update each CMA-ES with its offspring's improvement ranking (``before``/``after``: the
        archive of ``cells`` around their insertion); restart those that found nothing."""
        es, params = self._strategy
        tell_key, pick_key, init_key = jax.random.split(key, 3)
        shape = (self.emitters, self.population)
        valid = jnp.all(jnp.isfinite(descriptors), axis=-1)  # the archive never takes the others
        fitness = jnp.where(valid, fitness, -jnp.inf)
        index = qd_archive.cell_index(cells, descriptors)
        ranks, status = jax.vmap(lambda f, c: improvement_ranks(f, c, before))(
            fitness.reshape(shape), index.reshape(shape)
        )
        told, _ = jax.vmap(lambda k, x, r, s: es.tell(k, x, r.astype(jnp.float32), s, params))(
            jax.random.split(tell_key, self.emitters), offspring.reshape(shape + (-1,)), ranks, state.es
        )
        stalled = ~jnp.any(status > NO_GAIN, axis=1) | ~jnp.all(jnp.isfinite(told.mean), axis=1)
        centre = jnp.broadcast_to((self.low + self.high) / 2, (self.emitters,) + self.low.shape)
        elites = jnp.where(jnp.any(after.filled), qd_archive.select(after, pick_key, self.emitters), centre)
        fresh = self._fresh(jax.random.split(init_key, self.emitters), elites)
        es_state = jax.tree.map(lambda new, old: _rows_where(stalled, new, old), fresh, told)
        return ImprovementState(es_state, state.restarts + jnp.sum(stalled, dtype=jnp.int32))


class EmitterSettings(Protocol):
    """The keys of MAP-Elites' config that split its offspring over the emitters."""

    @property
    def emitter(self) -> str: ...
    @property
    def batch_size(self) -> int: ...
    @property
    def improvement_fraction(self) -> float: ...
    @property
    def rotation_fraction(self) -> float: ...
    @property
    def cma_emitters(self) -> int: ...


def improvement_count(cfg: EmitterSettings) -> int:
    """Offspring per iteration from the improvement emitters (0 without them)."""
    if cfg.emitter == "improvement":
        return int(cfg.batch_size)
    if cfg.emitter == "mixed":
        return round(int(cfg.batch_size) * float(cfg.improvement_fraction))
    return 0


def rotation_count(cfg: EmitterSettings) -> int:
    """Offspring per iteration turned by a symmetry (``emitter=rotation``; 0 otherwise)."""
    return round(int(cfg.batch_size) * float(cfg.rotation_fraction)) if cfg.emitter == "rotation" else 0


def check_emitter(cfg: EmitterSettings) -> str | None:
    """``algo.emitter`` is known, and the improvement offspring split evenly over the CMA-ES emitters."""
    if cfg.emitter not in EMITTERS:
        return f"algo.emitter must be one of {', '.join(EMITTERS)}, got {cfg.emitter!r}"
    if cfg.emitter == "rotation" and rotation_count(cfg) == 0:  # the fraction itself is in (0, 1]: map_elites.Config
        return (
            f"algo.emitter=rotation: algo.rotation_fraction={cfg.rotation_fraction} of algo.batch_size="
            f"{cfg.batch_size} turns no offspring; give a fraction of at least {1 / int(cfg.batch_size):.3g}"
        )
    count, batch = improvement_count(cfg), int(cfg.batch_size)
    if cfg.emitter == "mixed" and not 0 < count < batch:
        return (
            f"algo.emitter=mixed: algo.improvement_fraction={cfg.improvement_fraction} of algo.batch_size={batch} "
            f"gives {count} improvement offspring; give a fraction that leaves both emitters some "
            f"(between {1 / batch:.3g} and {1 - 1 / batch:.3g})"
        )
    emitters = int(cfg.cma_emitters)
    if 0 < count < 2:
        return f"algo.emitter={cfg.emitter} gives {count} offspring to CMA-ES, which needs at least 2 (raise algo.batch_size)"
    if count and (count % emitters or count // emitters < 2):
        return (
            f"algo.emitter={cfg.emitter} gives {count} offspring to algo.cma_emitters={emitters} CMA-ES emitters, "
            f"which need an equal share of at least 2 each; set algo.cma_emitters to a divisor of {count} "
            f"up to {count // 2}"
        )
    return None


def _rows_where(rows: jax.Array, new: jax.Array, old: jax.Array) -> jax.Array:
    """``new`` where ``rows`` (one flag per emitter, the leading axis), else ``old``, in ``old``'s dtype."""
    mask = rows.reshape(rows.shape + (1,) * (jnp.ndim(old) - 1))
    return jnp.where(mask, new, old).astype(jnp.asarray(old).dtype)
