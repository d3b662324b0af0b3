"""How long a tuned pair's plain command takes on the machine it is about to run on (conf/expected.yaml),
said before anything compiles, with the quick alternative where that is over 5 minutes; and, for a recipe the matrix
measured short of its goal, what it reaches instead and which recipe reaches the goal."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from rlq.config.conf_dir import CONF_DIR
from rlq.config.plain import read_recorded, select
from rlq.config.spec import RunSpec, as_spec

#: a run expected to take longer says so, with the quick alternative
LONG_S = 300.0
MACHINES = {"cpu": "2 idle CPU cores", "gpu": "one H200"}


@dataclass(frozen=True)
class Expected:
    seconds: float
    source: str
    device: str  # where it was measured, e.g. "one H200"


def _table() -> dict[str, Any]:
    data = read_recorded(CONF_DIR / "expected.yaml")
    return {str(key): value for key, value in dict(data).items()}


def expected(pair: str, machine: str, table: dict[str, Any] | None = None) -> Expected | None:
    """The measured seconds of pair ``<env>_<algo>``'s plain command on ``machine`` (cpu or gpu), or None. A source
    measured on another device than the machine's usual one names it under ``devices`` (e.g. one H100)."""
    table = _table() if table is None else table
    entry = table["pairs"].get(pair, {}).get(machine)
    if entry is None:
        return None
    device = dict(table.get("devices") or {}).get(entry[1], MACHINES[machine])
    return Expected(float(entry[0]), str(table["sources"][entry[1]]), str(device))


def duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min"


def plain_command(run: RunSpec | Mapping[str, Any], choices: dict[str, Any]) -> bool:
    """Whether the run runs what the table measured: the pair's tuned budget and one seed."""
    spec = as_spec(run)
    pair, budget = f"{choices['env']}_{choices['algo']}", None
    for path in (
        CONF_DIR / "tuned" / f"{pair}.yaml",
        CONF_DIR / "tuned" / "machine" / f"{pair}_{choices.get('machine')}.yaml",
    ):
        if path.is_file():  # the machine's file, applied last, wins
            budget = select(read_recorded(path), "budget.env_steps", budget)
    return int(spec.seeds.count) == 1 and (budget is None or float(budget) == float(spec.budget.env_steps))


def measured_pair(run: RunSpec | Mapping[str, Any], choices: dict[str, Any]) -> str | None:
    """``<env>_<algo>`` where the run is what conf/expected.yaml measured (a tuned pair's plain command), else None."""
    env, algo = choices.get("env"), choices.get("algo")
    if not env or not algo or not (CONF_DIR / "tuned" / f"{env}_{algo}.yaml").is_file():
        return None
    return f"{env}_{algo}" if plain_command(run, choices) else None


def expected_line(run: RunSpec | Mapping[str, Any], choices: dict[str, Any]) -> str | None:
    """The line a run prints before it compiles: its pair's measured time on this kind of machine (the ``machine``
    choice), and over ``LONG_S`` the quick alternative. None for a pair without a tuned file or a run that is not
    the measured command (another budget or seed count)."""
    pair = measured_pair(run, choices)
    if pair is None:
        return None
    machine = (
        "gpu" if choices.get("machine") == "gpu" else "cpu"
    )  # a GPU node's recipe pinned to its CPU: measured there
    table = _table()
    here, gpu = expected(pair, machine, table), expected(pair, "gpu", table)
    if here is None:
        on_gpu = (
            f" ({gpu.device}: {duration(gpu.seconds)}, {gpu.source})" if gpu is not None and machine == "cpu" else ""
        )
        return f"rlq: expected time on {MACHINES[machine]}: not measured for this recipe{on_gpu}"
    line = f"rlq: expected time: about {duration(here.seconds)} on {here.device} ({here.source})"
    if here.seconds <= LONG_S:
        return line
    quick = []
    if machine == "cpu" and gpu is not None:
        quick.append(f"a GPU ({duration(gpu.seconds)} on {gpu.device})")
    alternative = table["pairs"][pair].get("alternative")  # [env, algo]: a quicker recipe for the same task
    if alternative:
        other = expected("_".join(alternative), machine, table)
        took = f" ({duration(other.seconds)} here)" if other is not None else ""
        quick.append(f"`rlq train algo={alternative[1]} env={alternative[0]}`{took}")
    return f"{line}; quicker: {' or '.join(quick)}" if quick else line


def shortfall_line(run: RunSpec | Mapping[str, Any], choices: dict[str, Any]) -> str | None:
    """The line a run of a recipe that falls short of the matrix's goal prints before it compiles: what its held-out
    seeds reached (``short`` in conf/expected.yaml) and the recipe for the same task that reaches the goal
    (``alternative``). None for other pairs and for a run that is not the measured command."""
    pair = measured_pair(run, choices)
    entry = _table()["pairs"].get(pair, {}) if pair is not None else {}
    if "short" not in entry:
        return None
    line = f"rlq: this recipe falls short of the matrix's goal: {entry['short']} (docs/matrix.md)"
    alternative = entry.get("alternative")
    return f"{line}; `rlq train algo={alternative[1]} env={alternative[0]}` reaches it" if alternative else line
