"""The one reader of a run's JSON files (rlq/store/jsonfiles.py): a torn last line is skipped with a note, damage is
refused in one line that names the file and what to do."""

from __future__ import annotations

import json

import pytest

from rlq.errors import DamagedFileError
from rlq.store.jsonfiles import read_json_object, read_rows
from rlq.store.logging import drop_rows_after

ROWS = [{"kind": "train", "env_steps": 512 * i, "seed": 0, "loss": 0.5} for i in (1, 2, 3)]


def lines(rows) -> str:
    return "".join(json.dumps(r) + "\n" for r in rows)


def test_whole_rows_are_read_and_blank_lines_left_out(tmp_path):
    path = tmp_path / "metrics.jsonl"
    path.write_text(lines(ROWS[:2]) + "\n" + lines(ROWS[2:]))
    assert read_rows(path).rows == ROWS
    assert read_rows(tmp_path / "absent.jsonl").rows == []


def test_a_torn_last_line_is_skipped_with_one_note(tmp_path, capsys):
    path = tmp_path / "metrics.jsonl"
    path.write_text(lines(ROWS[:2]) + json.dumps(ROWS[2])[:17])
    found = read_rows(path)
    assert found.rows == ROWS[:2] and found.torn == json.dumps(ROWS[2])[:17]
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"rlq: note: {path}: skipped its last line, cut short (17 characters; a write stopped midway)"]


@pytest.mark.parametrize(
    "text, problem",
    [
        (lines(ROWS[:1]) + "garbage\n" + lines(ROWS[1:]), "line 2 is not JSON: Expecting value"),
        (lines(ROWS) + "garbage\n", "line 4 is not JSON"),  # a whole line (it ends in a newline): not a torn write
        (lines(ROWS[:1]) + "[1, 2]\n", "line 2 is not a JSON object"),
    ],
    ids=["middle", "last-with-newline", "not-an-object"],
)
def test_a_damaged_file_is_refused_naming_it_the_line_and_what_to_do(tmp_path, text, problem):
    path = tmp_path / "metrics.jsonl"
    path.write_text(text)
    with pytest.raises(DamagedFileError) as info:
        read_rows(path)
    assert str(info.value).startswith(f"{path} is damaged ({problem}")
    assert "restore it from a copy, or move it away" in str(info.value)


def test_a_summary_that_is_not_json_or_not_an_object_is_refused(tmp_path):
    path = tmp_path / "summary.json"
    path.write_text('{"eval_return": [1.0, ')
    with pytest.raises(DamagedFileError, match=f"{path} is damaged \\(not JSON: Expecting value, line 1\\)"):
        read_json_object(path)
    path.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(DamagedFileError, match="not UTF-8 text"):
        read_json_object(path)
    path.write_text("[1, 2]")
    with pytest.raises(DamagedFileError, match="a JSON list, not an object"):
        read_json_object(path)


def test_dropping_rows_after_a_checkpoint_also_drops_a_torn_last_line(tmp_path, capsys):
    path = tmp_path / "metrics.jsonl"
    path.write_text(lines(ROWS) + '{"kind": "tra')
    drop_rows_after(path, 1024)
    assert path.read_text() == lines(ROWS[:2])
    assert "skipped its last line" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["metrics.jsonl"]  # replaced whole, no temporary left
