"""IPOPT inside this process: checking a study's IPOPT options before any work
(:func:`check_ipopt_options`, one line naming a refused option) and the thread count of the BLAS
under IPOPT's linear solver (:func:`limit_blas_threads`). :class:`~fatigue_pin.ocp.solver.NlpSolver`
uses both."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import casadi as ca

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.text import shown

__all__ = ["check_ipopt_options", "limit_blas_threads"]


def limit_blas_threads(threads: int) -> bool:
    """Set the thread count of CasADi's OpenBLAS (the BLAS of its MUMPS) to ``threads``.

    The library is loaded with IPOPT's plugin, so call this after ``nlpsol``. OpenBLAS keeps one
    count per process: the last call wins. Returns False (and changes nothing) where CasADi
    ships no OpenBLAS of its own (other platforms or builds).
    """
    import ctypes

    # the copy IPOPT's MUMPS loaded (the wheel holds the same library under three names, each a
    # separate copy once loaded): from the process's memory map where there is one
    maps = Path("/proc/self/maps")
    loaded = sorted({line.split()[-1] for line in maps.read_text().splitlines() if "libcasadi-tp-openblas" in line}) if maps.exists() else []
    folder = Path(ca.__file__).parent
    for path in loaded or sorted(folder.glob("libcasadi-tp-openblas*")):
        try:
            lib = ctypes.CDLL(str(path))
            lib.openblas_set_num_threads(ctypes.c_int(int(threads)))
        except (OSError, AttributeError):
            continue
        return True
    return False


def _ipopt_refusal(name: str, value: Any, said: list[str], exc: Exception) -> ParameterError:
    """The one-line error of an option that IPOPT refused, from IPOPT's own lines (``said``)."""
    key = "solver.linear_solver" if name == "linear_solver" else f"solver.ipopt.{name}"
    text = " ".join(str(exc).split())
    if "No such IPOPT option" in text:
        return ParameterError(f"{key}: IPOPT has no option {name!r}; expected an IPOPT option name (IPOPT's options reference)")
    if "type mismatch" in text:
        return ParameterError(f"{key} = {shown(value)}: IPOPT expects another type of value for {name!r}")
    settings = [line.split()[0] for line in said if line.split() and not line.startswith(("Setting:", "###", "Category:",
                                                                                            "Description:", "Valid", "Default:"))]
    ranges = [line for line in said if "<" in line and "(" in line]
    if ranges:
        expected = f"a value in {ranges[0].split('(')[0].strip()} ... {ranges[0].split(')')[-1].strip()}"
    elif settings:
        expected = f"one of {settings}"
    else:
        expected = "a valid setting (IPOPT's options reference)"
    return ParameterError(f"{key} = {shown(value)}: not a valid IPOPT setting; expected {expected}")


@functools.lru_cache(maxsize=64)
def check_ipopt_options(items: tuple[tuple[str, str], ...]) -> None:
    """Check IPOPT options (``(name, repr(value))`` pairs, hashable so that a set of options is
    checked once per process) on a one-variable NLP: each option alone when IPOPT refuses the
    set (IPOPT names neither the option nor the value), then one solve of zero iterations, which
    fails with ``Invalid_Option`` when the linear solver cannot be loaded (an HSL solver without
    its library). IPOPT's own lines are kept for the message instead of reaching the terminal.

    Raises:
        ParameterError: one line naming the option, its value and what is expected.
    """
    from fatigue_pin.core.streams import captured

    import ast

    options = {name: ast.literal_eval(value) for name, value in items}
    x = ca.SX.sym("x")
    nlp = {"x": x, "f": (x - 1) ** 2, "g": x}

    def build(opts: dict[str, Any]) -> ca.Function:
        return ca.nlpsol("fatigue_pin_option_check", "ipopt", nlp, {"ipopt": opts, "print_time": False, "error_on_fail": False})

    with captured(1) as said:
        try:
            solver = build({**options, "max_iter": 0, "print_level": 5})  # level 5: IPOPT says why a library fails to load
        except RuntimeError:
            solver = None
    if solver is None:
        for name, value in options.items():
            with captured(1) as said:
                try:
                    build({name: value, "print_level": 0, "sb": "yes"})
                except RuntimeError as exc:
                    failure = exc
                else:
                    continue
            raise _ipopt_refusal(name, value, said, failure)
        raise ParameterError(f"IPOPT refuses the options {options}; expected options IPOPT accepts together")
    with captured(1) as said:
        solver(x0=0.0, lbg=-10.0, ubg=10.0)
    if solver.stats().get("return_status") == "Invalid_Option":
        why = next((line.removeprefix("Exception message:").strip() for line in said if line.startswith("Exception message:")),
                   "IPOPT cannot load it")
        raise ParameterError(f"solver.linear_solver = {options.get('linear_solver')!r} cannot be used on this machine ({why}); "
                             "expected an installed linear solver, e.g. 'mumps' (ships with CasADi)")
