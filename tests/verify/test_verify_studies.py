"""``fatigue-pin verify`` on real results of the shipped studies (studies/*.toml): it passes on a
short result of every study, on the model the run was solved on (payload and gravity included),
checks every task item kind the study declares, and fails when one node is moved.

Each study is shortened (:func:`short`): the fewest cycles its horizon allows (one cycle; a
sliding study keeps one window of one cycle), evaluated without compiling. The UR5 studies keep
their shipped grid (:data:`OWN_GRID`): a shipped study must pass verify as shipped, and their
grids are chosen for it (RK4 steps of 0.025 s; docs/verify.md). The curl studies run on a grid
whose RK4 error is below verify's default gap tolerances (1e-3 rad, rad/s; 1e-5 for the fatigue
states) and cheaper than the paper's 50 intervals per cycle uncompiled; the paper's own grid is
verified in tests/verify/test_verifier.py. The closed-loop study (curl_mpc.toml) is verified
twice: its model's plan as above, and its closed loop, the plant's run, on its shipped grid
(:func:`test_the_closed_loop_study_passes_verify_as_shipped`, marked slow: 62 s uncompiled; the
default suite verifies closed-loop runs in tests/verify/test_verify_closed_loop.py).
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.cli.main import main
from fatigue_pin.io.results import list_runs, read_run, write_run
from fatigue_pin.io.study import Study, run_study
from fatigue_pin.verify import VerifyTolerances, verify_run

STUDIES = Path(__file__).resolve().parents[2] / "studies"

#: Length of an RK4 substep (s) that keeps the curl's RK4 error below the default gap tolerances:
#: 0.0125 s (10 intervals of 0.1 s, 8 substeps: gap qdot 2.4e-4 rad/s).
SUBSTEP = 0.0125
#: Grids (intervals per cycle, substeps) for the curl studies the rule of :func:`short` does not
#: fit: the curl with a 10 kg dumbbell in 2 s cycles swings faster than the paper's 3.6 kg (one
#: window of one cycle: 20 intervals with 8 substeps of 0.0125 s, gap qdot 8.4e-3 rad/s; its own 50
#: with 5 substeps of 0.008 s, 1.4e-3; 50 with 8 of 0.005 s, 7.7e-5).
#: bioptim's pendulum (LD = 100): its own 30 intervals with 20 substeps (docs/porting.md; with its
#: 5, RK4's truncation leaves gaps above the tolerances). bioptim's static arm: its shipped grid,
#: 50 intervals with 2 substeps (gap qdot 1.5e-6 rad/s), uncompiled in about 3 s.
GRID = {"curl_physiological.toml": (50, 8), "bioptim_pendulum_xia.toml": (30, 20), "bioptim_static_arm_xia.toml": (50, 2)}
#: Studies whose short result takes minutes (uncompiled muscles on the grid verify passes: 10
#: intervals with 8 substeps of 0.0125 s, 35-90 s of solve and 15-60 s of verify; with 4 substeps
#: of 0.025 s the gaps fail: qdot 6.8e-3 rad/s, fatigue 1.5e-5): run with ``-m slow``. The default
#: suite verifies a muscle run on polynomial paths in tests/verify/test_verify_muscles.py.
SLOW = {"curl_muscles_sliding.toml", "curl_muscles_exhaustion.toml", "ur5_motors_paced.toml", "ur5_mpc.toml"}
#: (ur5_motors_paced.toml, 17 s, is ur5_motors_lift.toml with a tighter limit and the heat budget:
#: the lift's short result is verified by default, the budget's rows in tests/drivers/test_heat_budget.py.
#: ur5_mpc.toml's plan, 37 s, is ur5_carry.toml's study on its grid with an elbow range: the carry's
#: short result is verified by default, a range's rows in tests/verify/test_task_checks.py.)
#: Models whose studies are verified on their shipped grid (intervals per cycle and substeps as
#: the study file has them): the UR5's. Measured on one window of one cycle, uncompiled, with
#: verify's default tolerances: ur5_carry (and ur5_mpc's plan), 20 intervals of 0.1 s with 4
#: substeps: gap q 4.9e-6 rad, qdot 3.2e-5 rad/s, fatigue 5.9e-6 (with the 2 substeps first
#: shipped: 8.4e-5, 4.8e-4, 1.2e-4, failing on the fatigue gap); ur5_lift_swing, 20 intervals of
#: 0.05 s with 2 substeps: 2.6e-6, 2.5e-5, 3.8e-6.
OWN_GRID = {"ur5"}


def short(study: Study, grid: tuple[int, int] | None = None) -> dict:
    """The changes that make a short, uncompiled version of ``study`` that verify can pass with
    its default tolerances.

    A study of a model in :data:`OWN_GRID` keeps its grid. Otherwise, a sliding window and a full
    horizon with an end box (``cyclic_end``) end near their initial state: 10 intervals per
    second with substeps of :data:`SUBSTEP`. A full horizon with a free end velocity whips the
    arm in its last interval (docs/verify.md), which only the paper's grid (50 intervals per
    second, 5 substeps) resolves within 1e-3 rad/s. ``grid``: (intervals per cycle, substeps)
    instead of these (:data:`GRID`).
    """
    h, task = study.horizon, study.data["task"]
    duration = float(task["cycle_duration"])
    changes: dict = {"solver.compile": False}
    if study.data["solver"]["hessian"] != "exact":  # an approximate Hessian is one of the derivative blocks
        changes["solver.derivative_blocks"] = True
    if h["kind"] == "sliding":
        changes.update({"horizon.cycles": 1, "horizon.max_cycles": 1})
    elif h["kind"] == "max-cycles":
        changes.update({"horizon.max_cycles": 1})
    else:
        changes.update({"horizon.cycles": 1})
    if study.data["model"]["urdf"] in OWN_GRID and grid is None:
        return changes
    free_end = h["kind"] != "sliding" and not h["cyclic_end"]
    if free_end:
        n, substeps = round(50 * duration), 5
    else:
        n = round(10 * duration)
        substeps = math.ceil(duration / n / SUBSTEP)
    n, substeps = grid or (n, substeps)
    changes.update({"task.intervals_per_cycle": n, "transcription.substeps": substeps})
    return changes


def _sources() -> list[tuple[str, int | None]]:
    """(study file, sweep job) for every file of studies/: a study file, or two jobs of a sweep
    file (its S = 0 sliding and max-cycles cases; the S = 10 ones equal curl_*_paper.toml)."""
    out: list[tuple[str, int | None]] = []
    for path in sorted(STUDIES.glob("*.toml")):
        if "base" not in tomllib.loads(path.read_text()):
            out.append((path.name, None))
            continue
        from fatigue_pin.sweep.plan import Sweep

        jobs = Sweep.from_file(path).jobs()
        kinds: dict[str, int] = {}
        for job in jobs:
            if job.values.get("fatigue.S") == 0.0:
                kinds.setdefault(job.study.horizon["kind"], job.index)
        out += [(path.name, index) for index in sorted(kinds.values())]
    return out


SOURCES = _sources()


def _study(source: tuple[str, int | None]) -> Study:
    """The study of a source; for a closed-loop study ([plant], [mpc]), the model's study, whose
    plan the controller solves window after window."""
    name, job = source
    if job is None:
        data = tomllib.loads((STUDIES / name).read_text())
        if "mpc" in data or "plant" in data:
            from fatigue_pin.io.mpc_study import MpcStudy

            return MpcStudy.from_file(STUDIES / name).study
        return Study.from_file(STUDIES / name)
    from fatigue_pin.sweep.plan import Sweep

    return Sweep.from_file(STUDIES / name).jobs()[job].study


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    """``solved(source)``: the result file of the short version of a study, solved once for all
    workers (:func:`conftest.built_once`: several tests read the UR5 carry's and the physiological
    curl's, about 30 s and 15 s to solve)."""
    from conftest import built_once

    def solve(source: tuple[str, int | None]) -> Path:
        def build(out: Path) -> None:
            study = _study(source)
            run_study(study.replace(short(study, GRID.get(source[0]))), out)

        return built_once(tmp_path_factory, f"short_{Path(source[0]).stem}_{source[1]}.h5", build)

    return solve


@pytest.mark.parametrize("source", [pytest.param(s, marks=pytest.mark.slow) if s[0] in SLOW else s for s in SOURCES],
                         ids=[n if j is None else f"{n}[job {j}]" for n, j in SOURCES])
def test_verify_passes_on_a_short_result_of_every_study(source, solved, capsys):
    out = solved(source)
    runs = list_runs(out)
    assert runs
    code = main(["verify", str(out), "--all"])
    text = capsys.readouterr().out
    assert code == 0, text
    assert text.count("  PASSED") == len(runs) and "Traceback" not in text
    study = _study(source)
    kinds = {"task joint targets": any("joint" in t for t in study.data["task"]["targets"]),
             "task frame targets": any("position" in t for t in study.data["task"]["targets"]),
             "task frame planes": bool(study.data["task"]["planes"])}
    for line, declared in kinds.items():  # every kind the study declares has its line, checked
        assert (f"  {line} " in text) == declared, (line, text)


def test_the_sources_cover_every_file_of_studies():
    assert {n for n, _ in SOURCES} == {p.name for p in STUDIES.glob("*.toml")}
    assert len(SOURCES) >= len(list(STUDIES.glob("*.toml")))


UR5 = [source for source in SOURCES if _study(source).data["model"]["urdf"] == "ur5"]


def test_the_ur5_studies_are_verified_on_their_shipped_grid():
    """The UR5 studies run here on the grid their files ship, only shorter (:func:`short` leaves
    their grid alone; a run stores the study it solved, tests/io), and their RK4 steps are short
    enough for verify's default gap tolerances (verify itself passes them, the fatigue gap
    included, in test_verify_passes_on_a_short_result_of_every_study: not repeated here)."""
    assert {name for name, _ in UR5} == {"ur5_carry.toml", "ur5_lift_swing.toml", "ur5_mpc.toml", "ur5_motors_lift.toml", "ur5_motors_paced.toml"}
    for source in UR5:
        study = _study(source)
        shipped = (study.data["task"]["intervals_per_cycle"], study.data["transcription"]["substeps"])
        assert not {"task.intervals_per_cycle", "transcription.substeps"} & set(short(study)), source
        shortened = study.replace(short(study)).data
        assert (shortened["task"]["intervals_per_cycle"], shortened["transcription"]["substeps"]) == shipped
        substep = study.data["task"]["cycle_duration"] / shipped[0] / shipped[1]
        assert substep <= 0.025 + 1e-12, (source, substep)  # the fatigue gap (LD = 10 1/s) needs 0.025 s


# -- a frame-target study with a payload: the UR5 carrying 4 kg ------------------------------------------

CARRY = ("ur5_carry.toml", None)


def _with_study(run, study: Study):
    return dataclasses.replace(run, study=study.to_toml())


def test_frame_target_study_with_a_payload_passes(solved):
    run = read_run(solved(CARRY))
    r = verify_run(run)
    assert r.passed, r.table()
    assert r.gap_qdot < 1e-3 and r.gap_fatigue < 1e-5 and r.rk4_residual < 1e-6
    targets, plane = r.check("task frame targets"), r.check("task frame planes")
    assert targets.checked and plane.checked and targets.unit == "m"
    assert targets.value < 1e-6 and plane.value < 1e-6  # IPOPT's tolerance
    # the payload is part of the model: without it the same nodes miss the dynamics by far
    study = Study.from_toml(run.study)
    bare = study.replace({"model.payload": None})
    r2 = verify_run(_with_study(run, bare))
    assert not r2.passed and r2.gap_qdot > 100 * r.gap_qdot, r2.table()


def test_frame_target_study_fails_when_one_node_moves(solved, tmp_path, capsys):
    run = read_run(solved(CARRY))
    n = run.q.shape[0] - 1
    k = n // 2  # the place target (phase 0.5)
    q = run.q.copy()
    q[k, 0] += 0.2  # shoulder pan: the tool swings about 7 cm sideways
    bad = tmp_path / "bad.h5"
    write_run(bad, dataclasses.replace(run, q=q))
    assert main(["verify", str(bad)]) == 1
    failed = next(line for line in capsys.readouterr().out.splitlines() if "FAILED" in line)
    assert "gap q" in failed and "task frame targets" in failed and f"node {k}" in failed
    # the frame target's violation, from the tool's position by numeric Pinocchio
    import pinocchio as pin

    study = Study.from_toml(run.study)
    model = study.replace({"model.urdf": "ur5"}).model().pin_model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q[k])
    p = data.oMf[model.getFrameId("tool0")].translation
    target = next(t for t in study.data["task"]["targets"] if t["at"] == 0.5)
    expected = np.linalg.norm(p - np.array(target["position"])) - target["tolerance"]
    r = verify_run(read_run(bad))
    assert r.check("task frame targets").value == pytest.approx(expected, rel=1e-9) and expected > 0.03


def test_planes_and_orientations_are_checked(solved):
    """A plane above the tool's lowest node and an orientation target 0.1 rad off the tool's
    rotation at phase 0.5, added to the stored study: verify reports their violations, computed
    here from numeric Pinocchio kinematics."""
    import pinocchio as pin

    run = read_run(solved(CARRY))
    study = Study.from_toml(run.study)
    model = study.replace({"model.urdf": "ur5"}).model().pin_model
    data, fid = model.createData(), model.getFrameId("tool0")
    z, R = [], []
    for qk in run.q:
        pin.framesForwardKinematics(model, data, qk)
        z.append(data.oMf[fid].translation[2])
        R.append(data.oMf[fid].rotation.copy())
    k = (run.q.shape[0] - 1) // 2
    off = R[k] @ pin.rpy.rpyToMatrix(0.1, 0.0, 0.0)  # 0.1 rad about the tool's x axis
    task = study.data["task"]
    changed = study.replace({
        "task.planes": [*task["planes"], {"frame": "tool0", "normal": [0.0, 0.0, 2.0], "offset": float(min(z) + 0.01)}],
        "task.targets": [*task["targets"], {"frame": "tool0", "rpy": pin.rpy.matrixToRpy(off).tolist(), "at": 0.5,
                                            "angle_tolerance": 0.04}],
    })
    r = verify_run(_with_study(run, changed), VerifyTolerances(task=1e-3))
    plane, orientation = r.check("task frame planes"), r.check("task frame orientations")
    assert plane.value == pytest.approx(0.01, abs=1e-12) and f"node {int(np.argmin(z))}" in plane.where
    assert orientation.value == pytest.approx(0.1 - 0.04, abs=1e-9) and f"node {k}" in orientation.where
    assert {c.name for c in r.failures} == {"task frame planes", "task frame orientations"}


# -- the physiological curl: a payload on arm26 -------------------------------------------------------


def test_physiological_payload_curl_passes(solved):
    run = read_run(solved(("curl_physiological.toml", None)))
    r = verify_run(run)
    assert r.passed, r.table()
    bare = Study.from_toml(run.study).replace({"model.payload": None})
    r2 = verify_run(_with_study(run, bare))  # 6.4 kg less in the hand
    assert "gap qdot" in [c.name for c in r2.failures] and r2.gap_qdot > 1.0


# -- the closed-loop study: the plant's run, on the controller's shipped grid -----------------------


def _closed_loop_run(tmp_path, cycles: int, capsys):
    """``fatigue-pin mpc studies/curl_mpc.toml --set horizon.max_cycles=<cycles>`` (uncompiled),
    then ``fatigue-pin verify`` of its run: (run, verify's exit code, its report)."""
    out = tmp_path / "curl_mpc.h5"
    assert main(["mpc", str(STUDIES / "curl_mpc.toml"), "--out", str(out), "--set", f"horizon.max_cycles={cycles}",
                 "--set", "solver.compile=false"]) == 0
    capsys.readouterr()
    code = main(["verify", str(out)])
    return read_run(out), code, capsys.readouterr().out


def _check_closed_loop(run, code, text, cycles: int) -> None:
    from fatigue_pin.io.mpc_study import MpcStudy

    assert code == 0 and "  PASSED" in text, text
    shipped = MpcStudy.from_file(STUDIES / "curl_mpc.toml").study.data
    stored = MpcStudy.from_toml(run.study).study.data
    for key in ("task", "transcription", "fatigue", "costs"):  # the shipped study, only its cycles shortened
        assert stored[key] == shipped[key], key
    assert run.attrs["repetitions"] == run.n_cycles == cycles
    assert f"the task is checked on the {cycles} cycle(s) it counts as repetitions" in text
    assert np.abs(run.qdot).max() < 10 * np.pi  # the plans' swing stays below the velocity bound


@pytest.mark.slow
def test_the_closed_loop_study_passes_verify_as_shipped(tmp_path, capsys):
    """studies/curl_mpc.toml's closed loop (the plant's run), on its shipped grid (10 intervals,
    8 RK4 substeps) for 3 cycles (its window's, the fewest it allows): verify passes, the task
    within the run's target tolerance on the cycles it counts, the tired swing of cycle 2 (about
    25 rad/s at the elbow) on the exact flow."""
    run, code, text = _closed_loop_run(tmp_path, 3, capsys)
    _check_closed_loop(run, code, text, 3)
    assert np.abs(run.qdot[:, 1]).max() > 20.0  # the swing is there, and physical


@pytest.mark.slow
def test_the_closed_loop_study_passes_verify_over_its_tired_cycles(tmp_path, capsys):
    """The run of round 3, item 9 (``--set horizon.max_cycles=4``, 45 s uncompiled): from cycle 1.5
    the tired arm's plans swing the elbow at 25.8 rad/s. On 2 substeps they rode the velocity bound
    22 rad/s off the exact flow and the plant left the elbow's range at node 29 (docs/mpc.md); on
    the shipped 8 the plant does all 4 cycles and verify passes."""
    run, code, text = _closed_loop_run(tmp_path, 4, capsys)
    _check_closed_loop(run, code, text, 4)
    assert np.abs(run.qdot[:, 1]).max() > 20.0  # the swing is there, and physical
