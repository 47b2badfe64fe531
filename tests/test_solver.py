"""Solver plumbing: compile flags and the filtered CasADi warning."""

from __future__ import annotations

import io
import sys

from fatigue_pin.solver import _DropLines, openmp_fallback_quiet


def test_drop_lines_forwards_everything_else():
    out = io.StringIO()
    stream = _DropLines(out, "WITH_OPENMP")
    stream.write("first line\nCasADi WARNING(not compiled WITH_OPENMP=ON)\nsec")
    stream.write("ond line\nunterminated")
    stream.flush()
    assert out.getvalue() == "first line\nsecond line\nunterminated"


def test_openmp_fallback_quiet_restores_stderr(capsys):
    before = sys.stderr
    with openmp_fallback_quiet():
        print("WITH_OPENMP fallback", file=sys.stderr)
        print("kept", file=sys.stderr)
    assert sys.stderr is before
    assert capsys.readouterr().err == "kept\n"


def test_cache_key_names_the_cpu_only_for_native_code():
    from fatigue_pin.solver import SolverOptions, _host_key

    assert _host_key(SolverOptions(compiler_flags=("-O1",))) == b""
    assert _host_key(SolverOptions(compiler_flags=("-O3", "-march=native"))) != b""
