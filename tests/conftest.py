"""Test fixtures, and the test session's environment: JAX's compilation cache in a temporary directory.
Helpers shared by the tests are in tests/helpers.py."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

import pytest

# Runs of the test suite (in-process and `rlq` subprocesses) keep JAX's compilation cache
# (compile_cache=user) in a temporary directory, not in the user's ~/.cache.
_CACHE_HOME = tempfile.mkdtemp(prefix="rlq-test-cache-")
os.environ["XDG_CACHE_HOME"] = _CACHE_HOME
atexit.register(shutil.rmtree, _CACHE_HOME, ignore_errors=True)


@pytest.fixture
def workdir(tmp_path: Path) -> Path:
    """An empty directory to run the CLI in (its outputs/ lands here)."""
    return tmp_path
