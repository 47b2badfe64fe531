"""Progress a person can see: log lines, a live line during long steps, and bars.

The Python API is quiet unless asked: its functions take ``progress`` (a :class:`Reporter`, or
any ``callable(str)`` that receives the log lines; default: nothing). The command line passes
:meth:`Reporter.for_stream` on standard output: on a terminal it draws ``tqdm`` bars and a live
line during a compile; when the output is not a terminal (a log file, CI) there are no bars,
only plain lines, and a long step prints a line every ``heartbeat_s`` seconds so that a log
never stays silent for long.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from typing import Any, Callable, Iterator, TextIO, Union


class Bar:
    """A progress bar (``tqdm`` on a terminal; nothing otherwise)."""

    def __init__(self, bar: Any = None) -> None:
        self._bar = bar

    def update(self, n: int = 1, **postfix: object) -> None:
        """Advance by ``n`` and show ``postfix`` (e.g. ``max_mf=0.42``) beside the bar."""
        if self._bar is not None:
            if postfix:
                self._bar.set_postfix({k: v for k, v in postfix.items()}, refresh=False)
            self._bar.update(n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


class Reporter:
    """Where progress goes.

    Args:
        line: receives log lines (``None``: dropped).
        stream: a text stream for bars and live lines (only used when ``bars`` is true).
        bars: draw tqdm bars and live lines (a terminal); ``False``: plain lines only.
        heartbeat_s: without bars, a long step (:meth:`task`) prints a line this often (s).
    """

    def __init__(self, line: Callable[[str], None] | None = None, stream: TextIO | None = None, bars: bool = False,
                 heartbeat_s: float = 10.0) -> None:
        self._line = line
        self._stream = stream
        self.bars = bool(bars and stream is not None)
        self.heartbeat_s = heartbeat_s

    @classmethod
    def quiet(cls) -> Reporter:
        return cls()

    @classmethod
    def for_stream(cls, stream: TextIO | None = None) -> Reporter:
        """Lines to ``stream`` (default stdout); bars when it is a terminal."""
        stream = stream or sys.stdout
        tty = bool(getattr(stream, "isatty", lambda: False)())

        def write(text: str) -> None:
            if tty:
                from tqdm import tqdm

                tqdm.write(text, file=stream)
            else:
                print(text, file=stream, flush=True)

        return cls(write, stream, bars=tty)

    def __call__(self, text: str) -> None:
        self.line(text)

    def line(self, text: str) -> None:
        """A log line."""
        if self._line is not None:
            self._line(text)

    def bar(self, total: int | None, desc: str, unit: str = "it") -> Bar:
        """A bar over ``total`` steps (``None``: unknown total)."""
        if not self.bars:
            return Bar()
        from tqdm import tqdm

        return Bar(tqdm(total=total, desc=desc, unit=unit, file=self._stream, dynamic_ncols=True, leave=True))

    @contextlib.contextmanager
    def task(self, text: str, expected_s: float | None = None) -> Iterator[None]:
        """A long step: a live line with the elapsed time on a terminal, else the line and a
        heartbeat every ``heartbeat_s`` seconds. Nothing is drawn or printed without a sink."""
        if self._line is None and not self.bars:
            yield
            return
        about = f" (about {expected_s:.0f} s)" if expected_s else ""
        done = threading.Event()
        t0 = time.perf_counter()
        if self.bars:
            from tqdm import tqdm

            live = tqdm(total=None, desc=text + about, bar_format="{desc}: {elapsed}", file=self._stream, leave=False)

            def tick() -> None:
                while not done.wait(0.5):
                    live.refresh()
        else:
            live = None
            self.line(text + about + " ...")

            def tick() -> None:
                while not done.wait(self.heartbeat_s):
                    self.line(f"  ... {text}: {time.perf_counter() - t0:.0f} s")

        thread = threading.Thread(target=tick, daemon=True)
        thread.start()
        try:
            yield
        finally:
            done.set()
            thread.join()
            if live is not None:
                live.close()
            self.line(f"{text}: done in {time.perf_counter() - t0:.1f} s")


Progress = Union[Reporter, Callable[[str], None], None]


def as_reporter(progress: Progress) -> Reporter:
    """A :class:`Reporter` from what an API function received: a Reporter, a line callback, or
    None (quiet)."""
    if isinstance(progress, Reporter):
        return progress
    if progress is None:
        return Reporter.quiet()
    return Reporter(progress)
