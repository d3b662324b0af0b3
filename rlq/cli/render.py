"""`rlq render run=<dir>`: a video of one greedy episode of a finished run.

With ``states=<npz>`` it draws instead the states a run saved where no OpenGL loaded
(rlq.store.render.save_frame_arrays); the env is rebuilt from the run's config, no checkpoint is read.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import jax

from rlq.cli.args import int_option, parse_args, seed_option, warn_skipped
from rlq.config.spec import RunSpec
from rlq.envs import Env, make_base_env
from rlq.envs.mujoco.gl import NoGLError
from rlq.errors import ConfigError, RunDirError, UsageError
from rlq.lib.batch import seed_entry
from rlq.lib.rollout import PolicyFn
from rlq.store.outputs import check_output_file
from rlq.store.render import render_command, render_saved, write_episode_video
from rlq.tools.evaluate import evaluation_target, load_run_config, restore_run

RENDER_KEYS = {"run", "seed_index", "seed", "steps", "out", "checkpoint", "env", "states", "cell"}
USAGE = (
    "usage: rlq render run=<run dir> [checkpoint=<env steps>|final] [seed_index=0] [seed=0] [steps=N]"
    " [out=video.mp4] [env=NAME]"
    " [cell=best|furthest|i,j|k (an archive's elite)]"
    " | rlq render run=<run dir> states=videos/<name>.npz [out=video.mp4]"
)
HELP = """usage: rlq render run=<run dir> [seed_index=I] [seed=S] [steps=N] [out=FILE] [env=NAME] [cell=C] [checkpoint=C]
       rlq render run=<run dir> states=videos/<name>.npz [out=FILE]

Render one greedy episode of a finished run to mp4 (default <run dir>/videos/final_seed<I>_episode<S>.mp4,
videos/step_<N>_seed<I>_episode<S>.mp4 for checkpoint=N).

options:
  run=DIR          a run directory written by `rlq train` (required)
  seed_index=I     which of the run's seeds acts (default 0)
  seed=S           PRNG seed of the episode (default 0)
  steps=N          episode cap (default: the env's time limit)
  out=FILE         where the video goes
  env=NAME         render on another env with the same spaces
  cell=C           an archive elite instead of the policy: best, furthest, i,j (grid) or k (CVT cell)
  checkpoint=C     the checkpoint to load: N (checkpoints/step_N.msgpack, kept with checkpoint.every_steps),
                   final, kept, or a file (default: kept.msgpack of a finished eval.keep=best run, else
                   final.msgpack, else the latest step_*)
  states=NPZ       draw the states a run saved where no OpenGL loaded (no checkpoint is read)
  env.<key>=VALUE  change a key of the env's config
"""
NO_GL_HINT = "install libegl1 or libosmesa6, or set MUJOCO_GL"


def _states_path(run_dir: Path, states: str) -> Path:
    """``states`` as given, else relative to the run directory."""
    path = Path(states)
    if not path.exists() and (run_dir / path).exists():
        path = run_dir / path
    if not path.exists():
        raise RunDirError(f"no states file {states} (nor {run_dir / states})")
    return path


def check_video_out(out: Path) -> None:
    """The video's path and the states' file that takes its place without OpenGL are files rlq may write."""
    for path in (out, out.with_suffix(".npz")):
        check_output_file(path, "out")


def render_saved_main(run_dir: Path, options: dict[str, str]) -> None:
    path = _states_path(run_dir, options["states"])
    check_output_file(Path(options["out"]) if "out" in options else path.with_suffix(".mp4"), "out")
    env = make_base_env(load_run_config(run_dir).env)
    try:
        video = render_saved(env, path, Path(options["out"]) if "out" in options else None)
    except NoGLError as err:
        raise ConfigError(f"{err}; {NO_GL_HINT}") from None
    except (TypeError, KeyError, ValueError) as err:
        raise RunDirError(f"{path} does not fit this run's env: {err}") from None
    print(f"rlq render: {video}", file=sys.stdout)


def elite_policy(spec: RunSpec, env: Env, seed_state: Any, cell: str) -> PolicyFn:
    """The policy of the archive elite named by ``cell`` (MAP-Elites, random search with an archive)."""
    from rlq.algos import algo_settings
    from rlq.algos.map_elites import grid_of
    from rlq.algos.qd.archive import chosen_cell
    from rlq.algos.qd.genotypes import make_genotype

    archive = getattr(seed_state, "archive", None)
    if archive is None:
        raise UsageError(
            f"cell= needs a run with an archive (algo=map_elites); this run is algo={spec.algorithm['name']}"
        )
    try:
        index = chosen_cell(archive, grid_of(algo_settings(spec.algorithm)), cell)
    except ValueError as err:
        raise UsageError(str(err)) from None
    print(
        f"rlq render: elite of cell {cell} (flat index {index}): fitness {float(archive.fitness[index]):.4g}, "
        f"descriptor {[round(float(x), 3) for x in archive.descriptors[index]]}",
        file=sys.stdout,
    )
    return make_genotype(algo_settings(spec.algorithm), env).policy(archive.genotypes[index])


def render_main(args: list[str]) -> None:
    options, env_overrides = parse_args(args, RENDER_KEYS, USAGE)
    run_dir = Path(options["run"])
    if "states" in options:
        render_saved_main(run_dir, options)
        return
    if "out" in options:
        check_video_out(Path(options["out"]))
    seed_index, seed = int_option(options, "seed_index", 0), seed_option(options)
    steps = int_option(options, "steps", 500) if "steps" in options else None  # 500: the example of a bad value's line
    if steps is not None and steps < 1:
        raise UsageError(f"steps must be >= 1, got {steps}")
    spec = load_run_config(run_dir)
    num_seeds = spec.seeds.count
    if not 0 <= seed_index < num_seeds:
        raise UsageError(f"seed_index must be in 0..{num_seeds - 1} for this run, got {seed_index}")
    _, env = evaluation_target(spec, options.get("env"), env_overrides, autoreset=False)
    if not env.jittable:
        raise UsageError(f"env={options.get('env')} runs on the host; render a JAX env")
    skipped: list[str] = []
    spec, programs, state, ckpt = restore_run(run_dir, options.get("checkpoint"), spec, skipped)
    warn_skipped(skipped, ckpt)
    seed_state = seed_entry(state, seed_index, int(spec.seeds.count))
    if "cell" in options:
        policy, name = elite_policy(spec, programs.env, seed_state, options["cell"]), f"cell_{options['cell']}_episode"
    else:
        policy, name = programs.algo.policy(seed_state), "episode"
    # named as training names its videos (final_seed0.mp4, step_2048_seed0.mp4), with the episode's seed
    default = run_dir / "videos" / f"{ckpt.stem}_seed{seed_index}_{name.replace(',', '_')}{seed}.mp4"
    out = Path(options.get("out", default))
    check_video_out(out)
    try:
        path = write_episode_video(env, policy, jax.random.PRNGKey(seed), out, steps)
    except NotImplementedError as err:
        raise ConfigError(f"{err}; env={spec.env['name']} cannot be rendered") from None
    if path.suffix == ".npz":
        print(f"rlq render: no OpenGL here, states saved instead; {render_command(run_dir, path)}", file=sys.stdout)
        return
    print(f"rlq render: {path}", file=sys.stdout)
