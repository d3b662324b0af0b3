"""The init and chunk programs take the algorithm's numeric hyperparameters as their argument
(rlq/run/programs/build.py): the same numbers as an init and update with them as constants, and other values through
the same compiled programs."""

from functools import partial

import jax
import numpy as np
import pytest

from rlq.run.programs.build import Programs, build
from rlq.run.programs.keys import seed_keys
from rlq.run.stops import guard
from tests.helpers import compose_config

RUNS = {
    "ppo": ("algo=ppo", "algo.num_envs=4", "algo.num_steps=32", "budget.env_steps=512", "log_every_steps=256"),
    "dqn": ("algo=dqn", "algo.learning_starts=64", "budget.env_steps=512", "log_every_steps=256"),
}
#: the black-box algorithms, tiny (two generations of CartPole episodes), and values of their hyperparameters off
#: the defaults
BLACK_BOX = {
    "es": ("algo=es", "algo.population=4", "algo.episodes=1", "budget.env_steps=4000"),
    "es_cma": ("algo=es", "algo.strategy=cma_es", "algo.population=4", "algo.episodes=1", "budget.env_steps=4000"),
    "random_search": (
        "algo=random_search",
        "algo.sampling=gaussian",
        "algo.population=4",
        "algo.episodes=1",
        "budget.env_steps=4000",
    ),
    "ars": (
        "algo=random_search",
        "algo.variant=ars",
        "algo.ars.directions=2",
        "algo.ars.top=1",
        "algo.episodes=1",
        "budget.env_steps=4000",
    ),
    "map_elites": (
        "algo=map_elites",
        "algo.batch_size=8",
        "algo.episodes=1",
        "algo.es_fraction=0.25",
        "budget.env_steps=8000",
    ),
    "map_elites_iso": (
        "algo=map_elites",
        "algo.variation=iso_line",
        "algo.batch_size=8",
        "algo.episodes=1",
        "budget.env_steps=8000",
    ),
}
BLACK_BOX_VALUES = {
    "es": ("algo.lr=0.05", "algo.sigma=0.3"),
    "es_cma": ("algo.sigma=0.3",),
    "random_search": ("algo.sigma=0.3",),
    "ars": ("algo.ars.step_size=0.05", "algo.ars.noise=0.1", "algo.ars.reward_shift=0.5"),
    "map_elites": ("algo.sigma=0.2", "algo.es_sigma=0.2", "algo.es_lr=0.1"),
    "map_elites_iso": ("algo.iso_sigma=0.02", "algo.line_sigma=0.2"),
}
#: how far a chunk's logged metrics may differ between the two programs (leaves_equal)
METRICS_ATOL = 1e-7
#: the other algorithms whose update takes its hyperparameters as arguments, with values off their defaults
OTHERS = {
    "pqn": ("algo=pqn", "algo.num_envs=4", "budget.env_steps=512", "algo.lr=3e-4", "algo.lam=0.8"),
    "reinforce": (
        "algo=reinforce",
        "algo.num_envs=2",
        "budget.env_steps=1000",
        "algo.gamma=0.97",
        "algo.ent_coef=0.02",
    ),
    "es": ("algo=es", "algo.population=4", "algo.episodes=1", "budget.env_steps=4000", "algo.lr=0.05"),
    "qlearning": ("algo=qlearning", "algo.num_envs=2", "algo.num_steps=64", "budget.env_steps=256", "algo.alpha=0.3"),
    **{name: (*BLACK_BOX[name], *values) for name, values in BLACK_BOX_VALUES.items()},
}


def constant_chunk(programs: Programs):
    """The chunk with the config's hyperparameters baked in (``Algorithm.hyperparams`` as constants), one seed, as
    ``on_mesh`` runs it."""
    update = guard.with_flags(programs.algo.update, programs.algo.params, programs.bounds)

    def chunk(state):
        one = jax.tree.map(lambda x: x[0], state)
        one, metrics = jax.lax.scan(
            lambda s, _: update(s, programs.algo.hyperparams),
            one,
            None,
            length=programs.updates_per_chunk // programs.calls_per_chunk,
        )
        return jax.tree.map(lambda x: x[None], (one, metrics))

    return jax.jit(chunk)


def constant_init(programs: Programs):
    """Init with the config's hyperparameters baked in, one seed, as ``on_mesh`` runs it."""

    def init(keys):
        return jax.tree.map(lambda x: x[None], programs.algo.init(keys[0], programs.algo.hyperparams))

    return jax.jit(init)


def leaves_equal(a, b, atol: float = 0.0) -> bool:
    """The same arrays, bit for bit (two states, or two (state, metrics) pairs: the metrics ``b`` has); NaN where the
    other has NaN too (evosax's first state has no best solution yet). A chunk's metrics are logged means, which
    XLA may sum in another order when a hyperparameter is a constant (PPO's policy loss, a mean of terms of about 1
    that cancel to 1e-4, differed by 5e-9 on a CPU while every parameter was the same to the bit): metrics agree to
    METRICS_ATOL, states to the bit."""
    if isinstance(a, tuple):
        metrics = {name: a[1][name] for name in b[1]}
        return leaves_equal(a[0], b[0]) and leaves_equal(metrics, b[1], atol=METRICS_ATOL)
    same = partial(np.allclose, rtol=0, atol=atol) if atol else np.array_equal
    pairs = zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True)
    return all(same(np.asarray(x), np.asarray(y), equal_nan=True) for x, y in pairs)


@pytest.mark.slow  # two chunks compiled per algorithm (15-30 s of CPU each): the full suite runs it
@pytest.mark.parametrize("algo", sorted(RUNS))
@pytest.mark.parametrize("values", [(), ("algo.lr=7e-4", "algo.gamma=0.97", "algo.num_envs=2")])
def test_hyperparameters_as_the_chunk_s_argument_give_the_numbers_of_constants(algo, values):
    programs = build(compose_config(*RUNS[algo], *values))
    assert set(programs.hyper) == set(programs.algo.hyperparams) >= {"lr", "gamma"}
    state = programs.init(seed_keys(0, 1), programs.hyper)
    assert leaves_equal(state, constant_init(programs)(seed_keys(0, 1)))
    got = programs.chunk(state, programs.hyper)
    want = constant_chunk(programs)(state)
    assert leaves_equal(got, want)


@pytest.mark.slow
@pytest.mark.parametrize("algo", sorted(OTHERS))
def test_the_other_algorithms_take_their_hyperparameters_as_arguments_with_the_same_numbers(algo):
    programs = build(compose_config(*OTHERS[algo], "log_every_steps=256"))
    assert programs.hyper
    state = programs.init(seed_keys(0, 1), programs.hyper)
    assert leaves_equal(state, constant_init(programs)(seed_keys(0, 1)))
    assert leaves_equal(programs.chunk(state, programs.hyper), constant_chunk(programs)(state))


@pytest.mark.slow
def test_one_compiled_chunk_trains_at_each_learning_rate_as_its_own_program_does():
    programs, other = build(compose_config(*RUNS["ppo"])), build(compose_config(*RUNS["ppo"], "algo.lr=3e-3"))
    state = programs.init(seed_keys(0, 1), programs.hyper)
    compiled = programs.chunk.lower(state, programs.hyper_shape).compile()
    assert leaves_equal(compiled(state, other.hyper), constant_chunk(other)(state))
    assert not leaves_equal(compiled(state, other.hyper)[0].params, compiled(state, programs.hyper)[0].params)


def twice(chunk, state):
    """Two chunks from ``state`` (a black box's first generation draws uniformly: its widths act from the second)."""
    return chunk(chunk(state)[0])


@pytest.mark.slow
@pytest.mark.parametrize("algo", sorted(BLACK_BOX))
def test_a_black_box_s_init_and_chunk_at_other_values_train_as_that_value_s_own_run(algo):
    """A sweep's later job: the ``init`` and ``chunk`` another value compiled, called with this job's values (ES's
    start width among them), give the numbers of this job's own init and updates with its values baked in."""
    base = build(compose_config(*BLACK_BOX[algo], "log_every_steps=256"))
    other = build(compose_config(*BLACK_BOX[algo], *BLACK_BOX_VALUES[algo], "log_every_steps=256"))
    assert set(other.hyper) == set(base.hyper)
    assert any(not np.array_equal(other.hyper[name], base.hyper[name]) for name in base.hyper)
    keys = seed_keys(0, 1)
    started = base.init(keys, other.hyper)
    assert leaves_equal(started, constant_init(other)(keys))
    got = twice(lambda state: base.chunk(state, other.hyper), started)
    assert leaves_equal(got, twice(constant_chunk(other), constant_init(other)(keys)))
    assert not leaves_equal(got, twice(lambda state: base.chunk(state, base.hyper), base.init(keys, base.hyper)))
