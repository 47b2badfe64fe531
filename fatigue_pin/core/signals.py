"""Ctrl-C (SIGINT) and SIGTERM during long work: the work stops at once, nothing half-done is
stored as finished, and the command exits with 128 + the signal's number (130, 143).

IPOPT, called through CasADi, checks for Python signals between iterations; an exception raised
there is swallowed and the solve returns with the status ``NonIpopt_Exception_Thrown``, as if it
had failed. :func:`watch` therefore remembers the signal and raises :class:`Interrupted` once the
solve has returned, so a driver never takes an interrupted solve for a failed or converged one.

A signal can arrive at any moment, also between two solves or in the middle of a write. The
steps that must be whole run in a :func:`deferred` block (every atomic write of a file,
:func:`fatigue_pin.core.files.atomic_write`, and a driver's update of its state with what it has
just solved): the signal is raised when the step is done. A driver catches :class:`Interrupted`
around its whole loop, so whatever it had finished is stored, marked interrupted, before the
command exits.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from typing import Iterator

__all__ = ["Interrupted", "watch", "deferred", "signal_name", "SIGNALS"]

#: The signals that interrupt work (SIGINT: Ctrl-C; SIGTERM: kill, a batch system's time limit).
SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived. ``exit_code`` is 128 + the signal's number (130, 143)."""

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        super().__init__(f"interrupted by {signal.Signals(self.signum).name}")

    @property
    def exit_code(self) -> int:
        return 128 + self.signum

    def __reduce__(self):  # pickles (Dask) with its signal number
        return (Interrupted, (self.signum,))


def signal_name(exc: Interrupted) -> str:
    """``SIGINT`` or ``SIGTERM``: the signal of an :class:`Interrupted`."""
    return signal.Signals(exc.signum).name


class _Handler:
    """The handler :func:`watch` installs: it records every signal and raises
    :class:`Interrupted` at once, unless a :func:`deferred` block is running (then the block
    raises it when it ends)."""

    def __init__(self) -> None:
        self.received: list[int] = []
        self.deferring = 0

    def __call__(self, signum: int, frame: object) -> None:
        self.received.append(signum)
        if not self.deferring:
            raise Interrupted(signum)


def _active() -> _Handler | None:
    """The handler of the innermost :func:`watch` running in this (main) thread, if any."""
    if threading.current_thread() is not threading.main_thread():
        return None
    handler = signal.getsignal(signal.SIGINT)
    return handler if isinstance(handler, _Handler) else None


@contextlib.contextmanager
def watch() -> Iterator[None]:
    """Inside the block, SIGINT and SIGTERM raise :class:`Interrupted` (where a C library
    swallows it, as CasADi's IPOPT does, the block still ends with it: the signal is remembered
    and raised again when the block ends). Outside the main thread the block runs as it is;
    inside another :func:`watch`, that one's handlers stay and the signals that arrive during
    the block are raised when it ends. The previous handlers are restored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    outer = _active()
    if outer is not None:  # inside another watch: its handler records the signals
        before = len(outer.received)
        yield
        if len(outer.received) > before and not outer.deferring:
            raise Interrupted(outer.received[before])
        return
    handler = _Handler()
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    if handler.received:
        raise Interrupted(handler.received[0])


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """A block that a signal does not cut short: inside a :func:`watch`, SIGINT and SIGTERM that
    arrive during the block are recorded, the block runs to its end, and :class:`Interrupted` is
    raised then. For steps that must be whole or not at all, and are short: a write of a result
    file, a driver's update of its state with the window it has just solved. Blocks nest (the
    outermost one raises). Outside a watch (or the main thread) the block runs as it is."""
    handler = _active()
    if handler is None:
        yield
        return
    before = len(handler.received)
    handler.deferring += 1
    try:
        yield
    finally:
        handler.deferring -= 1
    if len(handler.received) > before and not handler.deferring:
        raise Interrupted(handler.received[before])
