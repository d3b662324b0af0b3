"""`rlq train`'s overrides resolved into a RunSpec: composed, their types and added keys checked, integer keys
given in float notation rewritten. Nothing here touches a device or builds an env (rlq/cli/checked.py does what
a run needs of the machine, and the checks that build one)."""

from __future__ import annotations

import copy

from omegaconf import OmegaConf, open_dict

from rlq.config.choices import check_choices
from rlq.config.compose import (
    check_added_keys,
    check_group_values,
    check_interpolations,
    compose,
    compose_typed,
    explain_hydra_error,
    group_override,
)
from rlq.config.spec import RunSpec, run_spec
from rlq.config.store import declared_run_key
from rlq.config.types import check_types, given_values
from rlq.errors import ConfigError, UsageError


def check_written(overrides: list[str]) -> None:
    """Each override is ``key=value``, a group's choice or a group's deletion with its option (``~tuned=lunar_dqn``):
    what `rlq train` refuses, and its ``--cfg`` the same way (rlq/cli/train.py), with the line that names the fix. A
    key's deletion (``~seed=0``) and a deletion without ``=`` (``~tuned``) are refused."""
    for item in overrides:
        if "=" not in item:
            raise UsageError(f"'{item}' is not an override; write key=value (e.g. algo=ppo)")
        if item.startswith("~") and not group_override(item):
            key = item[1:].split("=", 1)[0]
            raise UsageError(f"'{item}': a key cannot be deleted (each has its declared default); write {key}=<value>")


def resolve(overrides: list[str], multirun: bool = False) -> RunSpec:
    """The RunSpec of `rlq train <overrides>` (with ``multirun``: of one job of a sweep, whose directory is
    ``hydra.sweep.dir``); raises ConfigError or UsageError with the line that names the fix."""
    check_written(overrides)
    overrides = [
        f"+{o}" if o.startswith("sweep.") else o for o in overrides
    ]  # its keys are added (rlq/run/programs/members.py)
    check_group_values(overrides)
    check_choices(overrides)
    values = [o for o in overrides if not group_override(o)]
    try:
        mode = "hydra.mode=MULTIRUN" if multirun else "hydra.mode=RUN"
        cfg, typed = compose_typed([*overrides, mode], with_hydra=True)
        # the group choices' own config, which the checks of given values and added keys compare with: a second
        # compose, needed only where the command gives a value (group choices alone compose it the first time)
        defaults = compose([o for o in overrides if group_override(o)]) if values else None
    except Exception as err:
        raise ConfigError(explain_hydra_error(err, overrides)) from None
    rewritten = [(given, new) for given, new in zip(overrides, typed, strict=False) if given != new]
    # hydra.main composes each job from the overrides as written: a run key's rlq train writes as the integer first
    # (types.integers_written), a component's is refused
    component = [
        (given, new) for given, new in rewritten if declared_run_key(given.split("=", 1)[0].lstrip("+")) is None
    ]
    if component and multirun:
        (given, new), *_ = component
        raise ConfigError(f"{given}: an integer key; a sweep's jobs take their values as written: {new}")
    overrides = typed[: len(overrides)]
    check_interpolations(cfg)
    out_key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
    try:
        out_dir = OmegaConf.select(cfg, out_key)
    except Exception as err:  # an interpolation in the directory's name that does not resolve
        raise ConfigError(f"{out_key}: {str(err).splitlines()[0]}") from None
    value_keys = [o.split("=", 1)[0].lstrip("+") for o in overrides if not group_override(o)]
    value_keys = [k for k in value_keys if not k.startswith("~")]
    if defaults is not None:
        check_types(defaults, cfg, value_keys, given_values(overrides))
        check_added_keys(defaults, overrides)
    composed = None if rewritten or multirun else copy.deepcopy(cfg)
    choices = dict(cfg.hydra.runtime.choices)
    with open_dict(cfg):
        del cfg["hydra"]
    return run_spec(cfg, overrides, choices, (out_key, "" if out_dir is None else str(out_dir)), composed)
