"""Headless Chromium driven over the DevTools protocol: open a page once, take screenshots at
chosen moments (a live page never goes idle, so --screenshot's one-shot modes do not fit).
The protocol's WebSocket is spoken with tornado's client (installed with meshcat)."""
from __future__ import annotations

import asyncio
import base64
import json
import shutil
import subprocess
import time
import urllib.request
from pathlib import Path

import cv2
import numpy as np

CHROMIUM = "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else shutil.which("chromium")


class Chromium:
    """One headless Chromium showing one page. profile: a new folder for its user data."""

    def __init__(self, profile: Path, size: tuple[int, int] = (800, 600), timeout_s: float = 60):
        from tornado.websocket import websocket_connect

        profile.mkdir(parents=True, exist_ok=True)
        self._proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
             "--disable-background-networking", "--no-first-run", f"--user-data-dir={profile}",
             f"--window-size={size[0]},{size[1]}", "--remote-debugging-port=0",
             "--remote-allow-origins=*", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self._loop = asyncio.new_event_loop()
        self._next_id = 0
        try:
            port_file, deadline = profile / "DevToolsActivePort", time.monotonic() + timeout_s
            while not (port_file.is_file() and port_file.read_text().strip()):
                if time.monotonic() > deadline or self._proc.poll() is not None:
                    raise RuntimeError("chromium did not start its DevTools server")
                time.sleep(0.1)
            port = int(port_file.read_text().split()[0])
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
                page = next(t for t in json.load(r) if t["type"] == "page")

            async def connect():   # tornado's client belongs to the loop that runs it
                return await websocket_connect(page["webSocketDebuggerUrl"],
                                               max_message_size=64 << 20)
            self._ws = self._loop.run_until_complete(connect())
        except BaseException:
            self.close()
            raise

    def _call(self, method: str, **params) -> dict:
        self._next_id += 1
        ident = self._next_id

        async def call():
            await self._ws.write_message(json.dumps({"id": ident, "method": method,
                                                     "params": params}))
            while True:
                reply = json.loads(await self._ws.read_message())
                if reply.get("id") == ident:
                    if "error" in reply:
                        raise RuntimeError(f"{method}: {reply['error']}")
                    return reply["result"]
        return self._loop.run_until_complete(asyncio.wait_for(call(), 60))

    def open(self, url: str) -> None:
        """Navigate to url (returns once navigation started; the page loads on its own)."""
        self._call("Page.navigate", url=url)

    def screenshot(self, path: Path | None = None) -> np.ndarray:
        """The page as it is now: (H, W, 3) uint8 RGB; also written to path if given."""
        data = base64.b64decode(self._call("Page.captureScreenshot", format="png")["data"])
        if path is not None:
            Path(path).write_bytes(data)
        return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1]

    def close(self) -> None:
        """Stop Chromium (idempotent)."""
        ws = getattr(self, "_ws", None)
        if ws is not None:
            ws.close()
            self._ws = None
        if self._proc.poll() is None:
            self._proc.terminate()
            try:
                self._proc.wait(10)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        self._loop.close()

    def __enter__(self) -> "Chromium":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
