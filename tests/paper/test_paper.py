"""The paper's study as data: the shipped study files, and parity with the formulation of
fatigue_pin 0.1 (main at 034cfcc, before problems became data)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from conftest import small_curl
from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.paper.curl import COSTS, VARIANTS, WINDOW, authors_variant_dict, curl_study
from fatigue_pin.drivers.sliding import SlidingHorizon, SlidingSettings
from fatigue_pin.io.study import Study

STUDIES = Path(__file__).resolve().parents[2] / "studies"


@pytest.mark.parametrize("preset", list(VARIANTS))
@pytest.mark.parametrize("cost", list(COSTS))
@pytest.mark.parametrize("kind, horizon", [("sliding", "sliding"), ("full", "max-cycles")])
def test_shipped_study_files_are_the_paper_configurations(preset, cost, kind, horizon):
    shipped = Study.from_file(STUDIES / f"curl_{kind}_{cost}_{preset}.toml")
    expected = curl_study(horizon, cost, preset, 10.0)  # the search has no cap
    assert shipped.data == expected.data
    assert shipped.run_name() == f"{kind}/{cost}_S10"
    assert shipped.replace({"fatigue.S": 0.0}).run_name() == f"{kind}/{cost}_S0"


def test_shipped_authors_variant_is_the_paper_modules():
    shipped = Study.from_file(STUDIES / "curl_full_authors-variant.toml")
    assert shipped.data == Study.from_dict(authors_variant_dict()).data
    solver, tr = shipped.solver(), shipped.transcription()
    assert solver.accept_acceptable and solver.mu_init == 0.1 and abs(solver.perturb_dec_fact - 1 / 3) < 1e-15
    assert not tr.scaling and tr.target_rows and not tr.torque_variable and shipped.horizon["cyclic_end"] and shipped.horizon["guess"] == "rest"
    assert shipped.run_name() == "full/authors-variant_fatigue-torque_S10"


# Reference values computed with fatigue_pin 0.1 (FatigueOcp, OcpSettings) on the same small
# problems: 10 intervals per cycle, 2 RK4 substeps, uncompiled.
REFERENCE_FULL = [
    (dict(cost="fatigue-torque"), 2, 25, 803.9509507670801),
    (dict(cost="torque", preset="authors-code", S=0.0), 1, 17, 261.88129433591996),
    (dict(cost="fatigue", S=10.0), 3, 23, 232.22166320401965),
]
REFERENCE_SLIDING = ([21, 16, 21], [244.9352114740196, 403.22205952688563, 712.3289125587902])


def _about(iterations: int, reference: int) -> bool:
    """IPOPT's iteration count is a property of the path, not of the optimum: a linear-solver
    update or another Hessian may change it by a few. The optimum (objective) is checked tightly;
    the count only within a band that still catches a formulation that doubles the work."""
    return abs(iterations - reference) <= max(5, 0.5 * reference)


@pytest.mark.parametrize("options, cycles, iterations, objective", REFERENCE_FULL)
def test_full_horizon_parity_with_the_previous_formulation(arm26, options, cycles, iterations, objective):
    study = small_curl(**options)
    sol = OcpBuilder(study.problem(arm26), study.transcription(), study.solver())(cycles).solve()
    assert sol.success
    assert _about(sol.iterations, iterations), (sol.iterations, iterations)
    assert sol.objective == pytest.approx(objective, rel=1e-6)


def test_sliding_horizon_parity_with_the_previous_formulation(arm26):
    study = small_curl("sliding", cost="fatigue")
    run = SlidingHorizon(study.problem(arm26), SlidingSettings(window=WINDOW, max_cycles=5), study.transcription(), study.solver()).run()
    iterations, objectives = REFERENCE_SLIDING
    assert all(_about(i, ref) for i, ref in zip(run.windows["iterations"], iterations)), list(run.windows["iterations"])
    assert list(run.windows["objective"]) == pytest.approx(objectives, rel=1e-6)
    assert run.attrs["repetitions"] == 5


def test_the_demo_ends_on_its_count_and_why_the_arm_stopped(tmp_path, monkeypatch):
    """The demo (on a small curl that tires within a few cycles: F = 5 1/s, 10 intervals per
    cycle) ends on its repetition count and why the sliding horizon ended, in words; the line
    before says why the paper's count differs (its authors' code's values, from
    fatigue_pin.paper.curl)."""
    from fatigue_pin.paper import curl
    from fatigue_pin.paper.curl import PAPER_REPETITIONS
    from fatigue_pin.paper.reproduce import demo

    small = small_curl("sliding").replace({"fatigue.F": 5.0})
    monkeypatch.setattr(curl, "curl_study", lambda *args, **kwargs: small)
    lines: list[str] = []
    demo(tmp_path / "demo", progress=lines.append)
    run_lines = [line for line in lines if line.startswith("window ")]
    assert run_lines[-1].startswith("window   2 (cycles 3-5): FAILED")  # the solver's line, not the last one
    # why it failed, and how near its last iterate was to a motion
    assert re.search(r"  \((infeasible|infeasible-growing|not-converged|numerical): constraint violation \d\.\de[+-]\d+ "
                     r"at the last iterate\)", run_lines[-1]), run_lines[-1]
    assert lines[-1].startswith("4 repetitions: then the arm was too tired to go on: the solver found no motion for the next 3 "
                                "cycles (3-5) from the end of cycle 2 (window 2: "), lines[-1]
    assert "FAILED" not in lines[-1] and lines[-1].endswith(" s of solving")
    paper = lines[-2]
    assert paper.startswith(f"the paper reports {PAPER_REPETITIONS[('sliding', 10.0)]['fatigue-torque']} repetitions for this curl")
    assert f"R = {VARIANTS['authors-code'].R:g} 1/s (text: {VARIANTS['paper'].R:g}" in paper
    assert "the solver settings are the same" in paper and "studies/curl_sliding_fatigue-torque_authors-code.toml" in paper
    assert (STUDIES / "curl_sliding_fatigue-torque_authors-code.toml").exists()
