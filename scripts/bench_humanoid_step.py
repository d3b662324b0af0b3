"""Where a humanoid control step's time goes: the physics strung together in different ways, brax's
env step around it, and rlq's wrapped env around that.

brax runs a control step's ``n_frames`` physics steps in a ``lax.scan`` inside one program; the loop
carries all of MJX's data from trip to trip. This benchmark times, on brax's humanoid (MJX, 4096 envs,
MJX's linesearch traced unrolled, fixed random controls):

- ``scan``: the physics alone, one program per control step (brax's scan of 5 physics steps) called
  from the host;
- ``unrolled``: the same with the 5 physics steps written out (``env.unroll_physics=all``);
- ``per_physics_step``: one program per physics step, called 5 times per control step from the host
  (the data donated from call to call, so no loop carries it);
- ``physics_loop``, ``brax_step_loop``, ``rlq_env_loop``: one program whose ``lax.scan`` runs all the
  control steps: of the physics alone, of brax's env step (physics, observation, reward, done), and
  of rlq's env as ``experiment=humanoid_ppo`` builds it (with time limit, episode statistics and
  auto-reset from the cached first state);
- ``physics_two_groups_loop``: the physics alone with the batch split in two halves that share one
  physics-step loop, so each trip holds two independent chains of kernels (``--xla-option
  xla_gpu_command_buffer_scheduling_mode=CONCURRENT`` lets them overlap).

    python scripts/bench_humanoid_step.py --out humanoid_step.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
from bench_common import parse_xla_options, run_header

from rlq.config.compose import compose
from rlq.envs.humanoid import mjx_unroll
from rlq.envs.humanoid.env import Humanoid
from rlq.run.programs.env_stack import make_env


def brax_humanoid():
    """brax's humanoid env with brax's own physics-step loop and MJX's own tree computations (rlq's
    defaults replace both: docs/humanoid.md); MJX's linesearch is unrolled by the callers."""
    return Humanoid(substep_carry="data", vectorized_cdof=False, vectorized_com_vel=False).brax_env


def host_loop(brax_env, variant: str, keys: jax.Array, action: jax.Array, control_steps: int) -> dict:
    """A program running a control step (or one physics step) per call, called from a Python loop."""
    step, calls = {
        "scan": (brax_env.pipeline_step, 1),
        "unrolled": (mjx_unroll.unrolled_pipeline_step(brax_env), 1),
        "per_physics_step": (lambda data, act: mjx_unroll.physics_step(brax_env, data, act), brax_env._n_frames),
    }[variant]
    with mjx_unroll.unrolled_linesearch():
        data = jax.jit(jax.vmap(brax_env.reset))(keys).pipeline_state
        t0 = time.perf_counter()
        compiled = jax.jit(jax.vmap(step), donate_argnums=0).lower(data, action).compile()
        compile_s = time.perf_counter() - t0
    for _ in range(calls * 5):  # warm-up
        data = compiled(data, action)
    jax.block_until_ready(data)
    t0 = time.perf_counter()
    for _ in range(control_steps * calls):
        data = compiled(data, action)
    jax.block_until_ready(data)
    seconds = time.perf_counter() - t0
    return {
        "compile_s": round(compile_s, 2),
        "control_steps_per_s": round(control_steps * len(keys) / seconds, 1),
        "qpos_finite": bool(jnp.isfinite(data.qpos).all()),
    }


def device_loop(make_step, keys: jax.Array, action: jax.Array, control_steps: int, options: dict) -> dict:
    """One program scanning ``control_steps`` batch steps of ``make_step()``'s (batch reset, batch
    step) pair, compiled with XLA ``options``."""
    reset, step = make_step()

    def run(state):
        return jax.lax.scan(lambda s, _: (step(s, action), None), state, None, control_steps)[0]

    with mjx_unroll.unrolled_linesearch():
        state = jax.jit(reset)(keys)
        t0 = time.perf_counter()
        compiled = jax.jit(run).lower(state).compile(options or None)
        compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(state))  # warm-up
    t0 = time.perf_counter()
    jax.block_until_ready(compiled(state))
    seconds = time.perf_counter() - t0
    return {"compile_s": round(compile_s, 2), "control_steps_per_s": round(control_steps * len(keys) / seconds, 1)}


def batched(reset, step):
    return jax.vmap(reset), jax.vmap(step)


def physics_only():
    brax_env = brax_humanoid()
    return batched(lambda key: brax_env.reset(key).pipeline_state, brax_env.pipeline_step)


def physics_two_groups():
    """The batch as two halves whose physics steps share one loop: independent kernels in each trip."""
    brax_env = brax_humanoid()
    physics = jax.vmap(lambda data, act: mjx_unroll.physics_step(brax_env, data, act))

    def reset(keys):
        return tuple(jax.vmap(lambda key: brax_env.reset(key).pipeline_state)(half) for half in jnp.split(keys, 2))

    def step(groups, action):
        actions = jnp.split(action, 2)

        def trip(gs, _):
            return tuple(physics(g, a) for g, a in zip(gs, actions, strict=True)), None

        return jax.lax.scan(trip, groups, None, brax_env._n_frames)[0]

    return reset, step


def brax_step():
    brax_env = brax_humanoid()
    return batched(brax_env.reset, brax_env.step)


def rlq_env():
    env = make_env(compose(["experiment=humanoid_ppo"]))
    return batched(env.reset, env.step)


HOST_LOOPS = ("scan", "per_physics_step", "unrolled")
DEVICE_LOOPS = {
    "physics_loop": physics_only,
    "physics_two_groups_loop": physics_two_groups,
    "brax_step_loop": brax_step,
    "rlq_env_loop": rlq_env,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--num-envs", type=int, default=4096)
    parser.add_argument("--control-steps", type=int, default=200)
    variants = [*HOST_LOOPS, *DEVICE_LOOPS]
    parser.add_argument("--variants", nargs="+", choices=variants, default=variants)
    parser.add_argument("--xla-option", action="append", default=[], help="KEY=VALUE for the device loops' compile")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    options = parse_xla_options(args.xla_option)

    brax_env = brax_humanoid()
    keys = jax.random.split(jax.random.PRNGKey(0), args.num_envs)
    action = jax.random.uniform(jax.random.PRNGKey(1), (args.num_envs, brax_env.action_size), minval=-1, maxval=1)
    runs = {}
    for name in args.variants:
        if name in HOST_LOOPS:
            runs[name] = host_loop(brax_env, name, keys, action, args.control_steps)
        else:
            runs[name] = device_loop(DEVICE_LOOPS[name], keys, action, args.control_steps, options)
        runs[name]["ms_per_control_step"] = round(1e3 * args.num_envs / runs[name]["control_steps_per_s"], 3)
        print(name, json.dumps(runs[name]), flush=True)
    report = {
        **run_header(),
        "what": " ".join(__doc__.split("\n\n")[:2]).replace("\n", " "),
        "num_envs": args.num_envs,
        "control_steps": args.control_steps,
        "xla_options": options,
        "runs": runs,
    }
    args.out.write_text(json.dumps(report, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
