"""A second table of bad inputs (types, ranges, interpolations, paths, sweeps, the commands' own
options), held to tests/cli/test_bad_inputs.py's rule: one line, exit 2, no traceback, nothing
compiled, nothing left behind. In-process, but for a few through the installed command."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rlq.store.sidecar import HASH_KEY
from tests.cli.test_bad_inputs import CASES as FIRST_CASES
from tests.cli.test_bad_inputs import check_bad_input, run_dir_case
from tests.helpers import run_cli


def foreign(*names: str):
    """Mark the sidecars of checkpoints ``names`` as written by a run of another config."""

    def mutate(run_dir: Path) -> None:
        for name in names:
            sidecar = run_dir / "checkpoints" / f"{name}.json"
            sidecar.write_text(json.dumps({**json.loads(sidecar.read_text()), HASH_KEY: "f" * 64}))

    return mutate


ALGOS = "dqn, es, map_elites, ppo, pqn, qlearning, random_search, reinforce"

#: (argv with {run} / {tmp} placeholders, how to make {run}, a fragment of the error line)
CASES = [
    # types
    (["train", "num_seeds=1.5"], None, "num_seeds must be an integer, got 1.5"),
    (["train", "num_seeds=true"], None, "num_seeds must be an integer, got True"),
    (["train", "seed=abc"], None, "seed must be an integer, got 'abc'"),
    (["train", "seed=1.5"], None, "seed must be an integer, got 1.5"),
    (["train", "budget.env_steps=abc"], None, "budget.env_steps must be an integer, got 'abc'"),
    (["train", "log_every_steps=abc"], None, "log_every_steps must be an integer, got 'abc'"),
    (["train", "eval.episodes=1.5"], None, "eval.episodes must be an integer, got 1.5"),
    (["train", "checkpoint.keep_best=maybe"], None, "checkpoint.keep_best must be a boolean (true/false)"),
    (["train", "return_window=1.5"], None, "return_window must be an integer, got 1.5"),
    (["train", "guard.max_abs_loss=abc"], None, "guard.max_abs_loss must be a number, got 'abc'"),
    # run keys whose default is null: their declared type or range (rlq/declared/run.py)
    (["train", "video.at_end=3"], None, "video.at_end must be null or a boolean (true/false), got 3"),
    (["train", "init_from=1"], None, "init_from must be null or a string, got 1"),
    (["train", "stop.when=5"], None, "stop.when must be null or a string, got 5"),
    (["train", "video.max_steps=2.5"], None, "video.max_steps must be null or an integer >= 1, got 2.5"),
    (["train", "shaped_for.platform=3"], None, "shaped_for.platform must be null or one of cpu, gpu, got 3"),
    (["train", "algo.lr=[1,2]"], None, "algo.lr must be a number, got [1, 2]"),
    (["train", "algo.lr={{a:1}}"], None, "algo.lr must be a number, got {{'a': 1}}"),
    (["train", "algo.hidden=abc"], None, "algo.hidden must be a list"),
    (["train", "env.max_episode_steps=abc"], None, "env.max_episode_steps must be an integer, got 'abc'"),
    # a group given a dict or a list
    (["train", "algo={{}}"], None, "algo={{}}: algo takes the name of one option (" + ALGOS + ")"),
    (["train", "algo=[ppo]"], None, "algo=[ppo]: algo takes the name of one option"),
    (["train", "env=[cartpole]"], None, "env=[cartpole]: env takes the name of one option"),
    (["train", "--cfg", "job", "algo={{}}"], None, "algo={{}}: algo takes the name of one option"),
    # in-program sweeps (rlq/run/programs/members.py)
    (["train", "sweep.algo.num_envs=[4,8]"], None, "sweep.algo.num_envs: algo=ppo sweeps algo.lr, algo.clip_eps"),
    (
        ["train", "algo=random_search", "sweep.algo.population=[10,20]"],
        None,
        "sweep.algo.population: algo=random_search sweeps algo.sigma, algo.ars.step_size",
    ),
    (["train", "sweep.algo.lr=1e-3"], None, "sweep.algo.lr=0.001: give a list, e.g. 'sweep.algo.lr=[1e-4,3e-4]'"),
    (["train", "sweep.algo.lr=[1e-3,-1]"], None, "sweep member algo.lr=-1: algo.lr must be a number > 0, got -1"),
    (["train", "sweep.algo.gamma=[0.9,nan]"], None, "sweep.algo.gamma: nan is not a finite number"),
    # ranges
    (["train", "budget.env_steps=-5"], None, "budget.env_steps must be an integer in [1, 2147483647], got -5"),
    (["train", "budget.env_steps=2147483648"], None, "budget.env_steps must be an integer in [1, 2147483647]"),
    (["train", "log_every_steps=0"], None, "log_every_steps must be an integer >= 1, got 0"),
    (["train", "eval.every_steps=-1"], None, "eval.every_steps must be an integer >= 0, got -1"),
    (["train", "checkpoint.every_steps=-1"], None, "checkpoint.every_steps must be an integer >= 0, got -1"),
    (["train", "checkpoint.keep_last=-1"], None, "checkpoint.keep_last must be an integer >= 0, got -1"),
    (["train", "algo.gamma=nan"], None, "algo.gamma must be a number in [0, 1], got nan"),
    (["train", "algo.gamma=inf"], None, "algo.gamma must be a number in [0, 1], got inf"),
    (["train", "algo.lr=-1e-3"], None, "algo.lr must be a number > 0, got -0.001"),
    # the typed nodes of an algorithm's schema (rlq/config/store.py) refuse these while composing
    (["train", "algo.lr=abc"], None, "algo.lr must be a number, got 'abc' (e.g. algo.lr=0.00025)"),
    (["train", "algo.no_such_key=1"], None, "unknown config key 'algo.no_such_key'"),
    (["train", "algo.hidden=null"], None, "algo.hidden must be a list of integers >= 1, e.g. [64,64], got None"),
    (["train", "algo.hidden=[a]"], None, "algo.hidden must be a list of integers >= 1, e.g. [64,64], got ['a']"),
    (["train", "algo=dqn", "algo.buffer_size=2.5"], None, "algo.buffer_size must be an integer >= 1, got 2.5"),
    (["train", "algo=dqn", "algo.epsilon.duration=abc"], None, "algo.epsilon.duration must be an integer, got 'abc'"),
    (["train", "algo=dqn", "algo.epsilon.nope=1"], None, "unknown config key 'algo.epsilon.nope'"),
    # what a typed node would convert (3 to true, 1 to '1') is refused as written
    (["train", "algo.anneal_lr=3"], None, "algo.anneal_lr must be a boolean (true/false), got 3"),
    (["train", "algo.activation=1"], None, "algo.activation must be a string, got 1"),
    (
        ["train", "-m", "seed=0,1", "algo=dqn", "algo.buffer_size=1e5"],
        None,
        "algo.buffer_size=100000.0: an integer key",
    ),
    # ... and those of an env's and a controller's schema (env/<name>_schema, controller/<name>_schema)
    (["train", "env=brittle_star", "env.num_arms=abc"], None, "env.num_arms must be an integer, got 'abc'"),
    (["train", "env.no_such_key=1"], None, "unknown config key 'env.no_such_key'"),
    (["train", "env=lunar", "env.solver.nope=1"], None, "unknown config key 'env.solver.nope'"),
    (["train", "env=lunar", "env.continuous=3"], None, "env.continuous must be a boolean (true/false), got 3"),
    (["train", "env=brittle_star", "env.physics.condim=2.5"], None, "env.physics.condim must be an integer in [1, 6]"),
    (["train", "env=humanoid", "env.randomize=3"], None, "env.randomize must be null or a group of keys, got 3"),
    (["train", "env=humanoid", "env.contacts=hands"], None, "env.contacts must be one of feet, all, got 'hands'"),
    (["train", "env=humanoid", "env.integrator=rk45"], None, "env.integrator must be one of euler, rk4, got 'rk45'"),
    (
        ["train", "env=humanoid", "env.solver_iterations=0"],
        None,
        "env.solver_iterations must be null (brax's 1) or an integer >= 1, got 0",
    ),
    (["train", "controller.no_such_key=1"], None, "unknown config key 'controller.no_such_key'"),
    (
        ["train", "env=brittle_star", "controller.coupling_weight=abc"],
        None,
        "controller.coupling_weight must be a number, got 'abc'",
    ),
    (["train", "algo.hidden=[64,-1]"], None, "algo.hidden must be a list of integers >= 1"),
    (["train", "algo.hidden=[64.5]"], None, "got [64.5]"),
    (["train", "algo.num_envs=0"], None, "algo.num_envs must be an integer >= 1, got 0"),
    (["train", "algo.num_minibatches=0"], None, "algo.num_minibatches must be an integer >= 1, got 0"),
    (["train", "algo=dqn", "algo.batch_size=0"], None, "algo.batch_size must be an integer >= 1, got 0"),
    (["train", "algo=dqn", "algo.buffer_size=0"], None, "algo.buffer_size must be an integer >= 1, got 0"),
    (["train", "platform=tpu"], None, "platform must be null (JAX's default) or one of cpu, gpu, got 'tpu'"),
    (
        ["train", "distributed.num_processes=2", "distributed.process_id=2", "distributed.coordinator_address=h:1"],
        None,
        "distributed.process_id=2 must be below distributed.num_processes=2 (processes count from 0)",
    ),
    (["train", "distributed.enabled=true"], None, "distributed: outside SLURM give distributed.coordinator_address"),
    (["train", "program_cache=sometimes"], None, "program_cache must be one of auto, always, never"),
    (["train", "return_window=-1"], None, "return_window must be an integer >= 0, got -1"),
    (["train", "guard.max_abs_loss=-1"], None, "guard.max_abs_loss must be null or a number > 0, got -1"),
    (["train", "guard.max_params_norm=0"], None, "guard.max_params_norm must be null or a number > 0, got 0"),
    (["train", "video.every_steps=-1"], None, "video.every_steps must be an integer >= 0, got -1"),
    (["train", "stop.when=garbage"], None, "stop.when='garbage' is not <eval|train>/<metric><op><number>"),
    (["train", "stop.when='eval/return=>5'"], None, "is not <eval|train>/<metric><op><number>"),
    (["train", "logger=nope"], None, "unknown logger 'nope'; choose one of: default, quiet"),
    (["train", "machine=tpu"], None, "unknown machine 'tpu'; choose one of: cpu, gpu (did you mean machine=gpu?)"),
    (["train", "experiment=nope"], None, "unknown experiment 'nope'"),
    # interpolations
    (["train", "run_name=${{nope}}"], None, "run_name: Interpolation key 'nope' not found"),
    (["train", "algo.gamma=${{run_name}}"], None, "algo.gamma must be a number, got 'cartpole-ppo'"),
    (["train", "seed=${{oops.x}}"], None, "seed: Interpolation key 'oops.x' not found"),
    (["train", "algo.lr=${{oc.env:RLQ_NO_SUCH_VARIABLE}}"], None, "Environment variable 'RLQ_NO_SUCH_VARIABLE'"),
    (["train", "hydra.run.dir=${{oops}}"], None, "hydra.run.dir: Interpolation key 'oops' not found"),
    # paths and names
    (["train", "run_name="], None, "run_name must be a non-empty name"),
    (["train", "run_name=a/b"], None, "run_name=a/b is not one directory name"),
    (["train", "run_name=.."], None, "run_name=.. is not one directory name"),
    (["train", "hydra.run.dir=/proc/rlq"], None, "hydra.run.dir=/proc/rlq cannot be created: /proc is not writable"),
    (["train", "hydra.run.dir={tmp}/afile"], None, "hydra.run.dir={tmp}/afile is a file; give a directory"),
    (["train", "compile_cache=/proc/rlqcache"], None, "compile_cache=/proc/rlqcache cannot be created"),
    # sweeps: the label names only what the sweep varies
    (["train", "-m", "algo.lr=0.1,-1"], None, "job 1 of 2 (algo.lr=-1): algo.lr must be a number > 0"),
    (["train", "-m", "seed=0,abc"], None, "job 1 of 2 (seed=abc): seed must be an integer"),
    (["train", "-m", "env=cartpole,nope"], None, "job 1 of 2 (env=nope): unknown env 'nope'"),
    (["train", "-m", "num_seeds=1,0"], None, "job 1 of 2 (num_seeds=0): num_seeds must be an integer >= 1"),
    (["train", "-m", "seed=1,1", "algo=dqn"], None, "jobs 0 and 1 of 2 are the same run (seed=1)"),
    (["train", "-m", "seed=0,1", "algo.hidden=[0, 64]"], None, "job 0 of 2 (seed=0): algo.hidden must be"),
    (["train", "-m", "seed=0,1", "+algo.lrr=1"], None, "job 0 of 2 (seed=0): unknown config key 'algo.lrr'"),
    (["train", "-m", "algo={{}}"], None, "algo={{}}: algo takes the name of one option"),
    # train's flags
    (["train", "--cfg", "nope"], None, "--cfg nope is not one of job, hydra, all"),
    (["train", "--cfg"], None, "--cfg takes one of job, hydra, all"),
    (["train", "-c", "bogus"], None, "--cfg bogus is not one of job, hydra, all"),
    # eval, render, export, resume, compare
    (["eval", "run={tmp}/afile"], None, "run={tmp}/afile is not a directory"),
    (["eval", "run="], None, "run= is empty"),
    (["eval", "run={run}", "env="], run_dir_case(), "env= is empty"),
    (["eval", "run={run}", "episodes=-1"], run_dir_case(), "episodes must be >= 1"),
    (["eval", "run={run}", "seed=-1"], run_dir_case(), "seed must be an integer in [0, 4294967295], got -1"),
    (["eval", "run={run}", "seed=4294967296"], run_dir_case(), "seed must be an integer in [0, 4294967295]"),
    (["eval", "run={run}", "checkpoint=123"], run_dir_case(), "no checkpoint step_123.msgpack in"),
    (["eval", "run={run}", "checkpoint=abc"], run_dir_case(), "no checkpoint file abc"),
    (["eval", "run={run}", "notkeyvalue"], run_dir_case(), "'notkeyvalue' is not key=value"),
    (["render", "run={run}", "steps=abc"], run_dir_case(), "steps=abc is not an integer"),
    (["render", "run={run}", "seed_index=-1"], run_dir_case(), "seed_index must be in 0..0 for this run, got -1"),
    (["render", "run={run}", "seed=-5"], run_dir_case(), "seed must be an integer in [0, 4294967295], got -5"),
    (["export", "out=x.msgpack"], None, "needs run=<run dir>"),
    (["export", "run={run}", "out="], run_dir_case(), "out= is empty"),
    (["export", "run={run}", "checkpoint=abc"], run_dir_case(), "no checkpoint file abc"),
    (["export", "run={run}", "seed_index=7"], run_dir_case(), "seed_index must be in 0..0 for this run, got 7"),
    (["resume"], None, "needs run=<run dir>"),
    # a checkpoint of another run's config (its sidecar's hash), before anything is built or metrics.jsonl cut
    (
        ["resume", "run={run}"],
        run_dir_case(foreign("step_2048"), steps=(2048,), final=False),
        "step_2048.msgpack does not belong to this run: it was written by a run of another config",
    ),
    (["eval", "run={run}"], run_dir_case(foreign("final")), "final.msgpack does not belong to this run"),
    (["eval", "run={run}", "checkpoint=2048"], run_dir_case(foreign("step_2048"), steps=(2048,)), "does not belong"),
    (["export", "run={run}"], run_dir_case(foreign("final")), "final.msgpack does not belong to this run"),
    (["resume", "run={tmp}/afile"], None, "run={tmp}/afile is not a directory"),
    (["compare"], None, "needs at least one run or multirun directory"),
    (["compare", "{tmp}/nowhere"], None, "{tmp}/nowhere is not a directory"),
    (["compare", "{tmp}", "metric=nosuch"], None, "metric=nosuch: write <kind>/<name>"),
    (["compare", "{tmp}", "threshold=high"], None, "threshold=high: not a number"),
    (["compare", "{tmp}", "threshold=inf"], None, "threshold=inf: give a finite number"),
    (["compare", "{tmp}", "threshold="], None, "threshold=: not a number"),
]


@pytest.mark.slow  # the full tables run in the full suite; the quick tier keeps the first (tests/cli/test_bad_inputs.py)
@pytest.mark.parametrize("argv, make, fragment", CASES, ids=[" ".join(c[0]) for c in CASES])
def test_bad_input_is_one_line_and_exit_2(argv, make, fragment, tmp_path, monkeypatch, capsys):
    check_bad_input(argv, make, fragment, tmp_path, monkeypatch, capsys)


def test_the_second_table_adds_at_least_40_new_inputs():
    first = {tuple(argv) for argv, _, _ in FIRST_CASES}
    assert len({tuple(argv) for argv, _, _ in CASES} - first) >= 40


@pytest.mark.slow
@pytest.mark.parametrize(
    "argv, line",
    [
        (["train", "--cfg", "nope"], "rlq: error: --cfg nope is not one of job, hydra, all (e.g. rlq train --cfg job)"),
        (["train", "algo={}"], f"rlq: error: algo={{}}: algo takes the name of one option ({ALGOS}); set its keys"),
        # the env is made (brax's model load) before DQN's check refuses its continuous actions
        (["train", "algo=dqn", "env=humanoid", "allow_untuned=true"], "rlq: error: algo=dqn needs a discrete action"),
    ],
    ids=["--cfg nope", "algo={}", "algo=dqn env=humanoid"],
)
def test_the_installed_command_prints_only_the_error_line(argv: list[str], line: str, workdir: Path):
    proc = run_cli(*argv, cwd=workdir)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(line), proc.stderr[-3000:]
    assert not list(workdir.iterdir())
