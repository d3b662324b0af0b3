"""The one reader of a run's JSON and JSONL files (metrics.jsonl, summary.json, eval_*.json, a best checkpoint's
sidecar): what a crash leaves is read, what damage leaves is refused in one line.

A run killed during a write (kill -9, a power cut) can leave ``metrics.jsonl`` with a last line cut short: each row
goes out in one write ending in its newline, so only the last line can be torn, and it has no newline. That line is
skipped with one note. Anything else that is not a JSON object per line (garbage, a cut in the middle, a file of
another format) is damage: a ``DamagedFileError`` names the file, the line and what to do, never a traceback.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rlq.errors import DamagedFileError

#: what to do about a damaged file of a run, unless the caller says better
RESTORE = "restore it from a copy, or move it away to go on without it"
#: what to do about a damaged summary.json (train.py writes it last, from the final evaluation)
SUMMARY_FIX = "restore it from a copy, or move it away: the run's metrics.jsonl still holds its final evaluation"


@dataclass(frozen=True)
class Rows:
    """The rows of a JSONL file, each with its line as written; ``torn``: the cut last line that was skipped."""

    rows: list[dict[str, Any]]
    lines: list[str]
    torn: str | None = None


def _text(path: Path, fix: str) -> str:
    try:
        return path.read_text()
    except UnicodeDecodeError:
        raise DamagedFileError(f"{path} is damaged (not UTF-8 text); {fix}") from None


def read_json(path: Path, fix: str = RESTORE) -> Any:
    """The JSON value in ``path``; DamagedFileError (naming it and ``fix``) when it is not JSON."""
    path = Path(path)
    try:
        return json.loads(_text(path, fix))
    except json.JSONDecodeError as err:
        raise DamagedFileError(f"{path} is damaged (not JSON: {err.msg}, line {err.lineno}); {fix}") from None


def read_json_object(path: Path, fix: str = RESTORE) -> dict[str, Any]:
    """``read_json`` of a file that holds one object (a summary, a sidecar)."""
    found = read_json(path, fix)
    if not isinstance(found, dict):
        raise DamagedFileError(f"{path} is damaged (a JSON {type(found).__name__}, not an object); {fix}")
    return found


def read_rows(path: Path, fix: str = RESTORE, note: bool = True) -> Rows:
    """The rows (JSON objects, one per line) of ``path``, blank lines left out; a torn last line (no newline, not
    JSON) is skipped, with one note on stderr where ``note``. An absent file has no rows."""
    path = Path(path)
    if not path.exists():
        return Rows([], [])
    text = _text(path, fix)
    lines = text.split("\n")
    rows: list[dict[str, Any]] = []
    kept: list[str] = []
    torn = None
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
        except json.JSONDecodeError as err:
            if number == len(lines):  # the last line, with no newline after it: a write cut short
                torn = line
                break
            raise DamagedFileError(f"{path} is damaged (line {number} is not JSON: {err.msg}); {fix}") from None
        if not isinstance(row, dict):
            raise DamagedFileError(f"{path} is damaged (line {number} is not a JSON object); {fix}")
        rows.append(row)
        kept.append(line)
    if torn is not None and note:
        print(
            f"rlq: note: {path}: skipped its last line, cut short ({len(torn)} characters; a write stopped midway)",
            file=sys.stderr,
            flush=True,
        )
    return Rows(rows, kept, torn)
