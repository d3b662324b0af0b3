"""An evolution-strategy emitter for MAP-Elites (after ME-ES, Colas et al. 2020): one OpenAI-ES whose
candidates are part of every batch, scored and inserted into the archive like the other offspring,
and whose search distribution follows an objective of its own instead of the archive's fitness.

``objective``:
- ``distance``: the descriptor's norm (``final_xy``: how far the body ends from its start, the archive's
  ``furthest-distance-travelled``), which pushes the archive's frontier outward where uniform elites
  plus noise creep;
- ``fitness``: the archive's fitness (ME-ES's exploit emitter).

The search runs in the genotype's box mapped to [-1, 1] (``rlq.algos.qd.genotypes.search_frame``), from its centre,
as ``algo=es`` does, so ``sigma`` is a share of each dimension's range. Its state (evosax's, a flax pytree)
is carried in MAP-Elites' state: checkpoints hold it and resume continues it exactly.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import jax
import jax.numpy as jnp
import optax

from rlq.lib.carry import strongly_typed

if TYPE_CHECKING:  # evosax's import starts JAX's backend: a run over several processes joins them first
    from evosax.algorithms import Open_ES

OBJECTIVES = ("distance", "fitness")


def open_es(population: int, dim: int, sigma: float | jax.Array, lr: float | jax.Array) -> tuple[Open_ES, Any]:
    """evosax's OpenAI-ES over ``dim`` numbers (antithetic pairs of width ``sigma``, Adam at ``lr``) and its
    params; ``algo=es algo.strategy=open_es`` and this emitter both build it here."""
    from evosax.algorithms import Open_ES  # its import starts JAX's backend (see TYPE_CHECKING above)

    es = Open_ES(
        population,
        jnp.zeros(dim, jnp.float32),
        optimizer=optax.adam(lr),
        std_schedule=optax.constant_schedule(sigma),
    )
    return es, es.default_params


def objective_values(objective: str, fitness: jax.Array, descriptors: jax.Array) -> jax.Array:
    """What the emitter maximises for each offspring ``(n,)``; non-finite scores rank last."""
    value = jnp.linalg.norm(descriptors, axis=-1) if objective == "distance" else fitness
    return jnp.where(jnp.isfinite(value), value, -jnp.inf)


@dataclass(frozen=True, eq=False)
class EsEmitter:
    """OpenAI-ES of ``population`` (even: antithetic pairs) over genotypes ``centre + scale * x`` in
    ``[low, high]``, step size ``sigma`` (in x), Adam of rate ``lr``, maximising ``objective``."""

    population: int
    sigma: float | jax.Array
    lr: float | jax.Array
    objective: str
    centre: jax.Array
    scale: jax.Array
    low: jax.Array
    high: jax.Array
    _strategy: tuple[Open_ES, Any] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.objective not in OBJECTIVES:
            raise ValueError(f"objective must be one of {', '.join(OBJECTIVES)}, got {self.objective!r}")
        with jax.ensure_compile_time_eval():  # concrete params even when first built inside a trace
            strategy = open_es(self.population, int(self.low.shape[0]), self.sigma, self.lr)
        object.__setattr__(self, "_strategy", strategy)

    def at(self, sigma: float | jax.Array, lr: float | jax.Array) -> EsEmitter:
        """This emitter at step size ``sigma`` and learning rate ``lr`` (maybe traced: init's or an update's
        arguments)."""
        return replace(self, sigma=sigma, lr=lr)

    def init(self, key: jax.Array) -> Any:
        """The first state, at the centre of the search frame, of width this emitter's ``sigma`` (``at``'s: the
        hyperparameters ``init`` is given)."""
        es, params = self._strategy
        return strongly_typed(es.init(key, jnp.zeros(self.low.shape, jnp.float32), params))

    def ask(self, state: Any, key: jax.Array) -> tuple[jax.Array, jax.Array]:
        """The candidates in the search frame ``(population, dim)`` (to tell back) and as genotypes,
        clipped to the bounds (to score)."""
        es, params = self._strategy
        candidates, _ = es.ask(key, state, params)
        return candidates, jnp.clip(self.centre + self.scale * candidates, self.low, self.high)

    def mean(self, state: Any) -> jax.Array:
        """The search distribution's mean as a genotype ``(dim,)``, clipped to the bounds."""
        return jnp.clip(self.centre + self.scale * state.mean, self.low, self.high)

    def tell(
        self,
        state: Any,
        key: jax.Array,
        candidates: jax.Array,
        fitness: jax.Array,
        descriptors: jax.Array,
    ) -> Any:
        """One ES step from the scored ``candidates`` (evosax minimises: it is told minus the objective)."""
        es, params = self._strategy
        values = -objective_values(self.objective, fitness, descriptors)
        told, _ = es.tell(key, candidates, values, state, params)
        return strongly_typed(told)


def es_count(cfg: Any) -> int:
    """Offspring per iteration from the ES emitter (``algo.es_fraction`` of the batch, rounded down to
    an even number: antithetic pairs; 0 without it)."""
    return 2 * (round(int(cfg.batch_size) * float(cfg.es_fraction)) // 2)


def check(cfg: Any, others: int) -> str | None:
    """The ES emitter's share fits beside the ``others`` offspring the other emitters take."""
    if not float(cfg.es_fraction):
        return None
    if cfg.es_objective not in OBJECTIVES:
        return f"algo.es_objective must be one of {', '.join(OBJECTIVES)}, got {cfg.es_objective!r}"
    count, batch = es_count(cfg), int(cfg.batch_size)
    if count < 2:
        return (
            f"algo.es_fraction={cfg.es_fraction} of algo.batch_size={batch} gives the ES emitter {count} offspring; "
            f"it needs at least 2 (antithetic pairs): give a fraction of at least {2 / batch:.3g}"
        )
    if count + others > batch:
        return (
            f"algo.es_fraction={cfg.es_fraction} ({count} offspring) and algo.emitter={cfg.emitter} ({others}) "
            f"need more than algo.batch_size={batch}; lower one of them"
        )
    return None
