"""Helpers shared by the benchmark scripts: run `rlq train` as a user would and read its outputs."""

from __future__ import annotations

import collections
import datetime
import gzip
import json
import os
import platform
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rlq.lib.versions import installed_versions


def ask_jax(code: str) -> str:
    """What ``code`` (after ``import jax``) prints in a fresh Python process: the benchmark's own
    process never initialises JAX's backends, so each run it starts gets the devices whole."""
    out = subprocess.run([sys.executable, "-c", f"import jax; {code}"], capture_output=True, text=True, check=True)
    return out.stdout.strip()


def device_name() -> str:
    return ask_jax("d = jax.devices()[0]; print(d.platform, '|', d.device_kind)")


#: the distributions that decide what a run computes with: JAX's release, and which physics ``env.mjx_impl=auto``
#: steps (MuJoCo Warp needs warp-lang and the mujoco-mjx release rlq reads; else MJX's JAX implementation)
VERSIONED = ("jax", "jaxlib", "mujoco-mjx", "warp-lang")


def package_versions() -> dict[str, str | None]:
    """The installed versions of ``VERSIONED`` (None: not installed), without importing JAX in this process."""
    return installed_versions(VERSIONED)


def rlq_commit() -> str:
    """The short git commit of the rlq checkout the scripts run from ("" outside a git checkout), with
    "+modified" where tracked files differ from it: a copy of a working tree may carry an older commit's
    ``.git`` beside newer files, and a result must not name code it did not run."""
    here = Path(__file__).parent
    out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=here)
    commit = out.stdout.strip()
    if commit and subprocess.run(["git", "diff", "--quiet", "HEAD", "--"], capture_output=True, cwd=here).returncode:
        commit += "+modified"
    return commit


#: overrides every benchmark's `rlq train` gets: no wandb, no final video (a machine without ffmpeg or a login)
QUIET = ["logger.wandb.mode=disabled", "video.at_end=false"]


def train_process(
    args: list[str],
    run_dir: Path,
    env: dict[str, str] | None = None,
    timeout: float | None = None,
    entry: list[str] | None = None,
) -> dict:
    """One `rlq train` process with ``args`` writing to ``run_dir``, timed from start to exit: its exit status
    (``"timeout"`` if cut off), wall seconds, stdout and stderr. ``entry``: another entry point than
    ``-m rlq.cli`` (e.g. a script that patches rlq first)."""
    cmd = [sys.executable, *(entry or ["-m", "rlq.cli"]), "train", *args, f"hydra.run.dir={run_dir}"]
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **(env or {})}, timeout=timeout)
        rc, stdout, stderr = proc.returncode, proc.stdout, proc.stderr
    except subprocess.TimeoutExpired as err:
        rc, stdout, stderr = "timeout", _text(err.stdout), _text(err.stderr)
    return {"rc": rc, "process_wall_s": round(time.perf_counter() - start, 2), "stdout": stdout, "stderr": stderr}


def _text(raw: bytes | str | None) -> str:
    return raw.decode(errors="replace") if isinstance(raw, bytes) else raw or ""


def run_rlq(overrides: list[str], keep_dir: Path | None = None) -> dict:
    """One `rlq train` process: its wall time, summary.json and metrics rows.

    The run directory is temporary unless ``keep_dir`` names where to leave it (e.g. for `rlq eval`).
    """
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = keep_dir or Path(tmp) / "run"
        proc = train_process(overrides, run_dir)
        if proc["rc"] != 0:
            raise SystemExit(f"rlq train {' '.join(overrides)} failed:\n{proc['stderr'][-3000:]}")
        summary = json.loads((run_dir / "summary.json").read_text())
        rows = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    return {"process_wall_s": proc["process_wall_s"], "summary": summary, "rows": rows}


def box2d_returns(run_dir: Path, episodes: int, cpu_only: bool = False) -> list[float]:
    """Each seed's mean return over ``episodes`` of Gymnasium's Box2D LunarLander, from `rlq eval`
    (``cpu_only``: the policy on the CPU, leaving a GPU to other work). Raises RuntimeError if it fails."""
    cmd = [sys.executable, "-m", "rlq.cli", "eval", f"run={run_dir}", "env=lunar_box2d", f"episodes={episodes}"]
    env = {**os.environ, "JAX_PLATFORMS": "cpu"} if cpu_only else None
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise RuntimeError(f"rlq eval failed:\n{proc.stderr[-3000:]}")
    return json.loads((run_dir / "eval_lunar_box2d.json").read_text())["per_seed_return"]


class CpuSampler:
    """Busy cores of the whole host (from /proc/stat) every ``period`` seconds while active."""

    def __init__(self, period: float = 0.2):
        self.period, self.samples, self._stop = period, [], threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    @staticmethod
    def _read() -> tuple[int, int]:
        fields = [int(x) for x in Path("/proc/stat").read_text().splitlines()[0].split()[1:]]
        idle = fields[3] + fields[4]
        return sum(fields) - idle, sum(fields)

    def _run(self) -> None:
        cores = os.cpu_count() or 1
        busy0, total0 = self._read()
        while not self._stop.wait(self.period):
            busy1, total1 = self._read()
            if total1 > total0:
                self.samples.append(cores * (busy1 - busy0) / (total1 - total0))
            busy0, total0 = busy1, total1

    def __enter__(self) -> CpuSampler:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()

    def summary(self) -> dict:
        if not self.samples:
            return {}
        return {"mean_busy_cores": round(sum(self.samples) / len(self.samples), 2), "peak": round(max(self.samples), 2)}


def time_to_threshold(rows: list[dict], threshold: float, every_seed: bool = False) -> dict | None:
    """First evaluation whose mean greedy return over seeds (or, with ``every_seed``, each seed's) reaches
    ``threshold``."""
    evals: dict[float, list[dict]] = {}
    for row in rows:
        if row["kind"] == "eval":
            evals.setdefault(row["env_steps"], []).append(row)
    for env_steps, group in evals.items():
        chosen = [r for r in group if (r["seed"] != "mean") == every_seed]
        if chosen and all((r.get("return") or -1e30) >= threshold for r in chosen):
            return {"env_steps": env_steps, "train_wall_s": chosen[0].get("wall_s")}
    return None


def run_figures(run: dict) -> dict:
    """The figures every preset benchmark reports from one `run_rlq` result."""
    summary = run["summary"]
    return {
        "process_wall_s": run["process_wall_s"],
        "compile_s": summary["compile_s"],
        "steady_env_steps_per_s": summary["steady_env_steps_per_s"],
        "env_steps_per_seed": summary["env_steps"],
        "final_eval_return": summary["eval_return"],
    }


def run_header() -> dict:
    """Date, device (this process's first jax device), jax and Python versions: the head of a report
    written by a benchmark that runs its work in-process."""
    import jax

    device = jax.devices()[0]
    return {
        "date": datetime.date.today().isoformat(),
        "device": f"{device.platform} | {device.device_kind}",
        "jax": jax.__version__,
        "python": platform.python_version(),
    }


def parse_xla_options(items: list[str]) -> dict:
    """``--xla-option KEY=VALUE`` items as rlq's ``compiler_options``: values read as YAML scalars
    (XLA wants ``true`` as a boolean, not the string)."""
    import yaml

    pairs = (item.split("=", 1) for item in items)
    return {key: yaml.safe_load(value) for key, value in pairs}


def write_report(benchmark: str, results: list[dict], out: Path | None) -> None:
    """The JSON report: benchmark name, date, device and result rows (written only with ``out``)."""
    if out is None:
        return
    report = {
        "benchmark": benchmark,
        "date": datetime.date.today().isoformat(),
        "device": device_name(),
        "results": results,
    }
    out.write_text(json.dumps(report, indent=2))


def device_trace_summary(run: Callable[[], Any], top: int = 12) -> dict:
    """Per device stream, for one call of ``run`` (under jax's profiler): the number of kernels and
    copies, the time the stream was busy and the span from its first to its last event (µs), and
    the ``top`` ops by busy time as [name, µs, count]; the ``top`` busiest streams only. Under
    ``CONCURRENT`` command-buffer scheduling a program's kernels spread over many streams, so the
    entry ``ALL_STREAMS`` sums them all and adds the time at least one stream was busy
    (``union_busy_us``). Empty on a CPU (no device streams)."""
    import jax

    with tempfile.TemporaryDirectory() as tmp:
        jax.profiler.start_trace(tmp, create_perfetto_trace=True)
        jax.block_until_ready(run())
        jax.profiler.stop_trace()
        trace = json.load(gzip.open(next(Path(tmp).rglob("*.json.gz"))))
    events = trace["traceEvents"] if isinstance(trace, dict) else trace
    meta = [e for e in events if e.get("ph") == "M"]
    process = {e["pid"]: e["args"]["name"] for e in meta if e["name"] == "process_name"}
    thread = {(e["pid"], e["tid"]): e["args"]["name"] for e in meta if e["name"] == "thread_name"}
    streams: dict[str, list[dict]] = collections.defaultdict(list)
    for event in events:
        if event.get("ph") == "X" and process.get(event["pid"], "").startswith("/device:"):
            streams[f"{process[event['pid']]} | {thread.get((event['pid'], event['tid']), event['tid'])}"].append(event)
    if not streams:
        return {}
    summary = {name: _stream_summary(evs, top) for name, evs in streams.items()}
    busiest = sorted(summary, key=lambda name: summary[name]["busy_us"], reverse=True)[:top]
    merged = _stream_summary([e for evs in streams.values() for e in evs], top)
    merged["union_busy_us"] = round(_union_length(streams.values()))
    return {ALL_STREAMS: merged, **{name: summary[name] for name in busiest}}


#: key of device_trace_summary's entry for all device streams together
ALL_STREAMS = "all device streams"


def _stream_summary(events: list[dict], top: int) -> dict:
    busy = collections.Counter()
    count = collections.Counter()
    for event in events:
        busy[event["name"][:80]] += event.get("dur", 0)
        count[event["name"][:80]] += 1
    return {
        "events": len(events),
        "busy_us": round(sum(busy.values())),
        "span_us": round(max(e["ts"] + e.get("dur", 0) for e in events) - min(e["ts"] for e in events)),
        "top": [[name, round(us), count[name]] for name, us in busy.most_common(top)],
    }


def _union_length(streams) -> float:
    """Microseconds during which at least one of the events (of any stream) ran."""
    spans = sorted((e["ts"], e["ts"] + e.get("dur", 0)) for evs in streams for e in evs)
    total, end = 0.0, float("-inf")
    for start, stop in spans:
        if stop > end:
            total += stop - max(start, end)
            end = stop
    return total
