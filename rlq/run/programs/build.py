"""The programs of one run: init, a chunk of updates and the greedy evaluation, built for the run's mesh."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any, cast

import jax
import jax.numpy as jnp
import numpy as np

from rlq.algos import make_algo
from rlq.algos.base import Algorithm
from rlq.config.spec import RunSpec, as_spec
from rlq.envs import Env
from rlq.envs.wrappers import ReturnWindow, window_return
from rlq.lib.env_api import EnvState
from rlq.lib.rollout import evaluate
from rlq.lib.sharding import SEED, to_host
from rlq.run.programs import members
from rlq.run.programs.cadences import Cadences, chunk_plan
from rlq.run.programs.devices import Placement, placement
from rlq.run.programs.env_stack import evaluation_env, make_env
from rlq.run.stops import guard, slices


def env_windows(state: Any) -> list[dict[str, jax.Array]]:
    """The return windows (``ReturnWindow``) of the env batches an algorithm's state holds: every
    algorithm that steps envs itself keeps them in its state; black-box algorithms hold none."""
    nodes = jax.tree.leaves(state, is_leaf=lambda node: isinstance(node, EnvState))
    return [
        cast(dict[str, jax.Array], node.extras[ReturnWindow.KEY])
        for node in nodes
        if isinstance(node, EnvState) and ReturnWindow.KEY in node.extras
    ]


@dataclass
class Programs:
    """The compiled pieces of a run, built once from a config. A chunk is ``calls_per_chunk`` calls
    (see ``call_chunk``), ``updates_per_chunk`` updates in all: with ``chunk_loop=scan`` its blocks
    (rlq.run.stops.slices), which bound how long a stop waits; ``full_calls`` of them call ``chunk``, and
    the last calls ``rest`` where the blocks do not divide the chunk (None where they do)."""

    env: Env
    algo: Algorithm
    init: jax.stages.Wrapped
    chunk: jax.stages.Wrapped
    evaluate: jax.stages.Wrapped
    updates_per_chunk: int
    num_chunks: int
    placement: Placement
    calls_per_chunk: int = 1
    full_calls: int = 1
    rest: jax.stages.Wrapped | None = None
    #: the divergence guard's bounds the chunk checks (``guard:``), for the line that names the one passed
    bounds: guard.Bounds = guard.NO_BOUNDS
    #: the chunks were planned to divide a resumed run's updates (not the plan a fresh run of the config gets)
    replanned: bool = False
    #: the algorithm's numeric hyperparameters (``AlgorithmSpec.sweepable``), one float32 value per seed: the second
    #: argument of ``init`` and of the chunk, so that runs that differ only in them share their compiled programs,
    #: and an in-program sweep's members (each seed its member's values) start and train in them as seeds do
    hyper: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def hyper_shape(self) -> dict[str, jax.ShapeDtypeStruct]:
        """The shapes of ``hyper``, to lower init and the chunk with."""
        return {name: jax.ShapeDtypeStruct(value.shape, value.dtype) for name, value in self.hyper.items()}

    @property
    def chunk_steps(self) -> int:
        """Env steps per seed of one chunk."""
        return self.updates_per_chunk * self.algo.steps_per_update


def on_mesh(fn: Callable, where: Placement, name: str) -> jax.stages.Wrapped:
    """``jit(vmap(fn))`` over seeds on the run's mesh: every input and output split along its
    leading (seed) axis, and ``fn`` traced under the mesh, so that its env axis is split where it
    says so (rlq.lib.sharding).

    One seed is traced without ``vmap`` (its axis taken off the inputs and put back on the
    outputs): the same numbers, but batching a program of nested loops re-traces every loop body
    at each level, which more than doubles the trace of a program such as LunarLander's chunk."""
    batched = jax.vmap(fn, spmd_axis_name=SEED)

    def one_seed(*args):
        out = fn(*jax.tree.map(lambda x: x[0], args))
        return jax.tree.map(lambda x: jnp.expand_dims(x, 0), out)

    def traced(*args):
        with jax.sharding.use_abstract_mesh(where.mesh.abstract_mesh):
            if jax.tree.leaves(args)[0].shape[0] == 1:
                return one_seed(*args)
            return batched(*args)

    traced.__name__ = traced.__qualname__ = name  # JAX's logs and profiles then say jit(chunk), not jit(traced)
    return jax.jit(traced, in_shardings=where.seeds, out_shardings=where.seeds)


def build(
    run: RunSpec | Mapping[str, Any], where: Placement | None = None, done_steps: int = 0, chunk_steps: int = 0
) -> Programs:
    """The run's env, algorithm and programs on ``where`` (default: the config's placement). An
    in-program sweep's spec is its ``members.program_config``: ``num_seeds`` counts all members' seeds.
    ``done_steps``: the nominal env steps per seed a resumed run has trained, which its chunks then divide.
    ``chunk_steps``: the env steps per seed of the resumed run's chunks, which it keeps (a run extended
    to a larger budget goes on with the same rows, evaluations and checkpoints)."""
    spec = as_spec(run)
    where = where or placement(spec)
    env = make_env(spec)
    algo = make_algo(spec.algorithm, env, spec.budget.env_steps)
    cadences = Cadences.from_config(spec)
    fresh = chunk_plan(algo.num_updates, algo.steps_per_update, cadences)
    per_chunk, num_chunks = fresh
    done, kept = done_steps // algo.steps_per_update, chunk_steps // algo.steps_per_update
    if kept and chunk_steps % algo.steps_per_update == 0 and done % kept == 0:
        per_chunk, num_chunks = kept, algo.num_updates // kept  # the resumed run's chunks, extended
    elif done and done % per_chunk:  # a checkpoint that does not say its chunks: chunks that divide its updates
        per_chunk, num_chunks = chunk_plan(algo.num_updates, algo.steps_per_update, cadences, done)
    replanned = per_chunk != fresh[0]
    plan = slices.BlockPlan(1, per_chunk) if spec.training.chunk_loop == "calls" else slices.block_plan(per_chunk)

    window = int(spec.training.return_window)

    bounds = guard.Bounds.from_config(spec.training.guard)

    def updates(length: int) -> Callable[[Any, Any], tuple[Any, dict]]:
        def run_block(state, hyper):
            update = guard.with_flags(algo.update, algo.params, bounds)
            state, metrics = jax.lax.scan(lambda s, _: update(s, hyper), state, None, length=length)
            windows = env_windows(state)
            if window and windows:
                metrics = {**metrics, "return_window": window_return(windows, window)[None]}
            return state, metrics

        return run_block

    @functools.cache
    def eval_env() -> Env:
        """Built when the evaluation program is traced, off the path to the first chunk; its
        construction (an MJX model's upload) runs eagerly inside that trace."""
        with jax.ensure_compile_time_eval():
            return evaluation_env(spec, env)

    def eval_one(state, key):
        record = evaluate(eval_env(), algo.policy(state), key, spec.evaluation.episodes)
        if algo.state_metrics is not None:
            record.update(algo.state_metrics(state))
        return record

    return Programs(
        env=env,
        algo=algo,
        replanned=replanned,
        init=on_mesh(algo.init, where, "init"),
        chunk=on_mesh(updates(plan.size), where, "chunk"),
        rest=on_mesh(updates(plan.rest), where, "rest") if plan.rest else None,
        evaluate=on_mesh(eval_one, where, "evaluate"),
        updates_per_chunk=per_chunk,
        num_chunks=num_chunks,
        placement=where,
        calls_per_chunk=plan.calls,
        full_calls=plan.full,
        bounds=bounds,
        hyper=hyper_values(algo, spec),
    )


def with_hyper(program: Callable[[Any, Any], Any], hyper: Any) -> Callable[[Any], Any]:
    """A compiled ``chunk`` (or ``rest``) as a function of the state alone, at hyperparameters ``hyper``
    (``Programs.hyper`` on the mesh)."""
    return lambda state: program(state, hyper)


def with_hyper_soon(soon: Future | None, hyper: Any) -> Future | None:
    """``with_hyper`` of a program still compiling (``CompiledPrograms.rest_soon``: (program, packed)), as a future
    of the same shape."""
    if soon is None:
        return None
    bound: Future = Future()

    def done(ready: Future) -> None:
        error = ready.exception()
        if error is not None:
            bound.set_exception(error)
        else:
            program, packed = ready.result()
            bound.set_result((with_hyper(program, hyper), packed))

    soon.add_done_callback(done)
    return bound


def hyper_values(algo: Algorithm, spec: RunSpec) -> dict[str, np.ndarray]:
    """The hyperparameter argument of init and the chunk: each of ``algo.hyperparams`` as float32, once per seed, the
    config's value but for the keys an in-program sweep gives each member (``members.seed_values``). The values a
    traced init or update would have taken as weakly typed Python floats, rounded the same way."""
    num_seeds = int(spec.seeds.count)
    values = {name: np.full(num_seeds, value, np.float32) for name, value in algo.hyperparams.items()}
    if members.sweeping(spec):
        values.update(members.seed_values(spec, num_seeds // members.member_count(spec)))
    return values


def call_chunk(chunk: Callable[[Any], tuple[Any, dict]], state: Any, calls: int) -> tuple[Any, dict]:
    """``calls`` calls of the compiled ``chunk`` (``with_hyper``'s), queued without waiting (jax dispatches them
    asynchronously), and their metrics joined along the update axis as one call's would be. The
    join runs in numpy on the host: a jax concatenate would compile a small program per metric on
    the first chunk.

    With ``chunk_loop=calls`` the program holds a single update and no loop around it: the MJX
    humanoid's update, compiled that way, runs 2-3 % faster than inside a loop of updates
    (docs/humanoid.md), and the host's dispatch hides behind updates that take a tenth of a second
    or more."""
    parts = []
    for _ in range(calls):
        state, metrics = chunk(state)
        parts.append(metrics)
    if calls == 1:
        return state, parts[0]
    return state, jax.tree.map(lambda *xs: np.concatenate(xs, axis=1), *to_host(parts))
