"""A chunk cut into blocks, waited for in slices: rlq.run.slices."""

import numpy as np

from rlq.run import slices


def test_blocks_divide_the_chunk_into_at_most_max_blocks():
    assert slices.blocks(4096) == 32 and slices.blocks(96) == 32
    assert slices.blocks(12) == 12 and slices.blocks(1) == 1
    assert slices.blocks(100) == 25  # the largest divisor up to 32
    assert slices.blocks(37) == 1  # a prime above 32 stays one call


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
