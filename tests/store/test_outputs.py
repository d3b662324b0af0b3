"""The output guard (rlq/store/outputs.py): rlq replaces regular files only and never nests a run in another."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from rlq.errors import OutputError
from rlq.store.files import write_atomic
from rlq.store.outputs import check_output_file, check_run_dir, enclosing_run


def test_an_absent_path_and_a_regular_file_may_be_written(tmp_path):
    check_output_file(tmp_path / "new.msgpack", "out")
    (tmp_path / "old.msgpack").write_bytes(b"old")
    check_output_file(tmp_path / "old.msgpack", "out")
    write_atomic(tmp_path / "old.msgpack", b"new")
    assert (tmp_path / "old.msgpack").read_bytes() == b"new"


@pytest.mark.parametrize("device", ["/dev/null", "/dev/full"])
def test_a_device_is_refused_and_stays_a_device(device):
    with pytest.raises(OutputError, match=f"out={device} is a character device, not a regular file"):
        check_output_file(Path(device), "out")
    with pytest.raises(OutputError, match="is a character device"):
        write_atomic(Path(device), b"never written")
    assert stat.S_ISCHR(os.lstat(device).st_mode)


def test_a_fifo_is_refused_and_stays_a_fifo(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(OutputError, match=f"out={fifo} is a FIFO, not a regular file"):
        check_output_file(fifo, "out")
    with pytest.raises(OutputError, match="is a FIFO"):
        write_atomic(fifo, b"never written")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]  # no temporary left


def test_a_symlink_to_elsewhere_is_refused_and_its_target_kept(tmp_path):
    target = tmp_path / "elsewhere" / "precious.txt"
    target.parent.mkdir()
    target.write_text("keep me")
    link = tmp_path / "out.msgpack"
    link.symlink_to(target)
    with pytest.raises(OutputError, match=f"out={link} is a symlink \\(to {target}\\)"):
        check_output_file(link, "out")
    with pytest.raises(OutputError, match="is a symlink"):
        write_atomic(link, b"never written")
    assert link.is_symlink() and target.read_text() == "keep me"


def test_a_directory_is_refused_as_a_file(tmp_path):
    with pytest.raises(OutputError, match=f"out={tmp_path} is a directory; give a file name"):
        check_output_file(tmp_path, "out")


def make_run(root: Path) -> Path:
    (root / ".hydra").mkdir(parents=True)
    (root / ".hydra" / "config.yaml").write_text("seed: 0\n")
    (root / "checkpoints").mkdir()
    return root


@pytest.mark.parametrize("inside", ["checkpoints", "checkpoints/new", ".hydra", "members/lr=0.1", "videos"])
def test_a_run_directory_inside_another_run_is_refused(tmp_path, inside):
    run = make_run(tmp_path / "run")
    assert enclosing_run(run / inside) == run
    with pytest.raises(OutputError, match=f"hydra.run.dir={run / inside} is inside the run {run}; runs do not nest"):
        check_run_dir(run / inside, "hydra.run.dir")


def test_a_run_directory_beside_a_run_its_own_or_an_empty_one_is_accepted(tmp_path):
    run = make_run(tmp_path / "run")
    assert enclosing_run(tmp_path / "other") is None
    check_run_dir(tmp_path / "other", "hydra.run.dir")
    check_run_dir(run, "hydra.run.dir")  # a run stopped before its first checkpoint starts over in place
    (tmp_path / "empty").mkdir()
    check_run_dir(tmp_path / "empty", "hydra.run.dir")


def test_a_run_directory_that_is_no_directory_or_not_rlqs_is_refused(tmp_path):
    os.mkfifo(tmp_path / "pipe")
    with pytest.raises(OutputError, match="hydra.run.dir=.*/pipe is a FIFO; give a directory"):
        check_run_dir(tmp_path / "pipe", "hydra.run.dir")
    with pytest.raises(OutputError, match="hydra.run.dir=/dev/null is a character device; give a directory"):
        check_run_dir(Path("/dev/null"), "hydra.run.dir")
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(OutputError, match="is a symlink"):
        check_run_dir(tmp_path / "link", "hydra.run.dir")
    (tmp_path / "home").mkdir()
    (tmp_path / "home" / "thesis.tex").write_text("mine")
    with pytest.raises(OutputError, match="holds files rlq did not write; give a new or empty directory"):
        check_run_dir(tmp_path / "home", "hydra.run.dir")
