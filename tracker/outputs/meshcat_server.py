"""A meshcat server bound to 127.0.0.1 only, running in a child process that cannot outlive us.

meshcat's own server listens on every network interface and outlives the process that started
it. Here the same bridge (``ZMQWebSocketBridge``: ZeroMQ in, WebSocket out, viewer JavaScript
from the installed package) listens on 127.0.0.1 only, on ports the system picks, and the child
exits on ``ViewerServer.close()`` (SIGTERM, then SIGKILL; also on leaving a ``with`` block and
at interpreter exit), when its stdin reaches end of file (the parent died in any way: it holds
the only write end), or on SIGTERM. It runs in a session of its own and ignores SIGINT, so a
terminal's Ctrl-C or SIGHUP reaches the parent only, which closes the view first and then stops
the child (else frames still being drawn found the server gone).

Run as ``python -m tracker.outputs.meshcat_server`` it is the child: it prints ``zmq_url=...``
and ``web_url=...`` lines and serves until one of the above happens.
"""
from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
import weakref
from pathlib import Path

import warnings

import tornado.httpserver
import tornado.netutil
import tornado.web
import tornado.websocket
import zmq
from zmq.eventloop.zmqstream import ZMQStream

from regressor.errors import SilhouettePoseError

with warnings.catch_warnings():
    # meshcat 0.3.2 imports zmq.eventloop.ioloop, deprecated (and unused) on pyzmq >= 17.
    warnings.simplefilter("ignore", DeprecationWarning)
    from meshcat.servers.zmqserver import (
        VIEWER_HTML,
        VIEWER_ROOT,
        StaticFileHandlerNoCache,
        WebSocketHandler,
        ZMQWebSocketBridge,
    )

LOOPBACK = "127.0.0.1"


class ViewerServerError(SilhouettePoseError, RuntimeError):
    """The meshcat server could not be started (message says why)."""


# ---------------------------------------------------------------- child process side

class _LoopbackApplication(tornado.web.Application):
    """A tornado application whose listen() binds 127.0.0.1 (port 0: the OS picks one)."""

    bound_port = 0

    def listen(self, port, address=None, **kwargs):  # noqa: ARG002 (address is forced)
        sockets = tornado.netutil.bind_sockets(port, address=LOOPBACK)
        server = tornado.httpserver.HTTPServer(self, **kwargs)
        server.add_sockets(sockets)
        self.bound_port = sockets[0].getsockname()[1]
        return server


class _PageSocket(WebSocketHandler):
    """meshcat's WebSocket handler, whose page may already have been dropped on closing."""

    def on_close(self):
        self.bridge.websocket_pool.discard(self)


class LoopbackBridge(ZMQWebSocketBridge):
    """meshcat's ZMQ/WebSocket bridge with both sockets on 127.0.0.1 and OS-chosen ports."""

    def __init__(self):
        super().__init__(zmq_url=f"tcp://{LOOPBACK}:*", host=LOOPBACK, port=0)
        self.fileserver_port = self.app.bound_port
        self.web_url = f"http://{LOOPBACK}:{self.fileserver_port}/static/"

    def make_app(self):
        return _LoopbackApplication([
            (r"/static/(.*)", StaticFileHandlerNoCache,
             {"path": VIEWER_ROOT, "default_filename": VIEWER_HTML}),
            (r"/", _PageSocket, {"bridge": self}),
        ])

    def forward_to_websockets(self, frames):
        """As meshcat's, but a page closed while a command is sent is dropped: meshcat's would
        raise, the command would go unanswered and the tracker would give up on the server."""
        data = frames[2]
        for websocket in list(self.websocket_pool):
            try:
                websocket.write_message(data, binary=True)
            except tornado.websocket.WebSocketClosedError:
                self.websocket_pool.discard(websocket)

    def setup_zmq(self, url):
        socket = self.context.socket(zmq.REP)
        socket.bind(url)
        stream = ZMQStream(socket)
        stream.on_recv(self.handle_zmq)
        # The wildcard port "*" is resolved by the bind; report the real endpoint.
        return socket, stream, socket.getsockopt_string(zmq.LAST_ENDPOINT)


def _exit_when_stdin_closes() -> None:
    """Block until the parent's end of our stdin closes (the parent died or closed it), then
    leave at once: the tornado loop is not ours to stop cleanly from another thread."""
    try:
        while sys.stdin.buffer.read(4096):
            pass
    finally:
        os._exit(0)


def serve() -> None:
    """Child entry point: start the bridge, announce its URLs on stdout, serve until stopped."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)          # the parent stops us (docstring)
    signal.signal(signal.SIGTERM, lambda *_: os._exit(0))
    bridge = LoopbackBridge()
    threading.Thread(target=_exit_when_stdin_closes, daemon=True).start()
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    bridge.run()


# ---------------------------------------------------------------- parent side

def _stop(proc: subprocess.Popen, timeout_s: float) -> None:
    """Terminate the child (SIGTERM, SIGKILL after timeout_s) and reap it; idempotent."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    for pipe in (proc.stdin, proc.stdout):
        if pipe is not None and not pipe.closed:
            pipe.close()


class ViewerServer:
    """A meshcat server on 127.0.0.1 in a child process (see the module docstring).

    Attributes once started: web_url ("http://127.0.0.1:PORT/static/"), zmq_url
    ("tcp://127.0.0.1:PORT", for ``meshcat.Visualizer(zmq_url=...)``), pid.
    startup_timeout_s: how long to wait for the child to announce its URLs.
    Raises ViewerServerError when the child exits or stays silent during start-up.
    """

    def __init__(self, startup_timeout_s: float = 30.0):
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[1])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
        # The child's stderr (tornado's log) goes to a temporary file: a pipe nobody reads
        # could fill up and block it; the file tells why a start-up failed.
        self._log = tempfile.TemporaryFile()
        self._proc = subprocess.Popen(
            [sys.executable, "-u", "-m", "tracker.outputs.meshcat_server"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._log, env=env,
            bufsize=0,  # unbuffered: select() on stdout must see every line not yet read
            start_new_session=True)     # the terminal's signals are the parent's (docstring)
        self.pid = self._proc.pid
        # Stops the child if close() is never called (also at interpreter exit).
        self._finalizer = weakref.finalize(self, _stop, self._proc, 5.0)
        try:
            urls = self._read_urls(startup_timeout_s)
        except BaseException:
            self.close()
            raise
        self.zmq_url, self.web_url = urls["zmq_url"], urls["web_url"]

    def _read_urls(self, timeout_s: float) -> dict[str, str]:
        urls: dict[str, str] = {}
        deadline = time.monotonic() + timeout_s
        stdout = self._proc.stdout
        while len(urls) < 2:
            remaining = deadline - time.monotonic()
            ready, _, _ = select.select([stdout], [], [], max(remaining, 0.0))
            if not ready:
                raise ViewerServerError(f"meshcat server gave no URL within {timeout_s:.0f} s")
            line = stdout.readline().decode("utf-8", "replace").strip()
            if not line:
                code = self._proc.wait()
                raise ViewerServerError(f"meshcat server exited during start-up with code {code}: "
                                        f"{self._last_log_line()}")
            key, _, value = line.partition("=")
            if key in ("zmq_url", "web_url"):
                urls[key] = value
        return urls

    def _last_log_line(self) -> str:
        self._log.seek(0)
        lines = self._log.read().decode("utf-8", "replace").strip().splitlines()
        return lines[-1] if lines else "(no error output)"

    @property
    def running(self) -> bool:
        """True while the child process is alive."""
        return self._proc.poll() is None

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the server and reap the child process; idempotent."""
        self._finalizer.detach()
        _stop(self._proc, timeout_s)
        self._log.close()

    def __enter__(self) -> "ViewerServer":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


if __name__ == "__main__":
    serve()
