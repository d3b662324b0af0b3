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


#: what ``probe`` sends: any HTTP server (or TLS server, or proxy) answers it at once, with a page, an error or a close
_REQUEST = b"HEAD / HTTP/1.0\r\nHost: %b\r\n\r\n"


def probe(host: str, port: int, timeout_s: float = 3.0) -> str | None:
    """Why the W&B server at ``host:port`` will not serve a run, or None: no connection within ``timeout_s``, or a
    connection accepted but no answer to a request within ``timeout_s`` (a hung server or proxy: wandb's own init
    would wait on it and report an AuthenticationError)."""
    result: list[str | None] = []

    def ask() -> None:
        try:
            with socket.create_connection((host, port), timeout=timeout_s) as conn:
                conn.sendall(_REQUEST % host.encode())
                try:
                    conn.recv(1)
                except TimeoutError:
                    result.append(f"accepted the connection but did not answer within {timeout_s:.0f} s")
                    return
                except OSError:
                    pass  # reset: it answered, if rudely
            result.append(None)
        except OSError:
            result.append(f"not reachable within {timeout_s:.0f} s")

    thread = threading.Thread(target=ask, daemon=True)
    thread.start()
    thread.join(2 * timeout_s)  # connect, then the answer
    return result[0] if result else f"not reachable within {timeout_s:.0f} s"
