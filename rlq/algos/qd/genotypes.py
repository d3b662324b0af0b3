"""Genotypes of black-box search: what a flat parameter vector means as a policy.

- ``policy``: the weights of a deterministic policy network for the ``direct`` controller
  (``hidden: []`` a linear map ``y = W·obs (+ b)``, else an ``rlq.lib.learning.networks.MLP``), decoded into
  an action: for two discrete actions the sign rule ``a = 1 if y >= 0`` (the textbook CartPole
  search), for n > 2 the argmax, for Box actions the outputs clipped to the bounds. Bounds: the
  config's ``[low, high]`` in every dimension.
- ``action``: one constant action, e.g. a CPG modulation latched at reset (``controller=cpg
  controller.mode=parametric controller.modulate=at_reset``: open-loop gaits); bounds: the
  env's Box action space.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, cast

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from rlq.lib.env_api import Env
from rlq.lib.learning import normalize
from rlq.lib.learning.networks import MLP, encode_obs
from rlq.lib.spaces import Box, Discrete, Space, flat_dim

GENOTYPES = ("policy", "action")

#: (flat genotype, one observation, key) -> one action
ApplyFn = Callable[[jax.Array, jax.Array, jax.Array], jax.Array]


class GenotypeSettings(Protocol):
    """The keys of a search's config (MAP-Elites', random search's, ES's ``Config``) that choose its genotype."""

    @property
    def genotype(self) -> str: ...
    @property
    def hidden(self) -> tuple[int, ...]: ...
    @property
    def bias(self) -> bool: ...
    @property
    def activation(self) -> str: ...
    @property
    def low(self) -> float: ...
    @property
    def high(self) -> float: ...


@dataclass(frozen=True)
class Genotype:
    dim: int
    low: np.ndarray
    high: np.ndarray
    apply: ApplyFn

    def applying(self, stats: normalize.RunningStats | None = None) -> ApplyFn:
        """``apply``, on observations normalised by ``stats`` where given (ARS's and ES's running statistics)."""
        if stats is None:
            return self.apply
        return lambda genotype, obs, key: self.apply(genotype, normalize.normalize_flat(stats, obs), key)

    def policy(
        self, genotype: jax.Array, stats: normalize.RunningStats | None = None
    ) -> Callable[[jax.Array, jax.Array], jax.Array]:
        """The greedy policy ``(obs, key) -> action`` of one genotype (on normalised observations: ``applying``)."""
        apply = self.applying(stats)
        return lambda obs, key: apply(genotype, obs, key)


def num_outputs(action_space: Space) -> int:
    if isinstance(action_space, Discrete):
        return 1 if action_space.n == 2 else action_space.n
    return action_space.shape[0]


def decode_action(y: jax.Array, action_space: Space, clip: bool = True) -> jax.Array:
    """Policy outputs -> env action: sign rule (2 actions), argmax (n actions), clip (Box; ``clip=False``: the
    outputs as they are, for an env that clamps them itself)."""
    if isinstance(action_space, Discrete):
        if action_space.n == 2:
            return (y[..., 0] >= 0).astype(jnp.int32)
        return jnp.argmax(y, axis=-1)
    assert isinstance(action_space, Box), "per-agent spaces are refused before (rlq.algos.check_algo)"
    if not clip:
        return y
    return jnp.clip(y, jnp.asarray(action_space.low), jnp.asarray(action_space.high))


def linear_policy(params: dict, obs: jax.Array) -> jax.Array:
    """``obs @ w (+ b)``; without ``b`` this is T1's rule ``a = 1 if w·obs >= 0``."""
    y = obs @ params["w"]
    return y + params["b"] if "b" in params else y


def check(cfg: GenotypeSettings, env: Env) -> str | None:
    """A one-line problem with ``algo.genotype`` on ``env``, or None."""
    if cfg.genotype not in GENOTYPES:
        return f"algo.genotype must be one of {', '.join(GENOTYPES)}, got {cfg.genotype!r}"
    space = env.action_space
    if cfg.genotype == "action":
        if not isinstance(space, Box) or not (np.isfinite(space.low).all() and np.isfinite(space.high).all()):
            return (
                "algo.genotype=action needs a bounded Box action space (e.g. controller=cpg controller.mode=parametric)"
            )
        return None
    if not isinstance(space, Discrete | Box):
        return "algo.genotype=policy needs a Discrete or Box action space"
    if not cfg.low < cfg.high:
        return f"algo.low={cfg.low} must be below algo.high={cfg.high}"
    return None


def _policy_genotype(cfg: GenotypeSettings, env: Env, clip: bool) -> Genotype:
    obs_space, action_space = env.observation_space, env.action_space
    out = num_outputs(action_space)
    outputs: Callable[[Any, jax.Array], jax.Array]
    if cfg.hidden:
        net = MLP(tuple(cfg.hidden), out, cfg.activation)
        example = net.init(jax.random.PRNGKey(0), encode_obs(jnp.zeros(obs_space.shape, jnp.float32), obs_space))
        outputs = cast(Callable[[Any, jax.Array], jax.Array], net.apply)
    else:
        example = {"w": jnp.zeros((flat_dim(obs_space), out), jnp.float32)}
        if cfg.bias:
            example["b"] = jnp.zeros((out,), jnp.float32)
        outputs = linear_policy
    flat0, unravel = ravel_pytree(example)
    dim = int(flat0.shape[0])

    def apply(genotype: jax.Array, obs: jax.Array, key: jax.Array) -> jax.Array:
        return decode_action(outputs(unravel(genotype), encode_obs(obs, obs_space)), action_space, clip)

    return Genotype(dim, np.full(dim, float(cfg.low), np.float32), np.full(dim, float(cfg.high), np.float32), apply)


def _action_genotype(env: Env) -> Genotype:
    space = env.action_space
    assert isinstance(space, Box), "check() admits only Box actions for genotype=action"
    low, high = np.asarray(space.low, np.float32).reshape(-1), np.asarray(space.high, np.float32).reshape(-1)

    def apply(genotype: jax.Array, obs: jax.Array, key: jax.Array) -> jax.Array:
        return genotype.reshape(space.shape)

    return Genotype(int(low.shape[0]), low, high, apply)


def genotype_rotations(cfg: GenotypeSettings, env: Env) -> np.ndarray | None:
    """Index permutations of the genotype under which the body is symmetric (row 0 the identity),
    or None: only an action genotype of a controller that knows its arms has them."""
    rotations = getattr(env, "action_rotations", None) if cfg.genotype == "action" else None
    return None if rotations is None else rotations()


def genotype_dim(cfg: GenotypeSettings, env: Env) -> int:
    """The numbers of ``make_genotype(cfg, env)``'s genotype, found without making one (the network's shapes only:
    a size check must not allocate what it checks)."""
    if cfg.genotype == "action":
        return flat_dim(env.action_space)
    obs_space, out = env.observation_space, num_outputs(env.action_space)
    if not cfg.hidden:
        return flat_dim(obs_space) * out + (out if cfg.bias else 0)
    net = MLP(tuple(int(n) for n in cfg.hidden), out, cfg.activation)
    obs = jax.ShapeDtypeStruct(obs_space.shape, jnp.float32)
    shapes = jax.eval_shape(lambda o: net.init(jax.random.PRNGKey(0), encode_obs(o, obs_space)), obs)
    return sum(int(np.prod(leaf.shape)) for leaf in jax.tree.leaves(shapes))


def make_genotype(cfg: GenotypeSettings, env: Env, clip_actions: bool = True) -> Genotype:
    """The genotype named by ``cfg.genotype`` (``policy`` or ``action``) on ``env``; ``clip_actions=False`` hands a
    policy's Box outputs to the env unclipped (the caller checks ``env.clamps_actions``)."""
    problem = check(cfg, env)
    if problem:
        raise ValueError(problem)
    return _action_genotype(env) if cfg.genotype == "action" else _policy_genotype(cfg, env, clip_actions)


def search_frame(cfg: GenotypeSettings, low: np.ndarray, high: np.ndarray) -> tuple[jax.Array, jax.Array]:
    """Where the strategy searches: genotype = centre + scale * x. A policy's weights are searched as they are
    (centre 0, scale 1). A constant action (a CPG modulation: amplitudes in [0, 1], a frequency up to 3 pi, phases in
    [-pi, pi]) is searched in its box mapped to [-1, 1] per dimension, so the search starts at the box's centre and
    one ``sigma`` means the same share of every dimension's range."""
    if cfg.genotype == "action":
        return jnp.asarray((low + high) / 2, jnp.float32), jnp.asarray((high - low) / 2, jnp.float32)
    return jnp.zeros(low.shape, jnp.float32), jnp.ones(low.shape, jnp.float32)
