"""``fatigue-pin mpc``: a closed loop from the command line, its report, figures and replay."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.image import imread

from conftest import small_mpc_study
from fatigue_pin.cli.main import main
from fatigue_pin.io.mpc_study import MpcStudy
from fatigue_pin.io.results import read_run

TABLES = """
[plant.fatigue]
F = 0.7

[plant.noise]
capacity = 0.01

[mpc]
estimator = "mhe"
capacity_margin = 0.03
"""


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mpc_cli")
    study = folder / "tired.toml"
    study.write_text(small_mpc_study(TABLES, seed=2, max_cycles=3))
    out = folder / "tired.h5"
    code = main(["mpc", str(study), "--out", str(out), "--set", "mpc.end=receding"])
    return code, study, out, folder


def test_mpc_writes_the_run_and_its_report(cli_run, capsys):
    code, study, out, folder = cli_run
    assert code == 0
    run = read_run(out)
    assert run.name == "mpc/fatigue-torque_S10" and run.attrs["repetitions"] == 3 and run.attrs["estimator"] == "mhe"
    stored = MpcStudy.from_toml(run.study)  # the run keeps its closed-loop study, --set included
    assert stored.mpc.end == "receding" and stored.plant_study.data["fatigue"]["F"] == 0.7 and stored.plant.seed == 2
    text = (folder / "tired_report.md").read_text()
    assert "**3** of 3" in text and "elbow_plus" in text and text.count("Solve_Succeeded") == len(run.extras["replans"])


def test_mpc_figures_and_replay_show_the_plant(cli_run, tmp_path):
    _, _, out, _ = cli_run
    figures = tmp_path / "figures"
    assert main(["plot", str(out), "--out", str(figures)]) == 0
    for stem in ("mpc_fatigue", "mpc_task_error", "mpc_replans"):
        image = imread(figures / f"mpc_fatigue-torque_S10_{stem}.png")
        assert image.shape[0] > 300 and np.std(image[..., :3]) > 0.05  # drawn, not blank
    html = tmp_path / "replay.html"
    assert main(["replay", str(out), "--html", str(html)]) == 0
    run = read_run(out)
    assert b"mpc/fatigue-torque_S10" in html.read_bytes()
    assert run.q.shape == (31, 2)  # the replay's trajectory is the plant's


@pytest.mark.parametrize("args, message", [
    (["--set", "mpc.replan_every=0"], "mpc.replan_every = 0: expected an integer number of intervals >= 1"),
    (["--set", "plant.noise.q=-0.5"], "plant.noise.q = -0.5: expected a standard deviation >= 0 (rad)"),
    (["--set", "plant.fatigue.Fmax=1"], "unknown key plant.fatigue.Fmax;"),
])
def test_bad_input_is_one_line_with_exit_code_2(cli_run, args, message, capsys, tmp_path):
    _, study, _, _ = cli_run
    capsys.readouterr()
    code = main(["mpc", str(study), "--out", str(tmp_path / "x.h5"), *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith(f"fatigue-pin: error: {message}") and "\n" not in err
    assert not (tmp_path / "x.h5").exists()


def test_run_hands_a_closed_loop_study_to_the_closed_loop(cli_run, tmp_path):
    """``fatigue-pin run`` of a study with [plant] / [mpc] tables runs the closed loop: the same
    run, bit for bit, as ``fatigue-pin mpc`` with the same changes."""
    _, study, out, _ = cli_run
    again = tmp_path / "again.h5"
    assert main(["run", str(study), "--out", str(again), "--set", "mpc.end=receding"]) == 0
    mine, theirs = read_run(again), read_run(out)
    assert mine.name == theirs.name and mine.attrs["repetitions"] == theirs.attrs["repetitions"]
    assert np.array_equal(mine.q, theirs.q) and np.array_equal(mine.tau_plus, theirs.tau_plus)
    assert (tmp_path / "again_report.md").is_file() and MpcStudy.from_toml(mine.study).mpc.end == "receding"


def test_verify_checks_a_closed_loop_run_against_the_plant(cli_run):
    """A closed-loop run stores the plant's trajectory: verify rebuilds the plant (its fatigue
    rates, F = 0.7 here, not the model's 0.456) and finds the stored states on the exact flow
    under the stored torques (the plant is adaptive), where the plan's RK4 (2 substeps) is 1e-2
    off; checked against the model's rates instead, the fatigue states would not be."""
    from fatigue_pin.verify.verifier import verify_run

    _, _, out, _ = cli_run
    run = read_run(out)
    report = verify_run(run)
    assert any("closed-loop run" in note for note in report.notes)
    assert report.passed, report.table()
    assert report.gap < 1e-7 and report.gap_fatigue < 1e-9  # the plant follows the exact flow, its own rates
    assert report.rk4_truncation > 1e-3  # which the transcription's RK4 does not
    model_rates = read_run(out)
    model_rates.attrs = {k: v for k, v in run.attrs.items() if k != "plant_fatigue_params"}
    assert verify_run(model_rates).gap_fatigue > 1e-4  # the model's F is not the plant's
