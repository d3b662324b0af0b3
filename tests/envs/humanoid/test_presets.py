"""The humanoid presets (conf/experiment/humanoid_ppo*.yaml): their XLA options reach the run, and a CPU run
of one (tests, a laptop) compiles with them too, so the CPU's XLA must take them; the fast preset is the
tutorial's recipe at another learning rate and budget."""

from __future__ import annotations

from omegaconf import DictConfig, OmegaConf, open_dict

from rlq.algos.base import updates_for_budget
from rlq.algos.ppo import steps_per_update
from rlq.run.programs.cadences import Cadences, chunk_plan
from tests.helpers import compose_config, preset_options


def test_preset_schedules_graphs_concurrently_and_takes_cublas_for_its_layers() -> None:
    """Concurrent graphs: +10 % steady env steps/s (H100). cuBLAS: a cold process about 8 s shorter (H100, H200)."""
    assert preset_options("humanoid_ppo") == {
        "xla_gpu_command_buffer_scheduling_mode": "CONCURRENT",
        "xla_gpu_enable_triton_gemm": False,
    }


#: the keys humanoid_ppo_fast sets over humanoid_ppo
CHANGED = ("algo.lr", "budget.env_steps", "eval.every_steps", "run_name")


def without(cfg: DictConfig, keys: tuple[str, ...]) -> DictConfig:
    """A copy of ``cfg`` with ``keys`` (dotted) taken out (an untyped copy: a schema's typed node keeps its keys)."""
    cfg = OmegaConf.create(OmegaConf.to_container(cfg))
    with open_dict(cfg):
        for key in keys:
            parent, _, leaf = key.rpartition(".")
            del (cfg[parent] if parent else cfg)[leaf]
    return cfg


def test_fast_preset_is_the_tutorial_preset_at_twice_the_rate_for_36_whole_updates() -> None:
    """humanoid_ppo_fast changes the learning rate, the budget and the evaluations only (and names its runs), and its budget
    is whole updates, so a run trains exactly the 11.8M steps its figures were measured at."""
    fast, tutorial = compose_config("experiment=humanoid_ppo_fast"), compose_config("experiment=humanoid_ppo")
    assert fast.algo.lr == 2 * tutorial.algo.lr
    assert fast.eval.every_steps == 0
    assert without(fast, CHANGED) == without(tutorial, CHANGED)
    per_update = steps_per_update(fast.algo)
    updates = updates_for_budget(fast.budget.env_steps, per_update)
    per_chunk, chunks = chunk_plan(updates, per_update, Cadences.from_config(fast))
    assert updates * per_update == fast.budget.env_steps == 11_796_480
    assert per_chunk * chunks == updates == 36
