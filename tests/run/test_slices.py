"""A chunk cut into blocks, waited for in slices: rlq.run.stops.slices."""

import numpy as np

from rlq.run.stops import slices


def test_blocks_divide_the_chunk_into_at_most_max_blocks():
    plan = slices.block_plan
    assert plan(4096) == slices.BlockPlan(128, 32) and plan(96) == slices.BlockPlan(3, 32)
    assert plan(12) == slices.BlockPlan(1, 12) and plan(1) == slices.BlockPlan(1, 1)
    assert plan(100) == slices.BlockPlan(4, 25)  # the largest divisor up to 32
    assert plan(34) == slices.BlockPlan(2, 17)  # blocks of 2 updates: no second program


def test_a_prime_chunk_is_cut_into_bounded_blocks_and_a_remainder():
    assert slices.block_plan(37) == slices.BlockPlan(2, 18, 1)  # 18 calls of 2 updates, then one of 1
    assert slices.block_plan(37).calls == 19
    assert slices.block_plan(74) == slices.BlockPlan(3, 24, 2)  # 74 = 2 x 37: halves would be 37 updates each
    assert slices.block_plan(1_000_003) == slices.BlockPlan(31_251, 31, 31_222)
    for updates in range(1, 3000):
        plan = slices.block_plan(updates)
        bound = -(-updates // slices.MAX_BLOCKS)
        assert plan.size * plan.full + plan.rest == updates, updates
        assert plan.size <= 2 * bound and plan.rest < plan.size and plan.calls <= slices.MAX_BLOCKS + 1, updates


def test_slices_start_with_one_call_then_grow_towards_the_target():
    sizer = slices.SliceSizer()
    assert sizer.next(32) == 1
    sizer.record(1, 0.01)  # 500 calls would take TARGET_S: growth is capped at 4x the slice before
    assert sizer.next(32) == 4
    sizer.record(4, 0.04)
    assert sizer.next(32) == 16
    sizer.record(16, 0.16)
    assert sizer.next(10) == 10  # never past the chunk's end
    sizer.record(10, 20.0)  # 2 s a call
    assert sizer.next(32) == int(slices.TARGET_S / 2.0)
    sizer.record(2, 60.0)
    assert sizer.next(32) == 1  # at least one call


def test_a_partial_chunk_keeps_its_metrics(tmp_path):
    parts = [
        {"loss": np.ones((2, 1)), "train/x": np.zeros((2, 1))},
        {"loss": np.full((2, 2), 3.0), "train/x": np.ones((2, 2))},
    ]
    part = slices.part_record(parts, 3)
    checkpoint_path = tmp_path / "checkpoints" / "step_1536.msgpack"
    part.save(checkpoint_path)
    loaded, done = slices.resumed_part(checkpoint_path, part.meta(8), 8)
    assert done == 3 and len(loaded) == 1
    np.testing.assert_array_equal(loaded[0]["loss"], [[1.0, 3.0, 3.0]] * 2)
    np.testing.assert_array_equal(loaded[0]["train/x"], [[0.0, 1.0, 1.0]] * 2)
    assert slices.resumed_part(None, part.meta(8), 8) == ([], 0)
