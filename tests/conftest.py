"""Test fixtures, and the test session's environment: JAX's compilation cache and MuJoCo Warp's kernel cache
in temporary directories; the slowest test modules first. Helpers shared by the tests are in tests/helpers.py."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

import pytest


def session_dir(variable: str, prefix: str) -> str:
    """The directory that environment variable ``variable`` names: a temporary one, made (and removed at exit) by
    the process that starts the test session unless it is set; xdist's workers inherit the name."""
    if variable not in os.environ:
        os.environ[variable] = tempfile.mkdtemp(prefix=prefix)
        atexit.register(shutil.rmtree, os.environ[variable], ignore_errors=True)
    return os.environ[variable]


# Runs of the test suite (in-process and `rlq` subprocesses) keep JAX's compilation cache and rlq's program cache
# (compile_cache=user) in a temporary directory, not in the user's ~/.cache: one directory for the session, made by
# the process that starts it; xdist's workers inherit its name (RLQ_TEST_CACHE_HOME), so a program that one worker
# compiled loads in the other, as on a node whose jobs share the cache (rlq's program cache writes each entry
# atomically; JAX's reads an entry still being written as a miss, with a warning, and compiles). Tests of the caches
# themselves give their runs a cache of their own.
os.environ["XDG_CACHE_HOME"] = session_dir("RLQ_TEST_CACHE_HOME", "rlq-test-cache-")
# JAX's persistent cache takes every program the tests compile, not only their rlq runs': the directory that
# compile_cache=user names, so a run in a test neither moves nor resets it (rlq.run.programs.compile_cache.cache_dir
# says which; it imports JAX, which must start after this line: spelt out here, tests/run/test_compile_cache.py checks
# that the two agree). A program that several tests (or both workers) compile is compiled once and loaded after, as
# the same executable: the same numbers (the second of two tests of tests/run/test_programs.py that compile one PPO
# chunk took 28 s without the cache, 14 s with it).
os.environ["JAX_COMPILATION_CACHE_DIR"] = os.path.join(os.environ["XDG_CACHE_HOME"], "rlq", "jax")
os.makedirs(os.environ["JAX_COMPILATION_CACHE_DIR"], exist_ok=True)

# MuJoCo Warp's kernels (compiled by warp-lang on the CPU: about 25 s for the humanoid's) are cached in one
# directory for the whole session, xdist's workers included: they inherit it from the controller, which made it.
# Warp builds each module in a directory of its own and renames it into place, so the workers may share it.
session_dir("WARP_CACHE_PATH", "rlq-test-warp-")

# The quick tier (`pytest`: -m "not slow") compiles its programs with LLVM's optimisations off: its tests run tiny
# budgets, so compiling is most of their time (12% less CPU on tests/lib and the DQN and MAP-Elites tests), and XLA
# computes the same numbers (tests/run/test_compiler.py). rlq's own programs keep their levels (rlq.run.programs.
# compiling gives each its own), and the full suite (CI) compiles as a user's run does. XLA_FLAGS set by hand win.
# XLA's older CPU fusion emitters too (as rlq's init and evaluation programs compile on a CPU): backend compiles take
# about half as long (a small DQN's update 0.84 s instead of 1.9 s; the quick tier 386 CPU s instead of 481). Two
# programs compiled so may differ in the last bits where the default emitters agree: a test that compares the bits
# of two programs compiles them as a run's chunk is compiled (tests/helpers.py run_emitters). Only where the
# installed jaxlib has the option (0.10, not 0.11: an unknown flag in XLA_FLAGS would stop XLA).
QUICK_TIER_XLA_FLAGS = "--xla_backend_optimization_level=0"
FUSION_EMITTERS_OFF = "--xla_cpu_use_fusion_emitters=false"


def _quick_tier_xla_flags() -> str:
    """QUICK_TIER_XLA_FLAGS, with the older fusion emitters where the installed jaxlib has the option (0.10; 0.11 has
    not): read from its version, since JAX must not start before XLA_FLAGS is set."""
    from importlib.metadata import version

    major, minor = (int(part) for part in version("jaxlib").split(".")[:2])
    return f"{QUICK_TIER_XLA_FLAGS} {FUSION_EMITTERS_OFF}" if (major, minor) <= (0, 10) else QUICK_TIER_XLA_FLAGS


def pytest_configure(config: pytest.Config) -> None:
    """In the quick tier, XLA's fast compile (QUICK_TIER_XLA_FLAGS) unless XLA_FLAGS is set; before JAX starts."""
    if config.getoption("markexpr") == "not slow" and "XLA_FLAGS" not in os.environ:
        os.environ["XLA_FLAGS"] = _quick_tier_xla_flags()


# The test modules that took longest in the full suite on 2 slow cores (2026-12-06: 80 min, the 120 longest tests
# summed per module; about 40 s or more each), slowest first; those the quick tier (`pytest`, which deselects `slow`
# tests) runs are at the end. xdist (`--dist loadfile --no-loadscope-reorder`, pyproject.toml) hands each worker whole
# modules in the collection's order, so these start first and the many short modules fill the end: no long module
# starts last while the other worker idles (longest-first scheduling).
SLOWEST_MODULES = (
    "tests/envs/lunar/test_presets.py",  # trains lunar_ppo on 3 seeds (~460 s; 742 s on slow cores), Box2D scoring
    "tests/envs/lunar/test_env.py",  # the unrolled-sweep and lockstep-reset programs (~600 s on slow cores)
    "tests/run/test_programs.py",  # two chunks compiled per algorithm
    "tests/run/test_distributed.py",
    "tests/envs/brittle_star/test_warp.py",
    "tests/algos/test_map_elites_brittle_star.py",
    "tests/envs/humanoid/test_env.py",
    "tests/cli/test_readme_examples.py",  # README's examples, in the test process
    "tests/envs/humanoid/test_mjx_unroll.py",
    "tests/envs/brittle_star/test_presets.py",
    "tests/algos/test_dqn.py",
    "tests/run/test_devices.py",
    "tests/envs/humanoid/test_mjx_vectorized.py",
    "tests/run/test_program_cache.py",
    "tests/run/test_per_shard_minibatches.py",
    "tests/run/test_make_train.py",
    "tests/run/test_train.py",
    "tests/envs/humanoid/test_mjx_patches.py",
    "tests/algos/test_decentralised.py",
    "tests/algos/test_ppo.py",
    "tests/controllers/test_cpg_cli.py",
    "tests/controllers/test_cpg_brittle_star.py",
    "tests/cli/test_requeue.py",
    "tests/envs/lunar/test_fused_positions.py",
    "tests/cli/test_slurm.py",
    "tests/algos/test_ppo_continuous.py",
    "tests/envs/mujoco/test_render_mujoco.py",
    "tests/envs/lunar/test_fused_sweeps.py",
    # the quick tier's longest (about 15-45 s each on one of two busy cores): those without a `slow` test would
    # otherwise go out by their number of tests, near the end
    "tests/run/test_tuned.py",  # composes and checks the env x algo pairs (every one on both machines: full suite)
    "tests/cli/test_bad_inputs.py",
    "tests/algos/test_map_elites_champion.py",
    "tests/run/test_pinned_metrics.py",
    "tests/run/test_build.py",
)


@pytest.hookimpl(trylast=True)  # after `-m` has deselected: the order of the tier that runs
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Order the modules slowest first: those of SLOWEST_MODULES, then those holding a `slow` test, then
    the rest by their number of tests (xdist's own reordering); a module's tests stay together, in order."""
    module = {id(item): item.nodeid.split("::", 1)[0] for item in items}
    count: dict[str, int] = {}
    slow: set[str] = set()
    for item in items:
        count[module[id(item)]] = count.get(module[id(item)], 0) + 1
        if item.get_closest_marker("slow"):
            slow.add(module[id(item)])
    rank = {name: i for i, name in enumerate(SLOWEST_MODULES)}

    def key(item: pytest.Item) -> tuple[int, int, int]:
        name = module[id(item)]
        return (rank.get(name, len(rank)), name not in slow, -count[name])

    items.sort(key=key)  # stable: the modules' tests keep their order


@pytest.fixture
def workdir(tmp_path: Path) -> Path:
    """An empty directory to run the CLI in (its outputs/ lands here)."""
    return tmp_path
