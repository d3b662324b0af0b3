"""`rlq render run=<dir>`: a video of one greedy episode of a finished run."""

from __future__ import annotations

import sys
from pathlib import Path

import jax

from rlq.cli import fail
from rlq.envs import make_env
from rlq.evaluate import eval_env_config, parse_args, restore_run
from rlq.render import write_episode_video

RENDER_KEYS = {"run", "seed_index", "seed", "steps", "out", "checkpoint", "env"}
USAGE = "usage: rlq render run=<run dir> [seed_index=0] [seed=0] [steps=N] [out=video.mp4] [env=NAME]"


def render_main(args: list[str]) -> None:
    options, env_overrides = parse_args(args, RENDER_KEYS, USAGE)
    try:
        seed_index, seed = int(options.get("seed_index", 0)), int(options.get("seed", 0))
        steps = int(options["steps"]) if "steps" in options else None
    except ValueError:
        fail("seed_index, seed and steps must be integers")
    run_dir = Path(options["run"])
    cfg, programs, state, _ = restore_run(run_dir, options.get("checkpoint"))
    if not 0 <= seed_index < cfg.num_seeds:
        fail(f"seed_index must be in 0..{cfg.num_seeds - 1} for this run")
    env = make_env(eval_env_config(cfg, options.get("env"), env_overrides), autoreset=False)
    if not env.jittable:
        fail(f"env={options.get('env')} runs on the host; render a JAX env")
    policy = programs.algo.policy(jax.tree.map(lambda x: x[seed_index], state))
    out = Path(options.get("out", run_dir / "videos" / f"seed{seed_index}_episode{seed}.mp4"))
    try:
        path = write_episode_video(env, policy, jax.random.PRNGKey(seed), out, steps)
    except NotImplementedError as err:
        fail(f"{err}; env={cfg.env.name} cannot be rendered")
    print(f"rlq render: {path}", file=sys.stdout)
