"""``algo=ppo``'s keys. Defaults: PureJaxRL's CartPole settings (experiment=humanoid_ppo is brax's MJX recipe)."""

from __future__ import annotations

from dataclasses import dataclass

from rlq.lib.learning.declared import ACTION_DISTS, ACTIVATION_NAMES, MINIBATCH_SHUFFLES
from rlq.lib.settings import NON_NEGATIVE, POSITIVE, POSITIVE_INT, PROBABILITY, OneOf, Sizes, setting


@dataclass(frozen=True)
class Config:
    """``algo=ppo``'s keys: type, default, allowed values and meaning. Rules across keys and the env:
    ``rlq.algos.ppo.check``."""

    name: str = setting("ppo")
    num_envs: int = setting(4, POSITIVE_INT)
    #: steps per unroll; GAE runs within an unroll (brax: unroll_length)
    num_steps: int = setting(128, POSITIVE_INT)
    #: null: one unroll per env per update, minibatch = num_envs*num_steps/num_minibatches. An integer takes brax's
    #: meaning: each minibatch holds batch_size unrolls, so an update collects batch_size*num_minibatches unrolls (a
    #: multiple of num_envs) and every epoch takes num_minibatches minibatches of batch_size*num_steps transitions
    batch_size: int | None = setting(None, POSITIVE_INT)
    #: brax: num_updates_per_batch
    update_epochs: int = setting(4, POSITIVE_INT)
    num_minibatches: int = setting(4, POSITIVE_INT)
    #: per_shard | global: the same on one device. With a seed's envs split over devices (devices=all), per_shard
    #: (brax's) shuffles each device's own envs' data and makes each minibatch of equal parts of every device's share,
    #: so no minibatch gathers across devices; global shuffles the whole batch at once (every minibatch from all
    #: devices: slower, but the numbers of the same run on one device)
    minibatch_shuffle: str = setting("per_shard", OneOf(MINIBATCH_SHUFFLES))
    lr: float = setting(2.5e-4, POSITIVE)
    #: linear decay to 0 over the run
    anneal_lr: bool = setting(True)
    adam_eps: float = setting(1.0e-5, POSITIVE)
    #: brax: discounting
    gamma: float = setting(0.99, PROBABILITY)
    gae_lambda: float = setting(0.95, PROBABILITY)
    clip_eps: float = setting(0.2, POSITIVE)
    #: clip the value loss with clip_eps as well (brax: off)
    clip_value: bool = setting(True)
    #: true (brax): minibatches of whole unrolls, GAE recomputed in every minibatch with the current value net (needs
    #: clip_value: false); false: advantages fixed once per update
    recompute_gae: bool = setting(False)
    #: brax: entropy_cost
    ent_coef: float = setting(0.01, NON_NEGATIVE)
    vf_coef: float = setting(0.5, NON_NEGATIVE)
    #: null or 0: no gradient clipping
    max_grad_norm: float | None = setting(0.5, NON_NEGATIVE)
    #: rewards are multiplied by this before GAE
    reward_scaling: float = setting(1.0, POSITIVE)
    #: running mean/std of observations (in the learner state; used by the greedy policy too)
    normalize_obs: bool = setting(False)
    #: Box actions: clipped_normal (state-free log-std, clipped at the env) | tanh_normal (brax: state-dependent std,
    #: tanh-squashed into the bounds)
    action_dist: str = setting("clipped_normal", OneOf(ACTION_DISTS))
    hidden: tuple[int, ...] = setting((64, 64), Sizes())
    #: one observation and action per agent (env.observation=arm_sectors, controller.mode=decentralised): true appends
    #: the agent's index, one-hot, to its input to the shared net
    agent_id: bool = setting(False)
    #: null: hidden
    policy_hidden: tuple[int, ...] | None = setting(None, Sizes())
    #: null: hidden
    value_hidden: tuple[int, ...] | None = setting(None, Sizes())
    activation: str = setting("tanh", OneOf(ACTIVATION_NAMES))
    #: float32 | bfloat16 (rlq.lib.learning.networks.COMPUTE_DTYPES: check): the hidden layers' compute dtype
    #: (parameters, outputs, losses and optimiser stay float32); bfloat16 halves the activations a minibatch step moves
    compute_dtype: str = setting("float32")
