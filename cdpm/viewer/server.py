"""The meshcat server process of the viewer, listening on 127.0.0.1 only.

:class:`cdpm.viewer.Viewer` starts ``python -m cdpm.viewer`` (which runs
:func:`_serve`) in a subprocess through :class:`_Server`, reads the zmq and
web URLs it prints, and stops it on close. meshcat and tornado are imported
only in that subprocess.

Both web servers of the viewer (meshcat's here, the inspection page's in
:mod:`cdpm.viewer.page`) answer only requests that name a loopback host
(:func:`host_problem`) and come from no page or a loopback page
(:func:`origin_problem`): a web site whose name resolves to 127.0.0.1 (DNS
rebinding) or a page of another site gets 403.
"""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from cdpm.errors import CdpmError, InputError

__all__ = ["LOOPBACK", "LOOPBACK_NAMES", "SERVER_TIMEOUT", "check_port"]

#: The only address the viewer's servers listen on.
LOOPBACK = "127.0.0.1"

#: Host names a request to the viewer's servers may name (as a URL spells
#: them: ``[::1]`` in a Host header).
LOOPBACK_NAMES = frozenset({"127.0.0.1", "localhost", "::1"})

#: Seconds to wait for the meshcat server to start or to answer.
SERVER_TIMEOUT = 20.0


def _short(text: str | None, most: int = 60) -> str:
    """``repr`` of a header value, cut to about ``most`` characters."""
    text = text or ""
    return repr(text if len(text) <= most else text[:most] + "...")


#: A Host header (or an Origin's host and port) naming a loopback name.
_LOOPBACK_HOST = re.compile(r"(127\.0\.0\.1|localhost|\[::1\])(:(\d{1,5}))?", re.IGNORECASE)


def _loopback(text: str) -> re.Match | None:
    """``text`` as a loopback name with an optional port 1-65535, else None."""
    match = _LOOPBACK_HOST.fullmatch(text.strip())
    if match is None or (match.group(3) is not None and not 1 <= int(match.group(3)) <= 65535):
        return None
    return match


def host_problem(host: str | None, port: int | None = None) -> str | None:
    """Why a request's Host header is refused, or None when it is exactly a
    loopback name (:data:`LOOPBACK_NAMES`) with, when ``port`` is given,
    that port.

    A site whose name resolves to 127.0.0.1 (DNS rebinding) sends its own
    name; the browser's port is the one listened on, so the name is what
    tells it apart. The page's server does not check the port: a forwarded
    port (ssh -L, VS Code) reaches it under another one.
    """
    match = _loopback(host or "")
    if match is None:
        return f"host {_short(host)} refused: the viewer answers only 127.0.0.1, localhost or [::1]"
    if port is not None and (match.group(3) is None or int(match.group(3)) != port):
        return f"host {_short(host)} refused: this server listens on port {port}"
    return None


def origin_problem(origin: str | None, host: str | None = None) -> str | None:
    """Why a request's Origin header is refused, or None when there is none
    or it is a page on a loopback host (and, when ``host`` is given, on that
    very host and port: the request's own Host header, the same origin)."""
    if origin is None:
        return None
    scheme, sep, rest = origin.partition("://")
    if not (sep and scheme.lower() in ("http", "https") and _loopback(rest)):
        return (
            f"a request from the page {_short(origin)} refused: only the viewer's own page may ask"
        )
    if host is not None and rest.lower() != host.strip().lower():
        return (
            f"a request from the page {_short(origin)} refused: only the page on "
            f"{_short(host)[1:-1]} may ask"
        )
    return None


def _serve(argv: list[str] | None = None) -> None:
    """Run a meshcat server whose zmq and web ports listen on 127.0.0.1 only.

    meshcat 0.3.2's ``ZMQWebSocketBridge`` binds zmq to its ``host``
    (127.0.0.1 by default) but calls tornado's ``Application.listen(port)``
    without an address, which listens on every interface; the web app here
    listens on the loopback address only (port 0: any free port), and its
    handlers refuse (403) a request naming another host or this server's
    port wrongly (:func:`host_problem`) or coming from a page that is not on
    a loopback host (:func:`origin_problem`).
    """
    # only `python -m cdpm.viewer` parses arguments
    import argparse

    # optional: cdpm[viz]
    import tornado.httpserver
    import tornado.ioloop
    import tornado.netutil
    import tornado.web
    import tornado.websocket
    from meshcat.servers import zmqserver

    parser = argparse.ArgumentParser(prog="python -m cdpm.viewer")
    parser.add_argument(
        "--port",
        type=int,
        default=None,
        help="web port, 0 for any free one (default: first free from 7000)",
    )
    args = parser.parse_args(argv)
    listening: list[int] = []  # the web port, once bound

    class Checked:
        """A handler that answers 403 to requests from elsewhere (before
        tornado's own handling, the websocket handshake included)."""

        def prepare(self):
            problem = host_problem(self.request.host, listening[0]) or origin_problem(
                self.request.headers.get("Origin")
            )
            if problem is not None:
                self.set_status(403)
                self.set_header("Content-Type", "text/plain; charset=utf-8")
                self.finish(problem + "\n")

        def check_origin(self, origin: str) -> bool:  # the websocket's own origin test
            return origin_problem(origin) is None

    class StaticHandler(Checked, zmqserver.StaticFileHandlerNoCache):
        pass

    class WebSocketHandler(Checked, zmqserver.WebSocketHandler):
        pass

    class LoopbackBridge(zmqserver.ZMQWebSocketBridge):
        def make_app(self):
            app = tornado.web.Application(
                [
                    (
                        r"/static/(.*)",
                        StaticHandler,
                        {"path": zmqserver.VIEWER_ROOT, "default_filename": zmqserver.VIEWER_HTML},
                    ),
                    (r"/", WebSocketHandler, {"bridge": self}),
                ],
                log_function=lambda handler: None,  # no request log (403s included)
            )

            def listen(port: int, **kwargs) -> None:
                sockets = tornado.netutil.bind_sockets(port, address=LOOPBACK)
                tornado.httpserver.HTTPServer(app, **kwargs).add_sockets(sockets)
                listening.append(sockets[0].getsockname()[1])

            app.listen = listen
            return app

        # meshcat's own raise on a websocket closed but not yet out of the
        # pool (a tab closed or reloaded mid-update): the zmq request then
        # got no answer and the viewer hung; a closed websocket is skipped
        def forward_to_websockets(self, frames):
            _, _, data = frames
            for websocket in list(self.websocket_pool):
                _write(websocket, data)

        def send_scene(self, websocket):
            for node in zmqserver.walk(self.tree):
                for data in [node.object, *node.properties, node.transform, node.animation]:
                    if data is not None:
                        _write(websocket, data)

    def _write(websocket, data: bytes) -> None:
        """Send a message unless the websocket is closed (now or before it goes out)."""
        try:
            sent = websocket.write_message(data, binary=True)
        except tornado.websocket.WebSocketClosedError:
            return
        # a websocket closing meanwhile fails the write later: nothing to report
        sent.add_done_callback(lambda done: done.cancelled() or done.exception())

    bridge = LoopbackBridge(host=LOOPBACK, port=args.port)
    # with port 0 meshcat names port 0 in its URL: name the bound one
    bridge.fileserver_port = listening[0]
    bridge.web_url = f"http://{LOOPBACK}:{listening[0]}/static/"
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


def check_port(port: Any, *, any_free: bool = False) -> int:
    """``port`` as an int when it is a TCP port (1-65535; also 0, any free
    port, when ``any_free``).

    Raises:
        InputError: it is not.
    """
    try:
        value = int(str(port).strip())
    except ValueError:
        value = -1
    if not (0 if any_free else 1) <= value <= 65535:
        choices = "0 (any free port) or 1-65535" if any_free else "1-65535"
        raise InputError(
            f"port {port} is not a TCP port; use {choices} (or omit it: the first free from 7000)"
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
