"""Muscle files: the bundled arm26 one, and one line for each bad entry."""

from __future__ import annotations

import pytest

from fatigue_pin.core.errors import ModelError, ParameterError
from fatigue_pin.muscles.files import load_muscles, read_muscles

GOOD_MUSCLE = """
[[muscles]]
name = "BRA"
max_force = 987.26
optimal_length = 0.0858
tendon_slack_length = 0.0535
points = [{ frame = "humerus", location = [0.0068, -0.1739, -0.0036] },
          { frame = "forearm", location = [-0.0032, -0.0239, 0.0009] }]
"""


def test_the_bundled_arm26_has_six_muscles_round_one_cylinder(arm26_muscles):
    assert arm26_muscles.names == ("TRIlong", "TRIlat", "TRImed", "BIClong", "BICshort", "BRA")
    assert [w.name for w in arm26_muscles.wraps] == ["TRI"]
    assert [u.turn for m in arm26_muscles.muscles for u in m.wraps] == ["positive"] * 3 + ["negative"]
    assert arm26_muscles.muscles[0].max_force == 798.52 and len(arm26_muscles.muscles[3].points) == 9


def test_a_good_file_reads():
    s = read_muscles(GOOD_MUSCLE, "m.toml")
    assert s.names == ("BRA",) and s.muscles[0].kind == "degroote"


@pytest.mark.parametrize("text, message", [
    (GOOD_MUSCLE.replace("987.26", "-1.0"), r"^m\.toml: muscle 'BRA': max_force = -1\.0: expected a force > 0 \(N\)$"),
    (GOOD_MUSCLE.replace("optimal_length = 0.0858", "optimal_length = 0"), r"^m\.toml: muscle 'BRA': optimal_length = 0: expected"),
    (GOOD_MUSCLE.replace("max_force", "max_forse"), r"^m\.toml: muscles\[0\] \('BRA'\): unknown key 'max_forse'"),
    (GOOD_MUSCLE.replace("tendon_slack_length = 0.0535\n", ""), r"^m\.toml: muscles\[0\] \('BRA'\): missing key 'tendon_slack_length'$"),
    (GOOD_MUSCLE + 'wraps = ["TRI"]\n', r"^muscle 'BRA' wraps round 'TRI' in m\.toml, which is not a wrap of the set"),
    (GOOD_MUSCLE + '[[wraps]]\nname = "TRI"\nframe = "humerus"\ntranslation = [0, 0, 0]\nrotation = [0, 0, 0]\nradius = 0.0\n',
     r"^m\.toml: wrap 'TRI' radius = 0\.0: expected a cylinder radius > 0 \(m\)$"),
    (GOOD_MUSCLE + "[model]\n", r"^m\.toml: unknown table 'model'; expected \[\[muscles\]\] and \[\[wraps\]\]$"),
    ("[[muscles]\n", r"^m\.toml is not valid TOML"),
    (GOOD_MUSCLE + GOOD_MUSCLE, r"^muscle 'BRA' is defined twice in m\.toml"),
])
def test_bad_entries_get_one_line_naming_them(text, message):
    with pytest.raises(ParameterError, match=message) as info:
        read_muscles(text, "m.toml")
    assert "\n" not in str(info.value)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(ModelError, match=r"muscle file '.*nowhere\.muscles\.toml' does not exist"):
        load_muscles(tmp_path / "nowhere.muscles.toml")
    assert load_muscles("arm26").source.endswith("arm26.muscles.toml")
