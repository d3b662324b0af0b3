"""The keys of the learning pieces that the algorithms' declarations (rlq/declared/) share, apart from the pieces
themselves so that reading them imports no JAX: the names a network's activation, a policy's action distribution
and a learner's minibatch shuffle take, and the ``epsilon`` group of an ε-greedy algorithm."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.settings import FINITE, POSITIVE_INT, PROBABILITY, setting

#: values of ``algo.activation`` (flax.linen's functions of these names, rlq.lib.learning.networks)
ACTIVATION_NAMES = ("tanh", "relu", "elu", "gelu", "swish")

#: values of ``algo.action_dist`` (Box actions, rlq.lib.learning.distributions)
ACTION_DISTS = ("clipped_normal", "tanh_normal")

#: values of ``algo.minibatch_shuffle`` (rlq.lib.learning.minibatches)
MINIBATCH_SHUFFLES = ("per_shard", "global")


@dataclass(frozen=True)
class Epsilon:
    """The ``epsilon`` group of an ε-greedy algorithm (each algorithm's declaration gives its own defaults);
    ``rlq.lib.learning.schedules.check_epsilon`` states the rules of the pair and of the schedule."""

    #: linear: start -> end over duration env steps | exponential: start * decay^episodes, floor end
    schedule: str = setting("linear")
    start: float = setting(1.0, FINITE)  # start and end both in [0, 1]: check_epsilon says so of the pair
    end: float = setting(0.05, FINITE)
    #: linear: env steps (per seed, all envs together)
    duration: int = setting(50000, POSITIVE_INT)
    #: exponential: factor per completed episode
    decay: float = setting(0.995, PROBABILITY)
