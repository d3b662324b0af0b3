"""``algo=pqn``'s keys: PQN (Gallici et al. 2024), Q-learning from many parallel envs, no replay buffer and no target
network; Peng's Q(lambda) returns over each update's rollout, epochs of minibatches, LayerNorm in the Q-network.
One update = num_envs x num_steps env steps. experiment=cartpole_pqn and lunar_pqn_gpu set them for their envs."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.learning.declared import ACTIVATION_NAMES, MINIBATCH_SHUFFLES, Epsilon
from rlq.lib.settings import NON_NEGATIVE, POSITIVE, POSITIVE_INT, PROBABILITY, OneOf, Sizes, setting


@dataclass(frozen=True)
class Config:
    """``algo=pqn``'s keys: type, default, allowed values and meaning. Rules across keys and the env:
    ``rlq.algos.pqn.check``."""

    name: str = setting("pqn")
    num_envs: int = setting(32, POSITIVE_INT)
    #: env steps per env per update; the Q(lambda) returns run within them
    num_steps: int = setting(32, POSITIVE_INT)
    update_epochs: int = setting(4, POSITIVE_INT)
    num_minibatches: int = setting(4, POSITIVE_INT)
    #: per_shard | global: as algo=ppo's (the same on one device; per_shard keeps each minibatch's gather on the
    #: devices that hold the envs when devices=all splits them)
    minibatch_shuffle: str = setting("per_shard", OneOf(MINIBATCH_SHUFFLES))
    lr: float = setting(1e-3, POSITIVE)
    #: linear decay of lr to 0 over the run's gradient steps
    anneal_lr: bool = setting(True)
    #: global-norm gradient clipping (null or 0: off)
    max_grad_norm: float | None = setting(10.0, NON_NEGATIVE)
    gamma: float = setting(0.99, PROBABILITY)
    #: lambda of the Q(lambda) returns (0: one-step targets)
    lam: float = setting(0.65, PROBABILITY)
    #: rewards are multiplied by this before the returns
    reward_scaling: float = setting(1.0, POSITIVE)
    hidden: tuple[int, ...] = setting((128, 128), Sizes())
    #: one observation and action per agent (env.observation=arm_sectors, controller.mode=decentralised): true appends
    #: the agent's index, one-hot, to its input to the shared net
    agent_id: bool = setting(False)
    activation: str = setting("relu", OneOf(ACTIVATION_NAMES))
    #: LayerNorm before each hidden activation (what lets PQN drop the target network)
    layer_norm: bool = setting(True)
    epsilon: Epsilon = setting(Epsilon(duration=100000))
