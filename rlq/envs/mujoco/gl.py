"""Choosing MuJoCo's OpenGL backend (``MUJOCO_GL``) for offscreen rendering.

MuJoCo picks its GL context class when ``mujoco`` is imported, from ``MUJOCO_GL``, and PyOpenGL
fixes its platform (``PYOPENGL_PLATFORM``) when it is first imported; a backend that fails to
load in a process can leave it unable to load another. So where the user has not set
``MUJOCO_GL``, each backend (egl, then osmesa, then glfw) is tried in a subprocess, and only the
first that renders is activated here: the variables are set and MuJoCo's GL context module is
reloaded (rlq imports mujoco long before it renders; with ``MUJOCO_GL`` unset that import loads
no OpenGL). The choice is made once per process.

``MUJOCO_GL=disable`` (MuJoCo's own value for "no GL") means no backend: MuJoCo envs then save
the states of a video instead of its frames (rlq.store.render).
"""

from __future__ import annotations

import functools
import importlib
import os
import subprocess
import sys

BACKENDS = ("egl", "osmesa", "glfw")
#: MuJoCo's values of MUJOCO_GL that turn rendering off
DISABLED = ("disable", "disabled", "off", "false", "0")
#: MuJoCo's GL context module (4.x path first, then 3.x)
_GL_MODULES = ("mujoco.rendering.classic.gl_context", "mujoco.gl_context")
_PROBE = (
    "import mujoco\n"
    "model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\"0.1\"/></worldbody></mujoco>')\n"
    "renderer = mujoco.Renderer(model, 8, 8)\n"
    "renderer.update_scene(mujoco.MjData(model))\n"
    "renderer.render()\n"
    "renderer.close()\n"
)
PROBE_TIMEOUT_S = 60.0


class NoGLError(RuntimeError):
    """No OpenGL backend loads in this process, so MuJoCo cannot render offscreen."""


def _backend_env(backend: str) -> dict[str, str]:
    env = {"MUJOCO_GL": backend}
    if backend in ("egl", "osmesa"):
        env["PYOPENGL_PLATFORM"] = os.environ.get("PYOPENGL_PLATFORM") or backend
    return env


def probe(backend: str) -> bool:
    """Whether ``backend`` renders a tiny model in a fresh Python process."""
    try:
        done = subprocess.run(
            [sys.executable, "-c", _PROBE],
            env={**os.environ, **_backend_env(backend)},
            capture_output=True,
            timeout=PROBE_TIMEOUT_S,
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def _activate(backend: str) -> None:
    os.environ.update(_backend_env(backend))
    for name in _GL_MODULES:
        if name in sys.modules:
            importlib.reload(sys.modules[name])


@functools.cache
def _select(user_value: str | None) -> str | None:
    if user_value is not None and user_value.strip():
        return None if user_value.strip().lower() in DISABLED else user_value
    for backend in BACKENDS:
        if probe(backend):
            _activate(backend)
            return backend
    return None


def gl_backend() -> str | None:
    """The backend MuJoCo renders with in this process (the user's ``MUJOCO_GL`` if set, else
    the first of egl, osmesa, glfw that works, activated), or None where none does."""
    return _select(os.environ.get("MUJOCO_GL"))


def require_gl() -> str:
    """The backend, or ``NoGLError`` naming what was tried."""
    backend = gl_backend()
    if backend is None:
        user = os.environ.get("MUJOCO_GL")
        tried = f"MUJOCO_GL={user}" if user and user.strip() else "MUJOCO_GL=" + ", ".join(BACKENDS)
        raise NoGLError(f"no OpenGL backend for MuJoCo ({tried})")
    return backend
