"""Seed 0's greedy episode as a video, at training stages (``video.every_steps``) and at the end
(``video.at_end``): ``<run>/videos/<name>.mp4``, logged to W&B. The episode is one program,
compiled once per run and called with each new state; frames are drawn on the host.

A MuJoCo env without OpenGL saves the episode's states (``<name>.npz``) instead and says in one
line which `rlq render` command draws them; a video never fails the run.

On an accelerator the video's env is built and its program compiled while the run trains
(``prepare_soon``): the host's cores are idle then, and a MuJoCo episode's program takes as long
to compile as the run's evaluation, which would otherwise hold up training at the first stage
video, or come after the last chunk.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Mapping
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import jax

from rlq.algos.base import Algorithm
from rlq.config.spec import RunSpec, as_spec
from rlq.lib.batch import seed_entry
from rlq.lib.env_api import Env
from rlq.lib.rollout import episode_length, episode_program
from rlq.lib.sharding import first_seed
from rlq.run.programs.compiler import Option, compile_with
from rlq.run.programs.env_stack import make_env
from rlq.store.logging import RunLogger
from rlq.store.render import has_renderer, partial_path, render_command, write_states_video

#: folded into the run's seed for the video episode's key: every stage starts from the same state
VIDEO_KEY = 20_011
#: the share of a CPU run's time a final video nobody asked for (``video.at_end: null``) may cost
VIDEO_SHARE = 0.10
#: seconds to draw and encode a frame on a CPU, measured on 2 cores: CartPole 1.3 ms and LunarLander 2.6 ms to
#: draw (plus the mp4's encoding), a MuJoCo env ~30 ms (a 500-step brittle star episode takes about 15 s)
FRAME_S = {"host_gl": 0.03, "array": 0.004}


def wants_final_video(at_end: bool | None, sweep_job: bool) -> bool:
    """Whether a run may end with a video: ``video.at_end`` true (asked) or false; null (the default) renders one
    in a single run, none in a sweep's job (every job would pay for it)."""
    return bool(at_end) if at_end is not None else not sweep_job


def video_estimate_s(compile_s: float, frames: int, draws_on_host_gl: bool) -> float:
    """A cheap estimate of a final video's cost: its episode program compiles like the run's evaluation (about half
    of the run's compile time: init, chunk, evaluate; a cached one takes nothing), then ``frames`` are drawn."""
    return compile_s / 2 + frames * FRAME_S["host_gl" if draws_on_host_gl else "array"]


def cpu_video_skip(estimate_s: float, run_s: float, run_dir: Path) -> str | None:
    """The line that skips a default final video on a CPU where it would cost over ``VIDEO_SHARE`` of the run;
    None: it is cheap enough."""
    if estimate_s <= VIDEO_SHARE * run_s:
        return None
    return (
        f"no final video: about {estimate_s:.0f} s on this CPU, over {VIDEO_SHARE:.0%} of the run's {run_s:.0f} s "
        f"(video.at_end=true renders it; later: rlq render run={run_dir})"
    )


class Seed0Video:
    """Writes seed 0's greedy episode of a state of all seeds of a run on ``run_env``; ``enabled`` is
    False where that env cannot render (nothing is written then)."""

    def __init__(
        self, run: RunSpec | Mapping[str, Any], algo: Algorithm, run_dir: Path, logger: RunLogger, run_env: Env
    ):
        spec = as_spec(run)
        self.spec, self.algo = spec, algo
        self.num_seeds = int(spec.seeds.count)
        self.run_dir, self.logger = Path(run_dir), logger
        self.enabled = has_renderer(run_env)  # the video's env differs only in its wrappers
        self._prepared: Future | None = None  # the episode program compiled ahead (prepare_soon)

    # built at the first video, not with the run: an MJX env's build takes seconds (and the key's
    # two small programs a fraction of one), which would otherwise fall between the programs'
    # compile and the first chunk, or, at the end, before the "rendering" line
    @functools.cached_property
    def key(self) -> jax.Array:
        return jax.random.fold_in(jax.random.PRNGKey(self.spec.seeds.seed), VIDEO_KEY)

    @functools.cached_property
    def env(self) -> Env:
        return make_env(self.spec, autoreset=False)

    @functools.cached_property
    def max_steps(self) -> int:
        return int(self.spec.outputs.video.max_steps or self.env.max_episode_steps or 1000)

    @functools.cached_property
    def program(self) -> Any:
        return episode_program(self.env, self.algo.policy, self.max_steps)

    def prepare_soon(self, state_shape: Any, device: jax.Device, options: Mapping[str, Option] | None = None) -> None:
        """Build the env and compile the episode program for states of shape ``state_shape`` (all
        seeds) on ``device`` with XLA ``options``, in a thread; the first video waits for it. Not a daemon thread: one
        stopped inside XLA's compiler at exit could crash the process, so a run that ends before its
        video (an error, a signal) waits for the compile. A failure here leaves the video to build and
        compile as it would without this."""
        if not self.enabled:
            return
        prepared: Future = Future()

        def work() -> None:
            try:
                with jax.default_device(device):
                    seed0 = jax.eval_shape(lambda tree: seed_entry(tree, 0, self.num_seeds), state_shape)
                    prepared.set_result(compile_with(self.program.lower(seed0, self.key), options))
            except Exception:
                prepared.set_result(None)

        self._prepared = prepared
        threading.Thread(target=work, name="rlq-video-compile").start()

    def _episode(self, seed0: Any) -> Any:
        compiled = self._prepared.result() if self._prepared is not None else None
        if compiled is not None:
            try:
                return compiled(seed0, self.key)
            except (TypeError, ValueError):  # inputs placed otherwise than the program was compiled for
                self._prepared = None
        return self.program(seed0, self.key)

    def forget(self, name: str) -> None:
        """Remove the frames of video ``name`` written so far: a stop abandoned it (its thread ends with the process)."""
        partial_path(self.run_dir / "videos" / f"{name}.mp4").unlink(missing_ok=True)

    def __call__(self, state: Any, env_steps: int, name: str) -> Path | None:
        """``videos/<name>.mp4`` (or ``.npz`` without OpenGL) of seed 0 of ``state``; None if none."""
        if not self.enabled:
            return None
        seed0 = first_seed(state, self.num_seeds)  # over several processes: process 0's own copy
        try:
            states, done = self._episode(seed0)
            length = episode_length(done, self.max_steps)
            path = write_states_video(self.env, states, length, self.run_dir / "videos" / f"{name}.mp4")
        except Exception as err:
            self.logger.console.warn(f"no video: {type(err).__name__}: {err}")
            return None
        if path.suffix == ".npz":  # no OpenGL here: the episode's states were saved instead
            self.logger.console.warn(
                f"no OpenGL for the video, states saved to {path}; {render_command(self.run_dir, path)}"
            )
        else:
            self.logger.video(env_steps, path)
        return path
