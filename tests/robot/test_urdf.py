"""URDF checks before the parser: one line naming the element and the value, nothing of the
parser's own output on the process's standard error, and valid URDFs still load."""

from __future__ import annotations

import pytest

from fatigue_pin.core.errors import ModelError
from fatigue_pin.robot.model import bundled_urdf, load_model
from fatigue_pin.robot.urdf import check_urdf_text, quiet_stderr

ELBOW = 'name="elbow" type="revolute"'
LIMIT = 'lower="0.0" upper="3.141592653589793"'


def _urdf(tmp_path, old: str, new: str, name: str = "robot.urdf"):
    text = bundled_urdf().read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize("old, new, message", [
    (LIMIT, 'lower="0.0" upper="inf"', r"<limit upper='inf'>: expected a finite number"),
    (LIMIT, 'lower="1e999" upper="3"', r"<limit lower='1e999'>: expected a finite number"),
    (LIMIT, 'lower="0,5" upper="3"', r"<limit lower='0,5'>: expected a finite number"),
    ('<mass value="1.864572"/>', '<mass value="heavy"/>', r"link \[humerus\]: <mass value='heavy'>: expected a finite number"),
    ('<axis xyz="0.049400012 0.036600009 0.998108250"/>', '<axis xyz="0 0 1 0"/>', r"<axis xyz='0 0 1 0'>: expected 3 finite numbers"),
    ('<link name="forearm">', '<link name="humerus">', r"two links are named 'humerus'"),
    ('<joint name="elbow" type="revolute">', '<joint type="revolute">', r"a joint lacks its name attribute"),
    (ELBOW, 'name="elbow"', r"joint \[elbow\] lacks its type attribute"),
    ('<mass value="1.534315"/>', '<mass value="-0.001"/>', r"link 'forearm' has mass -0.001; expected a mass >= 0"),
    (LIMIT, 'lower="0.5" upper="0.4"', r"joint 'elbow' has lower limit 0.5 above its upper limit 0.4"),
    ('<axis xyz="0.049400012 0.036600009 0.998108250"/>', '<axis xyz="0 0 0"/>', r"joint 'elbow' has axis xyz = '0 0 0'; expected a non-zero"),
    ('<mass value="1.864572"/>', "<mass/>", r"link \[humerus\]: <mass> has no value"),
    ('ixy="0" ixz="0" iyy="0.004551"', 'ixz="0" iyy="0.004551"', r"link \[humerus\]: <inertia> lacks \['ixy'\]"),
    ('effort="50.0" velocity="31.41592653589793"/>', 'effort="-5" velocity="31.41592653589793"/>', r"joint 'shoulder' has effort limit -5.0"),
    ('effort="50.0" velocity="31.41592653589793"/>', 'effort="50" velocity="-1"/>', r"joint 'shoulder' has velocity limit -1.0; expected a speed >= 0"),
])
def test_bad_urdf_is_one_line(tmp_path, capfd, old, new, message):
    path = _urdf(tmp_path, old, new)
    with pytest.raises(ModelError, match=message) as err:
        load_model(path)
    assert "\n" not in str(err.value)
    assert capfd.readouterr().err == ""  # nothing of the parser's own lines


def test_parser_lines_are_kept_in_the_message_not_printed(tmp_path, capfd):
    path = _urdf(tmp_path, ELBOW, 'name="elbow" type="weird"')
    check_urdf_text(path)  # the type is the parser's to judge
    with pytest.raises(ModelError, match=r"Joint \[elbow\] has no known type \[weird\]") as err:
        load_model(path)
    assert "\n" not in str(err.value) and "urdf_parser/src" not in str(err.value)
    assert capfd.readouterr().err == ""


def test_equal_limits_and_transmissions_are_accepted(tmp_path):
    # lower == upper is a valid (if useless) range; <transmission> holds <joint name=...> without type
    text = bundled_urdf().read_text().replace(LIMIT, 'lower="0.3" upper="3.0"', 1).replace(
        "</robot>", '<transmission name="t"><joint name="elbow"/></transmission></robot>')
    path = tmp_path / "ok.urdf"
    path.write_text(text)
    model = load_model(path)
    assert model.joint_names == ("shoulder", "elbow")
    assert model.q_lower[1] == pytest.approx(0.3) and model.q_upper[1] == pytest.approx(3.0)


def test_quiet_stderr_captures_file_descriptor_2(capfd):
    import os

    with quiet_stderr() as lines:
        os.write(2, b"from C++\n\n  second  \n")
    os.write(2, b"after\n")
    assert lines == ["from C++", "second"]
    assert capfd.readouterr().err == "after\n"


def test_urdf_path_that_is_a_folder_or_empty(tmp_path):
    with pytest.raises(ModelError, match="is a folder"):
        load_model(tmp_path)
    with pytest.raises(ModelError, match="URDF path '' is empty"):
        load_model("")
