"""The stage-wise KKT solver's library (``src/riccati_kkt.cpp``, ``linear_solver = "riccati"``)
seen from Python: where it is, the IPOPT options that load it, whether an NLP's patterns suit it,
and freeing its factors once a solve has returned. :class:`~fatigue_pin.ocp.solver.NlpSolver`
chooses and calls it; the library itself is IPOPT's MA27 interface (docs/ocp.md, "The KKT solve
by stages")."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable

import casadi as ca
import numpy as np


#: ``linear_solver = "riccati"`` falls back to MUMPS above this many rows and columns in one
#: dense block of the stage-wise elimination (a stage of the UR5 window with Xia halves is about
#: 130; a cost or constraint coupling distant stages merges them into one block).
RICCATI_MAX_BLOCK = 300
#: ``linear_solver = "auto"`` takes the stage-wise solver up to this many rows in one block, MUMPS
#: above. Measured (docs/ocp.md, "The KKT solve by stages"): arm26's windows and full horizons,
#: blocks of 52 rows, solve 25-45 % faster with the same iterations; the UR5's, 172 rows, 30 %
#: slower per iteration of IPOPT's own work.
RICCATI_AUTO_MAX_BLOCK = 100
#: Environment variable naming the stage-wise solver's library (development builds).
RICCATI_LIBRARY_ENV = "FATIGUE_PIN_RICCATI_LIB"


def riccati_library() -> Path | None:
    """The shared library of the stage-wise KKT solver (``src/riccati_kkt.cpp``, installed beside
    the package by CMake; ``$FATIGUE_PIN_RICCATI_LIB`` first), or None where it is missing."""
    given = os.environ.get(RICCATI_LIBRARY_ENV)
    candidates = [Path(given)] if given else []
    candidates.append(Path(__file__).resolve().parents[1] / "libfatigue_pin_riccati.so")
    return next((c for c in candidates if c.is_file()), None)


def linear_solver_options(name: str) -> dict[str, Any]:
    """IPOPT options of the linear solver ``name``: ``riccati`` (and ``auto``, until
    :class:`~fatigue_pin.ocp.solver.NlpSolver` has chosen) is IPOPT's MA27 interface on
    :func:`riccati_library` (exported as ``ma27ad``, ...), without IPOPT's MC19 scaling (the library exports none; it equilibrates
    the matrix itself, as MUMPS does); MUMPS where the library is missing."""
    if name not in ("riccati", "auto"):
        return {"linear_solver": name}
    library = riccati_library()
    if library is None:
        return {"linear_solver": "mumps"}
    return {"linear_solver": "ma27", "hsllib": str(library), "linear_system_scaling": "none"}


def riccati_releaser() -> Callable[[], int] | None:
    """The library's ``riccati_release_thread``, loaded once (None where the library is missing):
    called once an IPOPT solve has returned, it frees the stage-wise solver's factors of the solves
    this thread has made (IPOPT never says when one is gone; the library would keep the newest 16,
    about 10 MB each at the UR5's size); solves under way in other threads are left alone. It
    returns the number freed."""
    import ctypes

    library = riccati_library()
    if library is None:
        return None
    release = getattr(ctypes.CDLL(str(library)), "riccati_release_thread", None)  # None: a build before it
    if release is not None:
        release.restype = ctypes.c_int
    return release


def riccati_structure(hessian: ca.Sparsity, jacobian: ca.Sparsity, max_block: int | None = None) -> str | None:
    """Why the stage-wise solver cannot take an NLP with these Lagrangian Hessian (n x n) and
    constraint Jacobian (m x n) patterns, or None when it can: the library's own analysis of the
    augmented system's pattern (variables in NLP order, each row after the last variable it
    touches) gives dense blocks of at most ``max_block`` rows (default
    :data:`RICCATI_MAX_BLOCK`)."""
    limit = RICCATI_MAX_BLOCK if max_block is None else int(max_block)
    library = riccati_library()
    if library is None:
        return "the stage-wise solver's library is not installed"
    biggest, _ = riccati_blocks(hessian, jacobian)
    if biggest < 0:
        return "the augmented system's pattern has no stage order"
    if biggest > limit:
        return (f"its stages merge into a dense block of {biggest} rows (more than {limit}: "
                "a cost or constraint couples distant stages)")
    return None


def riccati_blocks(hessian: ca.Sparsity, jacobian: ca.Sparsity) -> tuple[int, int]:
    """The stage-wise solver's analysis of the augmented system of these patterns (every row an
    equality, no slacks): the largest dense block (-1: no stage order) and the number of blocks."""
    import ctypes

    library = riccati_library()
    n, m = hessian.size1(), jacobian.size1()
    hr, hc = (np.asarray(v, dtype=np.int32) for v in hessian.get_triplet())
    jr, jc = (np.asarray(v, dtype=np.int32) for v in jacobian.get_triplet())
    diag = np.arange(n + m, dtype=np.int32)
    irn = np.concatenate([np.maximum(hr, hc), jr + n, diag]) + 1
    jcn = np.concatenate([np.minimum(hr, hc), jc, diag]) + 1
    lib = ctypes.CDLL(str(library))
    lib.riccati_max_block.restype = ctypes.c_int
    blocks = ctypes.c_int(0)
    ptr = ctypes.POINTER(ctypes.c_int)
    biggest = lib.riccati_max_block(ctypes.c_int(n + m), ctypes.c_int(irn.size), irn.ctypes.data_as(ptr),
                                    jcn.ctypes.data_as(ptr), ctypes.byref(blocks))
    return int(biggest), int(blocks.value)
