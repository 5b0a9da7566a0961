"""The live viewer's Meshcat server, listening on one address only (127.0.0.1 by default).

Meshcat's own server (`meshcat.servers.zmqserver`) serves its web page and websocket with tornado's
``listen(port)``, which binds every interface (0.0.0.0 and ::): anyone on the network can watch the scene.
This module runs the same `ZMQWebSocketBridge` with the web server bound to `host` and the ZeroMQ command
socket bound to 127.0.0.1 whatever `host` is (commands come from this machine only).

    >>> server = start_server()                   # a subprocess; server.web_url = "http://127.0.0.1:7000/static/"
    >>> vis = meshcat.Visualizer(window=server.window())
    >>> server.stop()

It is also the subprocess' entry point: ``python -m regrasp_casadi.live_server [--host HOST]`` prints
``zmq_url=...`` and ``web_url=...`` and serves until it is terminated.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import io
import os
import selectors
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from regrasp_casadi.errors import RegraspError

__all__ = ["LOOPBACK", "LiveServer", "start_server", "check_host", "url_host"]

LOOPBACK = "127.0.0.1"
"""Default address of the live viewer's web server (this machine only)."""

START_TIMEOUT = 30.0
"""Seconds to wait for the server subprocess to print its URLs."""


def url_host(host: str) -> str:
    """`host` as written in a URL: IPv6 addresses in brackets (``::1`` -> ``[::1]``)."""
    return f"[{host}]" if ":" in host and not host.startswith("[") else host


def check_host(host: str) -> None:
    """Raise `ValueError` naming `host` unless a TCP socket can be bound to it on this machine."""
    if not isinstance(host, str) or not host:
        raise ValueError(f"host: expected an address such as {LOOPBACK}, got {host!r}")
    try:
        infos = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
    except socket.gaierror as e:
        raise ValueError(f"host: cannot resolve {host!r} ({e.strerror})") from None
    family, kind, proto, _, address = infos[0]
    with socket.socket(family, kind, proto) as s:
        try:
            s.bind(address)
        except OSError as e:
            raise ValueError(f"host: cannot listen on {host!r} ({e.strerror})") from None


def _bridge(host: str):
    """A Meshcat `ZMQWebSocketBridge` whose web server listens on `host` and ZeroMQ socket on loopback."""
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    class _Bridge(ZMQWebSocketBridge):
        def make_app(self):
            app = super().make_app()
            listen_all = app.listen   # tornado: Application.listen(port, address=None, ...)

            def listen(port: int, **kwargs):
                return listen_all(port, address=host, **kwargs)

            app.listen = listen
            return app

    bridge = _Bridge(host=LOOPBACK)
    bridge.web_url = f"http://{url_host(host)}:{bridge.fileserver_port}/static/"
    return bridge


def main(argv: list[str] | None = None) -> int:
    """Serve until terminated (the subprocess started by `start_server`)."""
    parser = argparse.ArgumentParser(prog="python -m regrasp_casadi.live_server",
                                     description="Meshcat server of the regrasp live viewer")
    parser.add_argument("--host", default=LOOPBACK, help="address of the web server (default: %(default)s)")
    args = parser.parse_args(argv)
    try:
        check_host(args.host)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    bridge = _bridge(args.host)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        bridge.run()
    return 0


@dataclass
class LiveServer:
    """A running server subprocess (see `start_server`)."""

    proc: subprocess.Popen
    """The server process."""
    zmq_url: str
    """Its ZeroMQ command socket, e.g. ``tcp://127.0.0.1:6000``."""
    web_url: str
    """The page to open in a browser, e.g. ``http://127.0.0.1:7000/static/``."""

    def window(self):
        """A Meshcat `ViewerWindow` connected to this server (its `server_proc` is this process)."""
        from meshcat.visualizer import ViewerWindow

        with contextlib.redirect_stdout(io.StringIO()):   # meshcat prints the URL
            window = ViewerWindow(zmq_url=self.zmq_url, start_server=False, server_args=[])
        window.server_proc = self.proc
        return window

    def stop(self, timeout: float = 5.0) -> None:
        """Terminate the server (kill it if it has not ended after `timeout` s)."""
        _stop(self.proc, timeout)


def _stop(proc: subprocess.Popen, timeout: float = 5.0) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def start_server(host: str = LOOPBACK, timeout: float = START_TIMEOUT) -> LiveServer:
    """Start the server in a subprocess (ended at exit of this Python process at the latest).

    Args:
        host: address the web server listens on (127.0.0.1: this machine only; 0.0.0.0: every IPv4
            interface, reachable from other machines).
        timeout: seconds to wait for the server to start.

    Raises:
        ValueError: `host` cannot be resolved or is not an address of this machine.
        RegraspError: the server did not start (its last error line is quoted).
    """
    check_host(host)
    package_parent = str(Path(__file__).resolve().parents[1])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, env.get("PYTHONPATH")) if p)
    cmd = [sys.executable, "-u", "-m", "regrasp_casadi.live_server", "--host", host]
    with tempfile.TemporaryFile() as errors:
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=errors,
                                env=env, start_new_session=True)
        atexit.register(_stop, proc, 1.0)
        try:
            urls = _read_urls(proc, timeout)
        except BaseException:
            _stop(proc, 1.0)
            raise
        if urls is None:
            _stop(proc, 1.0)
            errors.seek(0)
            lines = errors.read().decode("utf-8", "replace").strip().splitlines()
            raise RegraspError(f"the live viewer's server did not start within {timeout:g} s"
                               + (f": {lines[-1]}" if lines else ""))
    return LiveServer(proc, urls["zmq_url"], urls["web_url"])


def _read_urls(proc: subprocess.Popen, timeout: float) -> dict[str, str] | None:
    """The ``zmq_url=`` and ``web_url=`` lines of the server, or None on exit or after `timeout` s."""
    fd = proc.stdout.fileno()
    text = b""
    deadline = time.monotonic() + timeout
    with selectors.DefaultSelector() as sel:
        sel.register(fd, selectors.EVENT_READ)
        while True:
            urls = dict(line.partition("=")[::2]
                        for line in text.decode("utf-8", "replace").splitlines() if "=" in line)
            if "zmq_url" in urls and "web_url" in urls:
                return {k: urls[k].strip() for k in ("zmq_url", "web_url")}
            left = deadline - time.monotonic()
            if left <= 0 or not sel.select(left):
                return None
            chunk = os.read(fd, 4096)   # unbuffered: select() sees what is not read yet
            if not chunk:   # end of file: the process ended
                return None
            text += chunk


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
