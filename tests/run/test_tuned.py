"""The env x algo matrix (rlq/config/tuned.py, conf/tuned/): every pair is tuned or refused with one line, the plain
command composes its pair's recipe, and the named presets are that recipe under their own run name."""

from __future__ import annotations

import functools
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from rlq.cli.checked import check_overrides, checked_run
from rlq.config.compose import WITHOUT_TUNED
from rlq.config.conf_dir import CONF_DIR
from rlq.config.tuned import (
    TUNED_GROUPS,
    check_supported,
    machine_choice,
    supported,
    tuned_algos,
    tuned_files,
    tuned_line,
)
from rlq.errors import ConfigError
from tests.helpers import compose_config, quick_sample, refuse_to_train, run_cli_in_process

ENVS = ("cartpole", "lunar", "humanoid", "brittle_star", "brittle_star_undirected")
ALGOS = tuple(sorted(p.stem for p in (CONF_DIR / "algo").glob("*.yaml")))
#: what docs/matrix.md and the issue promise at least
SUPPORTED = {
    "cartpole": {"ppo", "dqn", "pqn", "reinforce", "random_search", "map_elites", "qlearning", "es"},
    "lunar": {"ppo", "dqn", "pqn", "reinforce", "map_elites", "es", "random_search"},
    "humanoid": {"ppo", "es", "random_search", "map_elites", "reinforce"},
    "brittle_star": {"ppo", "qlearning", "es", "random_search", "reinforce", "dqn", "pqn", "map_elites"},
    "brittle_star_undirected": {"map_elites", "random_search", "es", "ppo", "dqn", "pqn", "reinforce"},
}
PAIRS = [(env, algo) for env in ENVS for algo in ALGOS]
#: the tuned pairs, a fifth of them (each env's) in the quick tier: each composes and validates in 0.5-6 s
TUNED_PAIRS = quick_sample([p for p in PAIRS if p[1] in SUPPORTED[p[0]]], 5)


def _without(cfg, *keys: str) -> dict:
    plain = OmegaConf.to_container(cfg, resolve=False)
    for key in keys:
        plain.pop(key, None)
    return plain


@pytest.mark.parametrize("env", ENVS)
def test_the_tuned_pairs_are_the_promised_ones(env):
    assert set(tuned_algos(env)) == SUPPORTED[env]


@functools.cache
def checked_pair(env: str, algo: str, machine: str):
    """The RunSpec of `rlq train env=<env> algo=<algo> machine=<machine>`, checked as the command checks it
    (rlq.cli.checked, which check_overrides wraps): composed and validated once per test process, its config read
    by the tests of both the checks and the tuned keys (a pair composes and validates in about a second)."""
    return checked_run([f"env={env}", f"algo={algo}", f"machine={machine}"])


@pytest.mark.parametrize(("env", "algo"), TUNED_PAIRS)
@pytest.mark.parametrize("machine", ["cpu", pytest.param("gpu", marks=pytest.mark.slow)])  # gpu: the full suite
def test_every_tuned_pair_composes_and_validates(env, algo, machine):
    """`rlq train env=<env> algo=<algo>` passes every check before anything compiles, on both machines."""
    spec = checked_pair(env, algo, machine)
    assert spec.overrides == (f"env={env}", f"algo={algo}", f"machine={machine}")


def _leaves(node: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in node.items():
        if isinstance(value, dict):
            out.update(_leaves(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def _own_leaves(path: Path) -> dict:
    """The keys a config file sets itself (its defaults list aside), under its package (``# @package env``)."""
    package = next((line.split()[-1] for line in path.read_text().splitlines() if line.startswith("# @package")), "")
    data = OmegaConf.to_container(OmegaConf.load(path))
    data.pop("defaults", None)
    return _leaves(data, "" if package in ("", "_global_") else f"{package}.")


def _file_leaves(path: Path) -> dict:
    """The keys a tuned file sets, with those of the configs its defaults list includes by path (``- /env/physics/fast``,
    applied first); the groups it chooses (``- /tuned/physics: fast``) are files of their own (``tuned_files``)."""
    out = {}
    for entry in OmegaConf.to_container(OmegaConf.load(path)).get("defaults", []):
        if isinstance(entry, str) and entry != "_self_":
            out.update(
                _file_leaves(CONF_DIR / f"{entry[1:]}.yaml" if entry.startswith("/") else path.parent / f"{entry}.yaml")
            )
    return out | _own_leaves(path)


@pytest.mark.parametrize(("env", "algo"), TUNED_PAIRS)
@pytest.mark.parametrize("machine", ["cpu", pytest.param("gpu", marks=pytest.mark.slow)])  # gpu: the full suite
def test_every_tuned_files_keys_reach_the_run(env, algo, machine):
    """Each key of the pair's tuned files holds in the composed run (the last file to set it wins): a file without
    its ``# @package _global_`` line would put its keys under ``tuned.`` and the run would train on defaults. The
    config is the one the checked run trains on (``RunSpec.config``: composed by `rlq train`'s own path)."""
    cfg = checked_pair(env, algo, machine).config
    assert "tuned" not in cfg
    expected = {}
    for name in tuned_files(env, algo, cfg.controller.name, machine):
        expected.update(_file_leaves(CONF_DIR / name))
    composed = _leaves(OmegaConf.to_container(cfg, resolve=True))
    assert {key: composed.get(key) for key in expected if composed.get(key) != expected[key]} == {}


#: presets a tuned file chooses in its defaults list rather than repeat: the env's physics, the CPG of an open-loop gait
SHARED = sorted(
    [
        *(CONF_DIR / "env" / "physics").glob("*.yaml"),
        *(CONF_DIR / "tuned" / "physics").glob("*.yaml"),
        *(CONF_DIR / "tuned" / "open_loop").glob("*.yaml"),
    ]
)
TUNED_FILES = sorted((CONF_DIR / "tuned").rglob("*.yaml"))


@pytest.mark.parametrize("path", TUNED_FILES, ids=lambda p: str(p.relative_to(CONF_DIR)))
def test_no_tuned_file_repeats_a_preset_it_could_choose(path):
    """A tuned file on the fast physics names it in one line (``- /tuned/physics: fast``, conf/tuned/physics/fast.yaml
    includes conf/env/physics/fast.yaml), and the open-loop gait's CPG is one file (conf/tuned/open_loop/cpg.yaml):
    no file holds every key of such a preset at the preset's values."""
    own = _own_leaves(path).items()
    copied = [p.name for p in SHARED if path != p and (keys := _own_leaves(p).items()) and keys <= own]
    assert copied == [], f"{path.relative_to(CONF_DIR)} repeats {copied}: choose it in its defaults list"


def test_the_console_line_knows_every_group_of_tuned_files():
    groups = {str(p.parent.relative_to(CONF_DIR)) for p in TUNED_FILES}
    assert groups <= set(TUNED_GROUPS)


@pytest.mark.parametrize("algo", ["es", "map_elites", "random_search"])
def test_the_undirected_gait_searches_share_one_cpg_and_the_fast_physics(algo):
    assert tuned_files("brittle_star_undirected", algo, "cpg", "cpu") == [
        "tuned/physics/fast.yaml",
        "tuned/open_loop/cpg.yaml",
        f"tuned/brittle_star_undirected_{algo}.yaml",
    ]
    assert tuned_files("brittle_star_undirected", algo, "direct", "cpu") == [
        "tuned/physics/fast.yaml",
        f"tuned/brittle_star_undirected_{algo}.yaml",
    ]
    fast = compose_config("env=brittle_star_undirected", "env/physics=fast", "allow_untuned=true", "~tuned").env
    assert compose_config("env=brittle_star_undirected", f"algo={algo}").env.physics == fast.physics


def test_a_pairs_recipe_runs_on_the_envs_own_physics_without_its_physics_file():
    plain = compose_config("env=brittle_star", "algo=dqn", "~tuned/physics")
    assert plain.env.physics == compose_config("env=brittle_star", *WITHOUT_TUNED).env.physics
    assert plain.env.action_repeat == 50  # the rest of the recipe


@pytest.mark.parametrize(("env", "algo"), [p for p in PAIRS if p[1] not in SUPPORTED[p[0]]])
def test_every_other_pair_is_refused_with_what_works(env, algo):
    with pytest.raises(ConfigError) as err:
        check_overrides([f"env={env}", f"algo={algo}"])
    line = str(err.value)
    assert "\n" not in line
    assert f"env={env} algo={algo} has no tuned settings" in line
    assert f"tuned for env={env}: algo={'|'.join(sorted(SUPPORTED[env]))}" in line
    assert "allow_untuned=true" in line


@pytest.mark.parametrize(("env", "algo"), [p for p in PAIRS if p[1] not in SUPPORTED[p[0]]])
def test_a_refusal_says_why_the_spaces_cannot_meet(env, algo):
    """A pair is refused where its spaces cannot meet, and the line says which space: not only "no tuned settings"."""
    with pytest.raises(ConfigError) as err:
        check_overrides([f"env={env}", f"algo={algo}"])
    assert "continuous" in str(err.value)


def test_allow_untuned_runs_the_algorithms_defaults():
    check_supported(compose_config("env=lunar", "algo=qlearning", "allow_untuned=true"))
    untuned = compose_config("env=lunar", "algo=qlearning", "allow_untuned=true").algo
    assert untuned == compose_config("algo=qlearning", "~tuned").algo


@pytest.mark.slow
def test_the_refusal_comes_through_the_cli_as_one_line(workdir):
    proc = run_cli_in_process("train", "algo=qlearning", "env=lunar", cwd=workdir)
    assert proc.returncode == 2
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith("rlq: error: env=lunar algo=qlearning has no tuned settings: tabular Q needs a discrete")
    assert not (workdir / "outputs").exists()


@pytest.mark.parametrize(
    ("preset", "plain"),
    [
        ("cartpole_dqn", ["algo=dqn"]),
        ("cartpole_qlearning", ["algo=qlearning"]),
        ("lunar_ppo", ["env=lunar", "algo=ppo"]),
        ("lunar_ppo_gpu", ["env=lunar", "algo=ppo", "machine=gpu"]),
        ("lunar_dqn", ["env=lunar", "algo=dqn"]),
        ("lunar_pqn_gpu", ["env=lunar", "algo=pqn", "machine=gpu"]),
        ("humanoid_ppo_fast", ["env=humanoid", "algo=ppo"]),
        ("brittle_star_ppo_cpg", ["env=brittle_star", "algo=ppo"]),
        ("brittle_star_ppo_direct", ["env=brittle_star", "algo=ppo", "controller=direct"]),
        (
            "brittle_star_qlearning",
            [
                "env=brittle_star",
                "algo=qlearning",
                "tuned/physics=pruned",
                "env.observation=sector",
                "env.bearing_bins=5",
                "controller.mode=leading_arm",
                "algo.num_envs=1024",
                "algo.epsilon.duration=81920",
                "budget.env_steps=102400",
                "log_every_steps=10240",
            ],
        ),
        (
            "brittle_star_qlearning_decentralised",
            [
                "env=brittle_star",
                "algo=qlearning",
                "tuned/physics=pruned",
                "algo.num_envs=2048",
                "algo.epsilon.duration=163840",
                "budget.env_steps=204800",
                "log_every_steps=10240",
            ],
        ),
        ("brittle_star_map_elites", ["env=brittle_star_undirected", "algo=map_elites"]),
    ],
)
def test_a_preset_is_its_pairs_tuned_settings_under_its_name(preset, plain):
    named = compose_config(f"experiment={preset}")
    assert named.run_name == preset
    assert _without(named, "run_name") == _without(compose_config(*plain), "run_name")


#: (algo, the keys of the command measured before its tuned file held them): humanoid ES on 2026-11-29
#: (docs/results.md), humanoid REINFORCE on 2026-12-03 (tuning seed 100, greedy 485: docs/results/matrix_h200_2026_12_02.json,
#: ``tuning``)
MEASURED_COMMANDS = [
    (
        "es",
        "algo.strategy=snes algo.population=1024 algo.episodes=1 algo.sigma=0.05 algo.low=-1.0 algo.high=1.0 "
        "algo.keep=mean algo.mean_episodes=16 budget.env_steps=40000000 eval.every_steps=0 eval.episodes=16 "
        "log_every_steps=1",
    ),
    (
        "reinforce",
        "algo.num_envs=1024 algo.num_steps=1000 algo.baseline=value algo.normalize_advantages=true algo.gamma=0.99 "
        "algo.hidden=[64,64] algo.activation=tanh algo.lr=3e-4 budget.env_steps=40960000 env.unroll_physics=linesearch "
        "env.substep_carry=mjx env.vectorized_cdof=true env.vectorized_com_vel=true env.quick_model_load=true "
        "eval.every_steps=0 eval.episodes=16 log_every_steps=2048000",
    ),
]


@pytest.mark.parametrize(("algo", "keys"), MEASURED_COMMANDS)
def test_a_humanoid_recipe_is_its_measured_command(algo, keys):
    """`rlq train algo=<algo> env=humanoid` composes the command measured with its keys as overrides, whose keys
    conf/tuned/humanoid_<algo>.yaml holds; only the GPU shape's warning (shaped_for) is new."""
    measured = compose_config("env=humanoid", f"algo={algo}", "allow_untuned=true", "~tuned", *keys.split())
    plain = compose_config("env=humanoid", f"algo={algo}")
    assert plain.shaped_for.platform == "gpu"
    assert _without(measured, "allow_untuned", "shaped_for") == _without(plain, "allow_untuned", "shaped_for")


def test_the_brittle_stars_are_driven_by_their_cpg_unless_told():
    assert compose_config("env=brittle_star").controller.name == "cpg"
    assert compose_config("env=brittle_star_undirected").controller.name == "cpg"
    assert compose_config("env=brittle_star", "controller=direct").controller.name == "direct"
    assert compose_config("env=cartpole").controller.name == "direct"


def test_keys_given_win_over_the_tuned_ones():
    assert compose_config("env=lunar", "algo=dqn", "algo.lr=0.01").algo.lr == 0.01
    assert compose_config("env=lunar", "algo=dqn").algo.lr == 5.0e-4


def test_the_gpu_shape_comes_from_the_machine_file():
    cpu, gpu = compose_config("env=lunar", "algo=dqn"), compose_config("env=lunar", "algo=dqn", "machine=gpu")
    assert (cpu.algo.num_envs, gpu.algo.num_envs) == (16, 4096)
    assert tuned_files("lunar", "dqn", "direct", "gpu") == ["tuned/lunar_dqn.yaml", "tuned/machine/lunar_dqn_gpu.yaml"]


def test_the_console_line_names_the_tuned_files():
    choices = {"env": "brittle_star", "algo": "ppo", "tuned": "brittle_star_ppo"}
    choices |= {"tuned/controller": "brittle_star_ppo_cpg", "tuned/machine": "brittle_star_ppo_cpu"}
    assert tuned_line(choices) == (
        "rlq: tuned settings for env=brittle_star algo=ppo: tuned/brittle_star_ppo.yaml, "
        "tuned/controller/brittle_star_ppo_cpg.yaml (keys you pass win)"
    )
    physics = {"env": "brittle_star", "algo": "dqn", "tuned": "brittle_star_dqn", "tuned/physics": "fast"}
    assert tuned_line(physics) == (  # the file a pair's file chooses first: Hydra applies it before the pair's keys
        "rlq: tuned settings for env=brittle_star algo=dqn: tuned/physics/fast.yaml, tuned/brittle_star_dqn.yaml "
        "(keys you pass win)"
    )
    assert "no tuned settings" in tuned_line({"env": "lunar", "algo": "qlearning", "tuned": "lunar_qlearning"})


def test_the_machine_is_chosen_only_where_the_command_names_none(monkeypatch):
    monkeypatch.setattr("rlq.config.tuned.gpu_present", lambda: True)
    assert machine_choice(["env=lunar", "algo=dqn"]) == "machine=gpu"
    assert machine_choice(["env=lunar", "machine=cpu"]) is None
    assert machine_choice(["experiment=lunar_ppo"]) is None
    monkeypatch.setattr("rlq.config.tuned.gpu_present", lambda: False)
    assert machine_choice(["env=lunar", "algo=dqn"]) is None


def test_jax_platforms_cpu_means_no_gpu(monkeypatch):
    from rlq.config.tuned import gpu_present

    monkeypatch.setenv("JAX_PLATFORMS", "cpu")
    assert gpu_present() is False


@pytest.mark.slow
def test_cfg_job_names_the_tuned_settings(workdir):
    proc = run_cli_in_process("train", "env=lunar", "algo=ppo", "--cfg", "job", cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    assert (
        proc.stdout.splitlines()[0]
        == "# tuned settings for env=lunar algo=ppo: tuned/lunar_ppo.yaml (keys you pass win)"
    )
    assert OmegaConf.create(proc.stdout).algo.num_envs == 32


@pytest.mark.parametrize("given", ["~tuned", "~tuned/machine", "~seed", "~seed=0", "~algo.lr", "algo.lr"])
def test_cfg_job_refuses_a_deletion_with_the_line_a_run_refuses_it_with(given, workdir, monkeypatch):
    """`rlq train ~tuned --cfg job` printed the config with the tuned file deleted under the line naming it as applied
    (and ``~seed=0`` a traceback, ``algo.lr`` Hydra's error after that line); a run refuses them in one line, and so
    does ``--cfg``, with the same line and exit 2, printing nothing."""
    refuse_to_train(monkeypatch)
    run = run_cli_in_process("train", "env=lunar", "algo=dqn", given, cwd=workdir)
    printed = run_cli_in_process("train", "env=lunar", "algo=dqn", given, "--cfg", "job", cwd=workdir)
    assert run.returncode == printed.returncode == 2
    assert run.stderr.strip().startswith(f"rlq: error: '{given}'") and "\n" not in run.stderr.strip()
    assert printed.stderr == run.stderr and printed.stdout == ""


def test_cfg_job_names_the_tuned_settings_a_group_deletion_leaves(workdir):
    """A group's deletion with its option (``~tuned=lunar_dqn``), which a run takes: the line says what --cfg prints."""
    pair = ["env=lunar", "algo=dqn", "machine=cpu"]
    proc = run_cli_in_process("train", *pair, "~tuned=lunar_dqn", "--cfg", "job", cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0] == "# no tuned settings for env=lunar algo=dqn: the algorithm's own defaults"
    assert OmegaConf.create(proc.stdout).algo == compose_config(*pair, *WITHOUT_TUNED).algo


def test_supported_reads_the_files():
    assert supported("lunar", "ppo") and not supported("lunar", "qlearning")


@pytest.mark.slow
def test_the_plain_map_elites_command_balances_cartpole(tmp_path):
    """Learning threshold of conf/tuned/cartpole_map_elites.yaml: the fittest elite, re-scored on 32 new episodes,
    balances (>= 475) on a seed the tuning never saw."""
    from tests.helpers import train_run

    result = train_run(tmp_path, "algo=map_elites", "seed=97", "video.at_end=false")
    assert float(result.eval_return.min()) >= 475.0
