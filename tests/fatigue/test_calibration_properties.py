"""Generated endurance CSV files (hypothesis): any bytes, and CSVs built from the right columns
with odd cells, are read as data or refused with the project's error (a one-line
:class:`~fatigue_pin.fatigue.calibration.CalibrationDataError`), never another exception; what
is read is valid data, and a fit of it ends with finite parameters or the project's error."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.fatigue.calibration import CalibrationDataError, calibrate, read_endurance_csv

COLUMNS = ["target_load", "endurance_time_s", "duty_cycle", "cycle_s"]
cells = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", " ", "0", "1", "0.5", "1e-300", "1e300", "-1", "nan", "abc", "0,5", '"0.5"', "1e999"]),
    st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=6),
)


@st.composite
def csv_texts(draw):
    """A header of known (sometimes repeated, sometimes unknown) columns and rows of odd cells,
    with a byte-order mark or Windows line ends now and then."""
    header = draw(st.lists(st.sampled_from(COLUMNS + ["subject", ""]), min_size=1, max_size=5))
    rows = draw(st.lists(st.lists(cells, min_size=len(header), max_size=len(header) + 1), max_size=5))
    end = draw(st.sampled_from(["\n", "\r\n"]))
    text = end.join(",".join(r) for r in [header] + rows) + end
    return draw(st.sampled_from(["", "\ufeff"])) + text


def _check(path) -> None:
    try:
        data = read_endurance_csv(path)
    except CalibrationDataError as exc:
        assert "\n" not in str(exc)
        return
    assert data.n >= 1
    assert np.all((0 < data.target_load) & (data.target_load < 1))
    assert np.all(np.isfinite(data.endurance_time_s) & (data.endurance_time_s > 0))
    assert np.all((0 < data.duty_cycle) & (data.duty_cycle <= 1))
    try:
        result = calibrate(data)
    except FatiguePinError as exc:
        assert "\n" not in str(exc)
        return
    assert all(math.isfinite(v) and v > 0 for v in result.params.values())


@settings(max_examples=150, deadline=3000, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(csv_texts())
def test_generated_csv_is_data_or_one_line(tmp_path, text):
    path = tmp_path / "data.csv"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    _check(path)


@settings(max_examples=100, deadline=3000, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=300))
def test_any_bytes_are_data_or_one_line(tmp_path, raw):
    path = tmp_path / "data.csv"
    path.write_bytes(raw)
    _check(path)
