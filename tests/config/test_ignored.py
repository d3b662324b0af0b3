"""A key the chosen variant does not read, set on the command line, is refused with one line, exit 2, before anything
is made (rlq/config/ignored.py); the same key from a preset or the defaults is not."""

from __future__ import annotations

import pytest
from omegaconf import OmegaConf

from rlq.config import resolve
from rlq.config.compose import WITHOUT_TUNED, compose
from rlq.config.ignored import IGNORED, check_ignored, given_keys
from rlq.errors import ConfigError
from tests.cli.test_bad_inputs import check_bad_input
from tests.helpers import quick_sample

CASES = [
    (
        ["algo=random_search", "algo.variant=hill_climb", "algo.ars.top=8"],
        "algo.ars.top is not read with algo=random_search algo.variant=hill_climb: drop algo.ars.top, or set "
        "algo.variant=ars, which reads it",
    ),
    (
        ["algo=random_search", "algo.variant=ars", "algo.sigma=0.3"],
        "algo.sigma is not read with algo=random_search algo.variant=ars",
    ),
    (["algo=random_search", "algo.variant=ars", "algo.population=64"], "algo.population is not read"),
    (
        ["algo=random_search", "algo.sampling=uniform", "algo.sigma=0.2"],
        "algo.sigma is not read with algo=random_search algo.variant=hill_climb algo.sampling=uniform",
    ),
    (
        ["algo=dqn", "algo.epsilon.decay=0.99"],
        "algo.epsilon.decay is not read with algo=dqn algo.epsilon.schedule=linear",
    ),
    (
        ["algo=pqn", "algo.epsilon.schedule=exponential", "algo.epsilon.duration=1000"],
        "algo.epsilon.duration is not read with algo=pqn algo.epsilon.schedule=exponential",
    ),
    (["algo=es", "algo.strategy=cma_es", "algo.lr=0.01"], "algo.lr is not read with algo=es algo.strategy=cma_es"),
    (["algo=es", "algo.mean_episodes=8"], "algo.mean_episodes is not read with algo=es algo.keep=candidate"),
    (
        ["algo=es", "algo.activation=relu"],
        "algo.activation is not read with algo=es algo.genotype=policy algo.hidden=[]",
    ),
    (
        ["algo=es", "algo.hidden=[16]", "algo.bias=true"],
        "algo.bias is not read with algo=es algo.genotype=policy algo.hidden=[16]",
    ),
    (
        ["algo=map_elites", "algo.iso_sigma=0.01"],
        "algo.iso_sigma is not read with algo=map_elites algo.variation=gaussian",
    ),
    (
        ["algo=map_elites", "algo.cma_sigma=0.3"],
        "algo.cma_sigma is not read with algo=map_elites algo.emitter=gaussian",
    ),
    (["algo=map_elites", "algo.es_lr=0.1"], "algo.es_lr is not read with algo=map_elites algo.es_fraction=0.0"),
    (
        ["algo=map_elites", "algo.archive.cells=100"],
        "algo.archive.cells is not read with algo=map_elites algo.archive.kind=grid",
    ),
    (
        ["algo=map_elites", "algo.champion.episodes=8"],
        "algo.champion.episodes is not read with algo=map_elites algo.champion.candidates=0",
    ),
    (["algo=reinforce", "algo.vf_coef=1.0"], "algo.vf_coef is not read with algo=reinforce algo.baseline=mean"),
    (
        [
            "algo=qlearning",
            "algo.replay_batch=64",
        ],
        "algo.replay_batch is not read with algo=qlearning algo.replay_size=0",
    ),
    (["algo=ppo", "env=lunar", "env.wind_power=5"], "env.wind_power is not read with env=lunar env.enable_wind=false"),
    (["algo=es", "algo.mean_episodes=0"], "algo.mean_episodes must be an integer >= 1, got 0"),  # its range first
]


@pytest.mark.parametrize("overrides,fragment", quick_sample(CASES, 3))
def test_a_key_the_variant_ignores_is_one_line_and_exit_2(overrides, fragment, tmp_path, monkeypatch, capsys):
    check_bad_input(["train", *overrides], None, fragment, tmp_path, monkeypatch, capsys)


def test_a_sweep_names_the_job_whose_variant_ignores_the_key(tmp_path, monkeypatch, capsys):
    argv = [
        "train",
        "-m",
        "algo=random_search",
        "algo.variant=hill_climb,ars",
        "algo.population=64",
    ]
    check_bad_input(
        argv, None, "job 1 of 2 (algo.variant=ars): algo.population is not read", tmp_path, monkeypatch, capsys
    )


@pytest.mark.parametrize(
    "overrides",
    quick_sample(
        [
            ["algo=random_search", "algo.variant=ars", "algo.ars.top=8"],  # read by the variant set
            ["algo=random_search", "algo.sampling=gaussian", "algo.sigma=0.3"],
            ["algo=dqn", "algo.epsilon.schedule=exponential", "algo.epsilon.decay=0.99"],
            ["algo=es", "algo.keep=mean", "algo.mean_episodes=8"],
            ["algo=map_elites", "algo.emitter=mixed", "algo.cma_sigma=0.3", "algo.improvement_fraction=0.25"],
            ["algo=map_elites", "algo.variation=iso_line", "algo.iso_sigma=0.01"],
            ["algo=map_elites", "algo.champion.candidates=4", "algo.champion.episodes=8"],
            ["algo=reinforce", "algo.baseline=value", "algo.vf_coef=1.0"],
            ["algo=ppo", "env=lunar", "env.enable_wind=true", "env.wind_power=5"],
            ["experiment=brittle_star_map_elites"],  # a preset's keys of other variants are its own business
            ["algo=random_search", "algo.variant=ars"],  # the defaults carry population, sigma, ... : not the user's
        ],
        2,
    ),
)
def test_keys_the_variant_reads_and_keys_the_user_did_not_set_pass(overrides):
    spec = resolve(overrides)
    check_ignored(spec.config, given_keys(spec.overrides))


def test_the_keys_given_are_the_values_set_not_the_group_choices():
    assert given_keys(["algo=ppo", "algo.lr=1", "+sweep.algo.sigma=[1,2]", "~tuned", "env/physics=fast"]) == [
        "algo.lr",
        "sweep.algo.sigma",
    ]


def test_the_check_reads_only_the_keys_it_is_given():
    cfg = OmegaConf.create({"algo": {"name": "random_search", "variant": "ars", "sigma": 0.1}})
    check_ignored(cfg, [])
    check_ignored(cfg, ["algo.variant", "seed"])
    with pytest.raises(ConfigError, match="algo.sigma is not read"):
        check_ignored(cfg, ["algo.sigma"])


@pytest.mark.slow  # composes every component of the table (9 s)
def test_every_key_of_the_table_is_a_key_of_its_component():
    for entry in IGNORED:
        for name in entry.names:
            defaults = compose([f"{entry.section}={name}", *WITHOUT_TUNED])[entry.section]
            for key in entry.keys:
                assert OmegaConf.select(defaults, key, default="absent") != "absent", (entry.section, name, key)
