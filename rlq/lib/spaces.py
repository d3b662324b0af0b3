"""Action and observation spaces: small frozen dataclasses, static under jit."""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp


@dataclass(frozen=True)
class Discrete:
    """Integer actions or observations in ``0 .. n-1``."""

    n: int

    @property
    def shape(self) -> tuple[int, ...]:
        return ()

    def sample(self, key: jax.Array) -> jax.Array:
        return jax.random.randint(key, (), 0, self.n)


@dataclass(frozen=True)
class Box:
    """Real vectors with per-dimension bounds (``inf`` where unbounded)."""

    low: tuple[float, ...]
    high: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.low) != len(self.high):
            raise ValueError("Box low and high must have the same length")

    @property
    def shape(self) -> tuple[int, ...]:
        return (len(self.low),)

    @property
    def bounded(self) -> bool:
        return all(abs(x) < float("inf") for x in (*self.low, *self.high))

    def sample(self, key: jax.Array) -> jax.Array:
        low, high = jnp.asarray(self.low), jnp.asarray(self.high)
        return jax.random.uniform(key, self.shape, minval=low, maxval=high)

    @classmethod
    def uniform(cls, low: float, high: float, dim: int) -> Box:
        return cls((float(low),) * dim, (float(high),) * dim)


@dataclass(frozen=True)
class AgentsDiscrete:
    """One ``Discrete(n)`` value per agent, shape ``(agents,)``: decentralised control, where the
    agents (the brittle star's arms) act alike and share one learner (tabular Q: one table indexed
    by an agent's own state). Algorithms that do not declare ``AlgorithmSpec.agents`` refuse it."""

    n: int
    agents: int

    @property
    def shape(self) -> tuple[int, ...]:
        return (self.agents,)

    def sample(self, key: jax.Array) -> jax.Array:
        return jax.random.randint(key, self.shape, 0, self.n)


Space = Discrete | Box | AgentsDiscrete


def flat_dim(space: Space) -> int:
    """Size of a network input/output for this space (one-hot for Discrete)."""
    return space.n if isinstance(space, Discrete) else space.shape[0]
