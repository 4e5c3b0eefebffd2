"""The meshcat server process of the viewer, listening on 127.0.0.1 only.

:class:`cdpm.viewer.Viewer` starts ``python -m cdpm.viewer`` (which runs
:func:`_serve`) in a subprocess through :class:`_Server`, reads the zmq and
web URLs it prints, and stops it on close. meshcat and tornado are imported
only in that subprocess.
"""

from __future__ import annotations

import contextlib
import functools
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from cdpm.errors import CdpmError, InputError

__all__ = ["LOOPBACK", "SERVER_TIMEOUT", "check_port"]

#: The only address the viewer's servers listen on.
LOOPBACK = "127.0.0.1"

#: Seconds to wait for the meshcat server to start or to answer.
SERVER_TIMEOUT = 20.0


def _serve(argv: list[str] | None = None) -> None:
    """Run a meshcat server whose zmq and web ports listen on 127.0.0.1 only.

    meshcat 0.3.2's ``ZMQWebSocketBridge`` binds zmq to its ``host``
    (127.0.0.1 by default) but calls tornado's ``Application.listen(port)``
    without an address, which listens on every interface; the web app's
    ``listen`` is pinned to the loopback address here.
    """
    # only `python -m cdpm.viewer` parses arguments
    import argparse

    # optional: cdpm[viz]
    import tornado.ioloop
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    parser = argparse.ArgumentParser(prog="python -m cdpm.viewer")
    parser.add_argument(
        "--port", type=int, default=None, help="web port (default: first free from 7000)"
    )
    args = parser.parse_args(argv)

    class LoopbackBridge(ZMQWebSocketBridge):
        def make_app(self):
            app = super().make_app()
            app.listen = functools.partial(app.listen, address=LOOPBACK)
            return app

    bridge = LoopbackBridge(host=LOOPBACK, port=args.port)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    # stop when the process that started us is gone (e.g. a killed kernel)
    parent = os.getppid()

    def check_parent() -> None:
        if os.getppid() != parent:
            bridge.ioloop.stop()

    tornado.ioloop.PeriodicCallback(check_parent, 1000).start()
    with contextlib.suppress(KeyboardInterrupt):
        bridge.run()


def check_port(port: Any) -> int:
    """``port`` as an int when it is a TCP port (1-65535).

    Raises:
        InputError: it is not.
    """
    try:
        value = int(str(port).strip())
    except ValueError:
        value = 0
    if not 1 <= value <= 65535:
        raise InputError(
            f"port {port} is not a TCP port; use 1-65535 (or omit it: the first free from 7000)"
        )
    return value


class _Server:
    """A meshcat server subprocess (see :func:`_serve`) and its log file."""

    def __init__(self, port: int | None) -> None:
        self.log = tempfile.NamedTemporaryFile(prefix="cdpm-meshcat-", suffix=".log", delete=False)
        args = [sys.executable, "-u", "-m", "cdpm.viewer"]
        if port is not None:
            args += ["--port", str(int(port))]
        self.process = subprocess.Popen(
            args,
            stdin=subprocess.DEVNULL,
            stdout=self.log,
            stderr=subprocess.STDOUT,
            start_new_session=True,  # Ctrl-C in a terminal or notebook reaches us, not it
        )
        self.zmq_url, self.web_url = self._wait_for_urls(port)

    def _wait_for_urls(self, port: int | None) -> tuple[str, str]:
        deadline = time.monotonic() + SERVER_TIMEOUT
        while time.monotonic() < deadline:
            text = Path(self.log.name).read_text(errors="replace")
            urls = dict(
                line.split("=", 1)
                for line in text.splitlines()
                if line.startswith(("zmq_url=", "web_url="))
            )
            if "zmq_url" in urls and "web_url" in urls:
                return urls["zmq_url"], urls["web_url"]
            if self.process.poll() is not None:
                self.close()
                hint = (
                    f"; is port {port} in use? choose another port or omit it"
                    if port is not None and "Address already in use" in text
                    else ""
                )
                raise CdpmError(f"the meshcat server exited at start{hint}:\n{text.strip()}")
            time.sleep(0.02)
        self.close()
        raise CdpmError(f"the meshcat server did not start within {SERVER_TIMEOUT:g} s")

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.log.close()
        with contextlib.suppress(OSError):
            os.unlink(self.log.name)
