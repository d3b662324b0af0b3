"""In-program sweeps (rlq/run/programs/members.py): `rlq train 'sweep.algo.lr=[a,b]' num_seeds=2` trains both members in
one program, and each member's directory holds what its separate run would write."""

import json

import numpy as np
import pytest
from omegaconf import OmegaConf

from rlq.errors import ConfigError
from rlq.run.programs import members
from rlq.store import checkpoint
from tests.helpers import compose_config, run_cli, run_cli_in_process, run_dirs

TINY = [
    "num_seeds=2",
    "budget.env_steps=4096",
    "log_every_steps=1024",
    "checkpoint.every_steps=2048",
    "eval.every_steps=2048",
    "eval.episodes=2",
    "video.at_end=false",
    "logger.wandb.mode=disabled",
]


def trained(workdir, *overrides):
    workdir.mkdir(exist_ok=True)
    proc = run_cli_in_process("train", *TINY, *overrides, cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = run_dirs(workdir)
    return run_dir, proc


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    return trained(tmp_path_factory.mktemp("swept"), "sweep.algo.lr=[1e-3,3e-3]", "sweep.algo.ent_coef=[0.0,0.01]")


def rows(run_dir):
    lines = (run_dir / "metrics.jsonl").read_text().splitlines()
    return [{k: v for k, v in json.loads(line).items() if k != "wall_s"} for line in lines]


@pytest.mark.slow
def test_a_member_is_its_separate_run(swept, tmp_path):
    """The third member (lr 3e-3, no entropy bonus) trains on the seeds and with the values its own run has:
    the same checkpoints, the same rows, the same greedy returns."""
    run_dir, _ = swept
    separate, _ = trained(tmp_path / "separate", "algo.lr=3e-3", "algo.ent_coef=0.0")
    member = run_dir / "members" / "algo.lr=0.003,algo.ent_coef=0.0"
    for name in ("step_2048", "final"):
        got = checkpoint.leaves(member / "checkpoints" / f"{name}.msgpack")
        want = checkpoint.leaves(separate / "checkpoints" / f"{name}.msgpack")
        assert len(got) == len(want)
        for a, b in zip(got, want, strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
    got, want = rows(member), rows(separate)
    assert [(r["kind"], r["env_steps"], r["seed"]) for r in got] == [
        (r["kind"], r["env_steps"], r["seed"]) for r in want
    ]
    for a, b in zip(got, want, strict=True):
        assert a.keys() == b.keys()
        numbers = [k for k in a if k not in ("kind", "seed")]
        assert [a[k] for k in numbers] == pytest.approx([b[k] for k in numbers], rel=1e-5, abs=1e-6)
    summary = json.loads((member / "summary.json").read_text())
    assert summary["eval_return"] == json.loads((separate / "summary.json").read_text())["eval_return"]
    assert OmegaConf.load(member / ".hydra" / "config.yaml").algo.lr == 3e-3


@pytest.mark.slow
def test_the_sweep_writes_every_member_a_table_and_a_line_each(swept):
    run_dir, proc = swept
    names = sorted(p.name for p in (run_dir / "members").iterdir())
    assert names == [
        "algo.lr=0.001,algo.ent_coef=0.0",
        "algo.lr=0.001,algo.ent_coef=0.01",
        "algo.lr=0.003,algo.ent_coef=0.0",
        "algo.lr=0.003,algo.ent_coef=0.01",
    ]
    table = (run_dir / "sweep_summary.csv").read_text().splitlines()
    assert table[0].startswith("run,algo.ent_coef,algo.lr") and len(table) == 5
    assert sum(line.startswith("rlq: member ") for line in proc.stdout.splitlines()) == 4
    assert "train (8 seeds" in proc.stderr or "8 seed(s)" in proc.stdout


@pytest.mark.slow
def test_a_member_directory_is_a_run_for_eval_and_compare(swept, tmp_path):
    run_dir, _ = swept
    member = run_dir / "members" / "algo.lr=0.001,algo.ent_coef=0.0"
    proc = run_cli("eval", f"run={member}", "episodes=2", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert len(json.loads((member / "eval_cartpole.json").read_text())["per_seed_return"]) == 2
    out = tmp_path / "members"
    proc = run_cli("compare", str(run_dir / "members"), f"out={out}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert out.with_suffix(".png").stat().st_size > 0


@pytest.mark.slow
def test_eval_of_the_sweeps_own_directory_names_a_member_in_one_line(swept, tmp_path):
    """The sweep's directory holds every member's seeds in one checkpoint: eval, render and export take a member."""
    run_dir, _ = swept
    proc = run_cli("eval", f"run={run_dir}", "episodes=2", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr[-3000:]
    (line,) = proc.stderr.strip().splitlines()
    assert "in-program sweep" in line and str(run_dir / "members" / "algo.lr=0.001,algo.ent_coef=0.0") in line


@pytest.mark.slow
def test_pqn_sweeps_its_learning_rate_and_lambda(tmp_path):
    run_dir, proc = trained(tmp_path, "algo=pqn", "num_seeds=1", "sweep.algo.lr=[1e-3,3e-3]", "sweep.algo.lam=[0.65]")
    assert sorted(p.name for p in (run_dir / "members").iterdir()) == [
        "algo.lr=0.001,algo.lam=0.65",
        "algo.lr=0.003,algo.lam=0.65",
    ]
    assert (
        OmegaConf.load(run_dir / "members" / "algo.lr=0.003,algo.lam=0.65" / ".hydra" / "config.yaml").algo.lam == 0.65
    )


@pytest.mark.slow
def test_es_sweeps_its_width_in_one_program_each_member_as_its_separate_run(tmp_path):
    """ES's ``sigma`` is the width of the state its ``init`` makes: a member's init takes its own value."""
    tiny = ("algo=es", "num_seeds=1", "algo.population=4", "algo.episodes=1", "budget.env_steps=6000")
    run_dir, _ = trained(tmp_path / "swept", *tiny, "sweep.algo.sigma=[0.2,0.8]")
    separate, _ = trained(tmp_path / "separate", *tiny, "algo.sigma=0.8")
    got = checkpoint.leaves(run_dir / "members" / "algo.sigma=0.8" / "checkpoints" / "final.msgpack")
    want = checkpoint.leaves(separate / "checkpoints" / "final.msgpack")
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
    returns = [json.loads((d / "summary.json").read_text())["eval_return"] for d in (run_dir / "members").iterdir()]
    assert len(returns) == 2


def test_members_are_every_combination_first_key_slowest():
    cfg = compose_config("num_seeds=2", "seed=0", "+sweep.algo.lr=[1.0,2.0]", "+sweep.algo.gamma=[0.9,0.99]")
    assert members.members(cfg) == [
        {"algo.lr": 1.0, "algo.gamma": 0.9},
        {"algo.lr": 1.0, "algo.gamma": 0.99},
        {"algo.lr": 2.0, "algo.gamma": 0.9},
        {"algo.lr": 2.0, "algo.gamma": 0.99},
    ]
    values = members.seed_values(cfg, 2)
    np.testing.assert_array_equal(values["lr"], [1, 1, 1, 1, 2, 2, 2, 2])
    np.testing.assert_allclose(values["gamma"], [0.9, 0.9, 0.99, 0.99] * 2)
    assert members.program_config(cfg).seeds.count == 8


def test_a_sweep_s_program_is_the_algorithm_s_with_each_seed_s_values_in_the_chunk_s_argument():
    """No wrapper: the state is the algorithm's, the swept values are the chunk's hyperparameters, member-major."""
    import jax

    from rlq.run.programs.build import build

    cfg = compose_config("num_seeds=2", "seed=0", "+sweep.algo.lr=[1e-3,3e-3]", "algo.num_envs=4")
    program = members.program_config(cfg)
    programs = build(program)
    np.testing.assert_array_equal(programs.hyper["lr"], np.float32([1e-3, 1e-3, 3e-3, 3e-3]))
    np.testing.assert_array_equal(programs.hyper["gamma"], np.full(4, np.float32(cfg.algo.gamma)))
    assert set(programs.hyper) == set(programs.algo.hyperparams)
    swept = jax.eval_shape(programs.init, members.init_keys(program), programs.hyper)
    four = compose_config("num_seeds=4", "seed=0", "algo.num_envs=4")
    alone_programs = build(four)
    alone = jax.eval_shape(alone_programs.init, members.init_keys(four), alone_programs.hyper)
    assert jax.tree.structure(swept) == jax.tree.structure(alone)


def test_a_layout_1_sweep_checkpoint_reads_as_the_algorithm_s_state(tmp_path):
    """rlq before the hyperparameters left the state wrote a sweep's checkpoints with each seed's swept values after
    the algorithm's state (its last leaves, sorted by name): they are left out, the config gives them again."""
    import json as json_

    cfg = compose_config("num_seeds=2", "+sweep.algo.lr=[1.0,2.0]", "+sweep.algo.gamma=[0.9,0.99]")
    state = [np.arange(8.0, dtype=np.float32), np.ones((8, 3), np.float32)]
    values = members.seed_values(cfg, 2)
    old = checkpoint.save(tmp_path / "old", "step_8", [*state, values["gamma"], values["lr"]], {"env_steps": 8})
    sidecar = json_.loads(old.with_suffix(".json").read_text())
    del sidecar[checkpoint.LAYOUT_KEY]
    old.with_suffix(".json").write_text(json_.dumps(sidecar))
    new = checkpoint.save(tmp_path / "new", "step_8", state, {"env_steps": 8})
    for path in (old, new):
        got = members.state_leaves(path, cfg)
        assert len(got) == len(state) and all(np.array_equal(a, b) for a, b in zip(got, state, strict=True))
        restored = members.load_state(path, state, cfg)
        assert all(np.array_equal(a, b) for a, b in zip(restored, state, strict=True))
    alone = compose_config("num_seeds=8")
    assert len(members.state_leaves(new, alone)) == 2 and len(checkpoint.leaves(old)) == 4


@pytest.mark.parametrize(
    ("sweep", "words"),
    [
        ({"algo": {"num_envs": [4, 8]}}, "algo=ppo sweeps algo.lr, algo.clip_eps"),
        ({"env": {"gravity": [9.0]}}, "use `rlq train -m env.gravity=a,b` for any key"),
        ({"algo": {"lr": 0.1}}, "give a list"),
        ({"algo": {"lr": []}}, "at least one value"),
        ({"algo": {"lr": ["fast"]}}, "'fast' is not a finite number"),
    ],
)
def test_a_sweep_the_program_cannot_run_is_refused(sweep, words):
    cfg = compose_config("algo=ppo")
    cfg.sweep = sweep
    with pytest.raises(ConfigError, match=words.replace("(", r"\(").replace("`", ".")):
        members.check(cfg, ("lr", "clip_eps"))


def same_run(got, want) -> None:
    """Two runs of one sweep ended alike: the program's final checkpoint and rows, every member's checkpoints, rows
    and summary, and the members' table."""
    for a, b in zip(
        checkpoint.leaves(got / "checkpoints/final.msgpack"),
        checkpoint.leaves(want / "checkpoints/final.msgpack"),
        strict=True,
    ):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
    assert [(r["kind"], r["env_steps"], r["seed"]) for r in rows(got)] == [
        (r["kind"], r["env_steps"], r["seed"]) for r in rows(want)
    ]
    names = sorted(p.name for p in (want / "members").iterdir())
    assert sorted(p.name for p in (got / "members").iterdir()) == names
    for name in names:
        for ckpt in sorted(p.name for p in (want / "members" / name / "checkpoints").glob("*.msgpack")):
            for a, b in zip(
                checkpoint.leaves(got / "members" / name / "checkpoints" / ckpt),
                checkpoint.leaves(want / "members" / name / "checkpoints" / ckpt),
                strict=True,
            ):
                np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
        got_rows, want_rows = rows(got / "members" / name), rows(want / "members" / name)
        assert [(r["kind"], r["env_steps"], r["seed"]) for r in got_rows] == [
            (r["kind"], r["env_steps"], r["seed"]) for r in want_rows
        ]
        for a, b in zip(got_rows, want_rows, strict=True):
            numbers = [k for k in a if k not in ("kind", "seed")]
            assert [a[k] for k in numbers] == pytest.approx([b[k] for k in numbers], rel=1e-5, abs=1e-6)
        summary = json.loads((got / "members" / name / "summary.json").read_text())
        wanted = json.loads((want / "members" / name / "summary.json").read_text())
        assert summary["eval_return"] == pytest.approx(wanted["eval_return"], rel=1e-5)
        assert summary["member_of"] == str(got)
        assert not list((got / "members" / name).rglob(".*.tmp-*"))
    table, wanted_table = ((run / "sweep_summary.csv").read_text().splitlines() for run in (got, want))
    assert [line.split(",")[0] for line in table] == [line.split(",")[0] for line in wanted_table]
    assert len(table) == len(wanted_table) == 5


@pytest.mark.slow
def test_a_sweep_killed_while_training_or_writing_its_members_resumes_to_the_uninterrupted_runs_end(swept, tmp_path):
    """kill -9 during the second chunk (a torn metrics row, a leftover temporary), and kill -9 while the members
    were written (one member half written, no table): `rlq resume` ends both as the uninterrupted sweep ended."""
    import shutil

    run_dir, _ = swept
    killed = tmp_path / "killed"
    shutil.copytree(run_dir, killed)
    shutil.rmtree(killed / "members")
    for path in [*(killed / "checkpoints").glob("final.*"), killed / "summary.json", killed / "sweep_summary.csv"]:
        path.unlink()
    (killed / "checkpoints" / ".step_4096.msgpack.tmp-4242").write_bytes(b"\0" * 1000)
    with open(killed / "metrics.jsonl", "a") as metrics:
        metrics.write('{"kind": "train", "env_steps": 30')
    proc = run_cli_in_process("resume", f"run={killed}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (
        "from step_2048" in proc.stdout
        and sum(line.startswith("rlq: member ") for line in proc.stdout.splitlines()) == 4
    )
    same_run(killed, run_dir)

    half = tmp_path / "half"
    shutil.copytree(run_dir, half)
    (half / "sweep_summary.csv").unlink()
    last = half / "members" / "algo.lr=0.003,algo.ent_coef=0.01"
    for path in [last / "summary.json", *(last / "checkpoints").glob("final.*")]:
        path.unlink()
    (last / "metrics.jsonl").write_text((last / "metrics.jsonl").read_text()[:100])
    (last / "checkpoints" / ".final.msgpack.tmp-4242").write_bytes(b"\0" * 1000)
    proc = run_cli_in_process("resume", f"run={half}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "stopped while writing its members: writing them" in proc.stdout and "resuming" not in proc.stdout
    same_run(half, run_dir)
    proc = run_cli_in_process("resume", f"run={half}", cwd=tmp_path)
    assert proc.returncode == 2 and "has finished" in proc.stderr
