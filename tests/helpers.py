"""Helpers the tests share: compose a run config like the CLI does, and run `rlq` as a user would.
(Fixtures live in conftest.py.)"""

from __future__ import annotations

import functools
import importlib
import os
import subprocess
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parent.parent


def quick_sample(cases: Sequence[Any], every: int, single: bool = False) -> list[Any]:
    """``cases`` for ``pytest.mark.parametrize`` with every ``every``-th of them (the first, then each ``every``
    along) in the quick tier and the others marked slow: a check repeated over many cases keeps a spread of them in
    `pytest` and runs all of them in the full suite (CI's `pytest -m "slow or not slow"`). ``single``: the test takes
    one argument, so a tuple case is one value, not the arguments' values."""
    if every < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    parameter_set = type(pytest.param(None))  # what pytest.param makes: a case with its own marks and id
    sampled = []
    for index, case in enumerate(cases):
        if index % every == 0:
            sampled.append(case)
        elif isinstance(case, parameter_set):
            sampled.append(pytest.param(*case.values, marks=[*case.marks, pytest.mark.slow], id=case.id))
        else:
            values = case if isinstance(case, tuple) and not single else (case,)
            sampled.append(pytest.param(*values, marks=pytest.mark.slow))
    return sampled


@contextmanager
def script_module(name: str) -> Iterator:
    """A module of scripts/ imported as the scripts import each other (with scripts/ on the path)."""
    sys.path.insert(0, str(REPO / "scripts"))
    try:
        yield importlib.import_module(name)
    finally:
        sys.path.remove(str(REPO / "scripts"))


@functools.cache
def fast_compile() -> dict:
    """Compile options for a test's own program whose compile dwarfs its run, for ``jax.jit(compiler_options=...)``:
    LLVM's optimisations and XLA's fusion emitters off (the LunarLander step: 13 s instead of 46 s on a CPU), those
    the installed jaxlib knows. The numbers may differ from the default compile's in the last bits: compare programs
    compiled alike."""
    from rlq.run.programs.compiler import known_to_cpu_xla

    options = {"xla_backend_optimization_level": 0, "xla_llvm_disable_expensive_passes": True}
    return known_to_cpu_xla({**options, "xla_cpu_use_fusion_emitters": False})


@functools.cache
def run_emitters() -> dict:
    """Compile options for a test's own programs whose bits it compares with another program's, for
    ``jax.jit(compiler_options=...)``: XLA's default CPU fusion emitters, which a run's chunk compiles with and the
    quick tier's XLA_FLAGS turn off (tests/conftest.py); two programs compiled without them may differ in the last
    bits where the default emitters agree. Empty where the installed jaxlib has no such option."""
    from rlq.run.programs.compiler import known_to_cpu_xla

    return known_to_cpu_xla({"xla_cpu_use_fusion_emitters": True})


def leaf_types(tree) -> list[tuple]:
    """Each leaf's (dtype, shape, weak type): a jitted function called on a tree of other leaf types compiles again."""
    import jax

    return [(x.dtype, x.shape, x.weak_type) for x in jax.tree.leaves(tree)]


def compose_config(*overrides: str):
    """The run config `rlq train <overrides>` would use (no run directory is made): a copy of its own, which
    the test may change. Hydra composes each set of overrides once per test process (about 0.1 s of CPU
    each, and many tests compose the same few); the tests of composition itself call rlq.config.compose."""
    import copy

    return copy.deepcopy(_composed(overrides))


@functools.cache
def _composed(overrides: tuple[str, ...]):
    from rlq.config.compose import compose

    return compose(list(overrides))


def preset_options(preset: str) -> dict:
    """The XLA options experiment=``preset`` compiles with. A CPU run of a GPU preset (tests, a laptop)
    compiles with them too, so on a CPU this also asserts that XLA takes them, as a run checks them."""
    import jax

    from rlq.run.programs.compiler import check_options, options_from_config

    options = options_from_config(compose_config(f"experiment={preset}"))
    if jax.default_backend() == "cpu":
        assert check_options(options) is None
    return options


def train_run(tmp_path: Path, *overrides: str):
    """Train in-process with the quiet logger; returns rlq.run.result.RunResult."""
    from rlq.run.train import train

    cfg = compose_config("logger=quiet", *overrides)
    return train(cfg, tmp_path)


def run_cli(
    *args: str, cwd: Path, timeout: float = 600, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess:
    """Run the installed `rlq` command in ``cwd`` with W&B offline and no network (``env``: more variables)."""
    env = {**os.environ, "WANDB_SILENT": "true", "WANDB_MODE": "offline", **(env or {})}
    return subprocess.run(
        [sys.executable, "-m", "rlq.cli", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout
    )


def run_cli_in_process(*args: str, cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """`rlq <args>` as ``run_cli`` runs it, but in this process (``rlq.cli.main.main``): no cold start of Python
    and JAX. Its stdout and stderr are captured, its exit status is SystemExit's code (0 when main returns).
    For what one command writes and prints; the entry point itself keeps its subprocess tests (``run_cli``)."""
    import contextlib
    import io

    from hydra.core.singleton import Singleton

    from rlq.cli.main import main

    variables = {"WANDB_SILENT": "true", "WANDB_MODE": "offline", **(env or {})}
    saved_env = {name: os.environ.get(name) for name in variables}
    saved_cwd = os.getcwd()
    saved_streams = sys.__stdout__, sys.__stderr__
    out, err = io.StringIO(), io.StringIO()
    code = 0
    # Hydra's singletons (the job's HydraConfig: the overrides the runner reads) go back to what they were, so a
    # later in-process run or library call does not see this command's job; the resolvers rlq registered stay
    hydra_instances = Singleton.get_state()["instances"]
    try:
        os.environ.update(variables)
        os.chdir(cwd)
        # Hydra's logging set-up closes the handlers there are; absl's closes its stream unless that is one of
        # sys.stdout, sys.stderr, sys.__stdout__ and sys.__stderr__: the streams before the redirection stay there
        sys.__stdout__, sys.__stderr__ = sys.stdout, sys.stderr  # type: ignore[misc]
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main(list(args))
            except SystemExit as exit_info:
                code = exit_info.code if isinstance(exit_info.code, int) else int(exit_info.code is not None)
    finally:
        Singleton.set_state({**Singleton.get_state(), "instances": hydra_instances})
        sys.__stdout__, sys.__stderr__ = saved_streams  # type: ignore[misc]
        os.chdir(saved_cwd)
        for name, value in saved_env.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
    return subprocess.CompletedProcess(["rlq", *args], code, out.getvalue(), err.getvalue())


#: how a bad-input case fails when its input was not refused (``refuse_to_train``)
NOT_REFUSED = "this input was expected to be refused but"


def refuse_to_train(monkeypatch, jobs: bool = False) -> None:
    """Make every way a command could go on past its checks fail the test at once, before anything compiles: the
    launch of `rlq train`'s job (``run_composed``, ``run_hydra``; ``jobs=True`` lets it start, for a refusal the job
    itself makes), the training entry (``rlq.run.train.train``: train, resume, each sweep job), ``build`` (the gateway to every compiled
    program of eval, render and export), a distributed join and ``os._exit`` (a hung join or a stop would end the
    test process, and the pytest worker with it). A bad-input case whose refusal stopped applying then fails with
    one clear line instead of training a real run in the test process. ``pytest.fail`` raises a BaseException, which
    neither rlq's nor Hydra's ``except Exception`` turns into an exit code."""
    import jax
    import pytest

    import rlq.cli.train
    import rlq.run.programs.build
    import rlq.run.train

    def stop(what: str):
        def refused(*args, **kwargs):
            pytest.fail(f"{NOT_REFUSED} {what}", pytrace=False)

        return refused

    if not jobs:  # Hydra's logging set-up, run before the job, would also close the streams pytest captures
        monkeypatch.setattr(rlq.cli.train, "run_composed", stop("training started (rlq train launched its job)"))
        monkeypatch.setattr(rlq.cli.train, "run_hydra", stop("training started (rlq train handed its jobs to Hydra)"))
    real = {"train": rlq.run.train.train, "build": rlq.run.programs.build.build}
    stand_ins = {"train": stop("training started"), "build": stop("it reached build(): programs would be compiled")}
    for module in [m for name, m in list(sys.modules.items()) if name == "rlq" or name.startswith("rlq.")]:
        for name, function in real.items():
            if getattr(module, name, None) is function:
                monkeypatch.setattr(module, name, stand_ins[name])
    monkeypatch.setattr(jax.distributed, "initialize", stop("it began a distributed join"))
    monkeypatch.setattr(os, "_exit", lambda code: pytest.fail(f"{NOT_REFUSED} it ended the process (os._exit({code}))"))


def run_forced_devices_module(module: str, out: Path, timeout: float) -> None:
    """Run ``python -m <module> <out>`` from the repo without the parent's XLA_FLAGS: the module forces its
    own CPU device count before JAX starts, which a test process (already started) cannot do."""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    proc = subprocess.run(
        [sys.executable, "-m", module, str(out)], cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout
    )
    assert proc.returncode == 0, proc.stderr[-3000:]


def run_dirs(workdir: Path) -> list[Path]:
    """The run directories `rlq train` left under ``workdir``/outputs (Hydra's default layout)."""
    return sorted(p for p in (workdir / "outputs").glob("*/*") if p.is_dir()) if (workdir / "outputs").exists() else []


def sbatch_runner(
    script: Path, tmp_path: Path, checkpoint_every: int, job_id: str, commands: dict[str, str] | None = None, **env: str
) -> Callable[..., subprocess.CompletedProcess]:
    """A function that runs a SLURM batch ``script`` as a plain bash script in ``tmp_path``, its run in
    ``tmp_path/run``, with ``rlq`` (and each of ``commands``: name -> script text) first on the PATH."""
    shim = tmp_path / "bin"
    shim.mkdir()
    stand_ins = {"rlq": f'#!/bin/sh\nexec "{sys.executable}" -m rlq.cli "$@"\n', **(commands or {})}
    for name, text in stand_ins.items():
        (shim / name).write_text(text)
        (shim / name).chmod(0o755)
    variables = {
        **os.environ,
        "PATH": f"{shim}:{os.environ['PATH']}",
        "RUN_DIR": str(tmp_path / "run"),
        "CHECKPOINT_EVERY": str(checkpoint_every),
        "WANDB_MODE": "disabled",
        "SLURM_JOB_ID": job_id,
        **env,
    }

    def sbatch(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            ["bash", str(script), *args], cwd=tmp_path, env=variables, capture_output=True, text=True, timeout=600
        )

    return sbatch


def stopped_at(run_dir: Path, tmp_path: Path, which: int) -> Path:
    """A copy of the finished ``run_dir`` as if stopped at its step checkpoint ``which`` (0: the earliest,
    -1: the latest): the final checkpoint and every other step checkpoint removed."""
    import shutil

    from rlq.store import checkpoint

    stopped = tmp_path / "stopped"
    shutil.copytree(run_dir, stopped)
    for path in (stopped / "checkpoints").glob("final.*"):
        path.unlink()
    kept = sorted((stopped / "checkpoints").glob("step_*.msgpack"), key=checkpoint.env_steps)[which]
    for path in (stopped / "checkpoints").glob("step_*"):
        if path.stem != kept.stem:
            path.unlink()
    return stopped


def updates_that_only_improve_elites(cfg, updates: int):
    """MAP-Elites built from ``cfg`` and run for ``updates`` iterations, asserting after each that no
    elite got worse; returns the final state and metrics."""
    import jax
    import numpy as np

    from rlq.algos import make_algo
    from rlq.run.programs.env_stack import make_env

    algo = make_algo(cfg.algo, make_env(cfg), budget_env_steps=10**9)
    state = jax.jit(lambda k: algo.init(k, algo.hyperparams))(jax.random.PRNGKey(0))
    update = jax.jit(lambda s: algo.update(s, algo.hyperparams))
    previous = np.asarray(state.archive.fitness)
    metrics = {}
    for _ in range(updates):
        state, metrics = update(state)
        fitness = np.asarray(state.archive.fitness)
        assert (fitness >= previous).all()
        previous = fitness
    return state, metrics
