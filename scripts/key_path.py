"""Which files of rlq a config key's value passes through, from the command line to the compiled update: a tiny
`rlq train` with the key set to a marked value, every call of an rlq function watched (``sys.setprofile``).

    python scripts/key_path.py --key algo.lr [--out path.json] [-- more overrides]

A function "takes the value" when one of its arguments or locals at the call is the value itself (a number, a small
NumPy array of it, or the command-line item that sets it) or a container that holds it directly: the algorithm's
section, its typed ``Config``, a dict of hyperparameters. Containers of whole configs (a RunSpec, the composed config,
the command's list of overrides) are counted apart, as ``whole``: every function handed the run's config holds every
key, so they say how far the config travels, not the key. Prints one line per file (the functions) and writes the
JSON with ``--out``. Bad input: one line, exit 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import threading
from collections.abc import Mapping
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent / "rlq"
#: the marked value: a number no config sets
MARK = 0.000987654
MARK_TEXT = "0.000987654"
TINY = ["algo=ppo", "env=cartpole", "budget.env_steps=4096", "eval.every_steps=0", "eval.episodes=2",
        "video.at_end=false", "logger.wandb.mode=disabled", "checkpoint.every_steps=0"]  # fmt: skip
#: keys of a whole run config: a mapping holding one of them holds every section
WHOLE_KEYS = ("algo", "env", "seed")


def is_mark(value: Any) -> bool:
    """The marked value itself, as a number, a small float array or the text that sets it."""
    if isinstance(value, float):
        return abs(value - MARK) < 1e-9
    if isinstance(value, str):
        return MARK_TEXT in value
    if isinstance(value, np.ndarray) and value.dtype.kind == "f" and 0 < value.size <= 64:
        return bool(np.any(np.abs(value - MARK) < 1e-9))
    return False


def members(value: Any) -> list[Any] | None:
    """The direct members of a container (a mapping, a dataclass, a list or tuple), None for anything else."""
    if isinstance(value, Mapping):
        return list(value.values())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return [getattr(value, field.name, None) for field in dataclasses.fields(value)]
    if isinstance(value, (list, tuple)):
        return list(value)
    return None


def is_whole(value: Any) -> bool:
    """A whole run config (its sections side by side) or the command's list of overrides."""
    if isinstance(value, Mapping):
        return any(key in value for key in WHOLE_KEYS)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        names = {field.name for field in dataclasses.fields(value)}
        return {"values", "overrides"} <= names
    return isinstance(value, (list, tuple)) and len(value) > 1 and all(isinstance(item, str) for item in value)


def holds(value: Any, depth: int = 1) -> bool:
    """``value`` is the mark or holds it within ``depth`` containers (never through ``JAX`` arrays: no device read)."""
    try:
        if is_mark(value):
            return True
        inside = members(value) if depth > 0 else None
        return bool(inside) and any(holds(item, depth - 1) for item in inside[:256])
    except Exception:  # a container whose members cannot be read (a lazy node): not counted
        return False


class Watch:
    """The rlq functions that took the value (``path``) or a whole config holding it (``whole``), per file."""

    def __init__(self) -> None:
        self.path: dict[str, set[str]] = {}
        self.whole: dict[str, set[str]] = {}

    def __call__(self, frame: FrameType, event: str, arg: Any) -> None:
        if event != "call" or not frame.f_code.co_filename.startswith(str(ROOT)):
            return
        where = str(Path(frame.f_code.co_filename).relative_to(ROOT.parent))
        for name, value in list(frame.f_locals.items()):
            if is_whole(value):
                if holds(value, depth=3):
                    self.whole.setdefault(where, set()).add(f"{frame.f_code.co_name}({name})")
            elif holds(value):
                self.path.setdefault(where, set()).add(f"{frame.f_code.co_name}({name})")
                return


def parse_args(argv: list[str] | None = None) -> tuple[argparse.Namespace, list[str]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--key", default="algo.lr", help="a numeric key of the run, e.g. algo.lr, algo.gamma")
    parser.add_argument("--out", type=Path, help="write the result as JSON here")
    args, extra = parser.parse_known_args(argv)
    extra = [item for item in extra if item != "--"]
    if not args.key or "=" in args.key or " " in args.key:
        parser.exit(2, f"key_path: --key must be a config key such as algo.lr, got {args.key!r}\n")
    return args, extra


def main(argv: list[str] | None = None) -> int:
    args, extra = parse_args(argv)
    from rlq.cli.main import main as rlq_main

    watch = Watch()
    with tempfile.TemporaryDirectory() as work:
        command = ["train", *TINY, f"{args.key}={MARK_TEXT}", *extra, f"hydra.run.dir={work}/run"]
        sys.setprofile(watch)
        threading.setprofile(watch)
        try:
            rlq_main(command)
        except SystemExit as stop:
            if stop.code:
                sys.setprofile(None)
                print(f"key_path: rlq {' '.join(command)} exited with {stop.code}", file=sys.stderr)
                return 2
        finally:
            sys.setprofile(None)
            threading.setprofile(None)  # type: ignore[arg-type]
    result = {
        "key": args.key,
        "command": "rlq " + " ".join(command[:-1]),
        "path_files": {where: sorted(calls) for where, calls in watch.path.items()},
        "whole_config_files": sorted(watch.whole),
    }
    for where, calls in result["path_files"].items():
        print(f"{where}: {', '.join(calls[:6])}")
    print(
        f"{args.key}: {len(watch.path)} files take the value or its section; the whole config reaches {len(watch.whole)}"
    )
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
