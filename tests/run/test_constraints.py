"""The allowed values of the declarations (rlq/declared/, checked by rlq/run/checks/constraints.py): integer lists
are never truncated floats."""

import pytest

from rlq.config.compose import explain_hydra_error
from rlq.run.checks.constraints import OneOf, Range, Sizes, problems
from tests.helpers import compose_config


def refusal(*overrides: str) -> str | None:
    """The one line that refuses ``overrides``: an algorithm's schema while composing (its typed node takes no
    fraction for an integer), else the declarations' ranges."""
    try:
        cfg = compose_config(*overrides)
    except Exception as err:
        return explain_hydra_error(err, list(overrides))
    return problems(cfg)


def test_sizes_take_whole_numbers_from_their_lowest_value_only():
    widths = Sizes()
    assert widths.accepts([64, 64]) and not widths.accepts([64.5, 64]) and not widths.accepts([0])
    indices = Sizes(nullable=True, low=0, example="[0,2]")
    assert indices.accepts(None) and indices.accepts([0, 2]) and not indices.accepts([0.0, 2])
    assert indices.allowed() == "null or a list of integers >= 0, e.g. [0,2]"
    assert not Range(0, integer=True).accepts(1.5)


def test_choices_take_names_or_booleans_of_their_own_type_and_may_say_what_null_means():
    enabled = OneOf(("auto", True, False))
    assert enabled.accepts("auto") and enabled.accepts(True) and enabled.accepts(False)
    assert (
        not enabled.accepts(1) and not enabled.accepts(0) and not enabled.accepts("true") and not enabled.accepts(None)
    )
    assert enabled.allowed() == "one of auto, true, false"
    platform = OneOf(("cpu", "gpu"), nullable=True, null="null (JAX's default)")
    assert platform.accepts(None) and platform.accepts("gpu") and not platform.accepts("tpu")
    assert platform.allowed() == "null (JAX's default) or one of cpu, gpu"
    assert Range(1, integer=True, nullable=True, null="null (read from SLURM)").allowed() == (
        "null (read from SLURM) or an integer >= 1"
    )


def test_the_run_s_platform_and_distributed_keys_are_held_to_their_declaration():
    assert (
        problems(compose_config("platform=tpu"))
        == "platform must be null (JAX's default) or one of cpu, gpu, got 'tpu'"
    )
    assert problems(compose_config("distributed.num_processes=0")) == (
        "distributed.num_processes must be null (read from SLURM) or an integer >= 1, got 0"
    )
    assert problems(compose_config("platform=cpu", "distributed.enabled=false")) is None


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (
            ["algo=map_elites", "algo.archive.shape=[20.5,20]"],
            "algo.archive.shape must be a list of integers >= 1, e.g. [20,20], got [20.5, 20]",
        ),
        (
            ["algo=map_elites", "algo.descriptor_dims=[0.5,2]"],
            "algo.descriptor_dims must be null or a list of integers >= 0, e.g. [0,2], got [0.5, 2]",
        ),
        (
            ["algo=qlearning", "env.discretize={bins:[3.5,3,6,12],low:[-2.4,-3,-0.21,-2],high:[2.4,3,0.21,2]}"],
            "env.discretize.bins must be a list of integers >= 1, e.g. [3,3,6,12], got [3.5, 3, 6, 12]",
        ),
        (
            ["env=brittle_star", "controller=cpg", "controller.leading_arm=1.5"],
            "controller.leading_arm must be null or an integer >= 0, got 1.5",
        ),
    ],
)
def test_integer_lists_and_indices_refuse_fractions(overrides, message):
    assert refusal(*overrides) == message


def test_keys_under_a_null_group_are_not_checked():
    assert problems(compose_config("algo=random_search")) is None  # algo.archive: null
    assert problems(compose_config("algo=ppo")) is None  # env.discretize: null


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["algo=dqn", "algo.batch_size=null"], "algo.batch_size must be an integer >= 1, got None"),
        (["algo=ppo", "algo.batch_size=0"], "algo.batch_size must be null or an integer >= 1, got 0"),
        (["algo=random_search", "algo.population=0"], "algo.population must be an integer >= 1, got 0"),
        (["algo=dqn", "algo.gradient_steps=2.5"], "algo.gradient_steps must be an integer >= 1, got 2.5"),
    ],
)
def test_batch_sizes_are_in_the_table_with_one_algorithms_own_meaning(overrides, message):
    assert refusal(*overrides) == message


def test_ppo_keeps_its_null_batch():
    assert problems(compose_config("algo=ppo", "algo.batch_size=null")) is None
