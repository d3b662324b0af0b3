"""The lander's bodies as float32 arrays (hull = 0, legs[0] = 1, legs[1] = 2) and 2-D vector math."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt

from rlq.envs.lunar import consts as C
from rlq.envs.lunar.physics.collide import rotate

F32 = jnp.float32


def constant(values: npt.ArrayLike) -> jax.Array:
    """A float32 device constant, converted by NumPy and copied with ``device_put``: ``jnp.asarray``
    compiles a small program per shape at import."""
    return jax.device_put(np.asarray(values, np.float32))


INV_MASS = constant(C.INV_MASS)
INV_I = constant(C.INV_INERTIA)
LOCAL_CENTER = constant(C.LOCAL_CENTER)
HULL_VERTS = constant(C.HULL_VERTS)
HULL_NORMALS = constant(C.HULL_NORMALS)
HULL_CENTROID = constant(C.HULL_CENTER)
LEG_VERTS = constant(C.LEG_VERTS)
LEG_NORMALS = constant(C.LEG_NORMALS)


def cross_vs(w: jax.Array, r: jax.Array) -> jax.Array:
    """Scalar × vector cross product: w k × r."""
    return jnp.stack([-w * r[..., 1], w * r[..., 0]], axis=-1)


def cross_vv(a: jax.Array, b: jax.Array) -> jax.Array:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def solve22(k11, k12, k21, k22, b0, b1):
    """b2Mat22::Solve: x with [[k11, k12], [k21, k22]] x = b (zero when singular)."""
    det = k11 * k22 - k12 * k21
    det = jnp.where(det != 0, 1.0 / jnp.where(det != 0, det, 1.0), 0.0)
    return det * (k22 * b0 - k12 * b1), det * (k11 * b1 - k21 * b0)


def origins(c: jax.Array, a: jax.Array) -> jax.Array:
    """Body origins (Box2D ``body.position``) from centres of mass (3, 2) and angles (3,)."""
    return c - rotate(a, LOCAL_CENTER)
