"""Host-side metric sinks: JSONL (always), a tqdm progress bar, the run's ``rlq.log``, and W&B.

The loop hands each sink per-seed arrays once per chunk; nothing here runs inside jit. A W&B
failure never stops training: the sink warns once and turns itself off. Every line the console
shows (and one line per chunk of training figures) also goes to ``<run dir>/rlq.log``.
"""

from __future__ import annotations

import io
import json
import math
import os
import secrets
import shutil
import string
import sys
import threading
import time
import warnings
from collections.abc import Mapping, MutableMapping
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from rlq.config.plain import plain
from rlq.store.files import write_atomic
from rlq.store.jsonfiles import read_rows
from rlq.store.reachable import probe, wandb_address
from rlq.store.record import sweep_group


def _clean(value: Any) -> float | None:
    value = float(value)
    return None if math.isnan(value) or math.isinf(value) else value


#: metrics that count things: integers in the rows
COUNTS = ("env_steps", "evaluations")


def _value(key: str, value: Any) -> float | int | None:
    clean = _clean(value)
    return int(round(clean)) if clean is not None and key in COUNTS else clean


def seed_rows(env_steps: int, kind: str, metrics: dict[str, np.ndarray]) -> list[dict[str, Any]]:
    """One row per seed plus one ``"seed": "mean"`` row (NaN-aware mean over seeds). Where the
    metrics count env steps, a row holds its seed's own count (black-box algorithms' seeds differ)."""
    num_seeds = len(next(iter(metrics.values())))
    rows = [
        {"kind": kind, "env_steps": env_steps, "seed": i, **{k: _value(k, v[i]) for k, v in metrics.items()}}
        for i in range(num_seeds)
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = {k: _value(k, np.nanmean(np.asarray(v, np.float64))) for k, v in metrics.items()}
    rows.append({"kind": kind, "env_steps": env_steps, "seed": "mean", **mean})
    return rows


#: what to do about a damaged metrics.jsonl
METRICS_FIX = "restore it from a copy, or move it away to go on without the rows logged so far"


def drop_rows_after(path: Path, env_steps: int, final_eval: bool = False) -> None:
    """Remove the rows logged after ``env_steps`` (a resumed run logs those steps again), and a last line a kill cut
    short (``read_rows`` notes it); the file is replaced whole (``write_atomic``), never left half-written.
    ``final_eval``: the ``eval`` rows after the last train row go too: the final evaluation's, logged after the final
    checkpoint (no periodic evaluation follows the last chunk unless the run reused it as its final one)."""
    if not path.exists():
        return
    found = read_rows(path, METRICS_FIX)
    pairs = [
        (line, row) for line, row in zip(found.lines, found.rows, strict=True) if row.get("env_steps", 0) <= env_steps
    ]
    while final_eval and pairs and pairs[-1][1].get("kind") == "eval":
        pairs.pop()
    kept = [line for line, _ in pairs]
    write_atomic(path, "".join(line + "\n" for line in kept).encode())


class JsonlSink:
    def __init__(self, path: Path):
        self._file = open(path, "a", buffering=1)

    def write(self, rows: list[dict[str, Any]]) -> None:
        for row in rows:
            self._file.write(json.dumps(row) + "\n")

    def close(self) -> None:
        self._file.close()


class LogFile:
    """``<run dir>/rlq.log``: the console's lines, one per line, appended (a resumed run goes on)."""

    def __init__(self, path: Path):
        self._file = open(path, "a", buffering=1)

    def write(self, line: str) -> None:
        if not self._file.closed:
            self._file.write(line.rstrip("\n") + "\n")

    def close(self) -> None:
        self._file.close()


def train_line(env_steps: int, mean_row: dict[str, Any]) -> str:
    """The latest figures of the mean-over-seeds row: the return, or for quality-diversity runs
    evaluations, coverage and max fitness."""
    if mean_row.get("archive-occupancy") is not None:
        parts = [
            f"evals {mean_row.get('evaluations') or 0:,.0f}",
            f"coverage {100 * mean_row['archive-occupancy']:.1f}%",
        ]
        if mean_row.get("maximum-fitness") is not None:
            parts.append(f"max fitness {mean_row['maximum-fitness']:.4g}")
        return ", ".join(parts)
    if mean_row.get("episode_return") is not None:
        return f"return {mean_row['episode_return']:.1f}"
    if "episode_return" in mean_row:
        return "no episode finished yet"
    return ""


class ConsoleSink:
    """What the console shows, in phases: "compiling …" with its elapsed time, then a tqdm bar over
    the training's env steps per seed (its rate and ETA count training only), then "evaluating …"
    and "rendering …". Lines (eval rows, warnings, Python warnings and log records) print above the
    bar, never after it; every line shown also goes to ``log`` (rlq.log). Where stderr is not a
    terminal (a batch job's log file, a pipe) nothing is redrawn: the bar's state prints as one line
    per chunk and a phase as its closing line."""

    def __init__(
        self,
        total_steps: int,
        num_seeds: int,
        enabled: bool,
        log: LogFile | None = None,
        start_steps: int = 0,
        unit: str = "step",
    ):
        """``unit``: what ``total_steps`` and ``start_steps`` count, ``step`` (env steps per seed) or
        ``it`` (iterations of a black-box algorithm, whose true env steps fall below the nominal ones)."""
        self._enabled, self._log, self._unit = enabled, log, unit
        self._tty = sys.stderr.isatty()
        self._total, self._num_seeds, self._start_steps = total_steps, num_seeds, start_steps
        self._bar: Any = None
        self._training_started = False
        self._phase: tuple[str, float] | None = None
        self._ticker: tuple[threading.Thread, threading.Event] | None = None
        self._redirect: Any = None
        self._showwarning: Any = None
        if enabled:
            from tqdm.contrib.logging import logging_redirect_tqdm

            self._redirect = logging_redirect_tqdm()
            self._redirect.__enter__()
            self._showwarning, warnings.showwarning = warnings.showwarning, self._show_warning

    def _record(self, line: str) -> None:
        if self._log is not None:
            self._log.write(line)

    def _show_warning(
        self,
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        self.warn(f"{category.__name__}: {message} ({Path(filename).name}:{lineno})")

    def end(self) -> None:
        """Close the bar or phase line on screen; a phase leaves one line with its duration."""
        if self._ticker is not None:
            thread, stop = self._ticker
            stop.set()
            thread.join()
            self._ticker = None
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        if self._phase is not None:
            name, started = self._phase
            self._phase = None
            self.message(f"rlq: {name}: {time.perf_counter() - started:.1f} s")

    def phase(self, name: str) -> None:
        """A phase without env steps ("compiling", "evaluating", "rendering"): its name and the
        seconds it has taken, refreshed every second on a terminal."""
        self.end()
        self._phase = (name, time.perf_counter())
        if not self._enabled or not self._tty:
            return
        from tqdm import tqdm

        self._bar = tqdm(desc=f"rlq: {name} …", bar_format="{desc} {elapsed}", file=sys.stderr, leave=False)
        stop = threading.Event()
        thread = threading.Thread(target=self._tick, args=(self._bar, stop), daemon=True)
        thread.start()
        self._ticker = (thread, stop)

    @staticmethod
    def _tick(bar: Any, stop: threading.Event) -> None:
        while not stop.wait(1.0):
            bar.refresh()

    def training(self) -> None:
        """The training phase: a bar over env steps per seed, from the run's start (or resumed) steps."""
        self.end()
        self._training_started = True
        if not self._enabled:
            return
        from tqdm import tqdm

        per_seed = "iterations" if self._unit == "it" else "steps per seed"
        self._bar = tqdm(
            desc="train" if self._num_seeds == 1 else f"train ({self._num_seeds} seeds, {per_seed})",
            total=self._total,
            initial=self._start_steps,
            unit=self._unit,
            unit_scale=self._unit == "step",  # 1.2M steps; iterations as they are
            dynamic_ncols=self._tty,
            file=sys.stderr if self._tty else io.StringIO(),  # off a terminal: printed as lines by advance
            ncols=None if self._tty else 100,
        )

    def advance(self, env_steps: int, mean_row: dict[str, Any], iterations: int | None = None) -> None:
        """Move the training bar (started by the first call) to ``env_steps`` per seed, or to
        ``iterations`` when it counts them, and show the latest figures of the mean-over-seeds row."""
        if not self._training_started:
            self.training()
        figures = train_line(env_steps, mean_row)
        self._record(f"[train @ {env_steps:,} steps] {figures}".rstrip())
        if self._bar is None:
            return
        position = iterations if self._unit == "it" and iterations is not None else env_steps
        self._bar.update(max(0, position - self._bar.n))
        if figures:
            self._bar.set_postfix_str(figures, refresh=self._tty)
        if not self._tty:
            print(str(self._bar), file=sys.stderr, flush=True)

    def message(self, text: str) -> None:
        self._record(text)
        if self._enabled:
            self._write(text)

    def warn(self, text: str) -> None:
        """Always shown, bar or not."""
        line = f"rlq: warning: {text}"
        self._record(line)
        self._write(line)

    def _write(self, line: str) -> None:
        if self._bar is not None and self._tty:
            self._bar.write(line, file=sys.stderr)
        else:
            print(line, file=sys.stderr, flush=True)

    def close(self) -> None:
        self.end()
        if self._redirect is not None:
            self._redirect.__exit__(None, None, None)
            warnings.showwarning = self._showwarning
            self._redirect = None


#: the sweep directories whose `wandb sync` line this process has shown (once per sweep, not per job)
_SYNC_TOLD: set[Path] = set()

#: seconds to wait for the W&B server before an online run logs offline
REACH_TIMEOUT_S = 3.0


def _entries(directory: Path) -> set[Path]:
    return set(directory.iterdir()) if directory.is_dir() else set()


def _remove_new(directory: Path, before: set[Path]) -> None:
    """Remove what a failed ``wandb.init`` left in ``directory`` (its half-made run folder)."""
    for path in _entries(directory) - before:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)


def run_id(run_dir: Path) -> str:
    """The W&B run id of ``run_dir`` (``<run dir>/wandb_id``, made on first use): a resumed run
    continues the same W&B run."""
    path = run_dir / "wandb_id"
    if path.exists():
        return path.read_text().strip()
    alphabet = string.ascii_lowercase + string.digits
    new = "".join(secrets.choice(alphabet) for _ in range(8))
    path.write_text(new + "\n")
    return new


def unset_empty_wandb_variables(environ: MutableMapping[str, str] = os.environ) -> list[str]:
    """Remove ``WANDB_*`` variables set to the empty string (``WANDB_SILENT=`` in a job script): for a shell they
    are unset, while wandb's settings would refuse them ("Input should be a valid boolean") and W&B would be off."""
    empty = [name for name, value in environ.items() if name.startswith("WANDB_") and not value.strip()]
    for name in empty:
        del environ[name]
    return empty


class WandbSink:
    def __init__(self, cfg: Mapping[str, Any], run_dir: Path, console: ConsoleSink):
        self._run = None
        self._console = console
        #: where an offline run's W&B files are (None: online or no W&B), for the line that says how to upload them
        self.offline_dir: Path | None = None
        wcfg = cfg["logger"]["wandb"]
        if wcfg["mode"] == "disabled":
            return
        mode = wcfg["mode"]
        unset_empty_wandb_variables()
        if mode == "online":
            host, port = wandb_address()
            problem = probe(host, port, REACH_TIMEOUT_S)
            if problem is not None:
                self._warn(
                    f"W&B server {host}:{port} {problem}; logging offline "
                    f"instead (`wandb sync {run_dir}/wandb/offline-run-*` uploads it later)"
                )
                mode = "offline"
        try:
            import wandb

            kwargs = dict(
                id=run_id(run_dir),
                resume="allow",
                project=wcfg["project"],
                entity=wcfg["entity"],
                group=wcfg["group"] or sweep_group(run_dir),
                tags=list(wcfg["tags"]),
                name=run_dir.name,
                dir=str(run_dir),
                config=plain(cfg),
                settings=wandb.Settings(silent=True, console="off"),
            )
            before = _entries(run_dir / "wandb")
            try:
                self._run = wandb.init(mode=mode, **kwargs)
            except Exception as err:  # online init failed though the server answered: keep the run, log offline
                if mode != "online":
                    raise
                _remove_new(run_dir / "wandb", before)
                self._warn(f"W&B online init failed ({type(err).__name__}); logging offline instead")
                try:
                    self._run = wandb.init(mode="offline", **kwargs)
                except Exception as again:  # W&B's service may still hold the failed run's id for a moment
                    if "in use" not in str(again):
                        raise
                    _remove_new(run_dir / "wandb", before)
                    self._run = wandb.init(mode="offline", **{**kwargs, "id": f"{kwargs['id']}-offline"})
                mode = "offline"
            if mode == "offline":
                self.offline_dir = run_dir / "wandb"
        except Exception as err:
            self._warn(f"W&B disabled: {type(err).__name__}: {err}")
            self._run = None

    def _warn(self, text: str) -> None:
        self._console.warn(text)

    def write(self, env_steps: int, kind: str, metrics: dict[str, np.ndarray]) -> None:
        if self._run is None:
            return
        try:
            payload = {}
            for key, values in metrics.items():
                values = np.asarray(values, np.float64)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    payload[f"{kind}/{key}"] = float(np.nanmean(values))
                if len(values) > 1:
                    payload.update({f"{kind}_seed{i}/{key}": float(v) for i, v in enumerate(values)})
            self._run.log(payload, step=env_steps)
        except Exception as err:
            self._warn(f"W&B logging failed, disabled for the rest of the run: {type(err).__name__}: {err}")
            self._run = None

    def images(self, env_steps: int, images: dict[str, np.ndarray]) -> None:
        if self._run is None:
            return
        try:
            import wandb

            self._run.log({key: wandb.Image(image) for key, image in images.items()}, step=env_steps)
        except Exception as err:
            self._warn(f"W&B image logging failed, disabled for the rest of the run: {type(err).__name__}: {err}")
            self._run = None

    def video(self, env_steps: int, key: str, path: Path) -> None:
        if self._run is None:
            return
        try:
            import wandb

            self._run.log({key: wandb.Video(str(path), format="mp4")}, step=env_steps)
        except Exception as err:
            self._warn(f"W&B video logging failed, disabled for the rest of the run: {type(err).__name__}: {err}")
            self._run = None

    def close(self) -> None:
        if self._run is not None:
            try:
                self._run.finish()
            except Exception as err:
                self._warn(f"W&B finish failed: {type(err).__name__}: {err}")


class RunLogger:
    """Fans metrics out to every sink; the training loop's only logging interface."""

    def __init__(
        self,
        cfg: Mapping[str, Any],
        run_dir: Path,
        total_steps: int,
        num_seeds: int,
        start_steps: int = 0,
        started: float | None = None,
        unit: str = "step",
    ):
        """``started``: the ``time.perf_counter()`` the run's wall clock counts from (a resumed run's
        lies before this process started, by the checkpoint's wall time); ``unit``: what the progress
        bar, ``total_steps`` and ``start_steps`` count (ConsoleSink)."""
        self.jsonl = JsonlSink(run_dir / "metrics.jsonl")
        self.logfile = LogFile(run_dir / "rlq.log")
        console = bool(cfg["logger"]["console"])
        self.console = ConsoleSink(total_steps, num_seeds, console, self.logfile, start_steps, unit)
        self.wandb = WandbSink(cfg, run_dir, self.console)
        self._run_dir = Path(run_dir)
        self._start = time.perf_counter() if started is None else started

    def wall_s(self) -> float:
        """Seconds of the run's wall clock, resumed parts included."""
        return round(time.perf_counter() - self._start, 3)

    def log(self, env_steps: int, kind: str, metrics: dict[str, np.ndarray], iterations: int | None = None) -> None:
        """``iterations``: updates done, for a progress bar that counts them (train rows)."""
        metrics = {k: np.asarray(v).reshape(-1) for k, v in metrics.items()}
        num_seeds = len(next(iter(metrics.values())))
        metrics["wall_s"] = np.full(num_seeds, self.wall_s())
        rows = seed_rows(env_steps, kind, metrics)
        self.jsonl.write(rows)
        self.wandb.write(env_steps, kind, metrics)
        if kind == "train":
            self.console.advance(env_steps, rows[-1], iterations)
        else:
            summary = ", ".join(
                f"{k} {v:.4g}" for k, v in rows[-1].items() if k in ("return", "length") and v is not None
            )
            self.console.message(f"[{kind} @ {env_steps:,} steps] {summary}")

    def figures(self, env_steps: int, per_seed: list[dict[str, np.ndarray]], tag: str) -> list[Path]:
        """Save each seed's pictures as ``figures/<name>_seed<i>_<tag>.png`` and log them to W&B
        as ``figures/<name>_seed<i>``."""
        from PIL import Image

        directory = self._run_dir / "figures"
        directory.mkdir(parents=True, exist_ok=True)
        paths, images = [], {}
        for seed, figures in enumerate(per_seed):
            for name, image in figures.items():
                path = directory / f"{name}_seed{seed}_{tag}.png"
                Image.fromarray(np.asarray(image, np.uint8)).save(path)
                paths.append(path)
                images[f"figures/{name}_seed{seed}"] = image
        if images:
            self.wandb.images(env_steps, images)
        return paths

    def video(self, env_steps: int, path: Path) -> None:
        """An mp4 of the run (``videos/<name>.mp4``) to W&B as ``videos/seed0``, at ``env_steps``."""
        self.wandb.video(env_steps, "videos/seed0", path)

    def sync_hint(self) -> str | None:
        """The `wandb sync` line of a run W&B logged offline; a sweep's jobs share one, said by the first job
        of the sweep this process runs (`wandb sync` takes every job's directories at once)."""
        if self.wandb.offline_dir is None:
            return None
        sweep_dir = self._run_dir.resolve().parent
        if (sweep_dir / "multirun.yaml").exists():
            if sweep_dir in _SYNC_TOLD:
                return None
            _SYNC_TOLD.add(sweep_dir)
            where, what = f"{sweep_dir}/*/wandb/offline-run-*", "uploads every job's"
        else:
            where, what = f"{self.wandb.offline_dir}/offline-run-*", "uploads it"
        return f"rlq: W&B logged offline, nothing was uploaded: `wandb sync {where}` {what} (logger.wandb.mode=online logs live)"

    def record(self, line: str) -> None:
        """A line for rlq.log only (the CLI prints it itself, e.g. the run's summary); ends the
        console's phase first."""
        self.console.end()
        self.logfile.write(line)

    def close(self) -> None:
        hint = self.sync_hint()
        if hint:
            self.console.message(hint)
        self.console.close()
        self.jsonl.close()
        self.wandb.close()
        self.logfile.close()
