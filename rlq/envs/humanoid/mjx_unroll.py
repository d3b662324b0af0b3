"""MJX steps with the physics' loops restructured: traced unrolled, or carrying less state.

brax steps MJX ``n_frames`` times per control step in a ``lax.scan``, and MJX's constraint solver
runs its linesearch as a ``lax.scan`` of ``ls_iterations`` guarded trips. On a GPU each loop
splits the step's program at its boundaries (XLA replays a loop-free stretch of kernels as one
CUDA graph; a loop runs trip by trip from the host), so a humanoid control step is some 30
separate launches. Unrolled, the step is one straight stretch of kernels.

The arithmetic is unchanged: every trip runs the same body with the same guard, in the same
order (under ``vmap`` MJX's guard is already a select, so a batch computes exactly what it did).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from typing import Any

import jax
from brax.base import Motion, Transform
from brax.mjx import pipeline as brax_mjx_pipeline
from mujoco import mjx
from mujoco.mjx._src import solver as mjx_solver


def unrolled_while_loop_scan(
    cond_fun: Callable[[Any], jax.Array], body_fun: Callable[[Any], Any], init_val: Any, max_iter: int
) -> Any:
    """MJX's ``_while_loop_scan`` (at most ``max_iter`` trips of ``body_fun`` while ``cond_fun``
    holds, a no-op trip once it fails) with the trips written out instead of scanned."""

    def trip(val):
        nxt = body_fun(val)
        return nxt, cond_fun(nxt)

    val, going = init_val, cond_fun(init_val)
    for _ in range(int(max_iter)):
        val, going = jax.lax.cond(going, trip, lambda v: (v, False), val)
    return val


@contextlib.contextmanager
def unrolled_linesearch() -> Iterator[None]:
    """While active, MJX's solver traces its linesearch unrolled (MJX looks the loop helper up in
    its module at trace time; rlq.envs.humanoid.env traces it one thread at a time)."""
    original = mjx_solver._while_loop_scan
    mjx_solver._while_loop_scan = unrolled_while_loop_scan
    try:
        yield
    finally:
        mjx_solver._while_loop_scan = original


def physics_step(brax_env: Any, pipeline_state: Any, action: jax.Array) -> Any:
    """One physics step of brax's pipeline (what ``PipelineEnv.pipeline_step`` repeats)."""
    return brax_env._pipeline.step(brax_env.sys, pipeline_state, action, brax_env._debug)


def unrolled_pipeline_step(brax_env: Any) -> Callable[[Any, jax.Array], Any]:
    """brax's ``PipelineEnv.pipeline_step`` (``n_frames`` physics steps under one action) unrolled."""

    def pipeline_step(pipeline_state: Any, action: jax.Array) -> Any:
        for _ in range(brax_env._n_frames):
            pipeline_state = physics_step(brax_env, pipeline_state, action)
        return pipeline_state

    return pipeline_step


#: MuJoCo's integration state (mj_stateSize's mjSTATE_INTEGRATION) as MJX Data fields: all a
#: physics step reads from the step before; everything else it recomputes before reading it
INTEGRATION_STATE = (
    "time",
    "qpos",
    "qvel",
    "act",
    "history",
    "qacc_warmstart",
    "plugin_state",
    "ctrl",
    "qfrc_applied",
    "xfrc_applied",
    "eq_active",
    "mocap_pos",
    "mocap_quat",
    "userdata",
)


def state_carry_pipeline_step(brax_env: Any) -> Callable[[Any, jax.Array], Any]:
    """brax's ``pipeline_step`` with a loop that carries only the integration state.

    brax scans ``n_frames`` physics steps carrying the whole MJX data (a hundred arrays, most of
    them recomputed by every step) from trip to trip. Here the first ``n_frames - 1`` steps carry
    the integration state only, each rebuilding the rest from the incoming data (which the step
    overwrites before it reads it), and the last step runs after the loop to return the full data.
    """

    def pipeline_step(pipeline_state: Any, action: jax.Array) -> Any:
        names = [name for name in INTEGRATION_STATE if hasattr(pipeline_state, name)]

        def substep(carry: dict, _) -> tuple[dict, None]:
            nxt = physics_step(brax_env, pipeline_state.replace(**carry), action)
            return {name: getattr(nxt, name) for name in names}, None

        carry = {name: getattr(pipeline_state, name) for name in names}
        carry = jax.lax.scan(substep, carry, (), brax_env._n_frames - 1)[0]
        return physics_step(brax_env, pipeline_state.replace(**carry), action)

    return pipeline_step


def brax_frames(sys: Any, data: Any) -> tuple[Transform, Motion]:
    """brax's link transforms ``x`` and motions ``xd`` (velocities about each link's origin) from
    MJX data, as brax's MJX pipeline derives them."""
    offset = Transform.create(pos=data.xpos[1:] - data.subtree_com[sys.body_rootid[1:]])
    velocity = Motion(vel=data.cvel[1:, 3:], ang=data.cvel[1:, :3])
    return Transform(pos=data.xpos[1:], rot=data.xquat[1:]), offset.vmap().do(velocity)


def brax_fields(sys: Any, data: Any) -> Any:
    """brax's own fields of its MJX state (``q``, ``qd``, ``x``, ``xd`` and, for MJX-JAX data, the
    contacts in brax's format) from the MJX data they describe: what brax's ``pipeline.step`` adds
    after every ``mjx.step``."""
    x, xd = brax_frames(sys, data)
    fields = {"q": data.qpos, "qd": data.qvel, "x": x, "xd": xd}
    if data.contact is not None and data._impl.ncon > 0:
        fields["contact"] = brax_mjx_pipeline._reformat_contact(sys, data._impl.contact)
    return data.replace(**fields)


def mjx_carry_pipeline_step(brax_env: Any) -> Callable[[Any, jax.Array], Any]:
    """brax's ``pipeline_step`` with a loop of bare ``mjx.step`` calls.

    brax's loop runs its ``pipeline.step`` ``n_frames`` times, and each trip also builds brax's own
    fields (``brax_fields``), which only the last trip's caller reads; the loop carries them, so
    XLA computes them in every trip. Here the loop runs MJX's step alone (the controls set once
    before it) and brax's fields are built once, after it. The physics is traced once, as in brax.
    """

    def pipeline_step(pipeline_state: Any, action: jax.Array) -> Any:
        sys = brax_env.sys

        def substep(data: Any, _) -> tuple[Any, None]:
            return mjx.step(sys, data), None

        data = jax.lax.scan(substep, pipeline_state.replace(ctrl=action), (), brax_env._n_frames)[0]
        return brax_fields(sys, data)

    return pipeline_step
