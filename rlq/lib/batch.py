"""One entry of a pytree batched over a run's seeds."""

from __future__ import annotations

from typing import Any

import jax


def seed_entry(tree: Any, index: int, num_seeds: int) -> Any:
    """Entry ``index`` of ``tree``, whose leaves carry the seeds along their leading axis.

    Leaves without that axis stay whole: ``vmap`` leaves MuJoCo Warp's buffers shared by a batch
    unbatched (rlq.envs.mujoco.impl), so a run's state holds them once for all seeds. They are
    scratch that every physics step rewrites, so a shared buffer whose length happens to equal the
    number of seeds and gets sliced does no harm."""

    def pick(leaf: Any) -> Any:
        batched = getattr(leaf, "ndim", 0) > 0 and leaf.shape[0] == num_seeds
        return leaf[index] if batched else leaf

    return jax.tree.map(pick, tree)
