"""The curl with physiological fatigue rates (issue 14, item 5), beside the paper's sped-up rates.

Runs four sliding-horizon studies (3-cycle windows, cost fatigue-torque, S = 10) to exhaustion,
writes them into ``--out/physiological.h5`` (resumable: a killed run continues), prints a table
and writes figures into ``--figures``:

1. ``physiological``: ``studies/curl_physiological.toml``: Frey-Law et al. (2012) elbow and
   shoulder rates, a 10 kg dumbbell, 2 s cycles, stopped after ``--max-cycles`` cycles (200);
   ``physiological-12kg``: the same with 12 kg;
2. ``paper-rates``: the same load and cycle with the paper's sped-up rates (F = 0.456,
   R = 0.0094, preset ``puchaud-2023/authors-code``) on both joints;
3. ``physiological-3.6kg``: Frey-Law rates with the paper's 3.6 kg in 1 s cycles, stopped after
   ``--light-cycles`` cycles (it does not tire in a tractable number of cycles);
4. ``paper``: the paper's study (3.6 kg, 1 s, sped-up rates; ``curl_sliding_fatigue-torque_authors-code``).

Usage::

    python experiments/physiological_curl.py --out results/physiological --figures docs/figures/physiological
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from fatigue_pin.io.results import list_runs, read_run
from fatigue_pin.viz.plots import peak_torques, plot_capacity, plot_fatigue_states, plot_joint_angles
from fatigue_pin.io.study import Study, run_study

STUDIES = Path(__file__).resolve().parent.parent / "studies"


def studies(light_cycles: int, max_cycles: int) -> dict[str, Study]:
    physio = Study.from_file(STUDIES / "curl_physiological.toml").replace({"horizon.max_cycles": max_cycles})
    data = physio.data
    paper_rates = {k: v for k, v in data["fatigue"].items() if k != "joints"} | {"preset": "puchaud-2023/authors-code"}
    light = physio.replace({"task.cycle_duration": 1.0, "horizon.max_cycles": light_cycles})
    heavier = physio.replace({"model.payload.mass": 8.4})
    light_data = dict(light.data)
    light_data["model"] = {k: v for k, v in light_data["model"].items() if k != "payload"}
    return {
        "physiological": physio,
        "paper-rates": Study.from_dict({**data, "fatigue": paper_rates, "name": "paper-rates_10kg_2s"}),
        "physiological-12kg": Study.from_dict({**heavier.data, "name": "physiological_12kg_2s"}),
        "physiological-3.6kg": Study.from_dict({**light_data, "name": "physiological_3.6kg_1s"}),
        "paper": Study.from_file(STUDIES / "curl_sliding_fatigue-torque_authors-code.toml"),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/physiological"), help="output folder")
    parser.add_argument("--figures", type=Path, default=None, help="figure folder (default: --out)")
    parser.add_argument("--light-cycles", type=int, default=100, help="cycles of the 3.6 kg run with physiological rates")
    parser.add_argument("--max-cycles", type=int, default=200, help="cycles after which the physiological runs stop")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    figures = args.figures or args.out
    out = args.out / "physiological.h5"
    rows = []
    for label, study in studies(args.light_cycles, args.max_cycles).items():
        print(f"== {label}: {study.run_name()}", flush=True)
        t0 = time.perf_counter()
        name = study.run_name()
        if out.exists() and name in list_runs(out) and read_run(out, name).attrs.get("finished"):
            run = read_run(out, name)  # done before
        else:
            run = run_study(study, out, resume=True, progress=lambda s: print(s, flush=True)).run
        elapsed = time.perf_counter() - t0
        model = study.problem().model
        q0 = np.asarray(study.data["task"]["q_init"], dtype=float)
        holding = dict(zip(model.joint_names, np.abs(model.gravity_torque(q0))))
        elbow_plus = list(run.actuator_names).index("elbow_plus")
        mf = run.fatigue["mf"]
        rows.append({
            "label": label, "forearm_kg": model.body_masses()["elbow"],  # forearm + dumbbell + payload
            "cycle_s": study.data["task"]["cycle_duration"], "repetitions": int(run.attrs.get("repetitions", run.n_cycles)),
            "cycles_kept": run.n_cycles, "mf_end": float(np.nanmax(mf[-1])), "elbow_capacity": float(abs(run.torque_limits[-1, elbow_plus])),
            "elbow_peak": float(peak_torques(run)[-1, elbow_plus]), "holding": float(holding["elbow"]),
            "solve_s": float(run.attrs.get("wall_time_s", np.nan)), "elapsed_s": elapsed,
        })
        plot_capacity(run, figures, holding=holding)
        if label == "physiological":
            plot_fatigue_states(run, figures)
            plot_joint_angles(run, figures)
    print("\nthe curl with physiological fatigue rates (sliding horizon, fatigue-torque, S = 10)")
    print(f"{'run':<22} {'forearm+load kg':>15} {'cycle s':>7} {'reps':>5} {'kept':>5} {'max mf':>7} {'elbow cap. N m':>15} {'peak N m':>9} "
          f"{'holding N m':>12} {'solve s':>8}")
    for r in rows:
        print(f"{r['label']:<22} {r['forearm_kg']:>15.2f} {r['cycle_s']:>7g} {r['repetitions']:>5} {r['cycles_kept']:>5} {r['mf_end']:>7.3f} "
              f"{r['elbow_capacity']:>15.2f} {r['elbow_peak']:>9.2f} {r['holding']:>12.2f} {r['solve_s']:>8.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
