"""brax's model load with device transfers (``env.quick_model_load``): the same arrays as brax's
own load, and no program compiled for them."""

import jax
import mujoco
import numpy as np
import pytest
from brax.io import mjcf as brax_mjcf
from etils import epath

from rlq.envs.humanoid import model_load
from rlq.envs.humanoid.mjx_patches import active_patches

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def hinge_chain(links: int) -> mujoco.MjModel:
    """A model whose array shapes (``links`` bodies, joints, geoms and motors) no other test uses."""
    bodies = "".join(
        f'<body pos="0 0 {0.2 * i}"><joint name="j{i}" type="hinge" axis="0 1 0"/>'
        '<geom type="capsule" size="0.05 0.1"/></body>'
        for i in range(links)
    )
    motors = "".join(f'<motor joint="j{i}"/>' for i in range(links))
    xml = f"<mujoco><worldbody><body>{bodies}</body></worldbody><actuator>{motors}</actuator></mujoco>"
    return mujoco.MjModel.from_xml_string(xml)


#: the event JAX records for each XLA compile
COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"


def compiles_of(load) -> int:
    """How many programs XLA compiles while ``load()`` runs."""
    events: list[str] = []

    def listener(event: str, duration: float, **_) -> None:
        if event == COMPILE_EVENT:
            events.append(event)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        load()
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    return len(events)


def test_the_loader_compiles_nothing_for_its_arrays():
    assert compiles_of(lambda: brax_mjcf.load_model(hinge_chain(13))) > 0  # brax's own: a program per new shape
    with model_load.arrays_by_transfer():
        assert compiles_of(lambda: brax_mjcf.load_model(hinge_chain(11))) == 0
    assert brax_mjcf.jp is jax.numpy  # brax's own loader again


def test_the_humanoid_model_is_the_same_array_for_array():
    mj_model = brax_mjcf.load_mjmodel(epath.resource_path("brax") / "envs/assets/humanoid.xml")
    own = brax_mjcf.load_model(mj_model)
    with model_load.arrays_by_transfer():
        quick = brax_mjcf.load_model(mj_model)
    own_leaves, own_tree = jax.tree.flatten(own)
    quick_leaves, quick_tree = jax.tree.flatten(quick)
    assert own_tree == quick_tree
    for a, b in zip(own_leaves, quick_leaves, strict=True):
        assert isinstance(b, jax.Array)
        assert (a.dtype, a.shape, a.weak_type, a.committed) == (b.dtype, b.shape, b.weak_type, b.committed)
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_the_quick_load_is_a_version_checked_patch():
    assert active_patches("jax", "none", "data", False, False, quick_model_load=True) == ["env.quick_model_load=true"]
