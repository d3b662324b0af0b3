"""JAX's persistent compilation cache (config key ``compile_cache``), on by default.

A program compiled once is read back from disk by later runs of the same program on the same
device and jax version, instead of being compiled again (tens of seconds for the MJX programs).
JAX caches the programs that take at least ``jax_persistent_cache_min_compile_time_secs`` (1 s by
default; the environment variable ``JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS`` changes it) to
compile. The cache is set once per run, before anything is compiled.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
from jax.experimental.compilation_cache import compilation_cache

#: ``compile_cache`` value for the user's cache dir
USER = "user"


def cache_dir(value: Any, environ: Mapping[str, str] = os.environ) -> Path | None:
    """Where ``compile_cache=<value>`` keeps compiled programs: ``user`` is ``$XDG_CACHE_HOME/rlq/jax``
    (else ``~/.cache/rlq/jax``), a path is that directory, null or false is no cache."""
    if value is None or value is False or value == "":
        return None
    if value == USER:
        base = environ.get("XDG_CACHE_HOME") or str(Path(environ.get("HOME") or Path.home()) / ".cache")
        return Path(base) / "rlq" / "jax"
    return Path(str(value)).expanduser()


def enable(value: Any) -> Path | None:
    """Point JAX's persistent cache at ``cache_dir(value)`` (or switch it off); returns the dir."""
    path = cache_dir(value)
    wanted = (path is not None, str(path) if path else None)
    current = (jax.config.values["jax_enable_compilation_cache"], jax.config.values["jax_compilation_cache_dir"])
    if path is None and not current[0]:
        return None
    if wanted != current:
        jax.config.update("jax_enable_compilation_cache", path is not None)
        if path is not None:
            path.mkdir(parents=True, exist_ok=True)
            jax.config.update("jax_compilation_cache_dir", str(path))
        compilation_cache.reset_cache()  # the cache reads its settings once: a changed dir needs a reset
    return path
