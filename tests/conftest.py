"""Shared fixtures: the arm26 model and small versions of the paper's curl."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
import pytest

from fatigue_pin.io.results import WINDOW_DTYPE, RunResult

from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.drivers.synthetic import synthetic_run
from fatigue_pin.robot.model import load_model
from fatigue_pin.paper.curl import curl_study


def built_once(tmp_path_factory, name: str, build) -> Path:
    """``build(path)`` run once per test session, however many xdist workers ask: the first to ask
    builds ``path`` in the folder all workers' temporary folders share, under a lock; the others
    wait on the lock (an event, not a delay) and reuse what it built. For results several tests
    read (a solved study, the docs pages' prepared folder) that cost tens of seconds to build. Returns
    ``path``; a build that raised is tried again by the next worker to ask."""
    import fcntl
    import os
    import shutil

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # pytest-of-USER/pytest-N: every worker's basetemp is a folder of it
    folder = root / "built_once"
    folder.mkdir(exist_ok=True)
    path, done = folder / name, folder / f"{name}.done"
    with open(folder / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            if path.is_dir() and not path.is_symlink():  # what a build that raised left
                shutil.rmtree(path)
            elif path.exists() or path.is_symlink():
                path.unlink()
            build(path)
            done.touch()
    return path


def small_curl(horizon: str = "full", cost: str = "fatigue-torque", preset: str = "paper", S: float = 10.0, **kwargs):
    """The paper's curl with 10 intervals per cycle and 2 RK4 substeps, evaluated without
    compiling: solves in about a second."""
    kwargs.setdefault("solver", {"compile": False})
    kwargs.setdefault("intervals_per_cycle", 10)
    kwargs.setdefault("substeps", 2)
    return curl_study(horizon, cost, preset, S, **kwargs)


@pytest.fixture(scope="session")
def arm26():
    return load_model()


@pytest.fixture(scope="session")
def small_study():
    return small_curl()


@pytest.fixture(scope="session")
def small_problem(arm26, small_study):
    return small_study.problem(arm26)


@pytest.fixture(scope="session")
def build(small_problem, small_study):
    """``build(n_cycles, **changes)``: an Ocp of the small curl (interval functions shared)."""
    builder = OcpBuilder(small_problem, small_study.transcription(), small_study.solver())
    return builder


def make_run(name: str = "full/torque_S10", cycles: int = 2, n: int = 10) -> RunResult:
    """A synthetic run of ``cycles`` cycles of ``n`` intervals (:func:`fatigue_pin.drivers.synthetic.synthetic_run`)."""
    return synthetic_run(name, cycles, n)


def make_pendulum_run(name: str = "full/pendulum", cycles: int = 2, n: int = 10, urdf: str | None = None) -> RunResult:
    """A synthetic run on urdf/pendulum.urdf's joints: the prismatic ``slider`` (m) and the revolute
    ``pendulum`` (rad), that URDF's text stored with it unless ``urdf`` is given."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "urdf" / "pendulum.urdf").read_text() if urdf is None else urdf
    return synthetic_run(name, cycles, n, urdf=text, joints=("slider", "pendulum"), joint_kinds=("prismatic", "revolute"))


HALVES = ("shoulder_plus", "shoulder_minus", "elbow_plus", "elbow_minus")
TERMS = ("shoulder_angle", "torque_rate", "fatigue", "torque")


def make_curl_run(name: str = "full/fatigue_torque", n_cycles: int = 2, n: int = 50, horizon: str = "full",
             urdf: str = "") -> RunResult:
    """A synthetic arm26 run: ``n_cycles`` curls of ``n`` intervals (0.02 s each for n = 50), elbow
    15 -> 150 -> 15 deg, every mf growing linearly-ish (elbow_plus 0 -> 0.8)."""
    nodes = n_cycles * n + 1
    t = np.linspace(0.0, n_cycles, nodes)
    phase = 2 * np.pi * t
    elbow = np.radians(15) + np.radians(135) * 0.5 * (1 - np.cos(phase))
    shoulder = 0.07 + 0.2 * np.sin(phase) * t / n_cycles
    q = np.column_stack([shoulder, elbow])
    qdot = np.gradient(q, t, axis=0)
    tau_plus = np.column_stack([10 + 5 * np.sin(phase[:-1]), 20 + 10 * np.sin(phase[:-1])])
    tau_minus = -np.column_stack([2 + np.cos(phase[:-1]), 3 + np.cos(phase[:-1])])
    frac = t / t[-1]
    mf = np.column_stack([0.4 * frac, 0.05 * frac, 0.8 * frac**1.5, 0.1 * frac])
    ma = np.column_stack([0.2 + 0.1 * np.sin(phase), 0.04 + 0 * t, 0.4 + 0.2 * np.sin(phase), 0.06 + 0 * t])
    mr = 1 - ma - mf
    costs = np.array([[1e2 * (c + 1), 0.1 * (c + 1), 10.0 * (c + 1) ** 2, 1e3] for c in range(n_cycles)])
    limits = np.array([50.0, -50.0, 50.0, -50.0])
    attrs = dict(horizon=horizon, cost="fatigue+torque", preset="test", S=10.0, F=0.456, R=0.0094, LD=10.0,
                 LR=10.0, n_cycles=n_cycles, converged=True, status="Solve_Succeeded", wall_time_s=12.0,
                 build_time_s=1.0, iterations=100, solver="ipopt", tau_limits=limits)
    windows = None
    if horizon == "sliding":
        n_win = max(n_cycles - 2, 1)
        windows = np.array([(i, i, b"Solve_Succeeded", True, 40 + i, 3.0 + i, 1.0) for i in range(n_win)],
                           dtype=WINDOW_DTYPE)
    return RunResult(
        name=name, attrs=attrs, t=t, q=q, qdot=qdot, tau_plus=tau_plus, tau_minus=tau_minus, fatigue={"ma": ma, "mr": mr, "mf": mf},
        cycle_costs=costs, torque_limits=(1 - mf[n::n]) * limits, joint_names=("shoulder", "elbow"),
        actuator_names=HALVES, cost_terms=TERMS, cycle_wall_time_s=np.full(n_cycles, 6.0), windows=windows,
        urdf=urdf, fatigued=mf,
    )


#: [plant] and [mpc] tables of the small curl against a plant that tires about 1.5 times as fast as
#: the model (F = 0.7 for 0.456 1/s), with measurement noise, MHE, a re-plan every cycle. With seed
#: 5 and 4 cycles: 4 whole cycles, 3 repetitions (in cycle 4 the plant misses its targets by more
#: than 0.05 rad), every interval on the exact flow. At twice the model's F (as
#: studies/curl_mpc.toml) the small curl's plans, on 2 RK4 substeps of 0.05 s, swing the elbow where
#: their RK4 is far from the exact flow and the plant leaves the elbow's range at node 29.
TIRED_MPC_TABLES = """
[plant.fatigue]
F = 0.7

[plant.noise]
q = 0.001
qdot = 0.01
capacity = 0.01

[mpc]
replan_every = 10
estimator = "mhe"
capacity_margin = 0.03
end = "receding"
"""


def mhe_closed_loop(folder, study, plant: str, params: list[str]):
    """``fatigue-pin mpc`` on ``study`` (one-cycle windows of a sliding study) with the [plant]
    table text ``plant``, re-planned every cycle (``end = "receding"``) with the moving-horizon
    estimator of ``params``: the run, read back."""
    from fatigue_pin.cli.main import main
    from fatigue_pin.io.results import read_run

    path = folder / "closed_loop.toml"
    path.write_text(f'{study.to_toml()}\n{plant}\n\n[mpc]\nreplan_every = {study.task().intervals_per_cycle}\nend = "receding"\n'
                    f'estimator = "mhe"\n\n[mpc.mhe]\nparams = {params!r}\n'.replace("'", '"'))
    out = folder / "closed_loop.h5"
    assert main(["mpc", str(path), "--out", str(out)]) == 0
    return read_run(out)


def small_mpc_study(tables: str = "", seed: int | None = None, max_cycles: int = 3) -> str:
    """TOML text of the small curl (10 intervals per cycle, 2 RK4 substeps, uncompiled) as a
    closed-loop study with a 3-cycle window; ``tables`` adds [plant...] and [mpc] tables."""
    study = small_curl("sliding", max_cycles=max_cycles)
    top = "" if seed is None else f"seed = {seed}\n"
    return f"{top}{study.to_toml()}\n{tables}\n"


@pytest.fixture(scope="session")
def pendulum():
    """The cart-pendulum of urdf/pendulum.urdf (prismatic ``slider``, revolute ``pendulum``)."""
    from fatigue_pin.robot.model import bundled_urdf

    return load_model(bundled_urdf("pendulum"))


def swing_up(model, *items, costs=None, n: int = 10, cycles: int = 1, **task):
    """The pendulum's swing-up as a non-cyclic problem: ``n`` intervals of 1 / n s per phase, the
    given task items (default: slider and pendulum at rest at (0, pi - 0.0016) at the end), Xia's
    model on every half, the torque cost; a Problem."""
    from fatigue_pin.fatigue.models import fatigue_model
    from fatigue_pin.ocp.costs import torque
    from fatigue_pin.ocp.problem import Problem
    from fatigue_pin.ocp.task import JointTarget, Task

    items = items or (JointTarget("slider", 0.0, "end", velocity=0.0), JointTarget("pendulum", 3.14, "end", velocity=0.0))
    task.setdefault("q_init", (0.0, 0.0))
    return Problem.build(model, fatigue_model("xia", LD=100.0, LR=100.0, F=5.0, R=10.0), Task(1.0, n, items, **task),
                         costs if costs is not None else [torque(1.0)])


@pytest.fixture(scope="session")
def arm26_muscles():
    """The bundled arm26 muscles (urdf/arm26.muscles.toml)."""
    from fatigue_pin.muscles.files import load_muscles

    return load_muscles("arm26")


@pytest.fixture(scope="session")
def arm26_geometry(arm26, arm26_muscles):
    """Their paths with the humeral cylinder TRI."""
    from fatigue_pin.muscles.geometry import MuscleGeometry

    return MuscleGeometry(arm26.pin_model, arm26_muscles)


@pytest.fixture(scope="session")
def arm26_geometry_unwrapped(arm26, arm26_muscles):
    """Their paths as straight segments between the points."""
    from fatigue_pin.muscles.geometry import MuscleGeometry

    return MuscleGeometry(arm26.pin_model, arm26_muscles.without_wraps())


def two_muscle_file(folder) -> str:
    """A muscle file of two of arm26's bundled muscles, the brachialis and the lateral triceps
    (with the humeral cylinder), written in ``folder``; its path."""
    from pathlib import Path

    from fatigue_pin.muscles.files import bundled_muscles

    head, *blocks = bundled_muscles("arm26").read_text().split("[[muscles]]")
    keep = [b for b in blocks if b.split('"')[1] in ("BRA", "TRIlat")]
    path = Path(folder) / "two.muscles.toml"
    path.write_text(head + "".join("[[muscles]]" + b for b in keep))
    return str(path)


def muscle_curl(muscles: str = "arm26", **changes):
    """The small curl (one cycle) driven by ``muscles`` with +-50 N m residual torques that do not
    tire; costs: fatigue, the activations, the residual torques, the shoulder's posture."""
    return small_curl("full").replace({
        "model.muscles": muscles, "actuators.kind": "muscles", "actuators.residuals": 50.0, "horizon.cycles": 1,
        "costs": {"fatigue": 1e3, "activation": 1.0, "residual": 1.0, "posture": {"weight": 1e5, "joints": ["shoulder"]}},
        **changes})


@pytest.fixture(scope="session")
def two_muscle_run(tmp_path_factory):
    """The one-cycle small curl on two muscles, run by ``run_study`` into an HDF5 file:
    (study, path of the file, the run read back). About 6 s."""
    from fatigue_pin.io.results import read_run
    from fatigue_pin.io.study import run_study

    folder = tmp_path_factory.mktemp("two_muscles")
    study = muscle_curl(two_muscle_file(folder))
    out = folder / "muscles.h5"
    run_study(study, out=out, name="full/two_muscles")
    return study, out, read_run(out, "full/two_muscles")


# -- OpenSim models (tests/robot/test_osim.py) -----------------------------------------------------

#: tests/data/arm26.osim: arm26 in OpenSim 4.x format, written for the tests (its wrap objects: the
#: humeral cylinder TRI, the glenoid cylinder TRIlongglen of quadrant x and two ellipsoids).
ARM26_OSIM = __import__("pathlib").Path(__file__).resolve().parent / "data" / "arm26.osim"

#: Its three shoulder wraps, which fatigue_pin cannot model (ignore_wraps = true leaves them out).
ARM26_SHOULDER_WRAPS = ("TRIlonghh", "TRIlongglen", "BIClonghh")


def opensim_geometry_rows(wraps: str) -> list[dict]:
    """Rows of tests/data/arm26_opensim_geometry.csv (OpenSim 4.6's lengths and moment arms of
    arm26's muscles at 7 x 14 poses) with ``wraps`` = ``"TRI"`` (the humeral cylinder on) or ``"none"``."""
    import csv

    table = ARM26_OSIM.parent / "arm26_opensim_geometry.csv"
    with open(table) as f:
        rows = [r for r in csv.DictReader(line for line in f if not line.startswith("#"))]
    return [r for r in rows if r["wraps"] == wraps]


def osim_variant(folder, change=None, name: str = "arm26.osim") -> str:
    """tests/data/arm26.osim with ``change(text) -> text`` applied, written in ``folder``; its path."""
    from pathlib import Path

    text = ARM26_OSIM.read_text()
    path = Path(folder) / name
    path.write_text(change(text) if change is not None else text)
    return str(path)


def osim_without_muscles(text: str, keep: tuple[str, ...]) -> str:
    """An .osim text with only the muscles ``keep`` in its ForceSet."""
    import re

    def drop(match):
        return match.group(0) if match.group(1) in keep else ""

    return re.sub(r'\s*<Thelen2003Muscle name="([^"]+)">.*?</Thelen2003Muscle>', drop, text, flags=re.S)


def dumbbell_payload(frame: str):
    """The bundled arm26's 3.6 kg dumbbell (its fixed link ``dumbbell`` on the forearm) as a
    :class:`~fatigue_pin.robot.model.Payload` on ``frame``: the bar along the forearm's z."""
    from fatigue_pin.robot.model import Payload

    return Payload(frame, 3.6, (0.0, -0.28, 0.05), (0.04669628, 0.0, 0.0, 0.04669628, 0.0, 0.00370584))


# -- motors (tests/motors, tests/ocp/test_motor_actuators.py): the reference's closed form and an independent integrator --


def network_ode(R_wh: float, R_ha: float, tau_w: float, tau_m: float, P_w: float, P_h: float = 0.0):
    """The two-node network's right-hand side on the rises (K), written from the equations."""
    C_w, C_h = tau_w / R_wh, tau_m / R_ha

    def f(t, th):
        flow = (th[0] - th[1]) / R_wh
        return [(P_w - flow) / C_w, (P_h + flow - th[1] / R_ha) / C_h]

    return f


def integrate(f, t: np.ndarray, y0) -> np.ndarray:
    """``solve_ivp`` (DOP853, tight tolerances) at the times ``t``; shape (len(t), n)."""
    sol = solve_ivp(f, (0.0, float(t[-1])), list(y0), method="DOP853", t_eval=t, rtol=1e-13, atol=1e-12)
    assert sol.success
    return sol.y.T


def step_from_ambient(R_wh: float, R_ha: float, tau_w: float, tau_m: float, P: float, t: np.ndarray):
    """The winding's and housing's rise (K) after a step of loss ``P`` (W) at the winding from
    ambient, as the reference's section 5.3 writes it (K_f, K_s with the eigen time constants)."""
    C_w, C_h = tau_w / R_wh, tau_m / R_ha
    a, b, c = 1 / (C_w * R_wh), 1 / (C_h * R_wh), 1 / (C_h * R_ha)
    s = a + b + c
    lam = np.roots([1.0, s, a * c])
    tf, ts = sorted(-1 / lam)
    w_inf, h_inf = (R_wh + R_ha) * P, R_ha * P
    Kf = tf * (P * ts / C_w - w_inf) / (ts - tf)
    Ks = ts * (w_inf - P * tf / C_w) / (ts - tf)
    w = w_inf - Kf * np.exp(-t / tf) - Ks * np.exp(-t / ts)
    h = h_inf * (1 - (ts * np.exp(-t / ts) - tf * np.exp(-t / tf)) / (ts - tf))
    return np.column_stack([w, h])
