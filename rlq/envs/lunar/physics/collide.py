"""Polygon-versus-terrain-edge contact manifolds, following Box2D 2.3's edge/polygon collider.

Terrain edges are lone two-sided edges (no ghost vertices), as Gymnasium creates them. A
manifold has up to two points; it is either of type ``FACE_EDGE`` (the terrain edge is the
reference face, the points are polygon vertices, clipped to the edge) or ``FACE_POLY`` (a polygon
face is the reference, the points are edge vertices, clipped to that face). The data kept per
point is what Box2D's solver needs to re-evaluate the separation while positions change.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from rlq.envs.lunar.consts import CONTACT_RADIUS

FACE_EDGE = 0
FACE_POLY = 1


class Manifold(struct.PyTreeNode):
    """Up to two contact points of one polygon against one edge (leading axes: any batch)."""

    valid: jax.Array  # (..., 2) bool: the point exists (separation within the contact radius)
    kind: jax.Array  # (...) int: FACE_EDGE or FACE_POLY
    normal: jax.Array  # (..., 2) FACE_EDGE: world normal; FACE_POLY: normal in the body frame
    plane: jax.Array  # (..., 2) FACE_EDGE: world point of the edge; FACE_POLY: body-frame vertex
    points: jax.Array  # (..., 2, 2) FACE_EDGE: body-frame points; FACE_POLY: world points
    key: jax.Array  # (..., 2) int: contact feature id, to carry impulses between steps
    separation: jax.Array  # (...) the separating-axis distance (negative when overlapping)


def rotate(angle: jax.Array, v: jax.Array) -> jax.Array:
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def inv_rotate(angle: jax.Array, v: jax.Array) -> jax.Array:
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.stack([c * v[..., 0] + s * v[..., 1], -s * v[..., 0] + c * v[..., 1]], axis=-1)


def dot(a: jax.Array, b: jax.Array) -> jax.Array:
    """Dot product over the last axis (elementwise: tiny matmuls compile slowly on XLA:CPU)."""
    return jnp.sum(a * b, axis=-1)


def _clip(p0: jax.Array, p1: jax.Array, normal: jax.Array, offset: jax.Array):
    """b2ClipSegmentToLine for a two-point segment: points behind the plane, plus the crossing."""
    d0 = dot(p0, normal) - offset
    d1 = dot(p1, normal) - offset
    denom = jnp.where(d0 - d1 == 0, 1.0, d0 - d1)
    cross = p0 + (d0 / denom) * (p1 - p0)
    ok = jnp.logical_or(d0 <= 0, d1 <= 0)
    return jnp.where(d0 <= 0, p0, cross), jnp.where(d1 <= 0, p1, cross), d0 > 0, d1 > 0, ok


def collide(
    verts_local: jax.Array,
    normals_local: jax.Array,
    centroid_local: jax.Array,
    origin: jax.Array,
    angle: jax.Array,
    v1: jax.Array,
    v2: jax.Array,
) -> Manifold:
    """Manifold of one convex polygon (body frame, placed at ``origin``/``angle``) against an edge."""
    n = verts_local.shape[0]
    verts = origin + rotate(angle, verts_local)
    normals = rotate(angle, normals_local)
    centroid = origin + rotate(angle, centroid_local)

    edge = v2 - v1
    edge = edge / jnp.linalg.norm(edge)
    normal1 = jnp.stack([edge[1], -edge[0]])
    front = dot(normal1, centroid - v1) >= 0
    m_normal = jnp.where(front, normal1, -normal1)

    edge_sep = jnp.min(dot(verts - v1, m_normal))
    neg = -normals
    s = jnp.minimum(dot(neg, verts - v1), dot(neg, verts - v2))
    poly_idx = jnp.argmax(s)
    poly_sep = s[poly_idx]
    separated = jnp.logical_or(edge_sep > CONTACT_RADIUS, poly_sep > CONTACT_RADIUS)
    use_poly = poly_sep > 0.98 * edge_sep + 0.001

    inc = jnp.argmin(dot(normals, m_normal))
    inc2 = (inc + 1) % n
    ref2 = (poly_idx + 1) % n
    ie0 = jnp.where(use_poly, v1, verts[inc])
    ie1 = jnp.where(use_poly, v2, verts[inc2])
    rv1 = jnp.where(use_poly, verts[poly_idx], jnp.where(front, v1, v2))
    rv2 = jnp.where(use_poly, verts[ref2], jnp.where(front, v2, v1))
    rn = jnp.where(use_poly, normals[poly_idx], m_normal)

    side1 = jnp.stack([rn[1], -rn[0]])
    a0, a1, c0a, c1a, ok1 = _clip(ie0, ie1, side1, dot(side1, rv1))
    b0, b1, c0b, c1b, ok2 = _clip(a0, a1, -side1, -dot(side1, rv2))
    pts = jnp.stack([b0, b1])
    sep_pts = dot(pts - rv1, rn)
    valid = (sep_pts <= CONTACT_RADIUS) & ~separated & ok1 & ok2

    kind = jnp.where(use_poly, FACE_POLY, FACE_EDGE).astype(jnp.int32)
    local_pts = inv_rotate(angle, pts - origin)
    points = jnp.where(use_poly, pts, local_pts)
    normal = jnp.where(use_poly, normals_local[poly_idx], rn)
    plane = jnp.where(use_poly, verts_local[poly_idx], rv1)
    feature = jnp.where(use_poly, 16 + poly_idx * 2, jnp.stack([inc, inc2]) * 2)
    clipped = jnp.stack([c0a | c0b, c1a | c1b]).astype(jnp.int32)
    key = kind * 64 + feature + jnp.array([0, 1]) * use_poly + clipped * 32
    return Manifold(
        valid=valid,
        kind=kind,
        normal=normal,
        plane=plane,
        points=points,
        key=key.astype(jnp.int32),
        separation=jnp.maximum(edge_sep, poly_sep),
    )


def _in_world(m: Manifold, origin: jax.Array, angle: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """A manifold's reference face and clip points in world coordinates, as Box2D's world and position-solver
    manifolds both read them: whether the face is the ground's edge, its normal, a point on its plane, the points."""
    face_edge = m.kind == FACE_EDGE
    n_poly = rotate(angle, m.normal)
    plane_poly = origin + rotate(angle, m.plane)
    pts_body = origin + rotate(angle, m.points)
    n = jnp.where(face_edge, m.normal, n_poly)
    plane = jnp.where(face_edge, m.plane, plane_poly)
    clip = jnp.where(face_edge, pts_body, m.points)
    return face_edge, n, plane, clip


def world_points(m: Manifold, origin: jax.Array, angle: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Box2D's b2WorldManifold: normal (ground -> body), contact points and separations."""
    face_edge, n, plane, clip = _in_world(m, origin, angle)
    r = 0.5 * CONTACT_RADIUS
    d = dot(clip - plane, n)
    on_ref = clip + (r - d)[:, None] * n
    on_inc = clip - r * n
    points = 0.5 * (on_ref + on_inc)
    normal = jnp.where(face_edge, n, -n)
    return normal, points, d - CONTACT_RADIUS


def position_points(m: Manifold, origin: jax.Array, angle: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Box2D's b2PositionSolverManifold: normal (ground -> body), points and separations."""
    face_edge, n, plane, clip = _in_world(m, origin, angle)
    sep = dot(clip - plane, n) - CONTACT_RADIUS
    return jnp.where(face_edge, n, -n), clip, sep


def terrain_edges(terrain_x: jax.Array, terrain_y: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Start and end points (n-1, 2) of the terrain polyline's edges."""
    pts = jnp.stack([terrain_x, terrain_y], axis=-1)
    return pts[:-1], pts[1:]
