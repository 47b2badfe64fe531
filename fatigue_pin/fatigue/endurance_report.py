"""Endurance tables as Markdown, in HDF5 and as a figure, and ``fatigue-pin endurance``'s run
(:func:`run_endurance`); the computations are in :mod:`fatigue_pin.fatigue.endurance`."""

from __future__ import annotations

import datetime
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fatigue_pin.core.files import atomic_write, check_output_dir
from fatigue_pin.core.progress import Progress
from fatigue_pin.core.settings import check_fields, is_bool, is_int, is_number, is_str, replaced, setting
from fatigue_pin.fatigue.endurance import (
    DEFAULT_LOADS,
    FREY_LAW_AVIN_2010,
    FREY_LAW_AVIN_SOURCE,
    MAX_CYCLES,
    EnduranceTable,
    compare_frey_law_avin,
    endurance_table,
    intermittent_et_closed_form,
    power_model_et,
    sustained_et_closed_form,
)
from fatigue_pin.fatigue.models import XiaFatigue

__all__ = ["EnduranceSettings", "format_table", "format_comparison", "write_h5", "plot_endurance", "run_endurance"]


def _fractions(v: Any) -> bool:
    return len(v) > 0 and all(is_number(x) and 0 < x <= 1 for x in v)


@dataclass(frozen=True)
class EnduranceSettings:
    """What :func:`run_endurance` computes (the options of ``fatigue-pin endurance``, whose
    defaults are these).

    Attributes:
        preset: a preset name (:data:`fatigue_pin.fatigue.presets.PRESETS`) or a calibrated .json file.
        loads: target loads, fractions of the maximum in (0, 1].
        duty_cycle: fraction of each cycle at the target load, in (0, 1] (1: sustained).
        cycle_s: cycle length of an intermittent task (s, > 0; needed when ``duty_cycle < 1``).
        compare: also compare per joint with Frey-Law & Avin (2010).
        max_cycles: most cycles simulated per load of an intermittent task.
    """

    preset: str = setting("frey-law-2012/elbow", "a preset name or a calibrated .json file", is_str)
    loads: tuple[float, ...] = setting(DEFAULT_LOADS, "target loads, fractions in (0, 1]", _fractions)
    duty_cycle: float = setting(1.0, "a fraction in (0, 1]", lambda v: is_number(v) and 0 < v <= 1)
    cycle_s: float | None = setting(None, "a cycle length > 0 (s)", lambda v: is_number(v) and v > 0)
    compare: bool = setting(True, "true or false", is_bool)
    max_cycles: int = setting(MAX_CYCLES, "an integer number of cycles >= 1", lambda v: is_int(v) and v >= 1)

    def __post_init__(self) -> None:
        object.__setattr__(self, "loads", tuple(self.loads))
        check_fields(self)


def _fmt(x: float) -> str:
    if not np.isfinite(x):
        return "inf" if x == np.inf else "-"
    return f"{x:.1f}"


def _pct(x: float) -> str:
    return "-" if not np.isfinite(x) else f"{100 * x:+.2f} %"


def format_table(tab: EnduranceTable) -> str:
    """The table as Markdown: TL, simulated ET, closed form, error, and the power model if any."""
    task = "sustained" if tab.duty_cycle == 1.0 else f"duty cycle {tab.duty_cycle:g}, cycle {tab.cycle_s:g} s"
    params = ", ".join(f"{k} = {v:g}" for k, v in tab.model.as_dict().items())
    lines = [f"Endurance times: {tab.name} ({tab.model.kind}: {params}); {task}", ""]
    head = "| TL | ET simulated (s) | ET closed form (s) | sim / closed - 1 |"
    sep = "|----|------------------|--------------------|------------------|"
    if tab.et_power.size:
        head += f" ET Frey-Law & Avin {tab.joint} (s) | closed / power - 1 |"
        sep += "------|------|"
    lines += [head, sep]
    for i, x in enumerate(tab.loads):
        row = f"| {x:.2f} | {_fmt(tab.et_sim[i])} | {_fmt(tab.et_closed[i])} | {_pct(tab.rel_error_closed[i])} |"
        if tab.et_power.size:
            row += f" {_fmt(tab.et_power[i])} | {_pct(tab.rel_error_power[i])} |"
        lines.append(row)
    return "\n".join(lines)


def format_comparison(tables: Sequence[EnduranceTable]) -> str:
    """One Markdown table: per joint and load, the 3CC closed form vs the power model, with the
    relative error, and per joint the RMS of the log error and of the error in seconds."""
    loads = tables[0].loads
    head = "| joint | " + " | ".join(f"TL {x:.1f}" for x in loads) + " | RMS log error | RMS error (s) |"
    lines = [
        "3CC closed form (Frey-Law et al. 2012 F, R) vs Frey-Law & Avin (2010) power model: ET (s) 3CC / power (error)",
        "",
        head,
        "|" + "---|" * (len(loads) + 3),
    ]
    for tab in tables:
        cells = [f"{_fmt(c)} / {_fmt(p)} ({_pct(c / p - 1 if np.isfinite(c) else np.nan)})"
                 for c, p in zip(tab.et_closed, tab.et_power)]
        with np.errstate(divide="ignore", invalid="ignore"):
            le = np.log(tab.et_closed / tab.et_power)
        rms = float(np.sqrt(np.mean(le[np.isfinite(le)] ** 2))) if np.isfinite(le).any() else math.nan
        diff = tab.et_closed - tab.et_power
        rms_s = float(np.sqrt(np.mean(diff[np.isfinite(diff)] ** 2))) if np.isfinite(diff).any() else math.nan
        lines.append(f"| {tab.joint} | " + " | ".join(cells) + f" | {rms:.3f} | {rms_s:.1f} |")
    return "\n".join(lines)


# -- files --------------------------------------------------------------------------------------------


def write_h5(path: Path | str, tables: Sequence[EnduranceTable], comparison: Sequence[EnduranceTable] = ()) -> Path:
    """Write endurance tables to HDF5 (atomic: :func:`fatigue_pin.core.files.atomic_write`).

    Layout: one group per table under ``/endurance/<i>`` and ``/frey_law_avin/<joint>`` with
    datasets ``TL``, ``et_sim_s``, ``et_closed_form_s``, ``et_power_model_s`` (if any) and attributes
    ``name``, ``model``, ``params`` (JSON), ``duty_cycle``, ``cycle_s``, ``source``, ``definition``.
    """
    import json

    import h5py

    from fatigue_pin.core.version import __version__ as version

    path = Path(path)
    definition = ("first time at which ma + mr < TL while the task asks for TL, from a rested actuator, rests "
                  "included; inf if none before t_max")
    def fill(tmp: Path) -> None:
        with h5py.File(tmp, "w") as h5:
            h5.attrs["description"] = "fatigue_pin endurance times of isometric tasks"
            h5.attrs["fatigue_pin_version"] = version
            h5.attrs["created"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
            h5.attrs["definition"] = definition
            h5.attrs["power_model_source"] = FREY_LAW_AVIN_SOURCE
            for group, tabs in (("endurance", tables), ("frey_law_avin", comparison)):
                for i, tab in enumerate(tabs):
                    g = h5.create_group(f"{group}/{tab.joint if group == 'frey_law_avin' else i}")
                    g.attrs["name"] = tab.name
                    g.attrs["model"] = tab.model.kind
                    g.attrs["params"] = json.dumps(tab.model.as_dict())
                    g.attrs["duty_cycle"] = tab.duty_cycle
                    g.attrs["cycle_s"] = np.nan if tab.cycle_s is None else tab.cycle_s
                    g.attrs["source"] = tab.source
                    g.create_dataset("TL", data=tab.loads)
                    g.create_dataset("et_sim_s", data=tab.et_sim)
                    g.create_dataset("et_closed_form_s", data=tab.et_closed)
                    if tab.et_power.size:
                        g.attrs["joint"] = tab.joint
                        g.create_dataset("et_power_model_s", data=tab.et_power)
    atomic_write(path, fill)
    return path


def plot_endurance(path: Path | str, tables: Sequence[EnduranceTable], comparison: Sequence[EnduranceTable] = ()) -> Path:
    """Log-log figure of ET vs TL: simulated points, closed-form lines and power models (PNG)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    n = 2 if comparison else 1
    fig = Figure(figsize=(6.5 * n, 5))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, n, squeeze=False)[0]
    ax = axes[0]
    fine = np.linspace(0.05, 0.98, 200)
    for k, tab in enumerate(tables):
        color = f"C{k}"
        ax.loglog(tab.loads, tab.et_sim, "o", color=color, label=f"{tab.name}: simulated")
        if isinstance(tab.model, XiaFatigue):
            m = tab.model
            closed = [intermittent_et_closed_form(m.F, m.R, x, tab.duty_cycle, tab.cycle_s, m.r) for x in fine]
            ax.loglog(fine, closed, "-", color=color, lw=1, label=f"{tab.name}: closed form (instant activation)")
        if tab.et_power.size:
            ax.loglog(fine, power_model_et(tab.joint, fine), "--", color="k", lw=1,
                      label=f"Frey-Law & Avin 2010, {tab.joint}")
    ax.set_xlabel("target load TL (fraction of maximum)")
    ax.set_ylabel("endurance time (s)")
    ax.set_title("Endurance time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    if comparison:
        ax = axes[1]
        for k, tab in enumerate(comparison):
            ax.loglog(fine, sustained_et_closed_form(tab.model.F, tab.model.R, fine), "-", color=f"C{k}", lw=1.2,
                      label=f"{tab.joint}: 3CC")
            ax.loglog(fine, power_model_et(tab.joint, fine), "--", color=f"C{k}", lw=1, label=f"{tab.joint}: power model")
        ax.set_xlabel("target load TL (fraction of maximum)")
        ax.set_ylabel("endurance time (s)")
        ax.set_title("3CC (Frey-Law et al. 2012) vs Frey-Law & Avin 2010")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=120)
    return out


def run_endurance(out_dir: Path | str, settings: EnduranceSettings | None = None, progress: Progress = None,
                  **changes: Any) -> tuple[EnduranceTable, list[EnduranceTable], dict[str, Path]]:
    """Endurance table of a preset (name or JSON file), the per-joint comparison with Frey-Law &
    Avin (2010), ``endurance.h5`` and ``endurance.png`` in ``out_dir`` (checked first), as
    ``settings`` (:class:`EnduranceSettings`, with ``changes`` to its fields by name) say.
    ``max_cycles`` bounds each intermittent simulation, ``progress`` receives its lines
    (:func:`~fatigue_pin.fatigue.endurance.endurance_time`)."""
    from fatigue_pin.fatigue.presets import preset, preset_source

    s = replaced(EnduranceSettings, settings, changes)
    preset_name, loads, duty_cycle, cycle_s, compare, max_cycles = s.preset, s.loads, s.duty_cycle, s.cycle_s, s.compare, s.max_cycles
    model = preset(preset_name)
    source = preset_source(preset_name)
    out = check_output_dir(out_dir)
    # a preset of a joint region (frey-law-2012/elbow, rakshit-2021/elbow) is set beside that joint's curve
    region = preset_name.split("/", 1)[1] if preset_name.count("/") == 1 and not preset_name.endswith(".json") else None
    joint = region if region in FREY_LAW_AVIN_2010 else None
    tab = endurance_table(model, loads, duty_cycle, cycle_s, name=preset_name, joint=joint, source=source,
                          max_cycles=max_cycles, progress=progress)
    comparison = compare_frey_law_avin(loads) if compare else []
    paths = {"h5": write_h5(out / "endurance.h5", [tab], comparison),
             "png": plot_endurance(out / "endurance.png", [tab], comparison)}
    return tab, comparison, paths
