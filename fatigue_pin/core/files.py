"""File safety: the one place where outputs are checked before any work, locked, and written so
that a crash, a kill or a full disk at any moment leaves the old file or the new one, whole.

Every writer of the package goes through these: result files (:mod:`fatigue_pin.io.results`),
the compiled-code cache (:mod:`fatigue_pin.ocp.compiled`), endurance tables and calibrations
(:mod:`fatigue_pin.fatigue`), sweep summaries and the paper's forward studies.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
import tempfile
from pathlib import Path
from typing import Callable, Iterator

from fatigue_pin.core.errors import CalibrationDataError, OutputLocationError
from fatigue_pin.core.signals import deferred

#: bytes a folder must have free, at the least, to receive outputs
MIN_FREE_BYTES = 1 << 20


@contextlib.contextmanager
def locked(lock_file: Path) -> Iterator[None]:
    """Hold an exclusive ``flock`` on ``lock_file`` (created if missing) so that concurrent
    writers take turns. On a file system without locks (some network mounts) the block runs
    unlocked."""
    lock_file.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(lock_file, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError as exc:
            if exc.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.EINVAL):
                raise
        yield
    finally:
        os.close(fd)  # releases the lock


def held(lock_file: Path) -> bool:
    """Whether another process holds the ``flock`` of ``lock_file`` (:func:`locked`) now: a
    non-blocking probe that takes and releases the lock if it is free. False if the file is missing."""
    try:
        fd = os.open(lock_file, os.O_RDWR)
    except FileNotFoundError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        return exc.errno in (errno.EAGAIN, errno.EACCES)
    finally:
        os.close(fd)  # releases the lock if it was taken here
    return False


def fsync(path: Path, directory: bool = False) -> None:
    """Flush ``path`` (a file, or with ``directory`` a folder's entries) to the disk."""
    fd = os.open(path, os.O_RDONLY if directory else os.O_RDWR)
    try:
        os.fsync(fd)
    except OSError:
        if not directory:
            raise
    finally:
        os.close(fd)


def clone(src: Path, dst: Path) -> None:
    """Copy the bytes of ``src`` to ``dst``: a reflink where the file system has them (btrfs,
    xfs: instant), else a kernel-side copy."""
    with open(src, "rb") as fin, open(dst, "wb") as fout:
        try:
            fcntl.ioctl(fout.fileno(), 0x40049409, fin.fileno())  # FICLONE
            return
        except OSError:
            pass
    shutil.copyfile(src, dst)  # sendfile / copy_file_range on Linux


def through_links(path: str | Path) -> Path:
    """The file that writing ``path`` means: ``path`` itself, or, for a symbolic link (a chain of
    them, or one whose target does not exist yet), the file it points to, so that an atomic
    replace writes through the link instead of replacing the link by a regular file."""
    path = Path(path)
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def atomic_write(path: Path, write: Callable[[Path], None], tmp: Path | None = None) -> Path:
    """Make ``path`` the file that ``write(tmp)`` writes at a temporary path beside it: the
    temporary file is fsynced and renamed over ``path`` (``os.replace``), then the folder is
    fsynced. On any error the temporary file is removed and ``path`` is unchanged. ``tmp``: the
    temporary path (default: a new unique name beside ``path``; a writer that holds the file's
    lock may name it). A symbolic link is written through (:func:`through_links`): the link
    stays, its target changes. A SIGINT or SIGTERM that arrives during the write is raised once
    it is done (:func:`fatigue_pin.core.signals.deferred`): a write is whole or not started."""
    with deferred():
        return _atomic_write(through_links(path), write, tmp)


def _atomic_write(path: Path, write: Callable[[Path], None], tmp: Path | None) -> Path:
    if tmp is None:
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        os.close(fd)
        tmp = Path(name)
    try:
        write(tmp)
        fsync(tmp)
        os.replace(tmp, path)
        fsync(path.parent, directory=True)
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()
    return path


def atomic_write_bytes(path: Path, data: bytes) -> Path:
    """:func:`atomic_write` of ``data``."""
    return atomic_write(path, lambda tmp: tmp.write_bytes(data))


def check_space(folder: Path, need: int, what: str) -> None:
    """Refuse to start ``what`` when the disk of ``folder`` has fewer than ``need`` bytes free."""
    try:
        st = os.statvfs(folder)
    except OSError:
        return
    free = st.f_bavail * st.f_frsize
    if free < need:
        raise OutputLocationError(f"the disk of {str(folder)!r} is full: {free // 1024} KiB free; "
                                  f"{what} needs at least {-(-need // 1024)} KiB")


def check_folder(folder: Path, label: str) -> None:
    """Create ``folder`` if needed and write (then remove) a small probe file in it, so that a
    folder that cannot be written is found before any work."""
    existing = folder
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise OutputLocationError(f"{label} cannot be created: {str(existing)!r} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputLocationError(f"{label} is not writable; expected a folder you can write to")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".fatigue_pin_probe_") as probe:
            probe.write(b"\0" * 4096)
            probe.flush()
            os.fsync(probe.fileno())
    except OSError as exc:
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise OutputLocationError(f"{label} is on a full disk (no space left on device)") from None
        raise OutputLocationError(f"{label} is not writable: a file cannot be created in it ({exc.strerror or exc})") from None


def check_output_dir(path: str | Path) -> Path:
    """Check, before any work, that the folder ``path`` can receive output files: it is a folder
    (created if missing) that can be written to, on a disk that is not full.

    Raises:
        OutputLocationError: naming the path and what is wrong.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputLocationError(f"output {str(path)!r} is a file; expected a folder (created if missing)")
    check_folder(path, f"output folder {str(path)!r}")
    check_space(path, MIN_FREE_BYTES, f"writing to {str(path)!r}")
    return path


def check_output_file(path: str | Path, suffix: str | None = None) -> Path:
    """Check, before any work, that a file can be written at ``path``: it is not a folder, its
    folder can be written to (created if missing), it ends with ``suffix`` when one is given,
    and an existing file there is writable.

    Raises:
        OutputLocationError: naming the path and what is wrong.
    """
    path = Path(path)
    if suffix is not None and path.suffix.lower() != suffix:
        raise OutputLocationError(f"output {str(path)!r}: expected a {suffix} file name")
    if path.is_dir():
        raise OutputLocationError(f"output {str(path)!r} is a folder; expected a file name")
    if path.exists() and not os.access(path, os.W_OK):
        raise OutputLocationError(f"output {str(path)!r} is not writable")
    folder = path.parent if str(path.parent) else Path(".")
    check_folder(folder, f"output folder {str(folder)!r}")
    check_space(folder, MIN_FREE_BYTES, f"writing {str(path)!r}")
    return path


def read_csv_table(p: Path, what: str) -> tuple[list[str], list[dict[str, str]], str]:
    """The header, the rows (column -> text, both stripped) and the delimiter of the CSV file
    ``p``, a file of ``what`` (``"endurance data"``): the delimiter is ``,``, or ``;`` or a tab
    where the first line has no comma (Excel writes ``;`` where the decimal mark is a comma); a
    byte-order mark is skipped; :func:`csv_number` reads a cell.

    Raises:
        CalibrationDataError: a missing or unreadable file (one line naming it).
    """
    import csv

    if not p.is_file():
        raise CalibrationDataError(f"{what} {str(p)!r} does not exist (or is not a file): expected a CSV file")
    try:
        with p.open(newline="", encoding="utf-8-sig") as fh:
            first = fh.readline()
            fh.seek(0)
            delimiter = max(",;\t", key=first.count) if first.count(",") == 0 else ","
            reader = csv.DictReader(fh, delimiter=delimiter)
            header = [h.strip() for h in (reader.fieldnames or [])]
            rows = [{k.strip(): (v or "").strip() for k, v in raw.items() if k is not None} for raw in reader]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise CalibrationDataError(f"{what} {str(p)!r} is not a readable CSV file ({exc})") from None
    return header, rows, delimiter


def csv_number(text: str, delimiter: str, where: str) -> float:
    """The number in a cell of a table of :func:`read_csv_table` (a decimal comma where the
    delimiter is ``;``); ``where`` names the cell (``"data.csv: row 3: time_s"``).

    Raises:
        CalibrationDataError: the cell is not a number.
    """
    try:
        return float(text.replace(",", ".") if delimiter == ";" else text)
    except ValueError:
        raise CalibrationDataError(f"{where} = {text!r}: expected a number") from None
