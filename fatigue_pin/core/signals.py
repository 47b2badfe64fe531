"""Ctrl-C (SIGINT) and SIGTERM during long work: the work stops at once, nothing half-done is
stored as finished, and the command exits with 128 + the signal's number (130, 143).

IPOPT, called through CasADi, checks for Python signals between iterations; an exception raised
there is swallowed and the solve returns with the status ``NonIpopt_Exception_Thrown``, as if it
had failed. :func:`watch` therefore remembers the signal and raises :class:`Interrupted` once the
solve has returned, so a driver never takes an interrupted solve for a failed or converged one.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from typing import Iterator

__all__ = ["Interrupted", "watch", "signal_name", "SIGNALS"]

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
    outer = getattr(signal.getsignal(signal.SIGINT), "received", None)
    if outer is not None:  # inside another watch: its handler records the signals
        before = len(outer)
        yield
        if len(outer) > before:
            raise Interrupted(outer[before])
        return
    received: list[int] = []

    def handler(signum, frame) -> None:
        received.append(signum)
        raise Interrupted(signum)

    handler.received = received  # type: ignore[attr-defined]
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    if received:
        raise Interrupted(received[0])
