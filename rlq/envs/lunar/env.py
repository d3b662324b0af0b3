"""LunarLander-v3 in JAX, faithful to Gymnasium's Box2D version (rlq's own port).

Gymnasium's ``lunar_lander.py`` is the spec: terrain, initial push, engines with dispersion,
wind and turbulence, observation, reward and termination follow it line by line; the rigid-body
physics that Box2D provides lives in ``rlq.envs.lunar.physics.step``.

``reset_with`` and ``LunarInner.dispersion`` accept externally drawn random numbers (terrain
heights, initial force, wind offsets, per-step engine dispersion), so that one episode can be
replayed on both simulators with the same draws (see ``rlq.envs.lunar.box2d_reference.LunarBox2D.draws``).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from rlq.declared.envs.lunar import Config, task_options
from rlq.envs.lunar import consts as C
from rlq.envs.lunar.landing import LandingReport
from rlq.envs.lunar.physics import step as P
from rlq.envs.lunar.physics.body import constant
from rlq.envs.lunar.physics.collide import terrain_edges
from rlq.lib.env_api import Env, EnvState, initial_state
from rlq.lib.spaces import Box, Discrete

OBS_LOW = (-2.5, -2.5, -10.0, -10.0, -2 * 3.141592653589793, -10.0, 0.0, 0.0)
OBS_HIGH = (2.5, 2.5, 10.0, 10.0, 2 * 3.141592653589793, 10.0, 1.0, 1.0)
F32 = jnp.float32
TERRAIN_X = constant(C.CHUNK_X)


class LunarInner(struct.PyTreeNode):
    """The simulator's state between steps."""

    physics: P.PhysicsState
    terrain_y: jax.Array  # (CHUNKS,) smoothed terrain heights at C.CHUNK_X
    leg_contact: jax.Array  # (2,) Gymnasium's legs[i].ground_contact flags
    game_over: jax.Array  # () the hull touched the ground
    prev_shaping: jax.Array  # ()
    wind_idx: jax.Array  # (2,) wind and turbulence phase counters
    t: jax.Array  # () steps taken, including the one inside reset
    engines: jax.Array  # (3,) last main power, side power, side direction (for rendering)
    #: optional (T, 2) engine dispersion per step (already / SCALE); None: drawn from the key
    dispersion: jax.Array | None = None


def smooth_terrain(heights: jax.Array) -> jax.Array:
    """Gymnasium's terrain: 12 raw heights -> helipad flattened -> 11 smoothed chunk heights."""
    h = jnp.asarray(heights, F32)
    h = h.at[C.CHUNKS // 2 - 2 : C.CHUNKS // 2 + 3].set(C.HELIPAD_Y)
    prev = jnp.roll(h, 1)[: C.CHUNKS]  # h[i - 1], wrapping to h[-1] for i = 0 as Python does
    return 0.33 * (prev + h[: C.CHUNKS] + h[1 : C.CHUNKS + 1])


def initial_physics() -> P.PhysicsState:
    """Hull and legs where Gymnasium creates them (legs not yet pulled onto their joints)."""
    origin = jnp.array(
        [[C.INITIAL_X, C.INITIAL_Y]] + [[C.INITIAL_X - i * C.LEG_AWAY / C.SCALE, C.INITIAL_Y] for i in C.LEG_SIDES],
        F32,
    )
    angle = jnp.array([0.0] + [i * 0.05 for i in C.LEG_SIDES], F32)
    return P.initial_state(origin, angle)


def _created(terrain: jax.Array, wind_idx: jax.Array | None, dispersion: jax.Array | None = None) -> LunarInner:
    """The simulator as Gymnasium's reset creates it, before reset's closing world step."""
    return LunarInner(
        physics=initial_physics(),
        terrain_y=smooth_terrain(terrain),
        leg_contact=jnp.zeros(2, bool),
        game_over=jnp.zeros((), bool),
        prev_shaping=jnp.zeros((), F32),
        wind_idx=jnp.zeros(2, F32) if wind_idx is None else jnp.asarray(wind_idx, F32),
        t=jnp.zeros((), jnp.int32),
        engines=jnp.zeros(3, F32),
        dispersion=None if dispersion is None else jnp.asarray(dispersion, F32),
    )


class LunarLander(Env):
    """Gymnasium's LunarLander-v3: Discrete(4) or, with ``continuous``, Box(-1, 1, (2,))."""

    render_fps = C.FPS
    descriptor_wrappers = {"landing": LandingReport}

    def __init__(
        self,
        continuous: bool = False,
        enable_wind: bool = False,
        wind_power: float = 15.0,
        turbulence_power: float = 1.5,
        gravity: float = -10.0,
        max_episode_steps: int | None = 1000,
        solver: P.SolverConfig | None = None,
        lockstep_reset: bool = False,
        reset_cache: bool = False,
    ):
        self.continuous = bool(continuous)
        self.enable_wind = bool(enable_wind)
        self.wind_power = float(wind_power)
        self.turbulence_power = float(turbulence_power)
        self.max_episode_steps = max_episode_steps
        if not -12.0 < gravity < 0.0:
            raise ValueError(f"env.gravity must be in (-12, 0) as in Gymnasium, got {gravity}")
        self.solver = dataclasses.replace(solver or P.SolverConfig(), gravity=float(gravity))
        self.observation_space = Box(OBS_LOW, OBS_HIGH)
        self.action_space = Box.uniform(-1.0, 1.0, 2) if self.continuous else Discrete(4)
        self.lockstep_reset = bool(lockstep_reset)
        #: AutoReset restarts each env from its own first episode's start (as brax's envs do): the
        #: step then holds no reset at all. For batches of thousands of envs, whose first starts
        #: sample Gymnasium's start distribution (docs/lunar.md).
        self.reset_cache = bool(reset_cache)

    # ---- reset ----------------------------------------------------------------------------------
    def reset(self, key: jax.Array) -> EnvState:
        return self.reset_with(*self._draws(key))

    @staticmethod
    def _draws(key: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
        """A new episode's random draws: (key, raw terrain heights, initial force, wind offsets)."""
        key, k_terrain, k_force, k_wind = jax.random.split(key, 4)
        terrain = jax.random.uniform(k_terrain, (C.CHUNKS + 1,), F32, 0.0, C.H / 2)
        force = jax.random.uniform(k_force, (2,), F32, -C.INITIAL_RANDOM, C.INITIAL_RANDOM)
        wind_idx = jax.random.randint(k_wind, (2,), -9999, 9999)
        return key, terrain, force, wind_idx

    def reset_with(
        self,
        key: jax.Array,
        terrain: jax.Array,
        init_force: jax.Array,
        wind_idx: jax.Array | None = None,
        dispersion: jax.Array | None = None,
    ) -> EnvState:
        """Reset from given draws: 12 raw terrain heights, the initial force (2,), wind offsets (2,)
        and optionally the engine dispersion of every step (T, 2), row 0 used inside reset."""
        inner = _created(terrain, wind_idx, dispersion)
        key, sub = jax.random.split(key)
        # Gymnasium's reset ends with step(noop); the lander starts far above the terrain, so that
        # step needs no collision work
        inner, obs, _, _, _, _ = self._advance(inner, self._noop(), sub, jnp.asarray(init_force, F32), contacts=False)
        return _started(obs, inner, key)

    def step_and_reset(self, state: EnvState, action: jax.Array, key: jax.Array) -> tuple[EnvState, EnvState]:
        """``step(state, action)`` and ``reset(key)``; with ``lockstep_reset``, both world steps in
        one batch of two.

        The reset's world step (Gymnasium's ``step(noop)`` inside reset) otherwise runs as a second
        chain of solver loops after the step's. Together, the compiled program holds one world step
        instead of two: on a GPU it compiles faster and runs no slower (docs/lunar.md). On a CPU the
        pair is twice a step's arithmetic, more than the collision-free reset's, so it is off by
        default. The reset's half runs the collision code too (Box2D's
        reset does); far above the terrain it finds no contact, so the new episode starts as
        ``reset`` starts it, up to float rounding."""
        if not self.lockstep_reset or state.inner.dispersion is not None:  # (a replay of given draws)
            return super().step_and_reset(state, action, key)
        key, terrain, init_force, wind_idx = self._draws(key)
        key, reset_sub = jax.random.split(key)
        step_key, step_sub = jax.random.split(state.key)
        both = jax.tree.map(lambda a, b: jnp.stack([a, b]), state.inner, _created(terrain, wind_idx))
        noop = self._noop()
        actions = jnp.stack([jnp.asarray(action, noop.dtype), noop])
        forces = jnp.stack([jnp.zeros(2, F32), jnp.asarray(init_force, F32)])
        inner, obs, reward, terminated, landed, crashed = jax.vmap(self._advance)(
            both, actions, jnp.stack([step_sub, reset_sub]), forces
        )
        stepped = _stepped(
            state, step_key, jax.tree.map(lambda x: x[0], (inner, obs, reward, terminated, landed, crashed))
        )
        return stepped, _started(obs[1], jax.tree.map(lambda x: x[1], inner), key)

    def _noop(self) -> jax.Array:
        return jnp.zeros(2, F32) if self.continuous else jnp.zeros((), jnp.int32)

    def render(self, states: EnvState) -> np.ndarray:
        from rlq.envs.lunar.render import render_frames

        return render_frames(states)

    # ---- step -----------------------------------------------------------------------------------
    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        key, sub = jax.random.split(state.key)
        return _stepped(state, key, self._advance(state.inner, action, sub, jnp.zeros(2, F32)))

    def _advance(self, inner: LunarInner, action: jax.Array, key: jax.Array, force: jax.Array, contacts: bool = True):
        """Gymnasium's ``step``: wind, engines, ``world.Step``, observation and reward."""
        ps = inner.physics
        torque = jnp.zeros((), F32)
        wind_idx = inner.wind_idx
        if self.enable_wind:
            calm = jnp.any(inner.leg_contact)
            wind = jnp.tanh(jnp.sin(0.02 * wind_idx) + jnp.sin(jnp.pi * 0.01 * wind_idx))
            force = force + jnp.where(calm, 0.0, jnp.stack([wind[0] * self.wind_power, 0.0]))
            torque = jnp.where(calm, 0.0, wind[1] * self.turbulence_power)
            wind_idx = jnp.where(calm, wind_idx, wind_idx + 1)

        if inner.dispersion is None:
            disp = jax.random.uniform(key, (2,), F32, -1.0, 1.0) / C.SCALE
        else:
            disp = inner.dispersion[jnp.minimum(inner.t, inner.dispersion.shape[0] - 1)]
        m_power, s_power, direction = self._throttle(action)
        ps = _fire_engines(ps, m_power, s_power, direction, disp)

        v1, v2 = terrain_edges(TERRAIN_X, inner.terrain_y)
        ps, ev = P.step(ps, v1, v2, force, torque, self.solver, contacts)

        flags = jnp.where(ev.leg_end, False, jnp.where(ev.leg_begin, True, inner.leg_contact))
        flags = flags | ev.leg_toi_begin
        game_over = inner.game_over | ev.hull_begin

        obs = observe(ps, flags)
        shaping = (
            -100 * jnp.sqrt(obs[0] ** 2 + obs[1] ** 2)
            - 100 * jnp.sqrt(obs[2] ** 2 + obs[3] ** 2)
            - 100 * jnp.abs(obs[4])
            + 10 * obs[6]
            + 10 * obs[7]
        )
        reward = shaping - inner.prev_shaping - m_power * 0.30 - s_power * 0.03
        crashed = game_over | (jnp.abs(obs[0]) >= 1.0)
        reward = jnp.where(crashed, -100.0, reward)
        reward = jnp.where(ev.asleep, 100.0, reward)
        terminated = crashed | ev.asleep
        inner = inner.replace(
            physics=ps,
            leg_contact=flags,
            game_over=game_over,
            prev_shaping=shaping,
            wind_idx=wind_idx,
            t=inner.t + 1,
            engines=jnp.stack([m_power, s_power, direction]),
        )
        return inner, obs, reward.astype(F32), terminated, ev.asleep, crashed & ~ev.asleep

    def _throttle(self, action: jax.Array):
        """Main power, side power and side direction (-1 left, +1 right) as Gymnasium decodes them."""
        if self.continuous:
            a = jnp.clip(jnp.asarray(action, F32), -1.0, 1.0)
            m_power = jnp.where(a[0] > 0.0, (jnp.clip(a[0], 0.0, 1.0) + 1.0) * 0.5, 0.0)
            side_on = jnp.abs(a[1]) > 0.5
            s_power = jnp.where(side_on, jnp.clip(jnp.abs(a[1]), 0.5, 1.0), 0.0)
            direction = jnp.sign(a[1])
        else:
            a = jnp.asarray(action, jnp.int32)
            m_power = jnp.where(a == 2, 1.0, 0.0)
            s_power = jnp.where((a == 1) | (a == 3), 1.0, 0.0)
            direction = (a - 2).astype(F32)
        return m_power.astype(F32), s_power.astype(F32), direction.astype(F32)


def _fire_engines(ps: P.PhysicsState, m_power, s_power, direction, disp) -> P.PhysicsState:
    """Main and side engine impulses at Gymnasium's (dispersed) engine positions."""
    angle = ps.a[0]
    pos = P.origins(ps.c, ps.a)[0]
    tip = jnp.stack([jnp.sin(angle), jnp.cos(angle)])
    side = jnp.stack([-tip[1], tip[0]])
    d0, d1 = disp[0], disp[1]

    main = C.MAIN_ENGINE_Y_LOCATION / C.SCALE + 2 * d0
    ox = tip[0] * main + side[0] * d1
    oy = -tip[1] * main - side[1] * d1
    impulse = jnp.stack([-ox, -oy]) * C.MAIN_ENGINE_POWER * m_power
    ps = P.apply_impulse(ps, impulse, pos + jnp.stack([ox, oy]))

    lateral = 3 * d1 + direction * C.SIDE_ENGINE_AWAY / C.SCALE
    ox = tip[0] * d0 + side[0] * lateral
    oy = -tip[1] * d0 - side[1] * lateral
    point = pos + jnp.stack([ox - tip[0] * 17 / C.SCALE, oy + tip[1] * C.SIDE_ENGINE_HEIGHT / C.SCALE])
    impulse = jnp.stack([-ox, -oy]) * C.SIDE_ENGINE_POWER * s_power
    return P.apply_impulse(ps, impulse, point)


def observe(ps: P.PhysicsState, flags: jax.Array) -> jax.Array:
    """Gymnasium's 8-value observation."""
    pos = P.origins(ps.c, ps.a)[0]
    vel = ps.v[0]
    half_w, half_h = C.W / 2, C.H / 2
    return jnp.stack(
        [
            (pos[0] - half_w) / half_w,
            (pos[1] - (C.HELIPAD_Y + C.LEG_DOWN / C.SCALE)) / half_h,
            vel[0] * half_w / C.FPS,
            vel[1] * half_h / C.FPS,
            ps.a[0],
            20.0 * ps.w[0] / C.FPS,
            flags[0].astype(F32),
            flags[1].astype(F32),
        ]
    ).astype(F32)


def _stepped(state: EnvState, key: jax.Array, advanced: tuple) -> EnvState:
    """``state`` after a step whose ``LunarLander._advance`` returned ``advanced``."""
    inner, obs, reward, terminated, landed, crashed = advanced
    return state.replace(
        obs=obs,
        reward=reward,
        terminated=terminated,
        truncated=jnp.zeros((), bool),
        info={**state.info, **_info(landed, crashed)},
        inner=inner,
        key=key,
    )


def _started(obs: jax.Array, inner: LunarInner, key: jax.Array) -> EnvState:
    """A new episode's state after reset's closing world step: neither landed nor crashed."""
    return initial_state(obs, inner, key, info=_info(jnp.zeros((), bool), jnp.zeros((), bool)))


def _info(landed: jax.Array, crashed: jax.Array) -> dict[str, jax.Array]:
    return {"landed": jnp.asarray(landed, bool), "crashed": jnp.asarray(crashed, bool)}


def make(cfg: Config) -> LunarLander:
    solver = cfg.solver
    solver_keys = (
        "velocity_iterations",
        "position_iterations",
        "warm_start",
        "block_solve",
        "toi",
        "unroll",
        "component_unroll",
        "sweep_layout",
    )
    return LunarLander(
        **task_options(cfg),
        solver=P.SolverConfig(**{k: getattr(solver, k) for k in solver_keys}),
        lockstep_reset=cfg.lockstep_reset,
        reset_cache=cfg.reset_cache,
    )
