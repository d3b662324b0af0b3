"""XLA compiler options from the run config (rlq.run.programs.compiler)."""

import jax
import jax.numpy as jnp
import pytest

from rlq.run.programs.compiler import check_options, compile_with, known_to_cpu_xla, options_from_config
from tests.helpers import compose_config

SCHEDULING = "xla_gpu_command_buffer_scheduling_mode"


def test_options_from_config():
    cfg = compose_config()
    cfg.compiler_options = None
    assert options_from_config(cfg) == {}
    cfg.compiler_options = {SCHEDULING: "CONCURRENT", "xla_gpu_autotune_level": 2}
    assert options_from_config(cfg) == {SCHEDULING: "CONCURRENT", "xla_gpu_autotune_level": 2}


def test_nested_option_value_is_refused():
    cfg = compose_config()
    cfg.compiler_options = {"bad": [1, 2]}
    with pytest.raises(ValueError, match="compiler_options.bad must be a string, number or boolean"):
        options_from_config(cfg)


def test_xla_names_the_bad_option():
    assert check_options({}) is None
    assert check_options({SCHEDULING: "CONCURRENT"}) is None
    assert "No such compile option" in check_options({"xla_no_such_option": 1})
    assert "'FAST' is not a valid enum value" in check_options({SCHEDULING: "FAST"})


def test_compiled_with_options_computes_the_same():
    lowered = jax.jit(lambda x: jnp.cumsum(jnp.sin(x)) * 2).lower(jnp.arange(5.0))
    plain = compile_with(lowered, {})(jnp.arange(5.0))
    tuned = compile_with(lowered, {SCHEDULING: "CONCURRENT"})(jnp.arange(5.0))
    assert jnp.array_equal(plain, tuned)


def test_run_programs_get_the_users_options_and_the_cpu_s_optimisation_levels(monkeypatch):
    """On a CPU init runs once, so it compiles without LLVM's optimisations and with XLA's older fusion
    emitters (a third of the time), and chunk at LLVM's level 1 (a third less compile, as fast to run);
    every program keeps the user's options."""
    from rlq.run.programs import compiling

    seen = {}

    def record(lowered, options):
        seen[lowered] = dict(options or {})
        return lowered

    monkeypatch.setattr(compiling, "compile_with", record)
    user = {"xla_cpu_enable_fast_math": False}
    compiling.compile_pipelined({"chunk": lambda: "chunk", "init": lambda: "init"}, user)
    on_cpu = jax.default_backend() == "cpu"
    assert seen["chunk"] == ({"xla_backend_optimization_level": 1, **user} if on_cpu else user)
    init = known_to_cpu_xla({"xla_backend_optimization_level": 0, "xla_cpu_use_fusion_emitters": False})
    assert seen["init"] == ({**init, **user} if on_cpu else user)


def test_init_compiled_without_llvm_optimisation_computes_the_same():
    program = jax.jit(lambda k: jax.random.normal(k, (64, 64)) @ jax.random.normal(k, (64, 8)))
    lowered = program.lower(jax.random.PRNGKey(0))
    fast = compile_with(lowered, {"xla_backend_optimization_level": 0})(jax.random.PRNGKey(0))
    assert jnp.allclose(fast, lowered.compile()(jax.random.PRNGKey(0)), atol=1e-5)


def test_the_cpu_options_follow_the_run_s_platform_not_jax_s_default():
    from rlq.run.programs.compiling import program_options

    assert program_options("init", None, "cpu") == known_to_cpu_xla(
        {"xla_backend_optimization_level": 0, "xla_cpu_use_fusion_emitters": False}
    )
    assert program_options("init", {"a": 1}, "gpu") == {"a": 1}
    assert program_options("chunk", None, "cpu") == {"xla_backend_optimization_level": 1}
    assert program_options("chunk", None, "gpu") is None


def test_the_run_s_own_options_win_over_the_cpu_defaults():
    from rlq.run.programs.compiling import program_options

    assert program_options("chunk", {"xla_backend_optimization_level": 2}, "cpu") == {
        "xla_backend_optimization_level": 2
    }
    assert program_options("evaluate", {"a": 1}, "cpu") == {
        **known_to_cpu_xla({"xla_backend_optimization_level": 1, "xla_cpu_use_fusion_emitters": False}),
        "a": 1,
    }


def test_on_a_gpu_the_evaluation_program_compiles_without_autotuning_unless_the_run_says_otherwise():
    from rlq.run.programs.compiling import program_options

    assert program_options("chunk", None, "gpu") is None
    assert program_options("init", {"a": 1}, "gpu") == {"a": 1}
    assert program_options("evaluate", {"a": 1}, "gpu") == {"xla_gpu_autotune_level": 0, "a": 1}
    assert program_options("evaluate", {"xla_gpu_autotune_level": 4}, "gpu") == {"xla_gpu_autotune_level": 4}


@pytest.mark.parametrize("program", ["chunk", "evaluate"])
def test_a_program_compiled_with_the_cpu_options_computes_the_same(program):
    from rlq.run.programs.compiling import CPU_OPTIONS

    lowered = jax.jit(lambda x: jnp.tanh(x @ x.T).sum(axis=1)).lower(jnp.ones((16, 8)))
    x = jax.random.normal(jax.random.PRNGKey(0), (16, 8))
    tuned = compile_with(lowered, known_to_cpu_xla(CPU_OPTIONS[program]))(x)
    assert jnp.allclose(tuned, lowered.compile()(x), atol=1e-6)


def test_options_the_cpu_compiler_does_not_know_are_left_out_and_the_others_kept():
    assert known_to_cpu_xla({"xla_backend_optimization_level": 1, "xla_no_such_option": True}) == {
        "xla_backend_optimization_level": 1
    }
    assert known_to_cpu_xla({"xla_backend_optimization_level": 0}) == {"xla_backend_optimization_level": 0}
    assert known_to_cpu_xla({}) == {}
