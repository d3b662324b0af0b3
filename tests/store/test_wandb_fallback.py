"""W&B's fallback to offline logging, against servers on 127.0.0.1 (no internet here): a hung server is found by
a short probe and named, empty ``WANDB_*`` variables count as unset, and the telemetry exporter stays quiet."""

from __future__ import annotations

import logging
import socket
import sys
import types

import numpy as np

from rlq.cli.main import main
from rlq.store.logging import RunLogger
from tests.helpers import compose_config


def fake_wandb(monkeypatch, modes: list) -> None:
    class FakeRun:
        def log(self, payload, step):
            modes.append(("log", step))

        def finish(self):
            pass

    def init(mode, **kwargs):
        modes.append(mode)
        return FakeRun()

    monkeypatch.setitem(sys.modules, "wandb", types.SimpleNamespace(init=init, Settings=lambda **k: None))


def test_a_server_that_accepts_and_never_answers_is_named_and_the_run_logs_offline(tmp_path, monkeypatch, capsys):
    hung = socket.create_server(("127.0.0.1", 0))  # the kernel accepts connections; nothing ever reads or answers
    port = hung.getsockname()[1]
    monkeypatch.setenv("WANDB_BASE_URL", f"http://127.0.0.1:{port}")
    modes: list = []
    fake_wandb(monkeypatch, modes)
    cfg = compose_config("logger.wandb.mode=online", "logger.console=false")
    try:
        logger = RunLogger(cfg, tmp_path, total_steps=10, num_seeds=1)
        logger.log(5, "train", {"episode_return": np.array([1.0])})
        logger.close()
    finally:
        hung.close()
    assert modes == ["offline", ("log", 5)]  # wandb's online init never waited on it
    err = capsys.readouterr().err
    assert f"W&B server 127.0.0.1:{port} accepted the connection but did not answer within 3 s" in err
    assert "AuthenticationError" not in err


def test_empty_wandb_variables_count_as_unset(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WANDB_SILENT", "")
    monkeypatch.delenv("WANDB_MODE", raising=False)
    cfg = compose_config("logger.wandb.mode=offline", "logger.console=false")
    logger = RunLogger(cfg, tmp_path, total_steps=10, num_seeds=1)
    logger.log(5, "train", {"episode_return": np.array([1.0])})
    logger.close()
    err = capsys.readouterr().err
    assert "W&B disabled" not in err and "valid boolean" not in err, err
    assert any(p.name.startswith("offline-run-") for p in (tmp_path / "wandb").iterdir())


def test_the_telemetry_exporter_says_nothing_after_a_fallback(caplog):
    main(["--version"])  # what every command sets up first
    with caplog.at_level(logging.DEBUG):
        logging.getLogger("opentelemetry.exporter.otlp.common.http").error(
            "Failed to export logs batch code: 401, reason: Unauthorized"
        )
    assert not [r for r in caplog.records if r.name.startswith("opentelemetry")]
