import json
import re
import socket
import sys
import threading
import types
import warnings
from pathlib import Path

import numpy as np
import pytest

from rlq.store.logging import ConsoleSink, RunLogger, seed_rows
from rlq.store.reachable import wandb_address
from tests.helpers import compose_config, run_cli_in_process, train_run


def test_seed_rows_have_per_seed_and_mean():
    rows = seed_rows(100, "train", {"episode_return": np.array([1.0, np.nan, 3.0])})
    assert [r["seed"] for r in rows] == [0, 1, 2, "mean"]
    assert rows[1]["episode_return"] is None
    assert rows[-1]["episode_return"] == 2.0


def test_wandb_failure_never_stops_training(tmp_path, monkeypatch, capsys):
    def broken_init(**kwargs):
        raise RuntimeError("wandb exploded")

    monkeypatch.setenv("WANDB_BASE_URL", "http://127.0.0.1:9")  # nothing listens: no network
    monkeypatch.setitem(sys.modules, "wandb", types.SimpleNamespace(init=broken_init, Settings=lambda **k: None))
    cfg = compose_config("logger.wandb.mode=online", "logger.console=false")
    logger = RunLogger(cfg, tmp_path, total_steps=10, num_seeds=1)
    logger.log(5, "train", {"episode_return": np.array([1.0])})
    logger.close()
    assert "W&B disabled" in capsys.readouterr().err
    assert json.loads((tmp_path / "metrics.jsonl").read_text().splitlines()[0])["episode_return"] == 1.0


def answering_server() -> socket.socket:
    """A local server that answers every request with 401 (a listening socket alone accepts and never answers,
    which the W&B probe takes for a hung server)."""
    server = socket.create_server(("127.0.0.1", 0))

    def serve() -> None:
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            with conn:
                conn.recv(1024)
                conn.sendall(b"HTTP/1.0 401 Unauthorized\r\nContent-Length: 0\r\n\r\n")

    threading.Thread(target=serve, daemon=True).start()
    return server


def test_wandb_online_init_failure_falls_back_to_offline(tmp_path, monkeypatch, capsys):
    """The server answers (a local listening socket) but wandb's online init fails: an offline run,
    and nothing of the failed attempt is left."""
    modes = []
    server = answering_server()
    monkeypatch.setenv("WANDB_BASE_URL", f"http://127.0.0.1:{server.getsockname()[1]}")

    class FakeRun:
        def log(self, payload, step):
            modes.append(("log", step))

        def finish(self):
            pass

    def init(mode, **kwargs):
        modes.append(mode)
        if mode == "online":
            (Path(kwargs["dir"]) / "wandb" / "run-half-made").mkdir(parents=True)
            raise ConnectionError("no network")
        return FakeRun()

    monkeypatch.setitem(sys.modules, "wandb", types.SimpleNamespace(init=init, Settings=lambda **k: None))
    cfg = compose_config("logger.wandb.mode=online", "logger.console=false")
    logger = RunLogger(cfg, tmp_path, total_steps=10, num_seeds=1)
    logger.log(5, "train", {"episode_return": np.array([1.0])})
    logger.close()
    server.close()
    assert modes == ["online", "offline", ("log", 5)]
    assert "logging offline" in capsys.readouterr().err
    assert not (tmp_path / "wandb" / "run-half-made").exists()


TINY = ("budget.env_steps=2048", "log_every_steps=1024", "eval.every_steps=0", "eval.episodes=2", "video.at_end=false")


def test_rlq_log_holds_the_console_lines_and_env_steps_are_ints(tmp_path):
    result = train_run(tmp_path, *TINY)
    rows = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    assert rows and all(type(r["env_steps"]) is int for r in rows)
    log = (tmp_path / "rlq.log").read_text()
    assert "[train @ 1,024 steps]" in log and "[eval @ 2,048 steps]" in log
    assert result.line() in log


def test_wandb_online_without_network_goes_offline_at_once(tmp_path, monkeypatch, capsys):
    """An unreachable W&B server (a closed local port): rlq's probe says so before W&B is asked, so wandb's own online
    init (which waits on its timeouts) never runs: one warning naming the server, an offline run, every row kept."""
    import wandb

    modes: list[str] = []
    real_init = wandb.init

    def init(**kwargs):
        modes.append(kwargs["mode"])
        return real_init(**kwargs)

    monkeypatch.setattr(wandb, "init", init)
    monkeypatch.setenv("WANDB_BASE_URL", "http://127.0.0.1:9")
    monkeypatch.setenv("WANDB_API_KEY", "x" * 40)
    monkeypatch.setenv("WANDB_SILENT", "true")
    monkeypatch.delenv("WANDB_MODE", raising=False)
    cfg = compose_config("logger.wandb.mode=online", "logger.console=false")
    logger = RunLogger(cfg, tmp_path, total_steps=10, num_seeds=1)
    logger.log(5, "train", {"episode_return": np.array([1.0])})
    logger.close()
    err = capsys.readouterr().err
    assert modes == ["offline"]  # no online attempt: nothing waited for a server that is not there
    assert err.count("W&B") == 1, err
    assert "W&B server 127.0.0.1:9 not reachable within 3 s; logging offline instead" in err
    runs = sorted(p.name for p in (tmp_path / "wandb").iterdir() if p.is_dir() and not p.is_symlink())
    assert runs and all(name.startswith("offline-run-") for name in runs), runs
    assert json.loads((tmp_path / "metrics.jsonl").read_text().splitlines()[0])["episode_return"] == 1.0


def test_wandb_address_is_the_base_url_or_its_proxy():
    assert wandb_address({}) == ("api.wandb.ai", 443)
    assert wandb_address({"WANDB_BASE_URL": "http://127.0.0.1:9"}) == ("127.0.0.1", 9)
    assert wandb_address({"HTTPS_PROXY": "http://proxy.local:3128"}) == ("proxy.local", 3128)
    assert wandb_address({"HTTPS_PROXY": "proxy.local:3128", "NO_PROXY": ".wandb.ai"}) == ("api.wandb.ai", 443)


def _segments(text: str) -> list[str]:
    """What a terminal shows line by line: the stream split at carriage returns and newlines."""
    return [s for s in re.split(r"[\r\n]", text) if s.strip()]


def test_warnings_print_above_the_bar_not_after_it(capsys):
    console = ConsoleSink(total_steps=100, num_seeds=2, enabled=True)
    console.advance(50, {"episode_return": 1.0})
    warnings.warn("something odd", UserWarning, stacklevel=1)
    console.close()
    shown = [s for s in _segments(capsys.readouterr().err) if "something odd" in s]
    assert shown and all(s.lstrip().startswith(("rlq: warning", "UserWarning")) for s in shown), shown


def _console_of_a_tiny_run(workdir, *overrides: str) -> list[str]:
    """What the console showed of a short run with the default logger (W&B off)."""
    proc = run_cli_in_process(
        "train", *overrides, "eval.episodes=2", "video.at_end=false", "logger.wandb.mode=disabled", cwd=workdir
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return _segments(proc.stderr)


@pytest.mark.slow
def test_progress_has_compile_train_and_eval_phases_per_seed(workdir):
    segments = _console_of_a_tiny_run(
        workdir, "num_seeds=2", "budget.env_steps=4096", "log_every_steps=2048", "eval.every_steps=0"
    )
    compiling = [i for i, s in enumerate(segments) if "compiling" in s]
    bar = [i for i, s in enumerate(segments) if "/4.10k" in s]  # per-seed steps, not 2 x 4,096
    evaluating = [i for i, s in enumerate(segments) if "evaluating" in s]
    assert compiling and bar and evaluating, segments
    assert compiling[0] < bar[0] < evaluating[0]
    assert not any("/8.19k" in s for s in segments)


def test_a_black_box_bar_counts_iterations_not_nominal_env_steps(workdir):
    """Random search's episodes end early: its true env steps fall far below the nominal budget, so
    a bar over env steps would end near 0 % with a wild ETA. It counts the 4 iterations instead."""
    segments = _console_of_a_tiny_run(
        workdir,
        "experiment=cartpole_random_search",
        "algo.population=4",
        "algo.episodes=1",
        "budget.env_steps=8000",
        "log_every_steps=1",
    )
    assert any("4/4 [" in s for s in segments), segments
    assert not any("step/s" in s for s in segments)


def test_wandb_full_disk_warns_once_and_jsonl_goes_on(tmp_path, monkeypatch, capsys):
    import errno

    class FullDiskRun:
        def log(self, payload, step):
            raise OSError(errno.ENOSPC, "No space left on device")

        def finish(self):
            raise OSError(errno.ENOSPC, "No space left on device")

    fake = types.SimpleNamespace(init=lambda **kwargs: FullDiskRun(), Settings=lambda **k: None)
    monkeypatch.setitem(sys.modules, "wandb", fake)
    cfg = compose_config("logger.wandb.mode=offline", "logger.console=false")
    logger = RunLogger(cfg, tmp_path, total_steps=10, num_seeds=1)
    for step in (5, 10):
        logger.log(step, "train", {"episode_return": np.array([float(step)])})
    logger.close()
    warnings = capsys.readouterr().err.strip().splitlines()
    assert len(warnings) == 1 and "No space left on device" in warnings[0], warnings
    rows = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    assert [r["env_steps"] for r in rows if r["seed"] == 0] == [5, 10]


def test_broken_wandb_dir_warns_and_jsonl_goes_on(tmp_path, capsys):
    (tmp_path / "wandb").write_text("a file where W&B wants its directory")
    cfg = compose_config("logger.wandb.mode=offline", "logger.console=false")
    logger = RunLogger(cfg, tmp_path, total_steps=10, num_seeds=1)
    logger.log(5, "train", {"episode_return": np.array([1.0])})
    logger.close()
    warnings = capsys.readouterr().err.strip().splitlines()
    assert len(warnings) == 1 and warnings[0].startswith("rlq: warning: W&B disabled"), warnings
    assert json.loads((tmp_path / "metrics.jsonl").read_text().splitlines()[0])["episode_return"] == 1.0


class FakeRun:
    """A W&B run that takes every call and sends nothing."""

    def log(self, payload, step):
        pass

    def finish(self):
        pass


@pytest.fixture
def fake_wandb(monkeypatch):
    monkeypatch.setitem(
        sys.modules, "wandb", types.SimpleNamespace(init=lambda mode, **k: FakeRun(), Settings=lambda **k: None)
    )


@pytest.mark.parametrize("mode", ["offline", "disabled"])
def test_an_offline_run_says_that_nothing_was_uploaded_and_how_to_upload(mode, tmp_path, fake_wandb, capsys):
    logger = RunLogger(compose_config(f"logger.wandb.mode={mode}"), tmp_path, total_steps=10, num_seeds=1)
    logger.close()
    err = capsys.readouterr().err
    line = f"nothing was uploaded: `wandb sync {tmp_path}/wandb/offline-run-*` uploads it"
    assert (line in err) == (mode == "offline"), err


def test_a_sweeps_jobs_say_how_to_upload_once(tmp_path, fake_wandb, capsys):
    (tmp_path / "multirun.yaml").write_text("{}")  # a sweep's directory: its jobs' directories within
    for job in ("0_seed=0", "1_seed=1"):
        (tmp_path / job).mkdir()
        RunLogger(compose_config("logger.wandb.mode=offline"), tmp_path / job, total_steps=10, num_seeds=1).close()
    err = capsys.readouterr().err
    assert err.count("wandb sync") == 1, err
    assert f"`wandb sync {tmp_path.resolve()}/*/wandb/offline-run-*` uploads every job's" in err
