"""Two of MJX's tree computations written for all DOFs at once: ``cdof`` and ``com_vel``.

MJX builds the motion DOFs (``cdof``, in ``com_pos``) and the body velocities and DOF velocity
products (``cvel``, ``cdof_dot``, in ``com_vel``) with ``scan.flat`` and ``scan.body_tree``: bodies
are grouped by joints and tree depth, each group gathers its rows of the per-body, per-joint and
per-DOF arrays, and the results are concatenated and gathered back. On a GPU, XLA fuses each into
kernels that evaluate many gathers and concatenations for every output element: for the humanoid
at 4096 envs the ``cdof`` kernel alone took 120 µs of each physics step, the two ``com_vel``
kernels about 80 µs (H100; docs/history/benchmarks.md).

Here every DOF reads its rows through static index tables instead, so ``cdof`` is a few gathers
and element-wise ops (bit for bit MJX's: same arithmetic per element), and ``com_vel`` sums each
body's and DOF's ancestors' ``cdof · qvel`` with a constant 0/1 matrix (one matrix product; MJX
adds them level by level, so the sums differ from MJX's by float rounding).
``vectorized_cdof()`` and ``vectorized_com_vel()`` swap them in while the physics is traced.
"""

from __future__ import annotations

import contextlib
import types
from collections.abc import Iterator
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from mujoco.mjx._src import math as mjx_math
from mujoco.mjx._src import scan as mjx_scan
from mujoco.mjx._src import smooth as mjx_smooth
from mujoco.mjx._src.types import JointType


def _dof_joints(m: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per DOF: its joint, the joint's type, and the DOF's index within the joint."""
    joint = np.asarray(m.dof_jntid)
    return joint, np.asarray(m.jnt_type)[joint], np.arange(len(joint)) - np.asarray(m.jnt_dofadr)[joint]


def dof_tables(m: Any) -> dict[str, np.ndarray]:
    """Per DOF: its body and joint, the row of the axis source (body frame columns, then joint
    axes, then a zero row), whether it rotates, slides, and its unit vector if it translates freely."""
    nbody, njnt, nv = len(m.body_rootid), len(m.jnt_type), len(m.dof_jntid)
    joint, kind, k = _dof_joints(m)
    body = np.asarray(m.jnt_bodyid)[joint]
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
    ``scan.flat`` call is MJX's own). rlq.envs.humanoid.env traces it one thread at a time."""
    original = mjx_smooth.scan
    mjx_smooth.scan = types.SimpleNamespace(**{**vars(mjx_scan), "flat": _flat})
    try:
        yield
    finally:
        mjx_smooth.scan = original


def velocity_tables(m: Any) -> dict[str, np.ndarray]:
    """0/1 matrices over DOFs ``u``: ``body_sum[b, u]`` if ``u`` moves body ``b`` (a DOF of ``b`` or
    of an ancestor); ``dof_sum[v, u]`` if ``u`` is already in the velocity that DOF ``v``'s
    ``cdof_dot`` crosses with (MJX's order: ancestors' DOFs, earlier joints of the same body, and
    for a free joint's rotations its translations); ``still[v]``: ``cdof_dot`` is zero (free
    translations)."""
    parent = np.asarray(m.body_parentid)
    nbody = len(parent)
    dof_body = np.asarray(m.dof_bodyid)
    dof_joint, kind, k = _dof_joints(m)
    ancestors = np.eye(nbody, dtype=bool)  # ancestors[b, a]: a is b or above it
    for b in range(1, nbody):
        ancestors[b] |= ancestors[parent[b]]
    body_sum = ancestors[:, dof_body]
    strict = ancestors[dof_body][:, dof_body] & (dof_body[:, None] != dof_body[None, :])
    same_body = dof_body[:, None] == dof_body[None, :]
    earlier_joint = same_body & (dof_joint[None, :] < dof_joint[:, None])
    free = kind == JointType.FREE
    free_translation = free & (k < 3)
    own_translations = (
        (dof_joint[:, None] == dof_joint[None, :]) & (free & (k >= 3))[:, None] & free_translation[None, :]
    )
    return {
        "body_sum": body_sum.astype(np.float32),
        "dof_sum": (strict | earlier_joint | own_translations).astype(np.float32),
        "still": free_translation[:, None],
    }


def com_vel(m: Any, d: Any) -> Any:
    """MJX's ``com_vel``: ``cvel`` [nbody, 6] and ``cdof_dot`` [nv, 6] from ``cdof`` and ``qvel``."""
    t = velocity_tables(m)
    moved = d.cdof * d.qvel[:, None]
    cvel = jnp.asarray(t["body_sum"]) @ moved
    before = jnp.asarray(t["dof_sum"]) @ moved
    cdof_dot = jnp.where(t["still"], 0.0, jax.vmap(mjx_math.motion_cross)(before, d.cdof))
    return d.tree_replace({"cvel": cvel, "cdof_dot": cdof_dot})


@contextlib.contextmanager
def vectorized_com_vel() -> Iterator[None]:
    """While active, MJX's forward pass computes ``cvel`` and ``cdof_dot`` with ``com_vel`` above."""
    original = mjx_smooth.com_vel
    mjx_smooth.com_vel = com_vel
    try:
        yield
    finally:
        mjx_smooth.com_vel = original
