"""Generated damaged result files (hypothesis): a valid file changed at the HDF5 level (a dataset
removed, replaced by one of another shape or type, an attribute changed or removed) or at the
byte level (bytes overwritten, the file cut) is read as runs or refused with the project's error
(:class:`~fatigue_pin.core.errors.FatiguePinError`), never another exception; what is read is
a consistent run (:meth:`RunResult.check_shapes`)."""

from __future__ import annotations

import h5py
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import make_run
from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.io.results import list_runs, read_run, read_search, write_run, write_search

DATASETS = ["t", "q", "qdot", "tau_plus", "tau_minus", "ma", "mr", "mf", "fatigued", "cycle_costs", "torque_limits",
            "cycle_wall_time_s"]
ATTRIBUTES = [("full/a", "fatigue_states"), ("full/a/q", "joints"), ("full/a/mf", "actuators"), ("full/a/cycle_costs", "terms"),
              ("full/a", "tau_limits"), ("full/a", "converged"), ("", "format")]
odd_arrays = st.one_of(
    st.integers(0, 25).flatmap(lambda n: st.integers(0, 5).map(lambda m: np.zeros((n, m)))),
    st.integers(0, 25).map(lambda n: np.arange(float(n))),
    st.just(np.array(3.0)), st.just(np.array([b"x", b"y"])), st.just(np.full((21, 2), np.nan)),
    st.just(np.zeros((21, 2, 2))), st.just(np.ones((21, 2), dtype=np.int8)),
)
odd_attrs = st.one_of(st.integers(-3, 3), st.floats(allow_nan=True), st.text(max_size=8), st.just([b"a", b"b"]),
                      st.just(["ma", "mr"]), st.just(np.zeros(0)), st.just("fatigue_pin.results/9"))


@st.composite
def damages(draw):
    """A list of changes: ("drop", dataset), ("replace", dataset, array), ("attr", where, key, value or None),
    ("bytes", fraction, length) or ("cut", fraction)."""
    out = []
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["drop", "replace", "replace", "attr", "bytes", "cut"]))
        if kind == "drop":
            out.append(("drop", draw(st.sampled_from(DATASETS))))
        elif kind == "replace":
            out.append(("replace", draw(st.sampled_from(DATASETS)), draw(odd_arrays)))
        elif kind == "attr":
            where, key = draw(st.sampled_from(ATTRIBUTES))
            out.append(("attr", where, key, draw(st.one_of(st.none(), odd_attrs))))
        elif kind == "bytes":
            out.append(("bytes", draw(st.floats(0, 1)), draw(st.integers(1, 64))))
        else:
            out.append(("cut", draw(st.floats(0, 1))))
    return out


def _damage(path, changes) -> None:
    for change in changes:
        if change[0] in ("bytes", "cut"):
            data = bytearray(path.read_bytes())
            at = int(change[1] * (len(data) - 1))
            if change[0] == "cut":
                data = data[:at]
            else:
                data[at:at + change[2]] = bytes((b ^ 0x5A) for b in data[at:at + change[2]])
            path.write_bytes(bytes(data))
            continue
        try:
            with h5py.File(path, "a") as h5:
                group = h5["full/a"]
                if change[0] == "drop" and change[1] in group:
                    del group[change[1]]
                elif change[0] == "replace":
                    if change[1] in group:
                        del group[change[1]]
                    group.create_dataset(change[1], data=change[2])
                elif change[0] == "attr":
                    obj = h5[change[1]] if change[1] else h5
                    if change[3] is None:
                        obj.attrs.pop(change[2], None)
                    else:
                        obj.attrs[change[2]] = change[3]
        except (OSError, KeyError, ValueError, TypeError, RuntimeError):  # h5py can raise RuntimeError on close
            return  # an earlier byte-level change already broke the file for h5py: read it as it is


_TEMPLATE: list[bytes] = []


def _template(folder) -> bytes:
    """The bytes of a valid file: runs full/a and full/b and a search table (written once)."""
    if not _TEMPLATE:
        path = folder / "template.h5"
        write_run(path, make_run("full/a"))
        write_run(path, make_run("full/b"))
        write_search(path, "full_a", [{"n_cycles": 1, "converged": True, "status": "ok", "iterations": 3, "wall_time_s": 0.1}])
        _TEMPLATE.append(path.read_bytes())
    return _TEMPLATE[0]


@settings(max_examples=80, deadline=3000, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(damages())
def test_a_damaged_file_is_read_or_refused_with_one_line(tmp_path_factory, changes):
    folder = tmp_path_factory.mktemp("damaged")
    path = folder / "runs.h5"
    path.write_bytes(_template(folder))
    _damage(path, changes)
    for read in (lambda: list_runs(path), lambda: read_run(path, "full/a"), lambda: read_run(path, "full/b"),
                 lambda: read_search(path), lambda: read_run(path)):
        try:
            out = read()
        except FatiguePinError as exc:
            assert "\n" not in str(exc)
            continue
        if hasattr(out, "check_shapes"):
            out.check_shapes()
            assert out.t.shape[0] == out.q.shape[0]
