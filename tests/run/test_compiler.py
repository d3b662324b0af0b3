"""XLA compiler options from the run config (rlq.run.compiler)."""

import jax
import jax.numpy as jnp
import pytest
from omegaconf import OmegaConf

from rlq.run.compiler import check_options, compile_with, options_from_config

SCHEDULING = "xla_gpu_command_buffer_scheduling_mode"


def test_options_from_config():
    assert options_from_config(OmegaConf.create({"compiler_options": None})) == {}
    cfg = OmegaConf.create({"compiler_options": {SCHEDULING: "CONCURRENT", "xla_gpu_autotune_level": 2}})
    assert options_from_config(cfg) == {SCHEDULING: "CONCURRENT", "xla_gpu_autotune_level": 2}


def test_nested_option_value_is_refused():
    with pytest.raises(ValueError, match="compiler_options.bad must be a string, number or boolean"):
        options_from_config(OmegaConf.create({"compiler_options": {"bad": [1, 2]}}))


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
