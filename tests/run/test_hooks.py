"""The loop's hooks: checkpoint pruning and the checkpoint of the best evaluation."""

import jax.numpy as jnp
import numpy as np
import pytest

from rlq.run.hooks import ChunkEnd, KeepBest, KeepLast, PeriodicCheckpoint, PeriodicEval, fires
from rlq.store import checkpoint
from tests.helpers import train_run


class Silent:
    def log(self, *args):
        pass


def _end(index: int, state) -> ChunkEnd:
    return ChunkEnd(index, 1000 * (index + 1), state, {}, last=False)


def test_periodic_hooks_fire_every_k_chunks_but_not_on_the_last():
    ends = [ChunkEnd(i, 37 * (i + 1), None, {}, last=i == 5) for i in range(6)]  # steps off any multiple
    assert [fires(end, 2) for end in ends] == [False, True, False, True, False, False]
    assert [fires(end, 1) for end in ends] == [True] * 5 + [False]
    assert not any(fires(end, 0) for end in ends)


def test_keep_last_prunes_older_periodic_checkpoints(tmp_path):
    hook = PeriodicCheckpoint(tmp_path, every_chunks=1, listeners=[KeepLast(2)])
    for i in range(5):
        hook.on_chunk(_end(i, {"w": jnp.full(3, float(i))}))
    assert sorted(p.name for p in tmp_path.glob("step_*")) == [
        "step_4000.json",
        "step_4000.msgpack",
        "step_5000.json",
        "step_5000.msgpack",
    ]


def test_keep_best_keeps_the_state_of_the_best_eval_return(tmp_path):
    returns = iter([1.0, 5.0, 3.0])

    def evaluate(state, index):
        return {"return": np.array([next(returns)])}

    hook = PeriodicEval(evaluate, every_chunks=1, logger=Silent(), listeners=[KeepBest(tmp_path)])
    for i in range(3):
        hook.on_chunk(_end(i, {"w": jnp.full(3, float(i))}))
    best = tmp_path / "best.msgpack"
    assert checkpoint.meta(best)["env_steps"] == 2000 and checkpoint.meta(best)["eval_return"] == 5.0
    np.testing.assert_array_equal(checkpoint.leaves(best)[0], np.full(3, 1.0))


@pytest.mark.slow  # a CLI run (7 s)
def test_keep_last_and_keep_best_from_the_config(tmp_path):
    train_run(
        tmp_path,
        "budget.env_steps=4096",
        "log_every_steps=1024",
        "checkpoint.every_steps=1024",
        "checkpoint.keep_last=2",
        "checkpoint.keep_best=true",
        "eval.every_steps=1024",
        "eval.episodes=2",
        "video.at_end=false",
    )
    names = sorted(p.name for p in (tmp_path / "checkpoints").glob("*.msgpack"))
    assert names == ["best.msgpack", "final.msgpack", "step_2048.msgpack", "step_3072.msgpack"]
