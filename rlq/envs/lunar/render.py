"""2-D frames of env=lunar states (numpy + PIL), in the look of Gymnasium's renderer.

``render_frames(states)`` takes a sequence of states stacked along a leading time axis (an
``EnvState`` of ``rlq.envs.lunar.env`` or its ``LunarInner``) and returns uint8 frames (T, H, W, 3),
ready for ``mediapy.write_video(path, frames, fps=50)``.
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np
from PIL import Image, ImageDraw

from rlq.envs.lunar import consts as C

SKY = (0, 0, 0)
GROUND = (255, 255, 255)
BODY = (128, 102, 230)
OUTLINE = (77, 77, 128)
FLAG = (204, 204, 0)
FLAME = (255, 140, 40)


def _rot(angle: float, pts: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return pts @ np.array([[c, s], [-s, c]])


def _frame(c: np.ndarray, a: np.ndarray, terrain_y: np.ndarray, engines: np.ndarray, scale: float) -> np.ndarray:
    width, height = int(C.VIEWPORT_W * scale), int(C.VIEWPORT_H * scale)
    px = C.SCALE * scale

    def to_px(pts: Any) -> list[tuple[float, float]]:
        return [(float(x * px), float(height - y * px)) for x, y in np.atleast_2d(pts)]

    img = Image.new("RGB", (width, height), GROUND)
    draw = ImageDraw.Draw(img)
    for i in range(C.CHUNKS - 1):
        x0, x1 = C.CHUNK_X[i], C.CHUNK_X[i + 1]
        draw.polygon(to_px([(x0, terrain_y[i]), (x1, terrain_y[i + 1]), (x1, C.H), (x0, C.H)]), fill=SKY)

    origin = c - _rot_many(a, C.LOCAL_CENTER)
    m_power, s_power, direction = engines
    hull_angle = a[0]
    tip = np.array([np.sin(hull_angle), np.cos(hull_angle)])
    side = np.array([-tip[1], tip[0]])
    if m_power > 0:
        base = origin[0] - tip * C.MAIN_ENGINE_Y_LOCATION / C.SCALE
        length = 0.4 + 0.5 * m_power
        flame = [base + side * 0.15, base - side * 0.15, base - tip * length]
        draw.polygon(to_px(np.array(flame)), fill=FLAME)
    if s_power > 0:
        base = origin[0] + tip * C.SIDE_ENGINE_HEIGHT / C.SCALE - side * direction * 17 / C.SCALE
        out = -side * direction
        flame = [base + tip * 0.07, base - tip * 0.07, base + out * (0.2 + 0.2 * s_power)]
        draw.polygon(to_px(np.array(flame)), fill=FLAME)

    shapes = [C.HULL_VERTS, C.LEG_VERTS, C.LEG_VERTS]
    for body, verts in enumerate(shapes):
        pts = origin[body] + _rot(a[body], verts)
        draw.polygon(to_px(pts), fill=BODY, outline=OUTLINE)

    for x in (C.HELIPAD_X1, C.HELIPAD_X2):
        fx, fy1 = x * px, height - C.HELIPAD_Y * px
        fy2 = fy1 - 50 * scale
        draw.line([(fx, fy1), (fx, fy2)], fill=GROUND, width=1)
        draw.polygon([(fx, fy2), (fx, fy2 + 10 * scale), (fx + 25 * scale, fy2 + 5 * scale)], fill=FLAG)
    return np.asarray(img, np.uint8)


def _rot_many(angles: np.ndarray, pts: np.ndarray) -> np.ndarray:
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    return np.concatenate([c * pts[:, :1] - s * pts[:, 1:], s * pts[:, :1] + c * pts[:, 1:]], axis=1)


def render_frames(states: Any, scale: float = 1.0) -> np.ndarray:
    """uint8 frames (T, 400·scale, 600·scale, 3) of states stacked along a leading time axis."""
    inner = getattr(states, "inner", states)
    inner = jax.device_get(inner)
    ps = inner.physics
    c, a = np.asarray(ps.c, np.float64), np.asarray(ps.a, np.float64)
    terrain = np.asarray(inner.terrain_y, np.float64)
    engines = np.asarray(inner.engines, np.float64)
    if c.ndim == 2:  # a single state
        c, a, terrain, engines = c[None], a[None], terrain[None], engines[None]
    return np.stack([_frame(c[t], a[t], terrain[t], engines[t], scale) for t in range(c.shape[0])])
