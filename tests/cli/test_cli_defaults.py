"""The command line holds no defaults of its own: the curl shortcuts' options left out keep the
defaults of the settings classes and of the curl, and the help shows those defaults."""

from __future__ import annotations

import argparse

import pytest

from fatigue_pin.cli.main import _curl_study, build_parser
from fatigue_pin.core.settings import default_of
from fatigue_pin.drivers.horizon import Horizon
from fatigue_pin.drivers.sliding import SlidingSettings
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.paper.curl import curl_study


def _args(*line: str) -> argparse.Namespace:
    return build_parser().parse_args([*line, "--out", "x.h5"])


@pytest.mark.parametrize("horizon, command", [("full", ["solve", "full"]), ("sliding", ["solve", "sliding"]),
                                               ("max-cycles", ["max-cycles"])])
def test_options_left_out_give_the_curl_study_on_its_defaults(horizon, command):
    assert _curl_study(_args(*command), horizon).data == curl_study(horizon).data


def test_options_given_set_their_keys():
    study = _curl_study(_args("solve", "sliding", "--window", "4", "--advance", "2", "--max-iter", "50", "--no-compile",
                              "-S", "0", "--guess", "physical"), "sliding")
    h, s = study.data["horizon"], study.data["solver"]
    assert (h["cycles"], h["advance"], h["guess"], s["max_iter"], s["compile"], study.data["fatigue"]["S"]) == \
        (4, 2, "physical", 50, False, 0.0)


def test_every_option_of_the_shortcuts_defaults_to_none():
    """Only flags, the command and the given --out are set when no option is given."""
    flags = {"command", "func", "debug", "out", "no_compile", "resume"}
    assert {k for k, v in vars(_args("solve", "full")).items() if v is not None} == flags | {"horizon"}
    assert {k for k, v in vars(_args("max-cycles")).items() if v is not None} == flags


def test_the_help_shows_the_defaults_of_the_settings_classes(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["solve", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"IPOPT iteration limit per solve (default {default_of(SolverOptions, 'max_iter')})" in text
    assert f"full horizon: number of cycles (default {default_of(Horizon, 'cycles')})" in text
    assert f"sliding: cycles the window advances (default {default_of(SlidingSettings, 'advance')})" in text
    assert "(default rest)" in text and f"(default {default_of(SolverOptions, 'linear_solver')})" in text


# -- endurance, calibrate and the SLURM options of sweep: their defaults are the settings classes' --------

@pytest.fixture(autouse=True)
def _wide_help(monkeypatch):
    """Help lines long enough that argparse breaks no word ("frey-law" stays whole)."""
    monkeypatch.setenv("COLUMNS", "1000")


def _help(*command: str, capsys) -> str:
    with pytest.raises(SystemExit):
        build_parser().parse_args([*command, "--help"])
    return " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("command, option, cls, name, value, shown", [
    ("endurance", "--preset", "fatigue_pin.fatigue.endurance_report:EnduranceSettings", "preset", "rakshit-2021/elbow", "rakshit-2021/elbow"),
    ("endurance", "--loads", "fatigue_pin.fatigue.endurance_report:EnduranceSettings", "loads", (0.25, 0.75), "0.25,0.75"),
    ("endurance", "--duty-cycle", "fatigue_pin.fatigue.endurance_report:EnduranceSettings", "duty_cycle", 0.625, "0.625"),
    ("endurance", "--max-cycles", "fatigue_pin.fatigue.endurance_report:EnduranceSettings", "max_cycles", 1234, "1234"),
    ("calibrate", "--model", "fatigue_pin.fatigue.calibration:CalibrationSettings", "model", "3cc-r", "3cc-r"),
    ("calibrate", "--ld", "fatigue_pin.fatigue.calibration:CalibrationSettings", "LD", 12.5, "12.5"),
    ("calibrate", "--lr", "fatigue_pin.fatigue.calibration:CalibrationSettings", "LR", 7.5, "7.5"),
    ("calibrate", "--confidence", "fatigue_pin.fatigue.calibration:CalibrationSettings", "confidence", 0.9, "0.9"),
    ("calibrate", "--intermittent", "fatigue_pin.fatigue.calibration:CalibrationSettings", "intermittent", "ode", "ode"),
    ("sweep", "--walltime", "fatigue_pin.sweep.cluster:SlurmSettings", "walltime", "07:06:05", "07:06:05"),
    ("sweep", "--cores", "fatigue_pin.sweep.cluster:SlurmSettings", "cores", 3, "3"),
    ("sweep", "--memory", "fatigue_pin.sweep.cluster:SlurmSettings", "memory", "9GB", "9GB"),
])
def test_the_help_shows_the_settings_default_and_follows_a_change_of_it(command, option, cls, name, value, shown, capsys, monkeypatch):
    """The help of an option ends with its setting's default, read from the field: change the
    field's default and the help changes with it (the command line holds no copy)."""
    from fatigue_pin.cli.options import owner
    from fatigue_pin.core.settings import field_of

    settings = owner(cls)
    f = field_of(settings, name)
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    text = " ".join(next(a for a in sub.choices[command]._actions if option in a.option_strings).help.split())
    default = f.default
    expected = ",".join(f"{v:g}" for v in default) if isinstance(default, tuple) else f"{default:g}" if isinstance(default, float) else str(default)
    assert f"{text} (default {expected})" in _help(command, capsys=capsys)
    monkeypatch.setattr(f, "default", value)
    assert f"{text} (default {shown})" in _help(command, capsys=capsys)


@pytest.mark.parametrize("command", ["endurance", "calibrate", "sweep"])
def test_their_options_hold_no_default_of_their_own(command):
    """Every option of these commands is None unless given (flags and --retries' owner aside)."""
    line = {"endurance": ["endurance", "--out", "x"], "calibrate": ["calibrate", "d.csv", "--out", "p.json"],
            "sweep": ["sweep", "s.toml", "--out", "x"]}[command]
    args = build_parser().parse_args(line)
    fixed = {"command", "func", "debug", "out", "data", "sweep", "no_compare", "slurm"}
    assert {k for k, v in vars(args).items() if v is not None and k not in fixed} == set()


def test_options_left_out_give_the_settings_defaults_and_given_ones_set_them(monkeypatch, tmp_path):
    import fatigue_pin.fatigue.calibration as calibration
    import fatigue_pin.fatigue.endurance_report as endurance_report
    from fatigue_pin.fatigue.calibration import CalibrationSettings
    from fatigue_pin.fatigue.endurance_report import EnduranceSettings

    seen = {}

    class Stop(Exception):
        pass

    def capture(key):
        def fake(*args, **kwargs):
            seen[key] = args[-1] if key == "calibrate" else args[1]
            raise Stop
        return fake

    monkeypatch.setattr(endurance_report, "run_endurance", capture("endurance"))
    monkeypatch.setattr(calibration, "run_calibrate", capture("calibrate"))
    for line, key, expected in [
        (["endurance"], "endurance", EnduranceSettings()),
        (["endurance", "--loads", "0.5", "--duty-cycle", "0.5", "--cycle-s", "2", "--no-compare"], "endurance",
         EnduranceSettings(loads=(0.5,), duty_cycle=0.5, cycle_s=2.0, compare=False)),
        (["calibrate", "d.csv"], "calibrate", CalibrationSettings()),
        (["calibrate", "d.csv", "--ld", "5", "--model", "3cc-r"], "calibrate", CalibrationSettings(LD=5.0, model="3cc-r")),
    ]:
        out = ["--out", str(tmp_path / ("e" if key == "endurance" else "p.json"))]
        args = build_parser().parse_args(line + out)
        with pytest.raises(Stop):
            args.func(args)
        assert seen[key] == expected


def test_a_bad_option_value_names_the_option():
    from fatigue_pin.core.errors import UsageError

    args = build_parser().parse_args(["calibrate", "d.csv", "--out", "p.json", "--confidence", "1.5"])
    with pytest.raises(UsageError, match=r"--confidence 1.5: expected a level in \(0, 1\)"):
        args.func(args)


def test_every_command_shows_its_help(capsys):
    """Each sub-command's help renders (every default it shows has an owner)."""
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name in sub.choices:
        assert "usage: fatigue-pin " + name in _help(name, capsys=capsys)
