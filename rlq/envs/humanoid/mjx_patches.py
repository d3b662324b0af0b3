"""Which of the humanoid's physics options replace private code of mujoco-mjx or brax, and the
versions those replacements were written against.

Every option below is off unless the config turns it on (``experiment=humanoid_ppo`` does). An
option that swaps a private function of a library, or steps brax's pipeline in a loop of our own,
is only correct for the library version it was written against, so building the env refuses, with
the option's name, on any other installed version instead of silently changing the physics.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from rlq.envs.mujoco.impl import release
from rlq.errors import ConfigError

#: (distribution, lowest version, first version not supported) that the patches were written for
WRITTEN_FOR = {"mujoco-mjx": ("3.17", "3.18"), "brax": ("0.14.2", "0.15")}


def active_patches(
    mjx_impl: str,
    unroll_physics: str,
    substep_carry: str,
    vectorized_cdof: bool,
    vectorized_com_vel: bool,
    quick_model_load: bool = False,
) -> list[str]:
    """The config options, as ``key=value``, that replace library code (empty: brax's own physics)."""
    active = []
    if mjx_impl == "warp":
        active.append("env.mjx_impl=warp")
    if unroll_physics != "none":
        active.append(f"env.unroll_physics={unroll_physics}")
    if substep_carry != "data":
        active.append(f"env.substep_carry={substep_carry}")
    if vectorized_cdof and mjx_impl == "jax":
        active.append("env.vectorized_cdof=true")
    if vectorized_com_vel and mjx_impl == "jax":
        active.append("env.vectorized_com_vel=true")
    if quick_model_load:
        active.append("env.quick_model_load=true")
    return active


def check_versions(active: list[str], installed: dict[str, str] | None = None) -> None:
    """Raise ConfigError if a patch is on and mujoco-mjx or brax is not the version it was written for."""
    if not active:
        return
    for dist, (low, high) in WRITTEN_FOR.items():
        try:
            found = installed[dist] if installed is not None else version(dist)
        except (PackageNotFoundError, KeyError):
            continue
        if not release(low) <= release(found) < release(high):
            raise ConfigError(
                f"{', '.join(active)} replace(s) private code of {dist} written for {low} <= version < {high}, "
                f"but {dist} {found} is installed; turn them off (brax's own physics: env.substep_carry=data "
                "env.unroll_physics=none env.vectorized_cdof=false env.vectorized_com_vel=false env.mjx_impl=jax "
                "env.quick_model_load=false)"
            )
