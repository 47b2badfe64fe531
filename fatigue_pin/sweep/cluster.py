"""Dask clusters of a sweep: a local cluster, SLURM through dask-jobqueue, or an existing
scheduler whose address is checked, and whose answer is awaited with a timeout, before any work
(:func:`connect_scheduler`)."""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from typing import Any

from fatigue_pin.core.cores import usable_cores
from fatigue_pin.core.settings import check_fields, is_int, is_str, setting
from fatigue_pin.sweep.plan import SweepError

# -- clusters ----------------------------------------------------------------------------------------


def local_cluster(workers: int | None = None):
    """One single-threaded worker process per core, everything on 127.0.0.1."""
    from distributed import LocalCluster

    n = workers or usable_cores()
    return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                        dashboard_address="127.0.0.1:0", scheduler_port=0)


@dataclass(frozen=True)
class SlurmSettings:
    """What each SLURM job of a sweep asks for (``fatigue-pin sweep --slurm``, whose defaults are these).

    Attributes:
        queue: the partition (None: the cluster's default).
        walltime: time limit of each job, ``HH:MM:SS`` (it must cover the longest sweep job).
        cores: cores per job, each running one single-threaded worker.
        memory: memory per job, e.g. ``4GB``.
        interface: the network interface the scheduler listens on, e.g. ``ib0`` (None: its default).
    """

    queue: str | None = setting(None, "a partition name", is_str)
    walltime: str = setting("01:00:00", "a time limit HH:MM:SS", is_str)
    cores: int = setting(1, "an integer >= 1", lambda v: is_int(v) and v >= 1)
    memory: str = setting("4GB", "a memory size, e.g. 4GB", is_str)
    interface: str | None = setting(None, "a network interface name, e.g. ib0", is_str)

    def __post_init__(self) -> None:
        check_fields(self, SweepError)


def slurm_cluster(settings: SlurmSettings | None = None, host: str | None = None, **kwargs: Any):
    """A dask-jobqueue ``SLURMCluster`` as ``settings`` ask (default :class:`SlurmSettings`):
    each SLURM job runs ``cores`` single-threaded workers.

    The workers run this Python (``sys.executable``) with this ``PYTHONPATH`` and one OpenMP
    thread. ``settings.interface`` (e.g. ``ib0``) or ``host`` says where the scheduler listens (it
    must be reachable from the compute nodes); the dashboard listens on 127.0.0.1 (reach it over ssh).
    """
    s = settings or SlurmSettings()
    try:
        from dask_jobqueue import SLURMCluster
    except ImportError:
        raise SweepError("--slurm needs dask-jobqueue: pip install 'fatigue_pin[slurm]' (or dask-jobqueue)") from None
    prologue = ["export OMP_NUM_THREADS=1"]
    if os.environ.get("PYTHONPATH"):
        prologue.append(f"export PYTHONPATH={os.environ['PYTHONPATH']}")
    scheduler_options = {"dashboard_address": "127.0.0.1:0", **kwargs.pop("scheduler_options", {})}
    if host is not None:
        scheduler_options["host"] = host
    return SLURMCluster(queue=s.queue, walltime=s.walltime, cores=s.cores, processes=s.cores, memory=s.memory,
                        interface=s.interface, python=sys.executable, job_script_prologue=prologue,
                        scheduler_options=scheduler_options, **kwargs)


def dashboard(client: Any) -> str:
    """The line saying where the Dask dashboard is, or that it is off: it needs bokeh (the
    ``dashboard`` extra, ``pip install 'fatigue_pin[dashboard]'``)."""
    try:
        if "dashboard" in client.scheduler_info().get("services", {}):
            return f"dashboard: {client.dashboard_link}"
    except Exception:  # noqa: BLE001 - no dashboard is not an error
        pass
    import importlib.util

    if importlib.util.find_spec("bokeh") is None:
        return "dashboard: off (it needs bokeh: pip install 'fatigue_pin[dashboard]')"
    return "dashboard: off (the scheduler serves none)"


# -- an existing scheduler -------------------------------------------------------------------------

#: Seconds to wait for each answer of a scheduler (connection, first bytes, identity).
SCHEDULER_TIMEOUT_S = 10.0
_SCHEMES = ("tcp", "tls")
_ADDRESS_FORM = "tcp://HOST:PORT (or HOST:PORT, tls://HOST:PORT), PORT in 1..65535"


def scheduler_address(text: str) -> tuple[str, str, int]:
    """``(scheme, host, port)`` of a Dask scheduler address; :class:`SweepError` naming the
    address and the expected form otherwise (checked before any work)."""
    bad = SweepError(f"--scheduler {text!r}: expected {_ADDRESS_FORM}")
    if not isinstance(text, str) or not text.strip() or any(c.isspace() for c in text):
        raise bad
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if scheme not in _SCHEMES or "/" in rest or "@" in rest:
        raise bad
    if rest.startswith("["):  # [IPv6]:port
        host, close, port_text = rest[1:].partition("]")
        if not close or not port_text.startswith(":"):
            raise bad
        port_text = port_text[1:]
    else:
        host, colon, port_text = rest.rpartition(":")
        if not colon or ":" in host:
            raise bad
    if not host or not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
        raise bad
    return scheme, host, int(port_text)


def _first_bytes(address: str, host: str, port: int, timeout: float) -> bytes:
    """What the server at ``host:port`` sends first (a Dask server sends its handshake at once)."""
    import socket

    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            data = sock.recv(64)
    except socket.timeout:
        raise SweepError(f"--scheduler {address!r} accepted the connection but sent nothing within {timeout:g} s; "
                         "expected a Dask scheduler (dask scheduler / distributed.Scheduler)") from None
    except OSError as exc:
        raise SweepError(f"--scheduler {address!r} cannot be reached ({exc.strerror or exc}); expected a running Dask "
                         "scheduler at that address") from None
    if not data:
        raise SweepError(f"--scheduler {address!r} closed the connection without a word; expected a Dask scheduler")
    return data


def _looks_like_dask(data: bytes) -> bool:
    """Dask's TCP messages start with their length, a small little-endian uint64 (binary)."""
    return len(data) >= 8 and 0 < int.from_bytes(data[:8], "little") < 1 << 30


def _identity(address: str, timeout: float) -> dict:
    """The scheduler's answer to Dask's ``identity`` request, within ``timeout`` seconds (run on
    its own event loop in a thread, so that it works under a running loop too)."""
    import asyncio
    import threading

    async def ask() -> Any:
        from distributed.comm import connect

        comm = await connect(address, timeout=timeout)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    out: dict[str, Any] = {}

    def work() -> None:
        try:
            out["reply"] = asyncio.run(asyncio.wait_for(ask(), timeout))
        except BaseException as exc:  # noqa: BLE001 - reported below, whatever the peer did
            out["error"] = exc

    thread = threading.Thread(target=work, daemon=True, name="fatigue-pin-scheduler-probe")
    thread.start()
    thread.join(timeout + 5.0)
    reply = out.get("reply")
    if isinstance(reply, dict) and reply.get("type") == "Scheduler":
        return reply
    why = "no answer" if thread.is_alive() or "error" not in out else type(out["error"]).__name__
    raise SweepError(f"--scheduler {address!r} does not answer as a Dask scheduler ({why} within {timeout:g} s); "
                     "expected a running Dask scheduler at that address")


def check_scheduler(address: str, timeout: float | None = None) -> str:
    """Check that ``address`` is a Dask scheduler that answers, every wait bounded by ``timeout``
    seconds: the address's form, a TCP connection, the first bytes (another protocol's banner,
    e.g. ``SSH-2.0-...``, is named in the error), then Dask's ``identity`` request (tcp only).

    Returns:
        The address with its scheme (``tcp://HOST:PORT``).

    Raises:
        SweepError: one line naming the address and what went wrong.
    """
    timeout = SCHEDULER_TIMEOUT_S if timeout is None else float(timeout)
    scheme, host, port = scheduler_address(address)
    full = address if "://" in address else f"{scheme}://{address}"
    if scheme == "tcp":
        data = _first_bytes(address, host, port, timeout)
        if not _looks_like_dask(data):
            text = data.decode("ascii", "replace").splitlines()[0][:60] if data.strip() else repr(data[:16])
            raise SweepError(f"--scheduler {address!r} answered {text!r}, another protocol; expected a Dask scheduler")
        _identity(full, timeout)
    return full


def connect_scheduler(address: str, timeout: float | None = None):
    """A ``distributed.Client`` of the scheduler at ``address``, once :func:`check_scheduler`
    has found it answering; the client's own connection waits at most ``3 * timeout`` seconds
    (``timeout``: :data:`SCHEDULER_TIMEOUT_S` by default)."""
    from distributed import Client

    timeout = SCHEDULER_TIMEOUT_S if timeout is None else float(timeout)
    full = check_scheduler(address, timeout)
    try:
        return Client(full, timeout=f"{3 * timeout:g}s")
    except (OSError, TimeoutError) as exc:
        raise SweepError(f"--scheduler {address!r}: the client could not connect ({' '.join(str(exc).split())})") from None
