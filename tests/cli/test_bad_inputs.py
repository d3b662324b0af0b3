"""Bad inputs to every subcommand: one line on stderr, exit 2, nothing compiled, nothing left on disk.

The cases run in-process (``rlq.cli.main.main``) under ``refuse_to_train`` (tests/helpers.py): the training entry,
``build`` (the gateway to every compiled program of eval, render and export), a distributed join and ``os._exit``
fail the test at once, so a case whose refusal stopped applying fails with one clear line instead of training a
real run in the test process (or ending it, and the pytest worker with it).
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from rlq.cli.main import main
from rlq.store import checkpoint
from rlq.store.lock import run_lock
from tests.helpers import NOT_REFUSED, compose_config, quick_sample, refuse_to_train

TINY = ["logger=quiet", "budget.env_steps=4096", "log_every_steps=2048", "eval.episodes=2"]


def make_run(
    root: Path, name: str = "run", steps: tuple[int, ...] = (), final: bool = True, overrides: tuple[str, ...] = ()
) -> Path:
    """A run directory as `rlq train <overrides>` leaves it: config, intact checkpoints (of a dummy state)."""
    run_dir = root / name
    (run_dir / ".hydra").mkdir(parents=True)
    cfg = compose_config(*TINY, "checkpoint.every_steps=2048", *overrides)
    OmegaConf.save(cfg, run_dir / ".hydra" / "config.yaml")
    (run_dir / "metrics.jsonl").write_text("")
    state = {"w": np.arange(64, dtype=np.float32)}
    for step in steps:
        checkpoint.save(run_dir / "checkpoints", f"step_{step}", state, {"env_steps": step, "chunks_done": 1})
    if final:  # a finished run: its final checkpoint, then its summary (written last)
        checkpoint.save(run_dir / "checkpoints", "final", state, {"env_steps": 4096})
        summary = {"env_steps": 4096, "num_seeds": 1, "eval_return": [20.0], "final_eval": {"return": [20.0]}}
        (run_dir / "summary.json").write_text(json.dumps(summary))
    return run_dir


def truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def flip_byte(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def run_dir_case(mutate=None, **kwargs):
    """A run dir (made in the test's directory) changed by ``mutate``; the case's ``{run}``."""

    def make(root: Path) -> Path:
        run_dir = make_run(root, **kwargs)
        if mutate is not None:
            mutate(run_dir)
        return run_dir

    return make


CKPT = "checkpoints/final.msgpack"
#: a CartPole run evaluated on an env with LunarLander's spaces
SPACES = (
    "env={env} gives observations of shape (8,) and actions Discrete(4); "
    "this run's policy was trained on env=cartpole: {obs} and actions Discrete(2)"
)
CARTPOLE_OBS = "observations of shape (4,)"

#: (argv with {run} / {tmp} placeholders, how to make {run}, a fragment of the error line)
CASES = [
    # train: unknown names and keys
    (["train", "algo=nope"], None, "unknown algo 'nope'"),
    (["train", "env=nope"], None, "unknown env 'nope'"),
    (["train", "env=cartpol"], None, "unknown env 'cartpol'; choose one of: brittle_star"),
    (["train", "env=cartpol"], None, "(did you mean env=cartpole?)"),
    (["train", "algo=ppoo"], None, "(did you mean algo=ppo?)"),
    (
        ["train", "algo.lrr=1e-3"],
        None,
        "unknown config key 'algo.lrr'; `rlq train --cfg job` lists the keys (did you mean algo.lr?)",
    ),
    (["train", "algo=dqn", "algo.gama=0.9"], None, "(did you mean algo.gamma?)"),
    (["train", "algo.lr=1e-3,3e-3"], None, "algo.lr=1e-3,3e-3 gives several values, which is a sweep: add -m"),
    (["train", "-m", "seed=0,0"], None, "jobs 0 and 1 of 2 are the same run (seed=0), which would share one directory"),
    (["train", "-m", "seed=0,1,0", "algo=dqn"], None, "jobs 0 and 2 of 3 are the same run (seed=0)"),
    (["train", "seed=99999999999999999999"], None, "seed must be an integer in [0, 4294967295], got 9999"),
    (["train", "seed=9223372036854775808"], None, "seed must be an integer in [0, 4294967295]"),
    (["train", "budget.env_steps=1e30"], None, "budget.env_steps must be an integer in [1, 2147483647]"),
    (["train", "algo.lr=${{oops}}"], None, "algo.lr: Interpolation key 'oops' not found"),
    (["train", "-m", "algo.lr=1e-3,${{oops}}"], None, "job 1 of 2"),
    (["train", "run_name=../../escape"], None, "run_name=../../escape is not one directory name"),
    (["train", "run_name=" + "a" * 300], None, "run_name is 300 bytes long; give at most 200"),
    (["train", "controller=nope"], None, "unknown controller 'nope'"),
    (["train", "foo=1"], None, "unknown config key 'foo'"),
    (["train", "algo.lr"], None, "is not an override"),
    (["train", "~seed=0"], None, "'~seed=0': a key cannot be deleted (each has its declared default); write seed="),
    (["train", "~algo.lr=0.00025"], None, "a key cannot be deleted"),
    # train: types, ranges, enums
    (["train", "num_seeds=abc"], None, "num_seeds must be an integer"),
    (["train", "num_seeds=0"], None, "num_seeds must be an integer >= 1"),
    (["train", "algo.lr=fast"], None, "algo.lr must be a number"),
    (["train", "algo.num_envs=-2"], None, "algo.num_envs must be an integer >= 1"),
    (["train", "budget.env_steps=0"], None, "budget.env_steps must be an integer in [1, 2147483647], got 0"),
    (["train", "+compiler_options.xla_no_such_option=1"], None, "compiler_options: INVALID_ARGUMENT: No such compile"),
    (["train", "compiler_options={{xla_gpu_autotune_level:0}}"], None, "adds to with a leading +: +compiler_options="),
    (["train", "+algo.lrr=1e-3"], None, "unknown config key 'algo.lrr' (in +algo.lrr=1e-3)"),
    (["train", "algo.lrr=1e-3"], None, "unknown config key 'algo.lrr'; `rlq train --cfg job` lists the keys"),
    (["train", "compile_cache={tmp}/afile/cache"], None, "compile_cache={tmp}/afile/cache cannot be created"),
    (["train", "compile_cache={tmp}/afile"], None, "compile_cache={tmp}/afile is a file"),
    (["train", "seed=-1"], None, "seed must be an integer in [0, 4294967295], got -1"),
    (["train", "algo.gamma=1.5"], None, "algo.gamma must be a number in [0, 1], got 1.5"),
    (["train", "algo=dqn", "algo.gamma=-0.1"], None, "algo.gamma must be a number in [0, 1]"),
    (["train", "algo.gae_lambda=2"], None, "algo.gae_lambda must be a number in [0, 1]"),
    (["train", "algo.lr=0"], None, "algo.lr must be a number > 0"),
    (["train", "algo.clip_eps=-1"], None, "algo.clip_eps must be a number > 0"),
    (["train", "algo.activation=nope"], None, "algo.activation must be one of tanh, relu"),
    (["train", "algo.hidden=[0]"], None, "algo.hidden must be a list of integers >= 1"),
    (["train", "logger.wandb.mode=bogus"], None, "logger.wandb.mode must be one of offline, online, disabled"),
    (["train", "chunk_loop=nope"], None, "chunk_loop must be one of scan, calls"),
    (["train", "eval.episodes=0"], None, "eval.episodes must be an integer >= 1"),
    (["train", "video.max_steps=0"], None, "video.max_steps must be null or an integer >= 1"),
    (["train", "env.max_episode_steps=0"], None, "env.max_episode_steps must be null or an integer >= 1"),
    (["train", "algo=dqn", "algo.epsilon.start=2"], None, "algo.epsilon.start and algo.epsilon.end must lie in"),
    (["train", "algo=reinforce", "algo.baseline=nope"], None, "algo.baseline must be one of"),
    (["train", "algo=map_elites", "algo.archive.shape=[0,20]"], None, "algo.archive.shape must be a list of"),
    (["train", "algo=map_elites", "algo.archive.shape=[20.5,20]"], None, "integers >= 1, e.g. [20,20], got [20.5"),
    (["train", "algo=map_elites", "algo.descriptor=landing"], None, "landing is not reported by this env"),
    (["train", "algo=map_elites", "algo.descriptor_dims=[0,9]"], None, "has 4 components (the observation's size)"),
    (["train", "algo=map_elites", "algo.emitter=cma"], None, "algo.emitter must be one of gaussian, iso_line, improv"),
    (["train", "algo=map_elites", "algo.archive.kind=cvt", "algo.archive.cvt_samples=10"], None, "is below algo.arch"),
    (["train", "env=lunar", "env.gravity=5"], None, "env.gravity must be in (-12, 0)"),
    (
        ["train", "env=cartpole", "env.max_episode_steps=null"],
        None,
        "env.max_episode_steps must be an integer >= 1 on CartPole",
    ),
    (
        ["train", "env=lunar", "env.max_episode_steps=null"],
        None,
        "env.max_episode_steps=null (no time limit) cannot be",
    ),
    (
        ["train", "env=lunar", "+eval.env.max_episode_steps=null"],
        None,
        "eval.env.max_episode_steps=null (no time limit) cannot be evaluated",
    ),
    (["train", "stop.when='eval/nosuch>=1'"], None, "eval rows have no 'nosuch'; they have: length, return"),
    # train: combinations
    (["train", "algo.num_minibatches=3"], None, "must divide"),
    (["train", "algo=dqn", "env=lunar", "env.continuous=true"], None, "algo=dqn needs a discrete action space"),
    (["train", "controller=cpg"], None, "controller=cpg needs a brittle star env"),
    (["train", "algo=qlearning", "env.discretize=null"], None, "algo=qlearning needs discrete observations"),
    (
        ["train", "algo=random_search", "env=lunar", "algo.ars.clip_actions=false"],
        None,
        "algo.ars.clip_actions=false hands the env actions outside its bounds",
    ),
    (["train", "env=lunar_box2d"], None, "runs on the host"),
    (
        ["train", "experiment=brittle_star_qlearning_decentralised", "controller.mode=leading_arm"],
        None,
        "algo=qlearning: one state per arm (env.observation=arm_sectors) needs one action per arm",
    ),
    (
        ["train", "experiment=brittle_star_qlearning_decentralised", "algo.replay_size=100"],
        None,
        "algo.replay_size=100 cannot hold one step's 10240 transitions",
    ),
    # train: output directories
    (["train", "hydra.run.dir={tmp}/afile/run"], None, "cannot be created"),
    (["train", "hydra.run.dir={run}"], run_dir_case(), "already holds a finished rlq run; choose another"),
    (["train", "hydra.run.dir={run}"], run_dir_case(steps=(2048,), final=False), "continue it with `rlq resume"),
    (["train", "hydra.run.dir="], None, "hydra.run.dir is empty"),
    (["train", "algo=nope", "--cfg", "job"], None, "unknown algo 'nope'"),
    (["train", "-m", "seed=0,1", "--cfg", "job"], None, "-m and --cfg/--info do not combine"),
    # as a run refuses them: Hydra would print the config with the tuned file deleted under the line naming it
    (["train", "~tuned", "--cfg", "job"], None, "'~tuned' is not an override; write key=value"),
    (["train", "~seed=0", "--cfg", "job"], None, "'~seed=0': a key cannot be deleted"),
    (["train", "algo.lr", "--info"], None, "'algo.lr' is not an override"),
    (
        ["train", "--cfg", "job", "--package", "algo.nosuch"],
        None,
        "--package algo.nosuch: --cfg job prints no such key; algo has: name, num_envs",
    ),
    (["train", "--cfg", "hydra", "-p", "run"], None, "--cfg hydra prints no such key; its top-level keys are: hydra"),
    (["train", "--package", "algo"], None, "--package algo picks the part of the config that --cfg prints: add --cfg"),
    # multirun: every job checked before the first starts
    (["train", "-m", "algo=dqn,nope"], None, "job 1 of 2 (algo=nope): unknown algo 'nope'"),
    (["train", "-m", "seed=0,1", "algo.gamma=2"], None, "job 0 of 2 (seed=0): algo.gamma must be"),
    (["train", "-m", "hydra.sweep.dir={tmp}/afile/sweep", "seed=0,1"], None, "hydra.sweep.dir"),
    (
        ["train", "-m", "hydra.sweep.dir={tmp}", "seed=0,1"],
        run_dir_case(),
        "holds finished jobs of an earlier sweep (run)",
    ),
    (["export", "run={run}", "out={tmp}"], run_dir_case(), "is a directory; give a file name"),
    (["export", "run={run}", "out={tmp}/afile/p.msgpack"], run_dir_case(), "cannot be written: {tmp}/afile is a file"),
    (["export", "run={run}", "seed_index=abc"], run_dir_case(), "seed_index=abc is not an integer"),
    # eval
    (["eval"], None, "needs run=<run dir>"),
    (["eval", "run={tmp}/nowhere"], None, "is not a directory"),
    (["eval", "run={tmp}"], None, "is not an rlq run directory"),
    (["eval", "run={run}", "episodes=0"], run_dir_case(), "episodes must be >= 1"),
    (["eval", "run={run}", "episodes=abc"], run_dir_case(), "episodes=abc is not an integer"),
    (["eval", "run={run}", "seed=1.5"], run_dir_case(), "seed=1.5 is not an integer"),
    (["eval", "run={run}", "bogus=1"], run_dir_case(), "unknown option 'bogus'"),
    (["eval", "run={run}", "env=nope"], run_dir_case(), "unknown env 'nope'"),
    (["eval", "run={run}"], run_dir_case(lambda d: truncate(d / ".hydra/config.yaml")), "truncated or corrupt"),
    (
        ["eval", "run={run}"],
        run_dir_case(lambda d: (d / ".hydra/config.yaml").write_text("algo: [unclosed\n")),
        "unreadable (truncated or corrupt)",
    ),
    (["eval", "run={run}"], run_dir_case(lambda d: truncate(d / CKPT)), "final.msgpack is truncated"),
    (["eval", "run={run}"], run_dir_case(lambda d: flip_byte(d / CKPT)), "final.msgpack is corrupt"),
    (["eval", "run={run}"], run_dir_case(lambda d: (d / "checkpoints/final.json").unlink()), "has no sidecar"),
    (["eval", "run={run}"], run_dir_case(final=False), "no checkpoint in"),
    # eval: env overrides checked as `rlq train` checks them
    (
        ["eval", "run={run}", "env.max_episode_steps=-1"],
        run_dir_case(),
        "env.max_episode_steps must be null or an integer >= 1, got -1",
    ),
    (
        ["eval", "run={run}", "env.max_episode_steps=abc"],
        run_dir_case(),
        "env.max_episode_steps must be an integer, got 'abc'",
    ),
    (
        ["eval", "run={run}", "env.max_episode_steps=null"],
        run_dir_case(overrides=("env=lunar",)),
        "env=lunar: env.max_episode_steps=null (no time limit) cannot be evaluated",
    ),
    (["eval", "run={run}", "env.nosuchkey=1"], run_dir_case(), "unknown config key 'env.nosuchkey' of env=cartpole"),
    (["eval", "run={run}", "env.gravity=-9.8"], run_dir_case(), "unknown config key 'env.gravity' of env=cartpole"),
    # eval: an env whose spaces the run's policy does not fit
    (["eval", "run={run}", "env=lunar_box2d"], run_dir_case(), SPACES.format(env="lunar_box2d", obs=CARTPOLE_OBS)),
    (["eval", "run={run}", "env=lunar"], run_dir_case(), SPACES.format(env="lunar", obs=CARTPOLE_OBS)),
    (["eval", "run={run}", "env=humanoid"], run_dir_case(), "env=humanoid gives observations of shape (244,)"),
    (["eval", "run={run}", "env=lunar"], run_dir_case(overrides=("algo=map_elites",)), "trained on env=cartpole"),
    (
        ["eval", "run={run}", "env=lunar"],
        run_dir_case(overrides=("experiment=cartpole_qlearning",)),
        SPACES.format(env="lunar", obs="observations Discrete(648)"),
    ),
    # render
    (["render", "run={run}", "seed_index=5"], run_dir_case(), "seed_index must be in 0..0"),
    (["render", "run={run}", "steps=0"], run_dir_case(), "steps must be >= 1"),
    (["render", "run={run}", "seed=abc"], run_dir_case(), "seed=abc is not an integer"),
    (["render", "run={run}", "seed_index=x"], run_dir_case(), "seed_index=x is not an integer"),
    (["render", "run={run}", "checkpoint={tmp}/nope.msgpack"], run_dir_case(), "no checkpoint"),
    (["render", "run={run}", "env=lunar"], run_dir_case(), SPACES.format(env="lunar", obs=CARTPOLE_OBS)),
    (["render", "run={run}", "env.nosuchkey=1"], run_dir_case(), "unknown config key 'env.nosuchkey' of env=cartpole"),
    (["render", "run={run}"], run_dir_case(lambda d: flip_byte(d / CKPT)), "final.msgpack is corrupt"),
    # resume
    (["resume", "run={run}"], run_dir_case(), "has finished"),
    (["resume", "run={run}", "env.gravity=1"], run_dir_case(), "a resumed run keeps its config"),
    (  # trained without periodic checkpoints (tests/cli/test_bad_inputs_third.py: with them, killed before the first)
        ["resume", "run={run}"],
        run_dir_case(final=False, overrides=("checkpoint.every_steps=0",)),
        "checkpoint.every_steps>0",
    ),
    (
        ["resume", "run={run}"],
        run_dir_case(lambda d: truncate(d / "checkpoints/step_2048.msgpack"), steps=(2048,), final=False),
        "no intact checkpoint",
    ),
    (["resume", "run={tmp}/nowhere"], None, "is not a directory"),
    (
        ["train", "shaped_for.note=use experiment=x"],
        None,
        "cannot read the override 'shaped_for.note=use experiment=x'",
    ),
    (["train", "shaped_for.platform=tpu"], None, "shaped_for.platform must be null or one of cpu, gpu, got 'tpu'"),
    # no such command
    (["fly"], None, "unknown command 'fly'"),
]


@pytest.mark.parametrize("argv, make, fragment", quick_sample(CASES, 5), ids=[" ".join(c[0]) for c in CASES])
def test_bad_input_is_one_line_and_exit_2(argv, make, fragment, tmp_path, monkeypatch, capsys):
    check_bad_input(argv, make, fragment, tmp_path, monkeypatch, capsys)


def check_bad_input(argv, make, fragment, tmp_path, monkeypatch, capsys) -> None:
    """``rlq <argv>`` in-process: exit 2, one to three lines ending in ``rlq: error: ...<fragment>...``, no
    traceback, nothing new under ``tmp_path``."""
    monkeypatch.chdir(tmp_path)
    refuse_to_train(monkeypatch)
    (tmp_path / "afile").write_text("not a directory")
    run_dir = make(tmp_path) if make else tmp_path / "run"
    before = sorted(p for p in tmp_path.rglob("*"))
    argv = [a.format(run=run_dir, tmp=tmp_path) for a in argv]
    fragment = fragment.format(run=run_dir, tmp=tmp_path)
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    err = capsys.readouterr().err
    assert exit_info.value.code == 2, err
    lines = err.strip().splitlines()
    assert 1 <= len(lines) <= 3 and "Traceback" not in err, err
    assert lines[-1].startswith("rlq: error: ") and fragment in lines[-1], lines
    assert sorted(p for p in tmp_path.rglob("*")) == before  # no run dir, no checkpoint, nothing new


def test_the_table_covers_every_subcommand_with_30_cases():
    commands = {argv[0] for argv, _, _ in CASES}
    assert {"train", "eval", "render", "resume"} <= commands
    assert len(CASES) >= 30


@pytest.mark.parametrize(
    "argv, make, stopped_by",
    [
        (["train", *TINY], None, "training started (rlq train launched its job)"),
        (["train", "-m", *TINY, "seed=0,1"], None, "training started (rlq train handed its jobs to Hydra)"),
        (["resume", "run={run}"], run_dir_case(steps=(2048,), final=False), "training started"),
        (["eval", "run={run}"], run_dir_case(), "it reached build()"),
        (["export", "run={run}", "out={tmp}/p.msgpack"], run_dir_case(), "it reached build()"),
    ],
    ids=["train", "train -m", "resume", "eval", "export"],
)
def test_an_input_that_is_not_refused_fails_its_case_before_anything_compiles(
    argv, make, stopped_by, tmp_path, monkeypatch, capsys
):
    """A valid input in the table (a refusal that stopped applying) fails the case at the training entry or at
    build, with the line saying so, instead of training a run in the test process."""
    with pytest.raises(pytest.fail.Exception, match=re.escape(f"{NOT_REFUSED} {stopped_by}")):
        check_bad_input(argv, make, "never printed", tmp_path, monkeypatch, capsys)


def test_a_run_dir_in_use_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    refuse_to_train(monkeypatch, jobs=True)  # the job takes the lock
    stopped = make_run(tmp_path, steps=(2048,), final=False)
    fresh = tmp_path / "fresh"
    for run_dir, argv in ((stopped, ["resume", f"run={stopped}"]), (fresh, ["train", f"hydra.run.dir={fresh}"])):
        with run_lock(run_dir), pytest.raises(SystemExit) as exit_info:
            main(argv)
        lines = capsys.readouterr().err.strip().splitlines()
        assert exit_info.value.code == 2
        assert len(lines) == 1 and f"is in use by another rlq process (pid {os.getpid()})" in lines[0]
    assert (stopped / "metrics.jsonl").read_text() == ""  # resume touched nothing
    assert sorted(p.name for p in fresh.iterdir()) == ["rlq.lock"]
