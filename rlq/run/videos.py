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
from omegaconf import DictConfig

from rlq.algos.base import Algorithm
from rlq.lib.batch import seed_entry
from rlq.lib.env_api import Env
from rlq.run.build import make_env
from rlq.run.compiler import Option, compile_with
from rlq.run.logging import RunLogger
from rlq.run.render import episode_length, episode_program, has_renderer, render_command, write_states_video

#: folded into the run's seed for the video episode's key: every stage starts from the same state
VIDEO_KEY = 20_011


class Seed0Video:
    """Writes seed 0's greedy episode of a state of all seeds of a run on ``run_env``; ``enabled`` is
    False where that env cannot render (nothing is written then)."""

    def __init__(self, cfg: DictConfig, algo: Algorithm, run_dir: Path, logger: RunLogger, run_env: Env):
        self.cfg, self.algo = cfg, algo
        self.num_seeds = int(cfg.num_seeds)
        self.run_dir, self.logger = Path(run_dir), logger
        self.enabled = has_renderer(run_env)  # the video's env differs only in its wrappers
        self._prepared: Future | None = None  # the episode program compiled ahead (prepare_soon)

    # built at the first video, not with the run: an MJX env's build takes seconds (and the key's
    # two small programs a fraction of one), which would otherwise fall between the programs'
    # compile and the first chunk, or, at the end, before the "rendering" line
    @functools.cached_property
    def key(self) -> jax.Array:
        return jax.random.fold_in(jax.random.PRNGKey(self.cfg.seed), VIDEO_KEY)

    @functools.cached_property
    def env(self) -> Env:
        return make_env(self.cfg, autoreset=False)

    @functools.cached_property
    def max_steps(self) -> int:
        return int(self.cfg.video.max_steps or self.env.max_episode_steps or 1000)

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

    def __call__(self, state: Any, env_steps: int, name: str) -> Path | None:
        """``videos/<name>.mp4`` (or ``.npz`` without OpenGL) of seed 0 of ``state``; None if none."""
        if not self.enabled:
            return None
        seed0 = seed_entry(state, 0, self.num_seeds)
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
