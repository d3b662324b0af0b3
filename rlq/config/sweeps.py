"""The jobs of a sweep (``algo=dqn,ppo seed=0,1``), read with Hydra's override parser and basic sweeper."""

from __future__ import annotations

from rlq.config.compose import explain_hydra_error
from rlq.errors import ConfigError


def _interval_ends(item: str) -> str:
    """An ``interval(a,b)`` sweep (Optuna's, any tag) as the choice of its two ends, the values to check; others as given."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.core.override_parser.types import IntervalSweep

    try:
        (override,) = OverridesParser.create().parse_overrides([item])
    except Exception:
        return item  # sweep_jobs reports it
    value = override.value()
    if not isinstance(value, IntervalSweep):
        return item
    return f"{override.get_key_element()}={value.start!r},{value.end!r}"


def sweep_jobs(overrides: list[str]) -> list[list[str]]:
    """The override list of every job of a sweep (``algo=dqn,ppo seed=0,1``: 4 jobs), in
    Hydra's basic sweeper's order. An ``interval(a,b)`` of a sampling sweeper (Optuna) stands
    for jobs at both of its ends."""
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        parsed = OverridesParser.create().parse_overrides([_interval_ends(o) for o in overrides])
    except Exception as err:
        raise ConfigError(explain_hydra_error(err)) from None
    (batch,) = BasicSweeper.split_arguments(parsed, max_batch_size=None)
    return [list(job) for job in batch]


def swept_keys(overrides: list[str]) -> set[str]:
    """The keys a sweep varies (``seed=0,1``: seed), as Hydra's parser reads them (``sweep_jobs`` parsed them first)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parsed = OverridesParser.create().parse_overrides(overrides)
    return {o.key_or_group for o in parsed if o.is_sweep_override()}
