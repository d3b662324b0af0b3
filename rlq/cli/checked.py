"""`rlq train`'s overrides checked before anything runs: resolved into a RunSpec (rlq.config), then what the run
needs of this machine (JAX kept off the GPU, the distributed runtime started) and the checks that build its env."""

from __future__ import annotations

from rlq.config import RunSpec, resolve
from rlq.config.ignored import check_ignored, given_keys
from rlq.config.sweeps import sweep_jobs, swept_keys
from rlq.config.tuned import check_supported
from rlq.errors import ConfigError, UsageError
from rlq.run.checks.validate import check_output_dir, check_run_config


def check_overrides(overrides: list[str], multirun: bool = False) -> list[str]:
    """Compose and validate the overrides of `rlq train` (one job); raises ConfigError or UsageError.

    Returns the overrides with integer keys written in float notation (``budget.env_steps=1e6``)
    rewritten as integers. The output directory (``hydra.run.dir``, with ``multirun``
    ``hydra.sweep.dir``) must be creatable.
    """
    return list(checked_run(overrides, multirun).overrides)


def checked_run(overrides: list[str], multirun: bool = False) -> RunSpec:
    """The RunSpec of ``overrides``, checked as ``check_overrides`` checks them, with JAX kept to the CPU where the
    run asks (``platform=cpu``) and, for a single run, the distributed runtime started."""
    spec = resolve(overrides, multirun)
    check_output_dir(spec.outputs.dir, spec.outputs.dir_key)
    if spec.devices.platform == "cpu":
        from rlq.run.programs.devices import keep_to_the_cpu

        keep_to_the_cpu()
    from rlq.run.programs.distributed import settings, start

    if multirun and settings(spec.devices.distributed).enabled:
        raise ConfigError("distributed: a sweep's jobs run in one process each; set distributed.enabled=false")
    if not multirun:
        start(spec.devices.distributed)  # before anything starts JAX's backends (check_run_config lays out the devices)
    check_supported(spec.values)
    check_run_config(spec)
    # after the ranges and the algorithms' own checks: a bad value is named as such first
    check_ignored(spec.config, given_keys(spec.overrides))
    return spec


def check_sweep(overrides: list[str]) -> None:
    """Validate every job of `rlq train -m` before the first starts; the error names the job."""
    for item in overrides:
        if "=" not in item:
            raise UsageError(f"'{item}' is not an override; write key=value (e.g. algo=ppo,dqn)")
    jobs = sweep_jobs(overrides)
    varied = swept_keys(overrides)

    def swept(job: list[str]) -> str:
        return " ".join(o for o in job if o.split("=", 1)[0].lstrip("+~") in varied) or "no sweep"

    seen: dict[tuple[str, ...], int] = {}
    for number, job in enumerate(jobs):
        same = seen.setdefault(tuple(sorted(job)), number)
        if same != number:
            raise UsageError(
                f"jobs {same} and {number} of {len(jobs)} are the same run ({swept(job)}), which would share one "
                "directory: give each value once"
            )
    for number, job in enumerate(jobs):
        try:
            check_overrides(job, multirun=True)
        except (ConfigError, UsageError) as err:
            raise type(err)(f"job {number} of {len(jobs)} ({swept(job)}): {err}") from None
