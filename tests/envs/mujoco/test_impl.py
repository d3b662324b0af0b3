"""env.mjx_impl: which MJX implementation steps an MJX env (rlq.envs.mujoco.impl)."""

import pytest

from rlq.envs.mujoco import impl


def test_names_resolve_and_unknown_ones_are_refused():
    assert impl.resolve_impl("jax") == "jax"
    with pytest.raises(ValueError, match="env.mjx_impl must be one of"):
        impl.resolve_impl("bullet")


def test_auto_picks_warp_only_on_an_nvidia_gpu_with_warp_on_the_release_it_was_run_with(monkeypatch):
    monkeypatch.setattr(impl, "warp_installed", lambda: True)
    monkeypatch.setattr(impl, "on_nvidia_gpu", lambda: False)
    assert impl.resolve_impl("auto", installed_mjx="3.17.0") == "jax"
    monkeypatch.setattr(impl, "on_nvidia_gpu", lambda: True)
    assert impl.resolve_impl("auto", installed_mjx="3.17.0") == "warp"
    assert impl.resolve_impl("auto", installed_mjx="3.18.0") == "jax"
    monkeypatch.setattr(impl, "warp_installed", lambda: False)
    assert impl.resolve_impl("auto", installed_mjx="3.17.0") == "jax"


def test_warp_on_another_mjx_release_or_without_warp_lang_is_refused(monkeypatch):
    monkeypatch.setattr(impl, "warp_installed", lambda: True)
    assert impl.resolve_impl("warp", installed_mjx="3.17.2") == "warp"
    with pytest.raises(ValueError, match=r"written for mujoco-mjx 3\.17\.x .* but 3\.18 is installed"):
        impl.resolve_impl("warp", installed_mjx="3.18.0")
    monkeypatch.setattr(impl, "warp_installed", lambda: False)
    with pytest.raises(ImportError, match="needs warp-lang"):
        impl.resolve_impl("warp", installed_mjx="3.17.0")


def test_the_installed_mjx_release_is_read():
    assert impl.mjx_release("3.17.0") == (3, 17) and impl.mjx_release("3.18.0rc1") == (3, 18)
    assert len(impl.mjx_release()) == 2  # mujoco-mjx is a dependency
