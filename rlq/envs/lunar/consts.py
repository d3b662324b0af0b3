"""Constants of Gymnasium's LunarLander-v3 and of the Box2D 2.3 solver it runs on.

Body mass properties are derived from the shapes and densities the way Box2D does it (polygon
area × density, centroid, rotational inertia about the centroid), so nothing is hand-tuned.
"""

from __future__ import annotations

import numpy as np

# --- Gymnasium's lunar_lander.py -------------------------------------------------------------
FPS = 50
SCALE = 30.0
MAIN_ENGINE_POWER = 13.0
SIDE_ENGINE_POWER = 0.6
INITIAL_RANDOM = 1000.0
LANDER_POLY = ((-14, 17), (-17, 0), (-17, -10), (17, -10), (17, 0), (14, 17))
LEG_AWAY = 20
LEG_DOWN = 18
LEG_W, LEG_H = 2, 8
LEG_SPRING_TORQUE = 40.0
SIDE_ENGINE_HEIGHT = 14
SIDE_ENGINE_AWAY = 12
MAIN_ENGINE_Y_LOCATION = 4
VIEWPORT_W = 600
VIEWPORT_H = 400

W = VIEWPORT_W / SCALE
H = VIEWPORT_H / SCALE
CHUNKS = 11
CHUNK_X = np.array([W / (CHUNKS - 1) * i for i in range(CHUNKS)])
HELIPAD_X1 = float(CHUNK_X[CHUNKS // 2 - 1])
HELIPAD_X2 = float(CHUNK_X[CHUNKS // 2 + 1])
HELIPAD_Y = H / 4
INITIAL_X = VIEWPORT_W / SCALE / 2
INITIAL_Y = VIEWPORT_H / SCALE

HULL_DENSITY = 5.0
LEG_DENSITY = 1.0
GROUND_FRICTION = 0.1
LEG_FRICTION = 0.2  # Box2D's default fixture friction (the legs set none)
#: Box2D mixes friction as the geometric mean of the two fixtures.
LEG_GROUND_FRICTION = float(np.sqrt(np.float32(GROUND_FRICTION) * np.float32(LEG_FRICTION)))

#: legs[0] is Gymnasium's i = -1 leg (to the right of the hull), legs[1] the i = +1 leg.
LEG_SIDES = (-1, +1)
LEG_LOWER = (0.9 - 0.5, -0.9)
LEG_UPPER = (0.9, -0.9 + 0.5)
LEG_MOTOR_SPEED = (-0.3, 0.3)
#: pybox2d's joint definition sets referenceAngle = bodyB.angle - bodyA.angle at creation, so
#: the joint angle (and its limits) is measured from the legs' initial tilt of i × 0.05 rad.
LEG_REFERENCE_ANGLE = tuple(float(np.float32(i * 0.05)) for i in (-1, +1))

# --- Box2D 2.3 b2Settings.h ----------------------------------------------------------------
LINEAR_SLOP = 0.005
ANGULAR_SLOP = 2.0 / 180.0 * np.pi
POLYGON_RADIUS = 2.0 * LINEAR_SLOP
MAX_LINEAR_CORRECTION = 0.2
MAX_ANGULAR_CORRECTION = 8.0 / 180.0 * np.pi
BAUMGARTE = 0.2
MAX_TRANSLATION = 2.0
MAX_ROTATION = 0.5 * np.pi
TIME_TO_SLEEP = 0.5
LINEAR_SLEEP_TOLERANCE = 0.01
ANGULAR_SLEEP_TOLERANCE = 2.0 / 180.0 * np.pi
#: Contact begins (manifold has points) when two polygon skins are this close: 2 × radius.
CONTACT_RADIUS = 2.0 * POLYGON_RADIUS
#: Continuous collision stops a body when cores would come closer than this (b2TimeOfImpact).
TOI_TARGET = max(LINEAR_SLOP, CONTACT_RADIUS - 3.0 * LINEAR_SLOP)
TOI_BAUMGARTE = 0.75
TOI_POSITION_ITERATIONS = 20


def _box(hx: float, hy: float) -> np.ndarray:
    return np.array([(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)])


def _ccw_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull starting at Box2D's first vertex (rightmost, then lowest)."""
    pts = [tuple(p) for p in points]
    start = max(range(len(pts)), key=lambda i: (pts[i][0], -pts[i][1]))
    order = sorted(range(len(pts)), key=lambda i: np.arctan2(pts[i][1] - pts[start][1], pts[i][0] - pts[start][0]))
    order.remove(start)
    return np.array([pts[start]] + [pts[i] for i in order])


def _normals(verts: np.ndarray) -> np.ndarray:
    edges = np.roll(verts, -1, axis=0) - verts
    n = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def polygon_mass(verts: np.ndarray, density: float) -> tuple[float, np.ndarray, float]:
    """Mass, centroid and rotational inertia about the centroid (b2PolygonShape::ComputeMass)."""
    s = verts.mean(axis=0)
    area, center, inertia = 0.0, np.zeros(2), 0.0
    for i in range(len(verts)):
        e1, e2 = verts[i] - s, verts[(i + 1) % len(verts)] - s
        d = e1[0] * e2[1] - e1[1] * e2[0]
        tri = 0.5 * d
        area += tri
        center += tri * (e1 + e2) / 3.0
        intx2 = e1[0] ** 2 + e2[0] * e1[0] + e2[0] ** 2
        inty2 = e1[1] ** 2 + e2[1] * e1[1] + e2[1] ** 2
        inertia += 0.25 / 3.0 * d * (intx2 + inty2)
    mass = density * area
    center_rel = center / area
    # inertia about s -> about the centroid
    inertia_c = density * inertia - mass * float(center_rel @ center_rel)
    return mass, center_rel + s, inertia_c


HULL_VERTS = _ccw_hull(np.array(LANDER_POLY, float) / SCALE)
HULL_NORMALS = _normals(HULL_VERTS)
LEG_VERTS = _box(LEG_W / SCALE, LEG_H / SCALE)
LEG_NORMALS = _normals(LEG_VERTS)

HULL_MASS, HULL_CENTER, HULL_INERTIA = polygon_mass(HULL_VERTS, HULL_DENSITY)
LEG_MASS, _LEG_CENTER, LEG_INERTIA = polygon_mass(LEG_VERTS, LEG_DENSITY)

#: Per body (hull, legs[0], legs[1]).
INV_MASS = np.array([1.0 / HULL_MASS, 1.0 / LEG_MASS, 1.0 / LEG_MASS])
INV_INERTIA = np.array([1.0 / HULL_INERTIA, 1.0 / LEG_INERTIA, 1.0 / LEG_INERTIA])
LOCAL_CENTER = np.array([HULL_CENTER, [0.0, 0.0], [0.0, 0.0]])
#: Joint anchors: on the hull at its origin, on each leg at (i·LEG_AWAY, LEG_DOWN)/SCALE.
ANCHOR_HULL = np.zeros(2)
ANCHOR_LEG = np.array([[i * LEG_AWAY / SCALE, LEG_DOWN / SCALE] for i in LEG_SIDES])
