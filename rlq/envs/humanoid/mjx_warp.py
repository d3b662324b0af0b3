"""brax's MJX pipeline on MuJoCo Warp (MJX's ``impl="warp"``): the same model and brax env, with
the physics step run by MuJoCo Warp's CUDA kernels instead of MJX's JAX implementation.

brax's own pipeline cannot do this: its ``init`` calls ``mjx.make_data(sys)``, which MuJoCo Warp
refuses (it builds data from a ``mujoco.MjModel`` only). This pipeline builds the data once, from
the model, and every reset starts from that template.

MuJoCo Warp keeps the contacts of all worlds (envs) of a batched call in one buffer of
``naconmax`` entries. Contacts beyond it are dropped (MuJoCo Warp prints "overflow"), so the buffer
must hold the most contacts of every env a program steps at once (envs × seeds).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import mujoco
from brax.mjx import pipeline as brax_pipeline
from mujoco import mjx

from rlq.envs.humanoid.mjx_unroll import brax_frames
from rlq.envs.mujoco.impl import with_template_buffers

#: MJX data's fields, which brax's state extends with its own
DATA_FIELDS = tuple(field.name for field in dataclasses.fields(mjx.Data))


class WarpPipeline:
    """Drop-in for ``brax.mjx.pipeline`` (``init``/``step``) on MuJoCo Warp data."""

    def __init__(self, mj_model: mujoco.MjModel, naconmax: int):
        self._template = mjx.make_data(mj_model, impl="warp", naconmax=int(naconmax))

    def init(self, sys: Any, q: jax.Array, qd: jax.Array, act=None, ctrl=None, unused_debug=False):
        data = self._template.replace(qpos=q, qvel=qd)
        if act is not None:
            data = data.replace(act=act)
        if ctrl is not None:
            data = data.replace(ctrl=ctrl)
        data = mjx.forward(sys, data)
        x, xd = brax_frames(sys, data)
        fields = {**data.__dict__, "contact": None}  # brax's contact view needs MJX-JAX contacts
        return brax_pipeline.State(q=data.qpos, qd=data.qvel, x=x, xd=xd, **fields)

    def _template_buffers(self, state: Any) -> Any:
        """brax's state (MJX data and brax's fields) with Warp's batch-shared buffers taken from the
        template (``rlq.envs.mujoco.impl.with_template_buffers``)."""
        view = mjx.Data(**{name: getattr(state, name) for name in DATA_FIELDS})
        fresh = with_template_buffers(self._template, view)
        return state.replace(**{name: getattr(fresh, name) for name in DATA_FIELDS})

    def step(self, sys: Any, state: Any, act: jax.Array, unused_debug=False):
        data = mjx.step(sys, self._template_buffers(state.replace(ctrl=act)))
        x, xd = brax_frames(sys, data)
        return data.replace(q=data.qpos, qd=data.qvel, x=x, xd=xd)


def use_warp(brax_env: Any, naconmax: int) -> None:
    """Switch a brax ``PipelineEnv`` with the MJX backend to MuJoCo Warp, in place."""
    mj_model = brax_env.sys.mj_model
    brax_env.sys = brax_env.sys.replace(**mjx.put_model(mj_model, impl="warp").__dict__)
    brax_env._pipeline = WarpPipeline(mj_model, naconmax)
