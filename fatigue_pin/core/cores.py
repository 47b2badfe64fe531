"""The processor cores this process may run on.

``os.cpu_count()`` counts the machine's cores; a SLURM job, a container or ``taskset`` may give a
process fewer (its affinity mask). Threads and worker processes are sized by :func:`usable_cores`,
so that a job granted 4 cores of a 64-core node starts 4 threads per map, not 64.
"""

from __future__ import annotations

import os

__all__ = ["usable_cores"]


def usable_cores() -> int:
    """The number of cores this process may run on (its affinity mask where the system has one,
    else ``os.cpu_count()``), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # no affinity masks (macOS, Windows)
        return max(1, os.cpu_count() or 1)
