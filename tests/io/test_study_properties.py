"""Generated bad studies (hypothesis): whatever a study file holds, reading it, building its
problem and its solver settings gives a study or one of the project's errors
(:class:`~fatigue_pin.core.errors.FatiguePinError`), never another exception."""

from __future__ import annotations

import copy
import math
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import small_curl
from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.io.study import Study

BASE = tomllib.loads(small_curl("full").to_toml())

# Values of every kind a TOML file can hold, odd ones included.
scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0, -1, 1e-300, 1e300, 10**20, 0.5, 2]),
    st.text(max_size=12), st.sampled_from(["", "arm26", "ur5", "/", ".", "a/b", "xia", "michaud", "full", "sliding",
                                           "max-cycles", "mumps", "rest", "elbow", "knee"]),
)
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.text(max_size=8), inner, max_size=3)),
                      max_leaves=6)


def _paths(node, prefix=()):
    """Every key path of a nested table (and list items), leaves and tables."""
    out = []
    if isinstance(node, dict):
        for k, v in node.items():
            out.append(prefix + (k,))
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out.append(prefix + (i,))
            out += _paths(v, prefix + (i,))
    return out


PATHS = _paths(BASE)


@st.composite
def mutated_studies(draw):
    """The small curl with a few changes: a value replaced, a key deleted or a key added."""
    data = copy.deepcopy(BASE)
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(PATHS))
        node = data
        try:
            for p in path[:-1]:
                node = node[p]
            action = draw(st.sampled_from(["replace", "delete", "add"]))
            if action == "replace":
                node[path[-1]] = draw(values)
            elif action == "delete" and isinstance(node, dict):
                del node[path[-1]]
            elif isinstance(node, dict):
                node[draw(st.text(min_size=1, max_size=8))] = draw(values)
        except (KeyError, IndexError, TypeError):
            continue  # an earlier change removed the path
    return data


_MODEL: dict = {}


def _model(study: Study):
    """Models are cached by their study table (building one takes a while)."""
    key = repr(study.data["model"])
    if key not in _MODEL:
        _MODEL[key] = study.model()
    return _MODEL[key]


@settings(max_examples=120, deadline=2000, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_studies())
def test_a_mutated_study_is_a_study_or_a_project_error(data):
    try:
        study = Study.from_dict(data)
        model = _model(study)
        problem = study.problem(model)
        study.transcription()
        study.solver()
        study.run_name()
    except FatiguePinError as exc:
        assert "\n" not in str(exc), str(exc)
        return
    assert problem.layout.nx > 0 and math.isfinite(problem.task.dt)


@settings(max_examples=60, deadline=2000)
@given(mutated_studies())
def test_an_accepted_study_reads_back_from_its_toml(data):
    """A study accepted from a table is written as TOML and read back to the same table."""
    try:
        study = Study.from_dict(data)
    except FatiguePinError:
        return
    assert Study.from_toml(study.to_toml()).data == study.data


@settings(max_examples=150, deadline=1000)
@given(st.one_of(st.text(max_size=200), st.binary(max_size=200).map(lambda b: b.decode("latin-1"))))
def test_any_text_is_a_study_or_a_project_error(text):
    try:
        Study.from_toml(text)
    except FatiguePinError as exc:
        assert "\n" not in str(exc)


@pytest.mark.parametrize("text", ["name = 1", "[model]\nurdf = []", "task = []", "horizon = {kind = 3}",
                                  "name = 'x'\n[task]\ntargets = [1, 2]"])
def test_examples_found_by_hand(text):
    with pytest.raises(FatiguePinError):
        Study.from_toml(text)
