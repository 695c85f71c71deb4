"""A screenshot of the Rerun dashboard (the web viewer in headless Chromium) for README.md.

``--live``: ``windwarden up SCENARIO --viewer web`` for ``--duration`` s in real time (free ports, its own API
token), the web viewer's page opened in headless Chromium (software WebGL: SwiftShader) as soon as it is served,
one generator-speed sensor stuck at 100 rad/s injected through ``POST /faults`` at ``--inject-at`` s and cleared
at ``--clear-at`` s; after the run, once two screenshots ``--settle`` s apart are equal (the viewer draws behind
real time without a GPU), the last one is written as a 256-colour PNG. With a run folder or a ``.rrd`` file
instead, the recording is served with ``rerun --serve-web`` and captured the same way (the viewer opens it at its
end). Every child process is stopped on the way out; Rerun's analytics are off (``RERUN_ANALYTICS=0`` and
``rerun analytics disable``).

    .venv/bin/python tools/screenshot_dashboard.py --live --runs-root /tmp/ww-runs --out docs/img/dashboard.png
    .venv/bin/python tools/screenshot_dashboard.py runs/<run-id> --out /tmp/dashboard.png

Chromium talks the DevTools protocol over a WebSocket; the few lines of RFC 6455 that needs are below, so the tool
needs nothing beyond the project's own dependencies and a ``chromium`` binary.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import hashlib
import io
import json
import os
import secrets
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path
from urllib.parse import quote, urlparse

from PIL import Image

from windwarden.live.finalize import rerun_binary
from windwarden.live.router import free_port

QUIET_ENV = {"RERUN_ANALYTICS": "0"}
FAULT = {  # what the README's caption describes: one generator-speed sensor stuck
    "target": "omega_g_m2",
    "kind": "fixed",
    "value": 100.0,
    "name": "generator-speed sensor 2 stuck at 100 rad per s",
}
CHROMIUM_FLAGS = [
    "--headless=new",
    "--no-sandbox",  # root in a container has no user namespace for the sandbox
    "--use-angle=swiftshader",  # WebGL on the CPU: no GPU on a build machine
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--enable-webgl",
    "--disable-extensions",
    "--disable-crash-reporter",
    "--disable-breakpad",
    "--no-first-run",
    "--no-default-browser-check",
    "--remote-debugging-address=127.0.0.1",
    "--remote-debugging-port=0",
]


class WebSocket:
    """A blocking WebSocket client, enough for Chromium's DevTools endpoint (RFC 6455: text frames, masked)."""

    def __init__(self, url: str, timeout: float = 60.0) -> None:
        u = urlparse(url)
        self.sock = socket.create_connection((u.hostname, u.port), timeout=timeout)
        key = base64.b64encode(secrets.token_bytes(16)).decode()
        self.sock.sendall(
            (
                f"GET {u.path} HTTP/1.1\r\nHost: {u.hostname}:{u.port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("DevTools closed the connection during the handshake")
            head += chunk
        status = head.split(b"\r\n", 1)[0]
        accept = base64.b64encode(hashlib.sha1((key + "258EAFA5-E914-47DA-95CA-C5AB0DC85B11").encode()).digest())
        if b" 101 " not in status or accept not in head:
            raise ConnectionError(f"DevTools refused the WebSocket: {status.decode(errors='replace')}")
        self.buffer = head.split(b"\r\n\r\n", 1)[1]

    def _read(self, n: int) -> bytes:
        while len(self.buffer) < n:
            chunk = self.sock.recv(1 << 20)
            if not chunk:
                raise ConnectionError("DevTools closed the connection")
            self.buffer += chunk
        out, self.buffer = self.buffer[:n], self.buffer[n:]
        return out

    def send(self, text: str) -> None:
        payload = text.encode()
        n = len(payload)
        if n < 126:
            header = struct.pack("!BB", 0x81, 0x80 | n)
        elif n < 1 << 16:
            header = struct.pack("!BBH", 0x81, 0x80 | 126, n)
        else:
            header = struct.pack("!BBQ", 0x81, 0x80 | 127, n)
        mask = secrets.token_bytes(4)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
        self.sock.sendall(header + mask + masked)

    def recv(self) -> str:
        """One whole message (continuation frames joined); control frames are skipped."""
        parts: list[bytes] = []
        while True:
            b0, b1 = self._read(2)
            n = b1 & 0x7F
            if n == 126:
                (n,) = struct.unpack("!H", self._read(2))
            elif n == 127:
                (n,) = struct.unpack("!Q", self._read(8))
            mask = self._read(4) if b1 & 0x80 else None
            data = self._read(n)
            if mask:
                data = bytes(b ^ mask[i % 4] for i, b in enumerate(data))
            opcode = b0 & 0x0F
            if opcode == 0x8:
                raise ConnectionError("DevTools closed the WebSocket")
            if opcode in (0x9, 0xA):  # ping, pong
                continue
            parts.append(data)
            if b0 & 0x80:
                return b"".join(parts).decode()

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()


class DevTools:
    """Calls on one page over the DevTools protocol; events are read and dropped."""

    def __init__(self, ws: WebSocket) -> None:
        self.ws = ws
        self.next_id = 0

    def call(self, method: str, **params) -> dict:
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})


def wait_for(what: str, check, timeout: float, proc: subprocess.Popen | None = None):
    """Poll ``check`` until it returns something truthy; fail if ``proc`` dies or time runs out."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc is not None and proc.poll() is not None:
            raise RuntimeError(f"{what}: the process ended with {proc.returncode}")
        with contextlib.suppress(OSError, ValueError, urllib.error.URLError):
            result = check()
            if result:
                return result
        time.sleep(0.5)
    raise TimeoutError(f"{what}: nothing after {timeout:.0f} s")


def http_json(url: str, data: dict | None = None, token: str | None = None) -> dict | list:
    headers = {"content-type": "application/json"}
    if token:
        headers["Authorization"] = f"Bearer {token}"
    body = json.dumps(data).encode() if data is not None else None
    with urllib.request.urlopen(urllib.request.Request(url, body, headers), timeout=10) as r:
        return json.load(r)


def stop(proc: subprocess.Popen, sig: int = signal.SIGTERM, timeout: float = 20.0) -> None:
    """Signal the child's process group (each child runs in its own session), SIGKILL it if it does not go."""
    for s in (sig, signal.SIGKILL):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, s)
        try:
            proc.wait(timeout)
            return
        except subprocess.TimeoutExpired:
            continue


def spawn(argv: list[str], log: Path, env: dict | None = None) -> subprocess.Popen:
    with log.open("ab") as out:
        return subprocess.Popen(
            argv,
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
            env=os.environ | QUIET_ENV | (env or {}),
        )


def chromium_binary() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        if path := shutil.which(name):
            return path
    raise SystemExit("no chromium on PATH (apt-get install chromium)")


class Browser:
    """Headless Chromium with one page, driven over the DevTools protocol; a context manager that stops it."""

    def __init__(self, work: Path, width: int, height: int) -> None:
        self.work, self.width, self.height = work, width, height
        self.proc: subprocess.Popen | None = None
        self.tools: DevTools | None = None

    def __enter__(self) -> Browser:
        profile = self.work / "chromium-profile"
        argv = [chromium_binary(), *CHROMIUM_FLAGS, f"--user-data-dir={profile}"]
        argv += [f"--window-size={self.width},{self.height}", "about:blank"]
        self.proc = spawn(argv, self.work / "chromium.log")
        active = profile / "DevToolsActivePort"
        port = wait_for("chromium", lambda: active.exists() and active.read_text().split()[0], 60, self.proc)
        pages = wait_for("a page", lambda: http_json(f"http://127.0.0.1:{port}/json/list"), 30, self.proc)
        page = next(p for p in pages if p.get("type") == "page")
        self.tools = DevTools(WebSocket(page["webSocketDebuggerUrl"]))
        size = {"width": self.width, "height": self.height, "deviceScaleFactor": 1, "mobile": False}
        self.tools.call("Emulation.setDeviceMetricsOverride", **size)
        return self

    def open(self, url: str) -> None:
        self.tools.call("Page.navigate", url=url)

    def capture(self) -> bytes:
        return base64.b64decode(self.tools.call("Page.captureScreenshot", format="png")["data"])

    def settled(self, settle_s: float, timeout: float) -> bytes:
        """The first screenshot equal to the one ``settle_s`` before it (the viewer has loaded and drawn all)."""
        last, deadline = b"", time.monotonic() + timeout
        while time.monotonic() < deadline:
            time.sleep(settle_s)
            png = self.capture()
            if png == last:
                return png
            last = png
        print(f"the page did not settle within {timeout:.0f} s; keeping the last screenshot", flush=True)
        return last

    def __exit__(self, *exc) -> None:
        if self.tools is not None:
            self.tools.ws.close()
        if self.proc is not None:
            stop(self.proc)


def save_png(png: bytes, out: Path) -> None:
    """The screenshot with a 256-colour palette (the viewer's flat colours survive it), optimised."""
    image = Image.open(io.BytesIO(png)).convert("RGB")
    out.parent.mkdir(parents=True, exist_ok=True)
    image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)
    print(f"{out}: {image.width}×{image.height}, {out.stat().st_size / 1024:.0f} KiB", flush=True)


def live(args: argparse.Namespace, work: Path, width: int, height: int) -> Path:
    """``windwarden up --viewer web``; the web viewer opened live; the fault injected and cleared over REST; the
    screenshot taken at ``--shot-at`` s of simulated time. Returns the run folder."""
    token = secrets.token_urlsafe(24)
    api_port = free_port()
    run_id = f"dashboard-{args.scenario}-{int(time.time())}"
    windwarden = Path(sys.executable).with_name("windwarden")
    argv = [str(windwarden), "up", args.scenario, "--duration", str(args.duration), "--seed", str(args.seed)]
    argv += ["--viewer", "web", "--listen", f"tcp/127.0.0.1:{free_port()}", "--api-port", str(api_port)]
    argv += ["--runs-root", str(args.runs_root), "--run-id", run_id, "--quiet"]
    up = spawn(argv, work / "up.log", {"WINDWARDEN_API_TOKEN": token})
    api = f"http://127.0.0.1:{api_port}"
    run_dir = args.runs_root / run_id

    def sim_time_reached(t: float) -> bool:
        return http_json(f"{api}/run").get("t", 0.0) >= t

    try:
        print(f"live run {run_dir}: {args.scenario}, {args.duration:g} s (log {work / 'up.log'})", flush=True)
        up_json = run_dir / "up.json"
        web_url = wait_for("the web viewer", lambda: json.loads(up_json.read_text())["web_viewer"], 60, up)
        wait_for("the plant", lambda: sim_time_reached(0.0), 120, up)
        with Browser(work, width, height) as browser:
            browser.open(web_url)
            wait_for("the injection time", lambda: sim_time_reached(args.inject_at), args.duration, up)
            fault = FAULT | {"start_s": 0.0, "end_s": args.clear_at}
            applied = http_json(f"{api}/faults", fault, token)
            print(f"injected at t = {applied['t']:.2f} s: {json.dumps(applied['fault']['fault'])}", flush=True)
            up.wait(args.duration + 120)  # the viewer draws behind real time on a CPU: let it catch up
            save_png(browser.settled(args.settle, args.timeout), args.out)
    finally:
        if up.poll() is None:
            stop(up, signal.SIGINT, 60)
    if up.returncode != 0:
        raise RuntimeError(f"windwarden up ended with {up.returncode}; see {work / 'up.log'}")
    for line in (run_dir / "events.jsonl").read_text().splitlines():
        print("  event", line[:160], flush=True)
    return run_dir


def from_recording(args: argparse.Namespace, work: Path, width: int, height: int) -> None:
    """Serve the recording with the web viewer, load it in headless Chromium, save the settled screenshot."""
    recording = args.source / "recording.rrd" if args.source.is_dir() else args.source
    web_port, grpc_port = free_port(), free_port()
    serve = [rerun_binary(), "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(web_port)]
    viewer = spawn([*serve, "--port", str(grpc_port), str(recording)], work / "rerun.log")
    try:
        page = f"http://127.0.0.1:{web_port}"
        wait_for("the web viewer", lambda: urllib.request.urlopen(page, timeout=2), 60, viewer)
        with Browser(work, width, height) as browser:
            proxy = quote(f"rerun+http://127.0.0.1:{grpc_port}/proxy", safe="")
            browser.open(f"{page}/?url={proxy}")
            save_png(browser.settled(args.settle, args.timeout), args.out)
    finally:
        stop(viewer)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("source", nargs="?", type=Path, help="a run folder or a .rrd file (omit with --live)")
    p.add_argument("--out", type=Path, default=Path("docs/img/dashboard.png"))
    p.add_argument("--size", default="1600x1000", help="browser window, WIDTHxHEIGHT (default 1600x1000)")
    live_args = p.add_argument_group("--live: a run of windwarden up, watched live")
    live_args.add_argument("--live", action="store_true", help="run windwarden up and watch it live")
    live_args.add_argument("--scenario", default="ftwse-2012", help="default ftwse-2012")
    live_args.add_argument("--seed", type=int, default=0, help="default 0")
    live_args.add_argument("--duration", type=float, default=80.0, help="s of simulated time (default 80)")
    live_args.add_argument("--inject-at", type=float, default=52.0, help="s, when to inject (default 52)")
    live_args.add_argument("--clear-at", type=float, default=70.0, help="s, the fault's end (default 70)")
    live_args.add_argument("--runs-root", type=Path, default=Path("runs"), help="default runs")
    p.add_argument("--settle", type=float, default=10.0, help="s between screenshots compared (default 10)")
    p.add_argument("--timeout", type=float, default=600.0, help="s to wait for the page to settle (default 600)")
    args = p.parse_args(argv)
    if args.live == (args.source is not None):
        p.error("give a run folder or .rrd file, or --live")
    if args.live and not args.inject_at < args.clear_at <= args.duration:
        p.error("need --inject-at < --clear-at <= --duration")
    width, height = (int(v) for v in args.size.lower().split("x"))
    subprocess.run([rerun_binary(), "analytics", "disable"], capture_output=True, check=False, timeout=30)
    work = Path(tempfile.mkdtemp(prefix="ww-dashboard-"))
    try:
        if args.live:
            print(f"run folder {live(args, work, width, height)}", flush=True)
        else:
            from_recording(args, work, width, height)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
