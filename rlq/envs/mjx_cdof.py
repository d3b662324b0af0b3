"""MJX's motion degrees of freedom (``cdof``) computed for all DOFs at once.

MJX's ``com_pos`` builds ``cdof`` (each DOF's 6D motion axis about its tree's centre of mass) with
``scan.flat``: bodies are grouped by their joints, each group gathers its rows of the per-body and
per-joint arrays, and the groups' results are concatenated and gathered back into DOF order. On a
GPU, XLA fuses all of it into one kernel that evaluates the 24 gathers and the concatenations for
every output element: for the humanoid at 4096 envs that kernel takes 120 µs of each physics step
(docs/benchmarks.md, ninth session).

Here every DOF reads its rows through one static index table instead (rows of ``xmat``'s columns
and of ``xaxis`` in one source array), so the same arithmetic is a few gathers and element-wise
ops: the angular part is the joint's axis (hinge), a column of the body's frame (ball, free
rotation) or zero (slide, free translation); the linear part is ``axis × (root com − anchor)``,
the slide's axis, or a unit vector (free translation). ``vectorized_cdof()`` swaps it in for
MJX's call while the physics is traced.
"""

from __future__ import annotations

import contextlib
import types
from collections.abc import Iterator
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from mujoco.mjx._src import scan as mjx_scan
from mujoco.mjx._src import smooth as mjx_smooth
from mujoco.mjx._src.types import JointType


def dof_tables(m: Any) -> dict[str, np.ndarray]:
    """Per DOF: its body and joint, the row of the axis source (body frame columns, then joint
    axes, then a zero row), whether it rotates, slides, and its unit vector if it translates freely."""
    nbody, njnt, nv = len(m.body_rootid), len(m.jnt_type), len(m.dof_jntid)
    joint = np.asarray(m.dof_jntid)
    body = np.asarray(m.jnt_bodyid)[joint]
    kind = np.asarray(m.jnt_type)[joint]
    k = np.arange(nv) - np.asarray(m.jnt_dofadr)[joint]
    free, ball = kind == JointType.FREE, kind == JointType.BALL
    hinge, slide = kind == JointType.HINGE, kind == JointType.SLIDE
    free_translation = free & (k < 3)
    frame_column = np.where(free, k - 3, k)
    row = np.where(
        free_translation, 3 * nbody + njnt, np.where(free | ball, 3 * body + frame_column, 3 * nbody + joint)
    )
    unit = np.zeros((nv, 3), np.float32)
    unit[free_translation, k[free_translation]] = 1.0
    return {
        "body": body,
        "joint": joint,
        "row": row,
        "rotates": (hinge | ball | (free & ~free_translation))[:, None],
        "slides": slide[:, None],
        "unit": unit,
    }


def cdof(m: Any, root_com: jax.Array, xmat: jax.Array, xanchor: jax.Array, xaxis: jax.Array) -> jax.Array:
    """``cdof`` [nv, 6] from per-body ``root_com`` and ``xmat`` and per-joint ``xanchor`` and ``xaxis``."""
    t = dof_tables(m)
    source = jnp.concatenate([jnp.swapaxes(xmat, -1, -2).reshape(-1, 3), xaxis, jnp.zeros((1, 3), xaxis.dtype)], axis=0)
    axis = source[t["row"]]
    offset = root_com[t["body"]] - xanchor[t["joint"]]
    angular = jnp.where(t["rotates"], axis, 0.0)
    linear = jnp.where(t["rotates"], jnp.cross(axis, offset), jnp.where(t["slides"], axis, t["unit"]))
    return jnp.concatenate([angular, linear], axis=-1)


def _flat(m: Any, f: Any, in_types: str, out_types: str, *args, **kwargs) -> Any:
    if getattr(f, "__name__", "") == "cdof_fn" and (in_types, out_types) == ("jbbjj", "v") and not kwargs:
        return cdof(m, *args[1:])
    return mjx_scan.flat(m, f, in_types, out_types, *args, **kwargs)


@contextlib.contextmanager
def vectorized_cdof() -> Iterator[None]:
    """While active, MJX's ``com_pos`` computes ``cdof`` with ``cdof`` above (every other
    ``scan.flat`` call is MJX's own). Tracing happens on one thread (rlq.train.compile_pipelined)."""
    original = mjx_smooth.scan
    mjx_smooth.scan = types.SimpleNamespace(**{**vars(mjx_scan), "flat": _flat})
    try:
        yield
    finally:
        mjx_smooth.scan = original
