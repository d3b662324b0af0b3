"""Where the Hydra configs are."""

from __future__ import annotations

from pathlib import Path


def _conf_dir() -> Path:
    """The Hydra configs: ``rlq/conf`` in an installed wheel, the repository's top-level ``conf/`` in a checkout
    (an editable install; a stale ``rlq/conf/`` left by an older checkout, without config.yaml, is not it)."""
    package = Path(__file__).resolve().parent.parent
    installed = package / "conf"
    return installed if (installed / "config.yaml").is_file() else package.parent / "conf"


CONF_DIR = _conf_dir()
