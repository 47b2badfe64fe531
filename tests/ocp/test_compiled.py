"""The per-model compiled function library: cache key, concurrent builders, corrupt entries,
exact derivatives through the externals, and its use by the transcription (library mode)."""

from __future__ import annotations

import multiprocessing
import os
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import fatigue_pin.ocp.compiled as compiled
from fatigue_pin.ocp.compiled import (
    BuildOptions,
    CompileError,
    FunctionLibrary,
    derivative,
    library_key,
    requested_derivatives,
    verify_entry,
)
from conftest import small_curl
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.transcription import IntervalFunctions

FAST = ("-O0",)


def tiny(scale: float = 2.0, name: str = "g") -> ca.Function:
    """g(x (3,), p (2,)) -> y (3,): nonlinear in x, with a sparse Jacobian and a parameter."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    y = ca.vertcat(ca.sin(x[0] * x[1]) * p[0], scale * x[2] ** 3 * p[1], ca.exp(x[0]) * x[2])
    return ca.Function(name, [x, p], [y], ["x", "p"], ["y"])


def tiny_mx(name: str = "G") -> ca.Function:
    """An MX function of two calls of the SX ``tiny`` (like F_rb: RK4 as MX calls of f_rb)."""
    g = tiny()
    x, p = ca.MX.sym("x", 3), ca.MX.sym("p", 2)
    return ca.Function(name, [x, p], [g(x + 0.1 * g(x, p), p)], ["x", "p"], ["y"])


def options(tmp_path: Path, **changes: object) -> BuildOptions:
    return BuildOptions(**{"flags": FAST, "cache_dir": tmp_path / "cache", "jobs": 1, **changes})


# -- cache key ----------------------------------------------------------------------------------


def test_key_changes_with_every_input(tmp_path, monkeypatch):
    base = options(tmp_path)
    key = library_key([tiny()], base)
    assert library_key([tiny()], base) == key  # deterministic
    assert library_key([tiny(scale=3.0)], base) != key  # the function itself
    assert library_key([tiny(name="h")], base) != key  # its name (the symbol)
    assert library_key([tiny()], options(tmp_path, flags=("-O1",))) != key  # flags
    assert library_key([tiny()], options(tmp_path, compiler="clang")) != key  # compiler
    assert library_key([tiny()], base, derivatives=("fwd2_", "adj1_")) != key  # compiled derivatives
    assert library_key([tiny()], base, plain=[tiny(name="h")]) != key  # functions compiled without derivatives
    assert library_key([tiny()], base, plain=[tiny(name="h")]) != library_key([tiny()], base, plain=[tiny(3.0, "h")])
    assert library_key([tiny()], options(tmp_path, jobs=2)) == key  # parallelism is not an input
    assert library_key([tiny()], options(tmp_path, cache_dir=tmp_path / "other")) == key
    monkeypatch.setattr(compiled.ca, "__version__", "0.0.0-other")
    assert library_key([tiny()], base) != key  # casadi version


def test_key_includes_the_cpu_only_for_native_code(tmp_path, monkeypatch):
    native, portable = options(tmp_path, flags=("-O1", "-march=native")), options(tmp_path, flags=("-O1",))
    keys = library_key([tiny()], native), library_key([tiny()], portable)
    monkeypatch.setattr(compiled, "host_key", lambda flags: b"another cpu" if any(f.endswith("=native") for f in flags) else b"")
    assert library_key([tiny()], native) != keys[0]
    assert library_key([tiny()], portable) == keys[1]


def test_key_does_not_depend_on_the_horizon(arm26):
    """The interval functions of a 1-cycle and of a 3-cycle problem are the same functions, so
    they give the same key; another interval length gives another key."""
    study = small_curl()
    problem = study.problem(arm26)
    keys = {library_key(IntervalFunctions(problem, study.transcription(), fatigue_calls=True).library_functions(), BuildOptions())
            for _ in (1, 3)}
    assert len(keys) == 1
    other = small_curl(intervals_per_cycle=20).problem(arm26)
    assert library_key(IntervalFunctions(other, study.transcription(), fatigue_calls=True).library_functions(), BuildOptions()) not in keys


def test_build_caches_and_reports_progress(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing may be written into the working directory
    lines: list[str] = []
    lib = FunctionLibrary.build([tiny()], "tinylib", options(tmp_path), progress=lines.append, description="the tiny functions")
    assert lib.compile_time_s > 0 and verify_entry(lib.path)
    assert len(lines) == 1 and lines[0].startswith("compiling the tiny functions (about ") and "once per machine" in lines[0]
    again = FunctionLibrary.build([tiny()], "tinylib", options(tmp_path), progress=lines.append)
    assert again.compile_time_s == 0 and again.path == lib.path and len(lines) == 1
    assert sorted(os.listdir(tmp_path)) == ["cache"]
    assert os.getcwd() == str(tmp_path)


def _build_in_child(cache_dir: str) -> tuple[str, bool, float]:
    lib = FunctionLibrary.build([tiny_mx()], "racelib", BuildOptions(flags=FAST, cache_dir=Path(cache_dir), jobs=1))
    value = float(ca.sum1(lib.function("G")([0.1, 0.2, 0.3], [1.0, 2.0])))
    return str(lib.path), lib.compile_time_s > 0, value


def test_concurrent_builders_share_one_valid_library(tmp_path):
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(2) as pool:
        results = pool.map(_build_in_child, [str(tmp_path / "cache")] * 2)
    paths, built, values = zip(*results)
    assert len(set(paths)) == 1 and verify_entry(Path(paths[0]))
    assert sum(built) == 1  # one process compiled, the other waited on the lock and loaded it
    expected = float(ca.sum1(tiny_mx()([0.1, 0.2, 0.3], [1.0, 2.0])))
    assert values[0] == pytest.approx(expected, abs=1e-12) and values[1] == pytest.approx(expected, abs=1e-12)
    leftovers = [p.name for p in (tmp_path / "cache").iterdir() if not p.name.endswith((".so", ".sha256", ".lock"))]
    assert leftovers == []  # no temporary build directories left behind


@pytest.mark.parametrize("damage", ["truncate", "flip", "drop_checksum", "bad_checksum"])
def test_corrupt_library_is_detected_and_rebuilt(tmp_path, damage):
    lib = FunctionLibrary.build([tiny()], "corrupt", options(tmp_path))
    data = lib.path.read_bytes()
    checksum = lib.path.with_name(lib.path.name + ".sha256")
    if damage == "truncate":
        lib.path.write_bytes(data[: len(data) // 2])
    elif damage == "flip":
        lib.path.write_bytes(data[:1000] + bytes([data[1000] ^ 0xFF]) + data[1001:])
    elif damage == "drop_checksum":
        checksum.unlink()
    else:
        checksum.write_text("0" * 64 + "\n")
    assert not verify_entry(lib.path)
    with pytest.raises(CompileError, match="checksum"):
        FunctionLibrary(lib.name, lib.key, lib.path, lib.names, lib.derivatives).function("g")  # never loaded
    rebuilt = FunctionLibrary.build([tiny()], "corrupt", options(tmp_path))
    assert rebuilt.compile_time_s > 0 and verify_entry(rebuilt.path)
    assert float(ca.norm_inf(rebuilt.function("g")([0.1, 0.2, 0.3], [1, 2]) - tiny()([0.1, 0.2, 0.3], [1, 2]))) == 0


def test_missing_compiler_is_named_only_when_compiling(tmp_path):
    opts = options(tmp_path, compiler="no-such-cc-1234")  # constructing the options is fine
    library_key([tiny()], opts)  # and so is the key
    with pytest.raises(CompileError, match="no-such-cc-1234"):
        FunctionLibrary.build([tiny()], "nocc", opts)
    assert not list((tmp_path / "cache").glob("*.so"))


def test_bad_arguments_name_the_value(tmp_path):
    with pytest.raises(ParameterError, match="'bad-name'"):
        FunctionLibrary.build([tiny()], "bad-name", options(tmp_path))
    with pytest.raises(ParameterError, match="'fwd_'"):
        FunctionLibrary.build([tiny()], "lib", options(tmp_path), derivatives=("fwd_",))
    with pytest.raises(ParameterError, match="'h'"):
        FunctionLibrary.build({"h": tiny()}, "lib", options(tmp_path))
    with pytest.raises(ParameterError, match="jobs"):
        BuildOptions(jobs=0)
    with pytest.raises(ParameterError, match="flags"):
        BuildOptions(flags="-O3")  # type: ignore[arg-type]
    lib = FunctionLibrary.build([tiny()], "lib", options(tmp_path))
    with pytest.raises(ParameterError, match="'nope'"):
        lib.function("nope")


# -- exact derivatives through the externals ------------------------------------------------------


def mapped_derivatives(f: ca.Function, n: int = 5) -> ca.Function:
    """(X, P, lam) -> Jacobian of the mapped call, Hessian of lam . call, as dense matrices."""
    X, P, lam = ca.MX.sym("X", 3, n), ca.MX.sym("P", 2), ca.MX.sym("lam", 3 * n)
    y = ca.vec(f.map(n)(X, P))
    lagrangian = ca.dot(lam, y) + ca.sumsqr(y)
    return ca.Function("d", [X, P, lam], [ca.jacobian(y, ca.vec(X)), ca.hessian(lagrangian, ca.vec(X))[0]])


@pytest.mark.parametrize("derivatives", [None, ("fwd3_", "adj1_", "fwd2_adj1_"), ("jac_", "adj1_", "jac_adj1_")])
@pytest.mark.parametrize("make", [tiny, tiny_mx])
def test_derivatives_through_the_external_are_exact(tmp_path, make, derivatives):
    f = make()
    lib = FunctionLibrary.build([f], f"exact_{f.name()}", options(tmp_path), derivatives=derivatives)
    ext = lib.function(f.name())
    assert ext.is_a("External")
    rng = np.random.default_rng(0)
    args = rng.uniform(-1, 1, (3, 5)), rng.uniform(0.5, 2, 2), rng.uniform(-1, 1, 15)
    exact, got = mapped_derivatives(f), mapped_derivatives(ext)
    for a, b, what in zip(exact(*args), got(*args), ("jacobian", "hessian")):
        assert a.sparsity() == b.sparsity(), f"{what} sparsity differs"
        assert float(ca.norm_inf(a - b)) < 1e-10, what
    assert ext.jac_sparsity(0, 0) == f.jac_sparsity(0, 0)


def test_library_always_has_the_first_and_second_order_fallbacks(tmp_path):
    lib = FunctionLibrary.build([tiny()], "fallback", options(tmp_path), derivatives=("fwd3_",))
    assert set(lib.derivatives["g"]) == {"fwd3_", *compiled.DEFAULT_DERIVATIVES}


def test_plain_functions_are_compiled_without_derivatives(tmp_path):
    lib = FunctionLibrary.build([tiny()], "plainlib", options(tmp_path), plain=[tiny(3.0, "h")])
    assert lib.names == ("g", "h") and lib.derivatives["h"] == () and lib.derivatives["g"]
    assert float(ca.norm_inf(lib.function("h")([0.1, 0.2, 0.3], [1.0, 2.0]) - tiny(3.0, "h")([0.1, 0.2, 0.3], [1.0, 2.0]))) < 1e-14
    with pytest.raises(ParameterError, match="both with and without derivatives"):
        FunctionLibrary.build([tiny()], "plainlib", options(tmp_path), plain=[tiny()])


def test_derivative_names_follow_casadi():
    f = tiny()
    assert derivative(f, "fwd4_").name() == "fwd4_g"
    assert derivative(f, "fwd6_adj1_").name() == "fwd6_adj1_g"
    assert derivative(f, "jac_adj1_").name() == "jac_adj1_g"


def test_requested_derivatives_finds_what_the_nlp_evaluates():
    f = tiny()
    X, P = ca.MX.sym("X", 3, 4), ca.MX.sym("P", 2)
    Y = f.map(4)(X, P)
    solver = ca.nlpsol("s", "ipopt", {"x": ca.vec(X), "p": P, "f": ca.sumsqr(Y), "g": ca.vec(Y)}, {"print_time": False})
    found = requested_derivatives(solver, ["g"])
    assert "adj1_" in found["g"]
    assert any(p.startswith("fwd") and p.endswith("_adj1_") for p in found["g"])  # the Hessian
    assert any(p.startswith("fwd") and "adj" not in p for p in found["g"])  # the constraint Jacobian


# -- library mode in the transcription ------------------------------------------------------------------


def test_ocp_with_a_compiled_library_matches_the_uncompiled_one(arm26, tmp_path):
    study = small_curl()
    problem = study.problem(arm26)
    reference = OcpBuilder(problem, study.transcription(), study.solver())(1).solve()
    solver = SolverOptions(compile=True, compile_mode="library", compiler_flags=("-O1",), cache_dir=tmp_path)
    lines: list[str] = []
    ocp = OcpBuilder(problem, study.transcription(), solver, progress=lines.append)(1)
    assert ocp.library is not None and ocp.compile_time_s > 0 and ocp.map_mode == "thread"
    assert any("arm26 interval functions" in line for line in lines)
    # the derivative blocks are compiled in the library and give IPOPT its Jacobian and Hessian
    assert {"jblk_F_rb", "hblk_F_rb", "jblk_terms", "hblk_F_fatigue_xia"} <= set(ocp.library.names)
    assert set(ocp.nlp.derivatives) == {"jac_g", "hess_lag"}
    assert all(ocp.functions.blocks[name].hess.is_a("External") for name in ("F_rb", "F_fatigue_xia"))
    # its blocks give IPOPT every derivative of the rigid body's step: no derivative code of the step
    assert "F_rb" in ocp.library.names and not ocp.library.derivatives.get("F_rb")
    # F_fatigue (the estimator's, the guesses') is the map of the compiled one-half step: the
    # values and the Jacobian in (m, u, p) of the uncompiled all-halves RK4
    plain = IntervalFunctions(problem, study.transcription())
    assert "F_fatigue" not in ocp.library.names and ocp.functions.fatigue_steps["F_fatigue_xia"].is_a("External")
    args = [ca.MX.sym(name, plain.F_fatigue.size1_in(i)) for i, name in enumerate("mup")]
    jacobians = [ca.Function("J", args, [ca.jacobian(f(*args), ca.vertcat(*args))]) for f in (ocp.functions.F_fatigue, plain.F_fatigue)]
    rng = np.random.default_rng(0)
    point = (rng.uniform(0, 1, args[0].numel()), 20 * rng.uniform(-1, 1, args[1].numel()), problem.actuators.param_vector())
    assert np.allclose(ocp.functions.F_fatigue(*point), plain.F_fatigue(*point), rtol=0, atol=1e-14)
    assert np.allclose(jacobians[0](*point), jacobians[1](*point), rtol=1e-12, atol=1e-12)
    sol = ocp.solve()
    assert sol.success and sol.iterations == reference.iterations
    assert sol.objective == pytest.approx(reference.objective, rel=1e-8)
    assert np.allclose(sol.x, reference.x, atol=1e-8)
    # another horizon, another process's builder: no compile, the same library
    again = OcpBuilder(problem, study.transcription(), solver)(2)
    assert again.compile_time_s == 0 and again.library.path == ocp.library.path
    assert again.solve().success
