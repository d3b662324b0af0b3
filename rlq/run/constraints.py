"""The allowed values of config keys, in one table: ranges, choices, batch sizes and lists of sizes.

The yaml files under conf/ are the schema (a key's type is its default's, rlq.run.validate);
this table says which values of a key mean something. An entry applies wherever the composed
config has its key: ``algo.gamma`` covers every algorithm with a discount, ``env.wind_power``
only the envs that have wind. Checks that relate several keys or need the env (a minibatch
that divides the batch, an action space an algorithm supports) are the algorithms' and
controllers' ``check`` functions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf

from rlq.lib.distributions import ACTION_DISTS
from rlq.lib.minibatches import MINIBATCH_SHUFFLES
from rlq.lib.networks import ACTIVATIONS
from rlq.run.cadences import CHUNK_LOOPS
from rlq.run.devices import PLATFORMS
from rlq.run.program_cache import MODES as PROGRAM_CACHE_MODES

#: W&B modes rlq passes to ``wandb.init``
WANDB_MODES = ("offline", "online", "disabled")


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


@dataclass(frozen=True)
class Range:
    """A number in [low, high] (open ends with ``low_open``/``high_open``); ``integer``: whole numbers only."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    nullable: bool = False

    def _text(self, bound: float) -> str:
        return str(int(bound)) if self.integer else f"{bound:g}"

    def allowed(self) -> str:
        kind = "an integer" if self.integer else "a number"
        if self.low is not None and self.high is not None:
            left, right = "(" if self.low_open else "[", ")" if self.high_open else "]"
            text = f"{kind} in {left}{self._text(self.low)}, {self._text(self.high)}{right}"
        elif self.low is not None:
            text = f"{kind} {'>' if self.low_open else '>='} {self._text(self.low)}"
        elif self.high is not None:
            text = f"{kind} {'<' if self.high_open else '<='} {self._text(self.high)}"
        else:
            text = f"{kind}"
        return f"null or {text}" if self.nullable else text

    def accepts(self, value: Any) -> bool:
        if value is None:
            return self.nullable
        if not _number(value) or not math.isfinite(value):
            return False
        if self.integer and not float(value).is_integer():
            return False
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            return False
        return not (self.high is not None and (value > self.high or (self.high_open and value == self.high)))


@dataclass(frozen=True)
class OneOf:
    """One of a fixed set of names."""

    choices: tuple[str, ...]
    nullable: bool = False

    def allowed(self) -> str:
        return ("null or " if self.nullable else "") + "one of " + ", ".join(self.choices)

    def accepts(self, value: Any) -> bool:
        return (value is None and self.nullable) or value in self.choices


@dataclass(frozen=True)
class Sizes:
    """A list of whole numbers >= ``low`` (layer widths, cells per archive dimension, component
    indices), never floats that would be truncated; null when ``nullable``."""

    nullable: bool = False
    low: int = 1
    example: str = "[64,64]"

    def allowed(self) -> str:
        return ("null or " if self.nullable else "") + f"a list of integers >= {self.low}, e.g. {self.example}"

    def accepts(self, value: Any) -> bool:
        if value is None:
            return self.nullable
        if not isinstance(value, (list, ListConfig)):
            return False
        return all(isinstance(v, int) and not isinstance(v, bool) and v >= self.low for v in value)


Constraint = Range | OneOf | Sizes

POSITIVE_INT = Range(1, integer=True)
COUNT = Range(0, integer=True)
#: JAX's PRNG takes a seed as two 32-bit words, and rlq folds each seed's index into it: an unsigned 32-bit seed
SEED = Range(0, 2**32 - 1, integer=True)
#: the run's step and update counters are 32-bit integers on the device (JAX's default)
BUDGET = Range(1, 2**31 - 1, integer=True)
PROBABILITY = Range(0.0, 1.0)
POSITIVE = Range(0.0, low_open=True)
NON_NEGATIVE = Range(0.0)
#: any finite number (no NaN or Inf): a key whose bounds another check states in its own words (the env's, the
#: algorithm's), or one that means something at any value (a genotype bound, a reward weight)
FINITE = Range()
WHOLE = Range(integer=True)

CONSTRAINTS: dict[str, Constraint] = {
    # run
    "seed": SEED,
    "num_seeds": POSITIVE_INT,
    "budget.env_steps": BUDGET,
    "log_every_steps": POSITIVE_INT,
    "chunk_loop": OneOf(CHUNK_LOOPS),
    "program_cache": OneOf(PROGRAM_CACHE_MODES),
    "shaped_for.platform": OneOf(PLATFORMS, nullable=True),
    "eval.episodes": POSITIVE_INT,
    "guard.max_abs_loss": Range(0, low_open=True, nullable=True),
    "guard.max_params_norm": Range(0, low_open=True, nullable=True),
    "eval.every_steps": COUNT,
    "checkpoint.every_steps": COUNT,
    "checkpoint.keep_last": COUNT,
    "video.every_steps": COUNT,
    "return_window": COUNT,
    "video.max_steps": Range(1, integer=True, nullable=True),
    "logger.wandb.mode": OneOf(WANDB_MODES),
    # algorithms (each key where the algorithm has it): batch sizes
    "algo.num_envs": POSITIVE_INT,
    "algo.num_steps": POSITIVE_INT,
    "algo.update_epochs": POSITIVE_INT,
    "algo.num_minibatches": POSITIVE_INT,
    "algo.train_every": POSITIVE_INT,
    "algo.gradient_steps": POSITIVE_INT,
    "algo.buffer_size": POSITIVE_INT,
    "algo.batch_size": POSITIVE_INT,
    "algo.target_every": POSITIVE_INT,
    "algo.population": POSITIVE_INT,
    "algo.episodes": POSITIVE_INT,
    "algo.replay_size": COUNT,
    "algo.replay_batch": POSITIVE_INT,
    "algo.replay_updates": POSITIVE_INT,
    # algorithms: the rest
    "algo.gamma": PROBABILITY,
    "algo.gae_lambda": PROBABILITY,
    "algo.lr": POSITIVE,
    "algo.adam_eps": POSITIVE,
    "algo.clip_eps": POSITIVE,
    "algo.ent_coef": NON_NEGATIVE,
    "algo.vf_coef": NON_NEGATIVE,
    "algo.max_grad_norm": Range(0.0, nullable=True),
    "algo.reward_scaling": POSITIVE,
    "algo.learning_starts": COUNT,
    "algo.init_scale": NON_NEGATIVE,
    "algo.sigma": POSITIVE,
    "algo.iso_sigma": NON_NEGATIVE,
    "algo.line_sigma": NON_NEGATIVE,
    "algo.heatmap_every": COUNT,
    "algo.improvement_fraction": Range(0.0, 1.0, low_open=True, high_open=True),
    "algo.rotation_fraction": Range(0.0, 1.0, low_open=True),
    "algo.cma_emitters": POSITIVE_INT,
    "algo.es_fraction": Range(0.0, 1.0, high_open=True),
    "algo.es_sigma": POSITIVE,
    "algo.es_lr": POSITIVE,
    "algo.cma_sigma": POSITIVE,
    "algo.ars.directions": POSITIVE_INT,
    "algo.ars.top": POSITIVE_INT,
    "algo.ars.step_size": POSITIVE,
    "algo.ars.noise": POSITIVE,
    "algo.ars.reward_shift": NON_NEGATIVE,
    "algo.archive.cells": POSITIVE_INT,
    "algo.archive.cvt_samples": POSITIVE_INT,
    "algo.archive.cvt_seed": SEED,
    "algo.epsilon.duration": POSITIVE_INT,
    "algo.epsilon.start": FINITE,  # both in [0, 1]: the algorithms' check says so of the pair
    "algo.epsilon.end": FINITE,
    "algo.epsilon.decay": PROBABILITY,
    "algo.mean_episodes": POSITIVE_INT,
    "algo.n_step": POSITIVE_INT,  # at most algo.train_every: DQN's check
    "algo.tau": Range(0.0, 1.0, low_open=True),
    "algo.ema": PROBABILITY,
    "algo.lam": PROBABILITY,
    "algo.alpha": Range(0.0, 1.0, low_open=True),
    "algo.low": FINITE,  # below algo.high: the genotype's check
    "algo.high": FINITE,
    "algo.qd_offset": FINITE,
    "algo.activation": OneOf(tuple(ACTIVATIONS)),
    "algo.action_dist": OneOf(ACTION_DISTS),
    "algo.minibatch_shuffle": OneOf(MINIBATCH_SHUFFLES),
    "algo.hidden": Sizes(),
    "algo.policy_hidden": Sizes(nullable=True),
    "algo.value_hidden": Sizes(nullable=True),
    "algo.archive.shape": Sizes(example="[20,20]"),
    "algo.descriptor_dims": Sizes(nullable=True, low=0, example="[0,2]"),
    # envs
    "env.max_episode_steps": Range(1, integer=True, nullable=True),
    "env.action_repeat": POSITIVE_INT,
    "env.wind_power": NON_NEGATIVE,
    "env.turbulence_power": NON_NEGATIVE,
    "env.episode_length": POSITIVE_INT,
    "env.n_frames": POSITIVE_INT,
    "env.reset_noise_scale": NON_NEGATIVE,
    "env.simulation_time": POSITIVE,
    "env.physics_steps_per_control_step": POSITIVE_INT,
    "env.time_scale": POSITIVE,
    "env.target_distance": NON_NEGATIVE,
    "env.joint_randomization": NON_NEGATIVE,
    "env.bearing_bins": POSITIVE_INT,
    "env.discretize.bins": Sizes(example="[3,3,6,12]"),
    "env.gravity": FINITE,  # in (-12, 0): the lunar env's check
    "env.num_arms": WHOLE,  # 1 to 5: the brittle star's check
    "env.segments_per_arm": POSITIVE_INT,
    "env.ctrl_cost_weight": NON_NEGATIVE,
    "env.forward_reward_weight": FINITE,
    "env.healthy_reward": FINITE,
    "env.warp_contacts": POSITIVE_INT,
    "env.physics.condim": Range(1, 6, integer=True),
    "env.physics.iterations": POSITIVE_INT,
    "env.physics.ls_iterations": POSITIVE_INT,
    "env.solver.velocity_iterations": POSITIVE_INT,
    "env.solver.position_iterations": POSITIVE_INT,
    "env.solver.unroll": POSITIVE_INT,
    "env.solver.component_unroll": POSITIVE_INT,
    # controllers
    "controller.leading_arm": Range(0, integer=True, nullable=True),
    "controller.coupling_weight": NON_NEGATIVE,
    "controller.amplitude_gain": POSITIVE,
    "controller.offset_gain": POSITIVE,
    "controller.phase_noise": NON_NEGATIVE,
    "controller.leading_amplitude": NON_NEGATIVE,
    "controller.max_amplitude": POSITIVE,
    "controller.max_offset": NON_NEGATIVE,
    "controller.max_omega": POSITIVE,
    "controller.leading_omega": FINITE,
}

#: where one algorithm gives a key another meaning than the table's entry (PPO: null batch = one unroll per env)
PER_ALGORITHM: dict[str, dict[str, Constraint]] = {
    "ppo": {"algo.batch_size": Range(1, integer=True, nullable=True)},
}

_MISSING = object()


def problems(cfg: DictConfig) -> str | None:
    """The first key of ``cfg`` whose value the table refuses, as one line; None when all fit."""
    algo = OmegaConf.select(cfg, "algo.name", default=None)
    special = PER_ALGORITHM.get(str(algo), {})
    for key, constraint in CONSTRAINTS.items():
        constraint = special.get(key, constraint)
        value = OmegaConf.select(cfg, key, default=_MISSING, throw_on_missing=False)
        if value is _MISSING:
            continue
        if not constraint.accepts(value):
            return f"{key} must be {constraint.allowed()}, got {value!r}"
    return None
