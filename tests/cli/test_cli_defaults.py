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
