"""Compiling a library in a detached process while the run goes on uncompiled
(``solver.first_compile``): the lock check, the detached compile, and a full-horizon solve that
gives the same optimum before and after its library is cached."""

from __future__ import annotations

import fcntl
import os
import time
from pathlib import Path

import casadi as ca
import pytest

from conftest import small_curl
from fatigue_pin.drivers.full import solve_full
from fatigue_pin.ocp.background import compiling
from fatigue_pin.ocp.compiled import BuildOptions, FunctionLibrary, verify_entry
from fatigue_pin.ocp.solver import BACKGROUND_MAX_INTERVALS, SolverOptions, resolve_first_compile


def tiny() -> ca.Function:
    x = ca.SX.sym("x", 2)
    return ca.Function("h", [x], [ca.vertcat(ca.sin(x[0]) * x[1], x[1] ** 3)], ["x"], ["y"])


def wait_for_entry(folder: Path, pattern: str, timeout_s: float = 300.0) -> Path:
    """The cache entry matching ``pattern`` once its checksum is written (the detached compile's
    last step), polled; fails after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        done = [p.with_suffix("") for p in folder.glob(pattern + ".sha256")]
        if done and verify_entry(done[0]):
            return done[0]
        time.sleep(0.1)
    raise AssertionError(f"no verified {pattern} in {folder} after {timeout_s} s: {sorted(p.name for p in folder.iterdir())}")


def test_compiling_sees_a_held_lock(tmp_path):
    entry = tmp_path / "lib_abc.so"
    assert not compiling(entry)  # no lock file
    fd = os.open(entry.with_name(entry.name + ".lock"), os.O_RDWR | os.O_CREAT)
    try:
        assert not compiling(entry)  # a lock file nobody holds
        fcntl.flock(fd, fcntl.LOCK_EX)
        assert compiling(entry)
    finally:
        os.close(fd)
    assert not compiling(entry)


def test_background_build_returns_at_once_and_caches_the_library(tmp_path):
    options = BuildOptions(flags=("-O0",), cache_dir=tmp_path, jobs=1)
    lines: list[str] = []
    assert FunctionLibrary.build([tiny()], "bglib", options, progress=lines.append, background=True) is None
    assert len(lines) == 1 and "in the background" in lines[0]
    entry = wait_for_entry(tmp_path, "bglib_*.so")
    log = entry.with_name(entry.name + ".log").read_text()
    assert "compiled" in log
    # the detached process removed its sources; a build now finds the library, compiles nothing
    assert not list(tmp_path.glob("*.src.*"))
    lib = FunctionLibrary.build([tiny()], "bglib", options, background=True)
    assert lib is not None and lib.compile_time_s == 0 and lib.path == entry
    assert float(lib.function("h")([0.5, 2.0])[1]) == pytest.approx(8.0, abs=1e-14)


def test_first_compile_auto_follows_the_horizon():
    auto = SolverOptions()
    assert auto.first_compile == "auto"
    assert resolve_first_compile(auto, BACKGROUND_MAX_INTERVALS).first_compile == "background"
    assert resolve_first_compile(auto, BACKGROUND_MAX_INTERVALS + 1).first_compile == "wait"
    for given in ("wait", "background"):
        assert resolve_first_compile(SolverOptions(first_compile=given), 1).first_compile == given


def test_a_short_full_solve_is_the_same_before_and_after_its_background_compile(arm26, tmp_path):
    study = small_curl()
    problem = study.problem(arm26)
    reference = solve_full(problem, 1, study.transcription(), study.solver())[1]  # uncompiled
    solver = SolverOptions(compile=True, compiler_flags=("-O0",), cache_dir=tmp_path)  # first_compile: auto
    lines: list[str] = []
    ocp, first = solve_full(problem, 1, study.transcription(), solver, progress=lines.append)
    assert ocp.library is None and ocp.compile_time_s == 0
    assert any("in the background" in line for line in lines)
    assert first.success and first.iterations == reference.iterations
    assert first.objective == pytest.approx(reference.objective, rel=1e-9)
    wait_for_entry(tmp_path, "arm26_intervals_*.so")
    ocp, second = solve_full(problem, 1, study.transcription(), solver)
    assert ocp.library is not None and ocp.compile_time_s == 0
    assert second.success and second.objective == pytest.approx(reference.objective, rel=1e-6)
