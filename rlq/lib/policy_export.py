"""A policy network's parameters alone, for inference without rlq's training state (`rlq export`).

An MLP policy is exported as ``params`` (``policy``: the MLP's parameters as ``rlq.lib.learning.networks.MLP``
builds them; ``obs_mean``, ``obs_std``: the observation normalisation, 0 and 1 where there is none)
and a JSON ``spec`` with what rebuilds and reads the network: ``hidden``, ``outputs``,
``activation``, ``head`` (``argmax``: a discrete action; ``clip``: the first ``len(low)`` outputs,
clipped to [low, high]; ``tanh``: those squashed by tanh into [low, high]) and the spaces.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import jax
import numpy as np

from rlq.errors import ExportError
from rlq.lib.spaces import AgentsDiscrete, Box, Discrete, Space

HEADS = ("argmax", "clip", "tanh")


@dataclass(frozen=True)
class PolicyExport:
    params: dict[str, Any]
    spec: dict[str, Any]


def _space(space: Space) -> dict[str, Any]:
    if isinstance(space, Discrete):
        return {"type": "discrete", "n": int(space.n)}
    assert isinstance(space, Box)
    return {
        "type": "box",
        "shape": list(space.shape),
        "low": np.asarray(space.low).tolist(),
        "high": np.asarray(space.high).tolist(),
    }


def mlp_policy(
    mlp_params: Any,
    obs_space: Space,
    action_space: Space,
    hidden: tuple[int, ...],
    outputs: int,
    activation: str,
    head: str,
    compute_dtype: str = "float32",
    obs_mean: Any = None,
    obs_std: Any = None,
) -> PolicyExport:
    """The export of an MLP policy (``mlp_params``: the MLP module's own parameter dict, with
    ``outputs`` units in its last layer)."""
    if head not in HEADS:
        raise ValueError(f"unknown policy head {head!r}; one of {HEADS}")
    if isinstance(obs_space, AgentsDiscrete) or isinstance(action_space, AgentsDiscrete):
        raise ExportError(
            "a policy shared by agents (one observation and action per arm: env.observation=arm_sectors, "
            "controller.mode=decentralised) has no export format yet; use rlq eval/render on the run"
        )
    size: tuple[int, ...]
    if isinstance(obs_space, Discrete):
        size = (int(obs_space.n),)  # the network reads a one-hot vector
    else:
        assert isinstance(obs_space, Box)
        size = tuple(obs_space.shape)
    params = {
        "policy": jax.tree.map(np.asarray, dict(mlp_params)),
        "obs_mean": np.zeros(size, np.float32) if obs_mean is None else np.asarray(obs_mean, np.float32),
        "obs_std": np.ones(size, np.float32) if obs_std is None else np.asarray(obs_std, np.float32),
    }
    spec: dict[str, Any] = {
        "network": "mlp",
        "hidden": [int(h) for h in hidden],
        "outputs": int(outputs),
        "activation": activation,
        "compute_dtype": compute_dtype,
        "head": head,
        "observation_space": _space(obs_space),
        "action_space": _space(action_space),
    }
    if isinstance(action_space, Box):
        spec["low"], spec["high"] = _space(action_space)["low"], _space(action_space)["high"]
    return PolicyExport(params, spec)
