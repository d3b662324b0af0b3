"""The env x algo matrix: which pairs have tuned settings (conf/tuned/), which machine a run is shaped for,
and the one line that refuses a pair without them.

Hydra picks ``tuned/<env>_<algo>.yaml`` (then ``tuned/controller/<env>_<algo>_<controller>.yaml`` and
``tuned/machine/<env>_<algo>_<machine>.yaml``) from the run's choices (conf/config.yaml's defaults list); a pair's
file may choose shared settings in its own defaults list (``tuned/physics/fast.yaml``: the env's fast physics;
``tuned/open_loop/cpg.yaml``: the CPG of an open-loop gait). This module only reads which of those files exist or
were chosen, so a new tuned file is a new supported pair.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Mapping
from glob import glob
from typing import Any

from rlq.config.compose import compose
from rlq.config.conf_dir import CONF_DIR
from rlq.errors import ConfigError

#: what to say for a pair that is refused, beyond the list of the env's tuned algorithms
PAIR_HINTS = {
    ("lunar", "qlearning"): "tabular Q needs a discrete observation, and LunarLander's is 8 continuous numbers "
    "(give env.discretize bins, low and high per component to try anyway)",
    ("humanoid", "qlearning"): "tabular Q needs discrete observations and actions, and the humanoid's are "
    "continuous (joint positions and velocities in, 17 joint torques out)",
    ("humanoid", "dqn"): "DQN chooses among discrete actions, and the humanoid's 17 joint torques are continuous",
    ("humanoid", "pqn"): "PQN chooses among discrete actions, and the humanoid's 17 joint torques are continuous",
    ("brittle_star_undirected", "qlearning"): "tabular Q needs a discrete observation, and the undirected brittle "
    "star's is its joints and disk as continuous numbers, with no target to take a bearing from (env.observation="
    "sector and arm_sectors need env=brittle_star)",
}


def machine_choice(overrides: list[str]) -> str | None:
    """``machine=<name>`` for a `rlq train` command that names no machine and no preset: ``gpu`` where JAX will see
    an NVIDIA GPU, else None (the config's default, cpu). A preset (``experiment=``) names its own machine."""
    keys = {o.split("=", 1)[0].lstrip("+~") for o in overrides}
    if keys & {"machine", "experiment"}:
        return None
    return "machine=gpu" if gpu_present() else None


def gpu_present() -> bool:
    """JAX will run on an NVIDIA GPU: its CUDA plugin is installed, a GPU device node exists and JAX_PLATFORMS does
    not keep JAX off it. Found without starting JAX (which would claim the GPU's memory in this process)."""
    platforms = os.environ.get("JAX_PLATFORMS", "")
    if platforms and not any(p in platforms for p in ("cuda", "gpu")):
        return False
    plugin = any(importlib.util.find_spec(f"jax_cuda{v}_plugin") for v in (12, 13))
    return plugin and bool(glob("/dev/nvidia[0-9]*"))


#: the groups of tuned settings, in the order Hydra applies them: those a pair's file chooses in its defaults list
#: (before its own keys), the pair's file, then its controller's and machine's refinements (conf/config.yaml)
TUNED_GROUPS = ("tuned/physics", "tuned/open_loop", "tuned", "tuned/controller", "tuned/machine")


def _applied(choices: Mapping[str, str | None]) -> list[str]:
    """The tuned files that exist for the groups' chosen names (paths under conf/), in the order Hydra applies them."""
    names = [f"{group}/{choices[group]}" for group in TUNED_GROUPS if choices.get(group)]
    return [f"{n}.yaml" for n in names if (CONF_DIR / f"{n}.yaml").is_file()]


def tuned_files(env: str, algo: str, controller: str, machine: str) -> list[str]:
    """The tuned files Hydra applies to this choice, in the order it applies them (paths under conf/)."""
    chosen = compose([f"env={env}", f"algo={algo}", f"controller={controller}", f"machine={machine}"], with_hydra=True)
    return _applied(chosen.hydra.runtime.choices)


def tuned_algos(env: str) -> list[str]:
    """The algorithms with tuned settings for ``env``."""
    prefix = f"{env}_"
    return sorted(
        p.stem[len(prefix) :]
        for p in (CONF_DIR / "tuned").glob(f"{prefix}*.yaml")
        if (CONF_DIR / "algo" / f"{p.stem[len(prefix) :]}.yaml").is_file()
    )


def supported(env: str, algo: str) -> bool:
    return (CONF_DIR / "tuned" / f"{env}_{algo}.yaml").is_file()


def check_supported(cfg: Mapping[str, Any]) -> None:
    """The pair of ``cfg`` (a run's config or ``RunSpec.values``) has tuned settings, or the user asked for the
    algorithm's defaults (``allow_untuned``). Raises ConfigError with the line that names what works for the env."""
    env, algo = str(cfg["env"]["name"]), str(cfg["algo"]["name"])
    algos = tuned_algos(env)
    if supported(env, algo) or cfg.get("allow_untuned", False) or not algos:  # not algos: e.g. lunar_box2d (eval only)
        return
    hint = PAIR_HINTS.get((env, algo))
    works = f"tuned for env={env}: algo={'|'.join(algos)}"
    raise ConfigError(
        f"env={env} algo={algo} has no tuned settings{f': {hint}' if hint else ''}; {works} (docs/matrix.md); "
        "allow_untuned=true runs the algorithm's own defaults"
    )


def tuned_line(choices: Mapping[str, str | None]) -> str:
    """The run's first console line: the tuned files applied to this run, or that there are none."""
    env, algo = choices.get("env"), choices.get("algo")
    files = _applied(choices)
    if files:
        return f"rlq: tuned settings for env={env} algo={algo}: {', '.join(files)} (keys you pass win)"
    return f"rlq: no tuned settings for env={env} algo={algo}: the algorithm's own defaults"
