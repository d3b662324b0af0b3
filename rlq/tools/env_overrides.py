"""The ``env.<key>=<value>`` overrides of `rlq eval` and `rlq render`, read and checked as `rlq train` reads and
checks its own."""

from __future__ import annotations

from rlq.config.recorded import env_overridden
from rlq.config.spec import RunSpec
from rlq.errors import ConfigError


def with_env_overrides(spec: RunSpec, overrides: list[str]) -> RunSpec:
    """``spec`` with the ``env.<key>=<value>`` overrides of `rlq eval` and `rlq render`, read and checked
    as `rlq train` reads and checks its own: the key must be one of the env's, the value keeps its
    default's type (rlq.config.recorded.env_overridden) and lies in its range (rlq.run.checks.constraints).
    Raises ConfigError or UsageError."""
    from rlq.run.checks.constraints import problems

    out = env_overridden(spec, overrides)
    problem = problems(out)
    if problem:
        raise ConfigError(problem)
    return out
