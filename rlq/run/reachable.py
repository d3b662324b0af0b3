"""Whether the W&B server answers, asked with a short timeout before ``wandb.init`` in online mode:
without network, wandb's own init waits about 90 s before it gives up."""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Mapping
from urllib.parse import urlsplit

DEFAULT_BASE_URL = "https://api.wandb.ai"


def wandb_address(environ: Mapping[str, str] = os.environ) -> tuple[str, int]:
    """Host and port the W&B client connects to: ``WANDB_BASE_URL`` (default api.wandb.ai), or the
    proxy that ``HTTPS_PROXY``/``HTTP_PROXY`` names for it."""
    url = urlsplit(environ.get("WANDB_BASE_URL") or DEFAULT_BASE_URL)
    no_proxy = [h.strip() for h in (environ.get("NO_PROXY") or environ.get("no_proxy") or "").split(",") if h.strip()]
    proxy = environ.get(f"{url.scheme.upper()}_PROXY") or environ.get(f"{url.scheme}_proxy")
    if proxy and not any((url.hostname or "").endswith(h.lstrip(".")) for h in no_proxy):
        url = urlsplit(proxy if "://" in proxy else f"http://{proxy}")
    return url.hostname or "", url.port or (443 if url.scheme == "https" else 80)


def reachable(host: str, port: int, timeout_s: float = 3.0) -> bool:
    """Whether a TCP connection to ``host:port`` opens within ``timeout_s`` (name lookup included:
    it runs in a thread, since a lookup without network ignores socket timeouts)."""
    result: list[bool] = []

    def connect() -> None:
        try:
            socket.create_connection((host, port), timeout=timeout_s).close()
            result.append(True)
        except OSError:
            result.append(False)

    thread = threading.Thread(target=connect, daemon=True)
    thread.start()
    thread.join(timeout_s)
    return bool(result and result[0])
