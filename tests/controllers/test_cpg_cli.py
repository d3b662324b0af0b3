"""`rlq train` with the CPG controller on the brittle star, end to end (tiny: ~3 min on 2 CPU cores,
nearly all of it MJX compilation), and the one-line errors of bad combinations."""

import pytest

from tests.helpers import run_cli_in_process

pytest.importorskip("biorobot")

pytestmark = pytest.mark.slow

TINY_BRITTLE_STAR = [
    "env=brittle_star",
    "env.segments_per_arm=1",
    "env.simulation_time=0.2",  # 5 control steps per episode
    "env.physics.wall_contacts=false",
    "algo=ppo",
    "algo.num_envs=2",
    "algo.num_steps=8",
    "algo.num_minibatches=2",
    "algo.update_epochs=1",
    "budget.env_steps=32",
    "log_every_steps=16",
    "eval.every_steps=0",
    "eval.episodes=2",
    "logger=quiet",
]


def test_ppo_drives_the_leading_arm_cpg(workdir):
    proc = run_cli_in_process("train", *TINY_BRITTLE_STAR, "controller=cpg", "controller.mode=leading_arm", cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = proc.stdout.strip().splitlines()[-1]
    assert summary.startswith("rlq: 32 env steps") and "brittle_star-ppo" in summary


@pytest.mark.parametrize(
    "overrides, fragment",
    [
        (
            ["controller=cpg", "env=cartpole"],
            "controller=cpg needs a brittle star env (env=brittle_star or env=brittle_star_undirected)",
        ),
        (["controller=cpg", "env=brittle_star", "controller.mode=gallop"], "controller.mode must be one of"),
        (
            ["controller=cpg", "env=brittle_star", "controller.leading_arm=7"],
            "controller.leading_arm must be null or an arm index",
        ),
        (["env=brittle_star", "env.num_arms=0"], "env.num_arms must be between 1 and 5"),
    ],
)
def test_bad_combination_exits_2_with_one_line(workdir, overrides, fragment):
    proc = run_cli_in_process("train", *overrides, cwd=workdir)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0], proc.stderr
    assert not (workdir / "outputs").exists()
