"""What C and C++ libraries write on the process's standard output or error (file descriptors
1 and 2, below Python's ``sys.stdout``): :func:`captured` keeps it for an error message instead
of letting it reach the terminal (the URDF parser's complaints, IPOPT's option errors)."""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
from typing import Iterator

__all__ = ["captured"]


def _flush_c_streams() -> None:
    """``fflush(NULL)``: write out every C ``FILE`` buffer of the process (C++'s ``std::cout``
    goes through them too)."""
    import ctypes

    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no C library to reach: nothing buffered by it either
        pass


@contextlib.contextmanager
def captured(fd: int = 2) -> Iterator[list[str]]:
    """Redirect file descriptor ``fd`` (1: standard output, 2: standard error) to a temporary
    file, and Python's ``sys.stdout`` (``sys.stderr``) to a buffer, for the duration of the
    block; the yielded list receives their non-empty lines, stripped, when the block ends. Python's own buffered stream of that descriptor is flushed first, so
    nothing written before the block is lost or captured."""
    lines: list[str] = []
    stream = {1: sys.stdout, 2: sys.stderr}.get(fd)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        try:
            if stream is not None:
                stream.flush()
            saved = os.dup(fd)
        except (OSError, ValueError):  # no such descriptor to redirect (a closed stream)
            yield lines
            return
        os.dup2(tmp.fileno(), fd)
        python_side = io.StringIO()  # CasADi writes through Python's sys.stdout, which may not be fd 1 (pytest)
        redirect = contextlib.redirect_stdout if fd == 1 else contextlib.redirect_stderr
        try:
            with redirect(python_side):
                yield lines
        finally:
            _flush_c_streams()  # C's buffered output (a file or pipe is fully buffered) goes to the capture
            os.dup2(saved, fd)
            os.close(saved)
            tmp.seek(0)
            text = tmp.read().decode("utf-8", "replace") + "\n" + python_side.getvalue()
            lines += [line.strip() for line in text.splitlines() if line.strip()]
