"""Every `rlq` command README.md shows (its first run, its three paths and its Examples block), run as a new
user would type it, at a tiny budget, through rlq's entry point in this process (``run_cli_in_process``: the same
exit codes and output, without 24 cold starts of Python and JAX; tests/cli/test_install.py runs the installed `rlq`
command itself).

The walk runs the commands in the README's order in one empty directory, so that `eval`, `render`,
`export`, `compare` and `resume` find runs made by the commands before them. What changes from the
README's text, and why:
- every `rlq train` gets a tiny budget (`TINY`), so the walk takes minutes, not hours;
- commands whose env is not CartPole (LunarLander, the MJX envs) and GPU-shaped recipes are walked
  with `--cfg job`: composed and printed, not trained;
- the SLURM sweep runs as typed and must end in rlq's one line saying that this machine has no
  `sbatch` (exit 2), which is what a user sees off the cluster;
- placeholders (`outputs/<date>/<time>_<name>`, `multirun/<date>/<time>`, in any command, `init_from=` too)
  become the directories the walk made; `rlq resume ... budget.env_steps=N` extends to twice the tiny budget; a run the README names by another env's preset (`..._brittle_star_map_elites`,
  `..._lunar_dqn`) is stood in for by a CartPole run of the same kind (an archive; a stopped run).
A new command in the README that the walk does not know fails the test, so the README stays walked.
"""

from __future__ import annotations

import re
import shlex
import shutil
import time
from pathlib import Path

import pytest

from tests.helpers import REPO, run_cli_in_process

pytestmark = pytest.mark.slow

TINY_STEPS = 4096
TINY = [f"budget.env_steps={TINY_STEPS}", "video.at_end=false", "eval.episodes=2"]
NOT_TRAINED_HERE = ("env=lunar", "experiment=lunar", "env=humanoid", "experiment=humanoid", "brittle_star", "--cfg")
OFF_THE_CLUSTER = "hydra/launcher=slurm"
PLACEHOLDER = re.compile(r"(outputs|multirun)/<date>/<time>(_[\w-]+)?")


def bash_commands(text: str) -> list[str]:
    """The `rlq` commands of the ```bash blocks in ``text``, in order, comments stripped."""
    commands = []
    for block in text.split("```bash")[1:]:
        for line in block.split("```", 1)[0].splitlines():
            command = line.split("  #", 1)[0].strip()
            if command.startswith("rlq "):
                commands.append(command)
    return commands


def readme_commands() -> list[str]:
    """Every `rlq` command README.md shows: its ```bash blocks' lines and its tables' `rlq ...` cells, in order."""
    commands = []
    for part in re.split(r"(```bash.*?```)", (REPO / "README.md").read_text(), flags=re.DOTALL):
        if part.startswith("```bash"):
            commands += bash_commands(part)
        else:
            rows = (line for line in part.splitlines() if line.startswith("|"))
            commands += [span for row in rows for span in re.findall(r"`(rlq [^`]+)`", row)]
    return commands


def walked_argv(command: str, made: dict[str, Path]) -> list[str]:
    """The argv the walk runs for one README command (see the module docstring)."""
    words = shlex.split(command)
    assert words[0] == "rlq", command
    verb, args = words[1], resolved(words[2:], made, command)
    if verb == "train":
        if OFF_THE_CLUSTER in args:
            return [verb, *args]
        if any(marker in word for word in args for marker in NOT_TRAINED_HERE):
            return [verb, *args, *([] if "--cfg" in args else ["--cfg", "job"])]
        return [verb, *tiny(args)]
    if verb == "resume" and any(word.startswith("budget.env_steps=") for word in args):
        # an extension: to twice the tiny budget the walk's runs were trained with
        return [verb, *(w for w in args if not w.startswith("budget.env_steps=")), f"budget.env_steps={2 * TINY_STEPS}"]
    return [verb, *args]


def resolved(args: list[str], made: dict[str, Path], command: str) -> list[str]:
    """``args`` with each placeholder (also inside ``init_from=...``) replaced by the run the walk made of its kind."""
    out = []
    for word in args:
        match = PLACEHOLDER.search(word)
        if match:
            key = match.group(0).split("<time>", 1)[1] or "multirun"
            assert key in made, f"the walk made no run for {word!r} (README: {command})"
            word = word.replace(match.group(0), str(made[key]))
        out.append(word)
    return out


def tiny(args: list[str]) -> list[str]:
    """``args`` with the tiny budget's keys set (replacing the README's own values of those keys)."""
    keys = {setting.split("=", 1)[0] for setting in TINY}
    return [word for word in args if word.split("=", 1)[0] not in keys] + TINY


def newest(root: Path) -> Path:
    return max((p for p in root.glob("*/*") if p.is_dir()), key=lambda p: p.stat().st_mtime)


def run_walked(*argv: str, cwd: Path):
    """``rlq <argv>`` in this process; a run that trains starts in a second of its own. Hydra names a run's directory
    by the second it starts (conf/config.yaml: ``${now:%H-%M-%S}_${run_name}``) and rlq refuses to write into a
    finished run's directory: a walk with warm program caches can start two CartPole runs within one second, which
    a person typing the README's commands cannot."""
    if argv[0] == "train" and "--cfg" not in argv:
        started = int(time.time())
        while int(time.time()) == started:
            time.sleep(0.05)
    return run_cli_in_process(*argv, cwd=cwd)


def stand_ins(workdir: Path, made: dict[str, Path]) -> None:
    """CartPole runs of the kinds the README's other-env placeholders name."""
    archive = run_walked("train", "algo=map_elites", "algo.episodes=1", *TINY, cwd=workdir)
    assert archive.returncode == 0, archive.stderr[-2000:]
    made["_brittle_star_map_elites"] = newest(workdir / "outputs")
    stopped = run_walked("train", "budget.env_steps=65536", "checkpoint.every_steps=16384", *TINY[1:], cwd=workdir)
    assert stopped.returncode == 0, stopped.stderr[-2000:]
    run = newest(workdir / "outputs")
    checkpoints = run / "checkpoints"
    assert any(p.name.startswith("step_") for p in checkpoints.iterdir()), sorted(checkpoints.iterdir())
    for final in checkpoints.glob("final.*"):
        final.unlink()  # as if the job had been stopped before its end
    made["_lunar_dqn"] = run


def test_every_readme_example_runs(tmp_path: Path) -> None:
    commands = readme_commands()
    examples = bash_commands((REPO / "README.md").read_text().split("## Examples", 1)[1].split("\n## ", 1)[0])
    assert len(examples) >= 10, examples
    made: dict[str, Path] = {}
    stand_ins(tmp_path, made)
    for command in commands:
        argv = walked_argv(command, made)
        result = run_walked(*argv, cwd=tmp_path)
        shown = f"README: {command}\nwalked: rlq {' '.join(argv)}\n{result.stderr[-3000:]}"
        assert "Traceback" not in result.stderr + result.stdout, shown
        if OFF_THE_CLUSTER in argv:
            assert result.returncode == 2, shown
            assert result.stderr.strip().splitlines()[-1].startswith("rlq: error:"), shown
            assert "sbatch" in result.stderr, shown
            continue
        assert result.returncode == 0, shown
        assert "Traceback" not in result.stderr + result.stdout, shown
        if argv[0] == "train" and "--cfg" not in argv:
            root = tmp_path / ("multirun" if "-m" in argv else "outputs")
            latest = newest(root)
            made["multirun" if "-m" in argv else "_" + latest.name.split("_", 1)[1]] = latest
    shutil.rmtree(tmp_path / "outputs", ignore_errors=True)
