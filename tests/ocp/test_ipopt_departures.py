"""The solver settings that differ from IPOPT's defaults (issue 32): one table,
``fatigue_pin.ocp.ipopt_defaults.DEPARTURES``, checked against IPOPT's and CasADi's own defaults, listed
in docs/ocp.md, and named by ``fatigue-pin run`` where they are in force and not the study's."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import small_curl
from fatigue_pin.cli.main import main
from fatigue_pin.io.study import Study, run_study, to_toml
from fatigue_pin.ocp.ipopt_defaults import DEPARTURES, EVERY_SOLVE, WARM_STARTED, departures_in_force, departures_line
from fatigue_pin.ocp.riccati import linear_solver_options
from fatigue_pin.ocp.solver import NLPSOL_OPTIONS, WARM_START_OPTIONS, SolverOptions

DOC = Path(__file__).resolve().parents[2] / "docs" / "ocp.md"

#: In a child (IPOPT writes its documentation on the C stdout): IPOPT's documented default of
#: every option, and CasADi's nlpsol defaults as they behave.
_PROBE = r"""
import json, re, casadi as ca
x, p = ca.SX.sym("x"), ca.SX.sym("p")
nlp = {"x": x, "p": p, "f": (x - p) ** 2 + x, "g": x}
s = ca.nlpsol("doc", "ipopt", nlp, {"ipopt": {"print_options_documentation": "yes", "max_iter": 0}, "print_time": False})
s(x0=0, p=2, lbg=-10, ubg=10)
s = ca.nlpsol("plain", "ipopt", nlp, {"ipopt": {"print_level": 0, "sb": "yes", "max_iter": 0}})
failed_quietly = True
try:
    out = s(x0=0, p=2, lbg=5, ubg=5)  # max_iter 0: not converged
except RuntimeError:
    failed_quietly = False
s = ca.nlpsol("plain", "ipopt", nlp, {"ipopt": {"print_level": 0, "sb": "yes"}, "print_time": False})
lam_p = float(s(x0=0, p=2, lbg=-10, ubg=10)["lam_p"])
print("CASADI " + json.dumps({"calc_lam_p": lam_p == lam_p, "no_nlp_grad": not s.has_function("nlp_grad"),
                              "error_on_fail": not failed_quietly}))
"""


@pytest.fixture(scope="module")
def defaults() -> tuple[dict[str, str], dict[str, bool], str]:
    """IPOPT's documented defaults (option -> text of the value), CasADi's nlpsol defaults, and
    the child's whole output (the timing table of a solve with CasADi's print_time)."""
    out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=120, check=True).stdout
    ipopt = {}
    for line in out.splitlines():
        m = re.match(r"^(\w+)\s+(?:\S+\s+<=?\s+)?\(\s*(\S+?)\s*\)", line)  # 'mu_init   0 <  ( 0.1) <  +inf', 'sb ("no")'
        if m:
            ipopt[m.group(1)] = m.group(2).strip('"')
    casadi = json.loads(next(line for line in out.splitlines() if line.startswith("CASADI "))[len("CASADI "):])
    return ipopt, casadi, out


def _same(ours: object, documented: str) -> bool:
    if isinstance(ours, bool) or isinstance(ours, str):
        return str(ours) == documented
    return math.isclose(float(ours), float(documented), rel_tol=1e-5)


def test_each_departure_departs_from_what_ipopt_documents(defaults):
    ipopt, casadi, _ = defaults
    assert ipopt["mu_init"] == "0.1" and ipopt["tol"] == "1e-08"  # the parse reads IPOPT's documentation
    for d in DEPARTURES:
        assert d.value != d.default, d
        if d.owner == "CasADi":
            assert d.option in casadi or d.option == "print_time", d
            if d.option in casadi:
                assert casadi[d.option] == d.default, d
        elif d.option in ipopt:
            assert _same(d.default, ipopt[d.option]), (d, ipopt[d.option])
        else:  # an option IPOPT does not document: only the banner switch
            assert d.option == "sb"


def test_casadi_prints_a_timing_table_by_default(defaults):
    """print_time's default is True: the probe's one solve without it printed CasADi's table."""
    _, _, out = defaults
    assert re.search(r"t_wall", out) and "print_time" in {d.option for d in DEPARTURES}


def test_every_other_option_we_pass_is_ipopts_default(defaults):
    """An option we pass that is not in the table has IPOPT's (CasADi's) default value: the table
    is complete."""
    ipopt, casadi, _ = defaults
    listed = {(d.option, d.when) for d in DEPARTURES}
    options = SolverOptions().ipopt_options()
    assert ("linear_solver", EVERY_SOLVE) in listed  # its row holds the options it brings (hsllib, linear_system_scaling)
    own = linear_solver_options(SolverOptions().linear_solver)
    passed = [(k, v, EVERY_SOLVE) for k, v in options["ipopt"].items() if k not in own]
    passed += [(k, v, WARM_STARTED) for k, v in WARM_START_OPTIONS.items()]
    for option, value, when in passed:
        if (option, when) not in listed:
            assert option in ipopt and _same(value, ipopt[option]), (option, value, ipopt.get(option))
    for option, value in options.items():
        if option != "ipopt" and (option, EVERY_SOLVE) not in listed:
            assert casadi[option] == value, option
    assert set(NLPSOL_OPTIONS) <= {d.option for d in DEPARTURES}


def _doc_rows() -> list[list[str]]:
    text = DOC.read_text()
    section = text[text.index("### Where the solver settings differ from IPOPT's"):]
    section = section[:section.index("\n## ")]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in section.splitlines() if line.startswith("| `")]
    return rows


def test_docs_list_every_departure_with_its_values():
    rows = _doc_rows()
    assert len(rows) == len(DEPARTURES)
    for d, row in zip(DEPARTURES, rows):
        option, ours, theirs, set_by, when, changes, why = row
        assert option.split()[0] == f"`{d.option}`", row
        assert _same(d.value, ours) and _same(d.default, theirs), (d, row)
        assert set_by == (f"`solver.{d.field}`" if d.field else "fixed"), row
        assert (when, changes) == (d.when, "yes" if d.changes_solve else "no"), row
        assert why, row


def test_the_line_names_the_defaults_in_force_that_the_study_does_not_set():
    study = small_curl("full")  # its [solver] table sets only compile
    line = study.solver_defaults()
    assert line.startswith("solver: non-IPOPT defaults in force: ") and "\n" not in line
    for part in ("tol = 1e-06 (IPOPT 1e-08)", "mu_init = 1.0 (IPOPT 0.1)", "perturb_dec_fact = 0.6 (IPOPT 0.333333)"):
        assert part in line
    assert "print_level" not in line and "warm" not in line  # output only; no warm starts
    chosen = study.replace({"solver.mu_init": 1.0}).solver_defaults()  # the study's value, though ours too
    assert "mu_init" not in chosen and "tol = 1e-06" in chosen
    assert "mu_init" not in study.replace({"solver.ipopt": {"mu_init": 0.1}}).solver_defaults()
    stated = study.replace({"solver.tol": 1e-6, "solver.mu_init": 1.0, "solver.perturb_dec_fact": 0.6})
    assert stated.solver_defaults() == "" and Study.from_toml(study.to_toml()).solver_defaults() == ""  # every key stated
    warm = small_curl("sliding").replace({"horizon.warm_start": True}).solver_defaults()
    assert "in warm-started windows warm_start_init_point = yes (IPOPT no), mu_init = 0.01 (IPOPT 0.1)" in warm
    assert "warm" not in study.replace({"horizon.warm_start": True}).solver_defaults()  # a full horizon never warm-starts


def test_departures_in_force_follow_the_options():
    assert departures_line([]) == ""
    assert [d.option for d in departures_in_force(SolverOptions(), given={"tol"})] == ["mu_init", "perturb_dec_fact", "linear_solver"]
    assert departures_in_force(SolverOptions(ipopt={"tol": 1e-8, "mu_init": 0.1, "perturb_dec_fact": 0.5}), given={"linear_solver"}) == []


def test_run_prints_the_line_before_solving(tmp_path, capsys):
    data = small_curl("full").data
    data["solver"] = {"compile": False}
    path = tmp_path / "curl.toml"
    path.write_text(to_toml(data))
    assert main(["run", str(path), "--out", str(tmp_path / "a.h5")]) == 0
    out = capsys.readouterr().out.splitlines()
    line = next(i for i, text in enumerate(out) if text.startswith("solver: non-IPOPT defaults in force:"))
    assert "mu_init = 1.0 (IPOPT 0.1)" in out[line] and line < len(out) - 1  # before the outcome line
    assert main(["run", str(path), "--out", str(tmp_path / "b.h5"), "--set", "solver.mu_init=0.1"]) == 0
    said = [text for text in capsys.readouterr().out.splitlines() if text.startswith("solver:")]
    assert len(said) == 1 and "mu_init" not in said[0] and "tol = 1e-06" in said[0]
    lines: list[str] = []
    run_study(Study.from_toml(path.read_text()), progress=lines.append)
    assert sum(text.startswith("solver: non-IPOPT") for text in lines) == 1
