"""The benchmark scripts' own configs compose against the current config schema and hold what they name: a script
that builds its env by hand breaks silently when the schema moves, and one that composes an env's plain command
picks up the tuned recipe's keys."""

from __future__ import annotations

from tests.helpers import script_module


def test_the_lunar_env_benchmark_builds_the_declared_env_with_its_solver_settings() -> None:
    with script_module("bench_lunar_env") as bench:
        env = bench.lunar_env(True, (180, 60), 2).unwrapped
    assert env.continuous is True
    assert (env.solver.velocity_iterations, env.solver.position_iterations, env.solver.unroll) == (180, 60, 2)
    assert env.max_episode_steps == 1000  # the declared time limit, not a tuned recipe's 500


def test_the_brittle_star_benchmark_s_default_is_the_env_s_own_physics() -> None:
    """Its variants are differences from the env's defaults; the directed brittle star's PPO recipe prunes the wall
    contacts, which would make "default" the same as "pruned"."""
    with script_module("bench_brittle_star") as bench:
        default = bench.run_config(bench.VARIANTS["default"], "sector", None)
        pruned = bench.run_config(bench.VARIANTS["pruned"], "sector", None)
    assert default.env.physics.wall_contacts is True
    assert pruned.env.physics.wall_contacts is False
