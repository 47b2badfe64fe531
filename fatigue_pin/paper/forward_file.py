"""The forward studies' file (``forward_studies.h5``, layout: docs/results.md) read back, and
its figures."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from fatigue_pin.paper.forward import ForwardStudiesResult, ForwardStudyConfig, Study2Run, plot_forward_studies
from fatigue_pin.viz.plots import png_as_pdf


def is_forward_file(path: str | Path) -> bool:
    """Whether ``path`` is an HDF5 file of the forward studies (groups study1 and study2)."""
    try:
        with h5py.File(path, "r") as h5:
            return "study1" in h5 and "study2" in h5
    except OSError:
        return False


def read_forward_studies(path: Path) -> ForwardStudiesResult:
    """Rebuild the in-memory forward-study results from ``forward_studies.h5`` (layout: docs/results.md)."""
    from fatigue_pin.fatigue.models import FatigueParams
    from fatigue_pin.fatigue.simulation import FatigueTrajectory

    def trajectory(g: h5py.Group) -> FatigueTrajectory:
        a = g.attrs
        params = FatigueParams(LD=float(a["LD"]), LR=float(a["LR"]), F=float(a["F"]), R=float(a["R"]),
                               S=float(a["S"]), r=float(a.get("r", 1.0)))
        return FatigueTrajectory(g["t"][()], g["ma"][()], g["mr"][()], g["mf"][()], params, str(a["method"]),
                                 float(a["rtol"]), float(a["atol"]), bool(a["success"]), "", int(a["nfev"]))

    with h5py.File(path, "r") as h5:
        s1 = {k: trajectory(h5[f"study1/{k}"]) for k in ("3cc", "3cc_s")}
        g0 = h5["study1/3cc"]
        refs: dict[float, FatigueTrajectory] = {}
        runs: list[Study2Run] = []
        groups = [h5[f"study2/{k}"] for k in h5["study2"]]
        for g in groups:
            if g.attrs["role"] == "reference":
                refs[float(g.attrs["S"])] = trajectory(g)
        refs = dict(sorted(refs.items()))
        for g in sorted((g for g in groups if g.attrs["role"] == "perturbed"),
                        key=lambda g: (float(g.attrs["S"]), -float(g.attrs["m0"][1]))):
            a = g.attrs
            runs.append(Study2Run(
                S=float(a["S"]), mr0=float(a["m0"][1]), trajectory=trajectory(g), reference=refs[float(a["S"])],
                time_to_precision=tuple(a["time_to_precision"]), time_to_first_precision=tuple(a["time_to_first_precision"]),
                final_abs_error=tuple(a["final_abs_error"]), max_error_after_1s=float(a["max_error_after_1s"]),
            ))
        cfg = ForwardStudyConfig(
            params=s1["3cc"].params.with_(S=0.0), TL=float(g0.attrs["TL"]), t_end=float(g0.attrs["t_end"]),
            n_eval=int(h5.attrs.get("n_eval", g0["t"].shape[0])), method=str(g0.attrs["method"]),
            rtol=float(g0.attrs["rtol"]), atol=float(g0.attrs["atol"]), study1_S=float(h5["study1/3cc_s"].attrs["S"]),
            study2_S=tuple(refs), study2_mr0=tuple(dict.fromkeys(r.mr0 for r in runs)),
            precisions=tuple(float(p) for p in h5.attrs["precisions"]),
        )
        rmse = np.asarray(g0.attrs["rmse"], dtype=float)
        final = np.asarray(g0.attrs["final_abs_error"], dtype=float)
    return ForwardStudiesResult(cfg, s1, rmse, final, tuple(runs), refs, Path(path))


def plot_forward_file(path: Path, out_dir: Path) -> list[Path]:
    """The forward-study figures of ``forward_studies.h5``, drawn by
    :func:`fatigue_pin.paper.forward.plot_forward_studies` (PNG), each also as a raster PDF."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    for png in plot_forward_studies(read_forward_studies(path), out).values():
        paths += [png, png_as_pdf(png)]
    return paths
