"""Watching a run live: a meshcat server bound to 127.0.0.1 only, frames played from Python, a
prompt that picks the cycle (``fatigue-pin replay FILE`` without ``--html``). The scene and its
animation come from :mod:`fatigue_pin.viz.replay`."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import webbrowser
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fatigue_pin.io.results import RunResult
from fatigue_pin.viz.replay import LOCALHOST, ReplayScene, build_animation, select_cycles

@dataclass
class LocalServer:
    """A meshcat server subprocess bound to 127.0.0.1 (HTTP/websocket and ZeroMQ).

    Attributes:
        process: the server process.
        zmq_url: where Python sends commands (``tcp://127.0.0.1:<port>``).
        web_url: the page to open (``http://127.0.0.1:<port>/static/``).
    """

    process: subprocess.Popen
    zmq_url: str
    web_url: str

    def close(self) -> None:
        """Stop the server process."""
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()

    def __enter__(self) -> LocalServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _run_local_server() -> None:
    """Body of the server subprocess: meshcat's ZMQ/websocket bridge with every socket on 127.0.0.1.

    meshcat 0.3.2 binds ZeroMQ to its ``host`` (127.0.0.1) but lets tornado listen on every
    interface (``app.listen(port)``); the HTTP listener is pinned to 127.0.0.1 here.
    """
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    class LocalBridge(ZMQWebSocketBridge):
        def make_app(self):  # type: ignore[no-untyped-def]
            app = super().make_app()
            listen = app.listen
            app.listen = lambda port, **kw: listen(port, address=LOCALHOST, **kw)
            return app

    bridge = LocalBridge(host=LOCALHOST)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass


def start_local_server(timeout_s: float = 30.0) -> LocalServer:
    """Start a meshcat server bound to 127.0.0.1 in a subprocess; returns once it listens."""
    env = dict(os.environ)
    package_parent = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, env.get("PYTHONPATH", "")) if p)
    proc = subprocess.Popen(
        [sys.executable, "-u", "-c", "from fatigue_pin.viz.server import _run_local_server; _run_local_server()"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env, start_new_session=True, text=True,
    )
    urls: dict[str, str] = {}
    deadline = time.monotonic() + timeout_s
    while len(urls) < 2:
        line = proc.stdout.readline() if proc.stdout else ""
        if not line:
            if proc.poll() is not None or time.monotonic() > deadline:
                proc.kill()
                raise RuntimeError(f"the meshcat server did not start (exit code {proc.poll()})")
            continue
        key, _, value = line.strip().partition("=")
        if key in ("zmq_url", "web_url"):
            urls[key] = value
    return LocalServer(proc, urls["zmq_url"], urls["web_url"])


def play_frames(vis: Any, scene: ReplayScene, cycles: Sequence[int] | None = None,
                say: Callable[[str], object] = print) -> None:
    """Send the frames of ``cycles`` (0-based, among ``scene.cycles``; default: all) to a live
    viewer in real time, printing each cycle's number as it starts."""
    sent: dict[str, tuple[int, ...]] = {}  # colours as 8-bit RGB: send only changes (the server keeps every property)
    t0 = time.monotonic()
    elapsed = 0.0
    for c in scene.cycles if cycles is None else cycles:
        i = scene.cycles.index(c)
        say(f"cycle {c + 1}")
        first, last = scene.cycle_frames[i]
        times = scene.frame_times_s[first: last + 1] - scene.frame_times_s[first]
        for dt, (poses, colors) in zip(np.diff(times, prepend=0.0), scene.frames[first: last + 1]):
            for path, T in poses.items():
                vis[path].set_transform(T)
            for path, rgb in colors.items():
                rgb8 = tuple(int(round(v * 255)) for v in rgb)
                if sent.get(path) != rgb8:
                    sent[path] = rgb8
                    vis[path].set_property("color", [v / 255 for v in rgb8] + [1.0])
            elapsed += dt
            delay = t0 + elapsed - time.monotonic()
            if delay > 0:
                time.sleep(delay)


def _ask_cycle(run: RunResult, input_fn: Callable[[str], str]) -> list[int] | None:
    """Prompt until a valid answer: the cycles to play next (None: quit, []: replay the last ones)."""
    n = run.n_cycles
    while True:
        try:
            answer = input_fn(f"[Enter] replay, 1-{n}: play that cycle, a: all cycles, q: quit > ").strip().lower()
        except EOFError:
            return None
        if answer == "q":
            return None
        if answer == "":
            return []
        if answer == "a":
            return list(range(n))
        if answer.isdigit() and 1 <= int(answer) <= n:
            return [int(answer) - 1]
        print(f"not a cycle number between 1 and {n}: {answer!r}")


def serve(
    run: RunResult,
    cycle: int | None = None,
    open_browser: bool = False,
    input_fn: Callable[[str], str] = input,
    wait_for_browser: bool = True,
) -> None:
    """Play ``run`` in a browser through a meshcat server on 127.0.0.1, with a prompt to pick cycles.

    Prints the URL, waits for a browser to open it, then plays ``cycle`` (0-based; default: every
    cycle in turn) in real time. At the prompt: Enter replays, a number (1-based) plays that
    cycle, ``a`` plays all cycles, ``q`` (or end of input) quits. The server stops on return.
    """
    import meshcat

    scene = build_animation(run)
    selection = list(range(run.n_cycles)) if cycle is None else select_cycles(run, [cycle])
    with start_local_server() as server:
        vis = meshcat.Visualizer(zmq_url=server.zmq_url)
        print(f"fatigue_pin: replay of {run.name!r} ({run.n_cycles} cycles) at {server.web_url} (this machine only)")
        if open_browser:
            webbrowser.open(server.web_url, new=2)
        if wait_for_browser:
            print("waiting for a browser to open the page ...")
            vis.wait()
        for command in scene.scene_commands:
            vis.window.send(command)
        try:
            while True:
                play_frames(vis, scene, selection)
                answer = _ask_cycle(run, input_fn)
                if answer is None:
                    return
                selection = answer or selection
        except KeyboardInterrupt:
            print()
