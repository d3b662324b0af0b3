"""``key=value`` arguments of `rlq eval`, `rlq render`, `rlq export` and `rlq resume`, and their shared lines."""

from __future__ import annotations

import sys
from pathlib import Path

from rlq.errors import UsageError

EVAL_KEYS = {"run", "env", "episodes", "seed", "checkpoint"}
EVAL_USAGE = (
    "usage: rlq eval run=<run dir> [checkpoint=<env steps>|final] [env=NAME] [episodes=N] [seed=S] [env.<key>=<value>]"
)


def parse_args(
    args: list[str], allowed: set[str] = EVAL_KEYS, usage: str = EVAL_USAGE
) -> tuple[dict[str, str], list[str]]:
    """Split ``key=value`` arguments of `rlq eval`/`rlq render` into options and env overrides."""
    options, env_overrides = {}, []
    for arg in args:
        key, sep, value = arg.partition("=")
        if not sep:
            raise UsageError(f"'{arg}' is not key=value; {usage}")
        if not value:
            raise UsageError(f"{key}= is empty (an unset shell variable?); give a value: {usage}")
        if key.startswith("env."):
            env_overrides.append(arg)
        elif key in allowed:
            options[key] = value
        else:
            raise UsageError(f"unknown option '{key}'; {usage}")
    if "run" not in options:
        raise UsageError(f"needs run=<run dir> (a directory written by `rlq train`); {usage}")
    return options, env_overrides


def int_option(options: dict[str, str], key: str, default: int) -> int:
    """``options[key]`` as an integer, ``default`` when not given; a UsageError naming the key and value
    when it is not one (``default`` is the example the message gives)."""
    value = options.get(key)
    if value is None:
        return default
    try:
        return int(value)
    except ValueError:
        raise UsageError(f"{key}={value} is not an integer; give a whole number, e.g. {key}={default}") from None


#: the seeds JAX's PRNG takes (as `rlq train`'s ``seed``, rlq.lib.settings.SEED)
SEED_MAX = 2**32 - 1


def seed_option(options: dict[str, str], key: str = "seed") -> int:
    """``options[key]`` as a PRNG seed (default 0); a UsageError when it is not an integer in [0, 2^32 - 1]."""
    seed = int_option(options, key, 0)
    if not 0 <= seed <= SEED_MAX:
        raise UsageError(f"{key} must be an integer in [0, {SEED_MAX}], got {seed}")
    return seed


def warn_skipped(skipped: list[str], path: Path) -> None:
    """One warning line per newer checkpoint a reader skipped as damaged (``checkpoint.newest_intact``), naming the
    one it used instead."""
    for problem in skipped:
        print(f"rlq: warning: {problem}; using {path} instead", file=sys.stderr, flush=True)
