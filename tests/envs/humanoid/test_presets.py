"""The humanoid preset (rlq/conf/experiment/humanoid_ppo.yaml): its XLA options reach the run, and a CPU run
of it (tests, a laptop) compiles with them too, so the CPU's XLA must take them."""

from __future__ import annotations

from tests.conftest import preset_options


def test_preset_schedules_graphs_concurrently_and_takes_cublas_for_its_layers() -> None:
    """Concurrent graphs: +10 % steady env steps/s (H100). cuBLAS: a cold process about 8 s shorter (H100, H200)."""
    assert preset_options("humanoid_ppo") == {
        "xla_gpu_command_buffer_scheduling_mode": "CONCURRENT",
        "xla_gpu_enable_triton_gemm": False,
    }
