"""The humanoid preset (rlq/conf/experiment/humanoid_ppo.yaml): its XLA options reach the run, and a CPU run
of it (tests, a laptop) compiles with them too, so the CPU's XLA must take them."""

from __future__ import annotations

import jax
import pytest

from rlq.run.compiler import check_options, options_from_config
from tests.conftest import compose_config


def test_preset_schedules_graphs_concurrently_and_takes_cublas_for_its_layers() -> None:
    """Concurrent graphs: +10 % steady env steps/s (H100). cuBLAS: a cold process about 8 s shorter (H100, H200)."""
    options = options_from_config(compose_config("experiment=humanoid_ppo"))
    assert options == {"xla_gpu_command_buffer_scheduling_mode": "CONCURRENT", "xla_gpu_enable_triton_gemm": False}
    if jax.default_backend() != "cpu":
        pytest.skip("checks the CPU's XLA")
    assert check_options(options) is None
