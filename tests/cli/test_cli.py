"""The command line over studies: a study of one's own on a robot from example-robot-data."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from fatigue_pin.cli.main import main
from fatigue_pin.io.results import read_run
from fatigue_pin.io.study import Study

STUDIES = Path(__file__).resolve().parents[2] / "studies"


def test_ur5_joint_space_study_solves_replays_and_plots(tmp_path, capsys):
    """The UR5 study file, run in sliding horizon for two one-cycle windows from the command line (a
    coarser grid, uncompiled, to stay quick); its result replays and plots."""
    out = tmp_path / "ur5.h5"
    code = main(["run", str(STUDIES / "ur5_lift_swing.toml"), "--out", str(out), "--set", "task.intervals_per_cycle=10",
                 "--set", "horizon.cycles=1", "--set", "horizon.max_cycles=2", "--set", "solver.compile=false"])
    assert code == 0
    run = read_run(out, "sliding/ur5_lift_swing")
    assert run.attrs["repetitions"] == 2 and run.windows["converged"].all() and len(run.windows) == 2
    assert run.q.shape == (21, 6) and run.fatigue["mf"].shape == (21, 12)
    lift, elbow = run.joint_names.index("shoulder_lift_joint"), run.joint_names.index("elbow_joint")
    assert np.allclose(run.q[[0, 10, 20], lift], -1.2, atol=1e-6) and np.allclose(run.q[[5, 15], elbow], 1.6, atol=1e-6)
    assert run.fatigue["mf"][-1].max() > 0.01  # the working halves tire
    assert Study.from_toml(run.study).data["model"]["urdf"] == "ur5"
    html = tmp_path / "ur5.html"
    assert main(["replay", str(out), "--html", str(html)]) == 0
    assert html.stat().st_size > 1_000_000 and b"sliding/ur5_lift_swing" in html.read_bytes()  # meshes inlined
    figures = tmp_path / "figures"
    assert main(["plot", str(out), "--out", str(figures)]) == 0
    printed = {Path(line.split(maxsplit=1)[1]).name for line in capsys.readouterr().out.splitlines() if line.startswith("wrote ")}
    per_run = ("joint_angles", "fatigue_states", "torque_limits", "cycle_costs", "solve_time")
    assert {f"sliding_ur5_lift_swing_{f}.{ext}" for f in per_run for ext in ("png", "pdf")} <= printed
    import matplotlib.image

    img = matplotlib.image.imread(figures / "sliding_ur5_lift_swing_fatigue_states.png")
    assert img.shape[0] > 300 and img.shape[1] > 300 and (img != img[0, 0]).any()  # a drawn figure, not a blank page
    assert (figures / "sliding_ur5_lift_swing_joint_angles.pdf").read_bytes().startswith(b"%PDF")


def test_errors_are_one_line_with_exit_code_2(tmp_path, capsys):
    study = tmp_path / "s.toml"
    study.write_text('[model]\nurdf = "arm26"\n[task]\ncycle_duration = 1.0\n')
    assert main(["run", str(study), "--out", str(tmp_path / "r.h5")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "intervals_per_cycle" in err and "Traceback" not in err
    assert main(["solve", "sliding", "--out", "/proc/x.h5", "--no-compile"]) == 2
    assert "/proc" in capsys.readouterr().err


def test_the_parser_imports_no_solver_library():
    """Every command line builds the whole parser (``--help`` too), which reads every sub-command's
    settings: that must not import scipy's optimisers, statistics or integrators (1.4 s and 0.8 s
    of a 2-3 s ``--help`` before), which only a calibration or an integration needs."""
    code = ("import sys\nfrom fatigue_pin.cli.main import build_parser\nbuild_parser()\n"
            "print(sorted(m for m in ('scipy.optimize', 'scipy.stats', 'scipy.integrate') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "[]", r.stdout + r.stderr
