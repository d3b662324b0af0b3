"""``algo=dqn``'s keys: DQN with vectorised acting, replay, a target network, optional Double DQN and EMA evaluation
params. One update = num_envs x num_steps env steps; after every train_every vectorised steps the learner takes
gradient_steps steps on batches from the replay buffer. Defaults: tuned on CartPole (experiment=cartpole_dqn reaches
a greedy return of 500 within 3.5e5 env steps)."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.learning.declared import ACTIVATION_NAMES, Epsilon
from rlq.lib.settings import COUNT, NON_NEGATIVE, POSITIVE, POSITIVE_INT, PROBABILITY, OneOf, Range, Sizes, setting


@dataclass(frozen=True)
class Config:
    """``algo=dqn``'s keys: type, default, allowed values and meaning. Rules across keys and the env:
    ``rlq.algos.dqn.check``."""

    name: str = setting("dqn")
    num_envs: int = setting(8, POSITIVE_INT)
    #: vectorised env steps per update (keeps the scan short)
    num_steps: int = setting(64, POSITIVE_INT)
    #: vectorised env steps (num_envs transitions each) between learner phases
    train_every: int = setting(1, POSITIVE_INT)
    #: learner steps per phase
    gradient_steps: int = setting(1, POSITIVE_INT)
    #: env steps collected before the first learner step
    learning_starts: int = setting(5000, COUNT)
    buffer_size: int = setting(50000, POSITIVE_INT)
    batch_size: int = setting(128, POSITIVE_INT)
    lr: float = setting(1e-3, POSITIVE)
    #: linear decay of lr to 0 over the run's learner steps
    anneal_lr: bool = setting(True)
    #: global-norm gradient clipping (null or 0: off)
    max_grad_norm: float | None = setting(10.0, NON_NEGATIVE)
    gamma: float = setting(0.99, PROBABILITY)
    #: n-step returns, taken within each block of train_every steps (n_step <= train_every: check)
    n_step: int = setting(1, POSITIVE_INT)
    #: mse | huber (LOSSES: check)
    loss: str = setting("mse")
    #: Double DQN: the online net picks a', the target net values it
    double: bool = setting(True)
    #: learner steps between target updates
    target_every: int = setting(1, POSITIVE_INT)
    #: each target update: target <- tau*online + (1-tau)*target (1: hard copy, e.g. every 200)
    tau: float = setting(0.005, Range(0.0, 1.0, low_open=True))
    #: > 0: evaluate with an EMA of the online params, updated by this rate per learner step
    ema: float = setting(0.005, PROBABILITY)
    hidden: tuple[int, ...] = setting((64, 64), Sizes())
    #: one observation and action per agent (env.observation=arm_sectors, controller.mode=decentralised): true appends
    #: the agent's index, one-hot, to its input to the shared net
    agent_id: bool = setting(False)
    activation: str = setting("relu", OneOf(ACTIVATION_NAMES))
    #: LayerNorm before each hidden activation, as in PQN's network
    layer_norm: bool = setting(False)
    epsilon: Epsilon = setting(Epsilon(duration=50000))
