"""``algo=qlearning``'s keys: tabular Q-learning, one Q-table shared by num_envs parallel envs (and by their agents in
decentralised control: env.observation=arm_sectors controller.mode=decentralised). Needs Discrete observations and
actions (for a Box observation, set env.discretize; see experiment=cartpole_qlearning)."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.learning.declared import Epsilon
from rlq.lib.settings import COUNT, NON_NEGATIVE, POSITIVE_INT, PROBABILITY, Range, setting


@dataclass(frozen=True)
class Config:
    """``algo=qlearning``'s keys: type, default, allowed values and meaning. Rules across keys and the env:
    ``rlq.algos.qlearning.check``."""

    name: str = setting("qlearning")
    num_envs: int = setting(16, POSITIVE_INT)
    #: vectorised env steps per update (num_envs x num_steps env steps)
    num_steps: int = setting(128, POSITIVE_INT)
    #: learning rate (the floor of the step size with alpha_decay=visits)
    alpha: float = setting(0.1, Range(0.0, 1.0, low_open=True))
    #: none: constant alpha | visits: per-(s,a) sample average max(alpha, 1/n) (ALPHA_DECAYS: check)
    alpha_decay: str = setting("none")
    gamma: float = setting(0.99, PROBABILITY)
    #: table initialised uniform in [-init_scale, init_scale]
    init_scale: float = setting(0.001, NON_NEGATIVE)
    #: transitions kept for replay (0: no replay; else at least num_envs x agents: check)
    replay_size: int = setting(0, COUNT)
    #: transitions drawn (uniformly, with replacement) per replay update
    replay_batch: int = setting(256, POSITIVE_INT)
    #: replay updates after each vectorised step's own update (with the same parallel_update)
    replay_updates: int = setting(1, POSITIVE_INT)
    #: sequential: the envs' transitions applied in env order | mean: each (s,a) once, towards its mean target
    #: (PARALLEL_UPDATES: check)
    parallel_update: str = setting("sequential")
    epsilon: Epsilon = setting(Epsilon(duration=200000))
