"""Run names (issue 25): one grammar, checked before any work, and a run never lands on anything
but a run of the same name: not on the group of other runs, a search table, inside another run.
Generated names (hypothesis) are accepted or refused with the project's error, and a refused
write leaves the file byte for byte as it was; an accepted one keeps every other run."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import make_run
from fatigue_pin.core.errors import FatiguePinError, ParameterError, ResultFileError
from fatigue_pin.drivers.run import check_run_name
from fatigue_pin.io.results import check_run_slot, list_runs, read_run, read_search, write_run, write_search

SEARCH_ROW = {"n_cycles": 1, "converged": True, "status": "ok", "iterations": 3, "wall_time_s": 0.1}


@pytest.fixture
def filled(tmp_path):
    """A file with runs full/a and full/b, a search table full_a and a step run of that search."""
    path = tmp_path / "runs.h5"
    for name in ("full/a", "full/b"):
        write_run(path, make_run(name))
    write_search(path, "full_a", [SEARCH_ROW])
    write_run(path, make_run("searched/full_a/N1"))
    return path


@pytest.mark.parametrize("name", ["full", "searched", "searched/full_a", "full/a/b", "searched/full_a/N1/x"])
def test_names_that_collide_with_the_files_structure_delete_nothing(filled, name):
    before = filled.read_bytes()
    with pytest.raises(FatiguePinError) as err:
        check_run_slot(filled, name, internal=True)
    assert "\n" not in str(err.value)
    with pytest.raises(FatiguePinError):
        write_run(filled, make_run(name))
    assert filled.read_bytes() == before


@pytest.mark.parametrize("name", ["", ".", "..", "/", "a//b", "/a", "a/", "a/./b", "a/../b", ".hidden", "a b", "a\nb", "a\\b",
                                  "search", "search/x", "searched/x/N1", "full/x_failed_window", "x" * 201, "bïcèps_💪 run", None, 3])
def test_the_grammar_refuses(name):
    with pytest.raises(ParameterError, match="expected segments of letters and digits of any script"):
        check_run_name(name)


@pytest.mark.parametrize("name, shown", [("bïcèps_💪 run", "'💪' (U+1F4AA)"), ("a b", "a space (U+0020)"),
                                         ("a\nb", "a control character (U+000A)"), ("x/y\\z", "'\\\\' (U+005C)")])
def test_a_refused_name_names_the_character_it_cannot_hold(name, shown):
    with pytest.raises(ParameterError) as err:
        check_run_name(name)
    assert f"holds {shown}, which is not allowed" in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("name", ["bïcèps_run", "ünïcode/x", "бицепс", "二頭筋_3.6kg", "x\u0308"])
def test_letters_of_any_script_are_letters(name, tmp_path):
    """HDF5 stores names as UTF-8: a run named in any script is written and read back by its name."""
    assert check_run_name(name) == name
    path = tmp_path / "runs.h5"
    write_run(path, make_run(name))
    assert list_runs(path) == [name] and read_run(path, name).name == name


@pytest.mark.parametrize("name", ["full/torque_S10", "sliding/physiological_3.6kg_1s", "a", "x/y/z", "S1e-05", "a=b,c+d"])
def test_the_grammar_accepts(name):
    assert check_run_name(name) == name


def test_a_run_replaces_a_run_of_the_same_name(filled):
    run = make_run("full/a", cycles=3)
    write_run(filled, run)
    assert read_run(filled, "full/a").n_cycles == 3
    assert list_runs(filled, failed_windows=True) == ["full/a", "full/b", "searched/full_a/N1"]
    assert set(read_search(filled)) == {"full_a"}


def test_the_command_line_checks_the_name_before_any_work(filled, tmp_path, capsys):
    from conftest import small_curl
    from fatigue_pin.cli.main import main

    study = tmp_path / "s.toml"
    study.write_text(small_curl("full").to_toml())
    before = filled.read_bytes()
    for name, message in (("full", "is the group of ['full/a', 'full/b']"), ("a//b", "expected segments"), ("", "run name ''"),
                          ("searched/full_a/N1", "expected segments"), ("full/a/b", "lies inside run 'full/a'")):
        assert main(["run", str(study), "--name", name, "--out", str(filled)]) == 2
        err = capsys.readouterr()
        assert message in err.err and err.err.count("\n") == 1 and "building" not in err.out, (name, err)
    assert filled.read_bytes() == before


names = st.one_of(
    st.text(alphabet=st.sampled_from("ab./_-+=, \n\\s"), max_size=12),
    st.sampled_from(["full", "full/a", "full/b", "full/a/x", "searched", "searched/full_a", "searched/full_a/N1", "search",
                     "search/full_a", "full/c", "new"]),
    st.lists(st.sampled_from(["full", "a", "b", "", ".", "..", "searched", "search", "full_a", "N1"]), min_size=1,
             max_size=4).map("/".join),
)


@settings(max_examples=80, deadline=3000, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(names)
def test_generated_names_never_lose_a_run(tmp_path_factory, name):
    path = tmp_path_factory.mktemp("names") / "runs.h5"
    for existing in ("full/a", "full/b"):
        write_run(path, make_run(existing))
    write_search(path, "full_a", [SEARCH_ROW])
    write_run(path, make_run("searched/full_a/N1"))
    before = path.read_bytes()
    runs = list_runs(path, failed_windows=True)
    try:
        write_run(path, make_run(name, cycles=3))
    except (ParameterError, ResultFileError) as exc:
        assert "\n" not in str(exc)
        assert path.read_bytes() == before
        return
    after = list_runs(path, failed_windows=True)
    assert set(runs) <= set(after) and set(after) - set(runs) <= {name}
    assert read_run(path, name).n_cycles == 3 and set(read_search(path)) == {"full_a"}
