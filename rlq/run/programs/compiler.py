"""XLA compiler options for the programs a run compiles (config key ``compiler_options``).

They are given to each compile call rather than through ``XLA_FLAGS``, so they apply to rlq's
programs only and can differ between runs of one process (the benchmarks run brax beside rlq).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any, cast

import jax

from rlq.config.plain import plain
from rlq.config.spec import RunSpec, as_spec

Option = str | bool | int | float


def options_from_config(run: RunSpec | Mapping[str, Any]) -> dict[str, Option]:
    """The run's ``compiler_options`` as a plain dict (empty when null)."""
    options = cast(dict[str, Option], plain(as_spec(run).compilation.compiler_options))
    for name, value in options.items():
        if not isinstance(value, Option):
            raise ValueError(f"compiler_options.{name} must be a string, number or boolean, got {value!r}")
    return options


def check_options(options: Mapping[str, Option]) -> str | None:
    """XLA's own complaint about ``options`` (an unknown name, a bad enum value), or None.

    Compiles a one-operation program, so a typo fails before minutes of tracing an env."""
    if not options:
        return None
    return _check_options(tuple(sorted(options.items())))


@functools.cache
def _check_options(options: tuple[tuple[str, Option], ...], platform: str | None = None) -> str | None:
    """``check_options`` once per process for each set of options (a run's config is checked twice), on
    ``platform``'s first device (None: JAX's default)."""
    try:
        with jax.default_device(jax.devices(platform)[0] if platform else None):
            jax.jit(lambda x: x + 1).lower(1.0).compile(cast(dict[str, Any], dict(options)))
    except Exception as err:  # XLA raises its runtime error type, which jax does not export stably
        first = next((line for line in str(err).splitlines() if line.strip()), type(err).__name__)
        return f"compiler_options: {first.strip()}"
    return None


def compile_with(lowered: jax.stages.Lowered, options: Mapping[str, Option] | None) -> jax.stages.Compiled:
    """``lowered`` compiled with ``options`` (none: XLA's defaults)."""
    return lowered.compile(cast(dict[str, Any], dict(options)) if options else None)


def known_to_cpu_xla(options: Mapping[str, Option]) -> dict[str, Option]:
    """Those of ``options`` that the CPU compiler of the installed jaxlib knows: XLA's debug options come
    and go between releases (``xla_cpu_use_fusion_emitters`` is in jaxlib 0.10, not in 0.11), so rlq's
    own defaults are dropped where unknown rather than failing the run. Checked once per process."""
    return dict(_known_to_cpu_xla(tuple(sorted(options.items()))))


@functools.cache
def _known_to_cpu_xla(options: tuple[tuple[str, Option], ...]) -> tuple[tuple[str, Option], ...]:
    if _check_options(options, "cpu") is None:
        return options
    return tuple(pair for pair in options if _check_options((pair,), "cpu") is None)
