"""Result files under stress: the layout version, concurrent writers, a full disk, a write that
fails at any step, and reading files that are damaged."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest

import fatigue_pin.core.files as files
import fatigue_pin.io.results as results
from fatigue_pin.io.results import LAYOUT, ResultFileError, list_runs, read_run, read_search, write_run, write_search
from conftest import make_run

ROOT = Path(__file__).resolve().parents[2]


def _layout(path: Path) -> str:
    with h5py.File(path, "r") as h5:
        return h5.attrs["format"]


def test_files_carry_layout_3(tmp_path):
    path = tmp_path / "a.h5"
    write_run(path, make_run("full/a"))
    assert LAYOUT == 3 and _layout(path) == "fatigue_pin.results/3"
    with h5py.File(path, "r") as h5:
        assert list(h5["full/a"].attrs["fatigue_states"]) == ["ma", "mr", "mf"]


def _layout_1_file(path: Path) -> None:
    """A file as layout 1 wrote it before fatigue states were named: no ``fatigue_states``, no
    persistent free-space tracking."""
    write_run(path, make_run("full/old"))
    with h5py.File(path, "r") as src, h5py.File(path.with_suffix(".v1"), "w") as dst:
        src.copy(src["full"], dst, name="full")
        dst.attrs["format"] = "fatigue_pin.results/1"
        del dst["full/old"].attrs["fatigue_states"]
    os.replace(path.with_suffix(".v1"), path)


def test_layout_1_files_are_read_and_upgraded_on_write(tmp_path):
    path = tmp_path / "v1.h5"
    _layout_1_file(path)
    old = read_run(path, "full/old")
    assert old.fatigue_states == ("ma", "mr", "mf") and np.array_equal(old.mf, make_run().mf)
    write_run(path, make_run("full/new"))
    assert _layout(path) == "fatigue_pin.results/3"
    assert list_runs(path) == ["full/new", "full/old"]
    with h5py.File(path, "r") as h5:
        assert list(h5["full/old"].attrs["fatigue_states"]) == ["ma", "mr", "mf"]
        assert h5.id.get_create_plist().get_file_space_strategy()[1]  # free space now persists
    assert np.array_equal(read_run(path, "full/old").q, old.q)


def test_layout_2_runs_with_torques_per_joint_are_read(tmp_path):
    """A run as layout 2 stored it, tau_plus and tau_minus (intervals, nv) per joint, reads back
    as the run written today (whose file has the halves' torques, tau_halves)."""
    path = tmp_path / "v2.h5"
    run = make_run("full/old")
    write_run(path, run)
    with h5py.File(path, "a") as h5:
        group = h5["full/old"]
        assert list(group["tau_halves"].attrs["actuators"]) == list(run.actuator_names)
        del group["tau_halves"]
        for name in ("tau_plus", "tau_minus"):
            group.create_dataset(name, data=getattr(run, name)).attrs["joints"] = list(run.joint_names)
        h5.attrs["format"] = "fatigue_pin.results/2"
    old = read_run(path, "full/old")
    assert np.array_equal(old.tau_plus, run.tau_plus) and np.array_equal(old.tau_minus, run.tau_minus)
    assert np.array_equal(old.target_loads(), run.target_loads())


def _newer(path: Path) -> bytes:
    write_run(path, make_run("full/a"))
    with h5py.File(path, "a") as h5:
        h5.attrs["format"] = "fatigue_pin.results/4"
    return path.read_bytes()


def test_newer_layout_is_refused_by_readers_and_writers(tmp_path):
    path = tmp_path / "new.h5"
    before = _newer(path)
    message = f"'{path}' was written by a newer fatigue_pin (layout 4); this version reads layouts up to 3"
    for call in (lambda: list_runs(path), lambda: read_run(path), lambda: read_search(path),
                 lambda: write_run(path, make_run("full/b")), lambda: results.check_output(path)):
        with pytest.raises(ResultFileError) as err:
            call()
        assert str(err.value) == message
    assert path.read_bytes() == before


def test_a_foreign_format_is_refused(tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as h5:
        h5.attrs["format"] = "somebody.else/7"
    with pytest.raises(ResultFileError, match="has format 'somebody.else/7'; expected a fatigue_pin result file"):
        list_runs(path)


def test_reading_damaged_files_names_the_path(tmp_path):
    good = tmp_path / "good.h5"
    write_run(good, make_run("full/a"))
    data = good.read_bytes()
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(ResultFileError, match=r"'.*truncated.h5' is not a readable HDF5 file: it is truncated or damaged"):
        read_run(truncated)
    stub = tmp_path / "stub.h5"
    stub.write_bytes(data[:4])
    with pytest.raises(ResultFileError, match="lacks the HDF5 signature"):
        list_runs(stub)
    with pytest.raises(ResultFileError, match="is a folder"):
        read_run(tmp_path)
    with pytest.raises(ResultFileError, match=r"run 'full/b' is not in '.*good.h5'; it holds \['full/a'\]"):
        read_run(good, "full/b")


def test_a_damaged_run_is_one_error(tmp_path, monkeypatch):
    path = tmp_path / "a.h5"
    write_run(path, make_run("full/a"))

    def broken(group, name):
        raise OSError("Can't read data (wrong B-tree signature)")

    monkeypatch.setattr(results, "read_run_group", broken)
    with pytest.raises(ResultFileError, match=r"run 'full/a' in '.*a.h5' cannot be read \(OSError: Can't read data"):
        read_run(path, "full/a")


@pytest.mark.parametrize("step", ["copy", "h5", "fsync", "replace"])
def test_a_write_failing_at_any_step_leaves_the_file_unchanged(tmp_path, monkeypatch, step):
    path = tmp_path / "a.h5"
    write_run(path, make_run("full/a"))
    write_search(path, "s", [{"n_cycles": 1, "converged": True, "status": "ok", "iterations": 3, "wall_time_s": 0.1}])
    before = path.read_bytes()

    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")

    target = {"copy": (files.shutil, "copyfile"), "h5": (results, "write_run_group"), "fsync": (files, "fsync"),
              "replace": (results.os, "replace")}[step]
    monkeypatch.setattr(*target, fail)
    with pytest.raises(ResultFileError, match=r"cannot write '.*a.h5': the disk is full \(no space left on device\); "
                                              "the previous file is unchanged"):
        write_run(path, make_run("full/b", cycles=3))
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert not (tmp_path / "a.h5.tmp").exists()
    assert list_runs(path) == ["full/a"]


@contextlib.contextmanager
def tiny_disk(folder: Path, size_kib: int = 256):
    """A tmpfs of ``size_kib`` mounted at ``folder`` (skips the test where mounting is not allowed)."""
    folder.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kib}k", "tmpfs", str(folder)], capture_output=True)
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.decode().strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def _fill(folder: Path, leave: int) -> None:
    """Fill the disk of ``folder`` up to ``leave`` bytes free."""
    st = os.statvfs(folder)
    free = st.f_bavail * st.f_frsize
    with open(folder / "filler", "wb") as fh:
        fh.write(b"\0" * max(free - leave, 0))


FULL_DISK = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    sys.path.insert(0, sys.argv[3])
    from conftest import make_run
    from fatigue_pin.io import results
    from fatigue_pin.io.results import ResultFileError, list_runs, write_run
    path, room = Path(sys.argv[1]), sys.argv[2]
    before = path.read_bytes()
    try:
        write_run(path, make_run("full/big", cycles=200))
    except ResultFileError as exc:
        assert "the disk is full" in str(exc), exc
    else:
        raise SystemExit("no error on a full disk")
    assert path.read_bytes() == before
    assert not path.with_name(path.name + ".tmp").exists()
    assert list_runs(path) == ["full/a"]
    try:
        results.check_output(path)
    except ResultFileError as exc:
        assert "full" in str(exc), exc
    else:
        raise SystemExit("check_output accepted a full disk")
    print("ok")
    """
)


@pytest.mark.parametrize("room", ["none", "copy only"])
def test_a_full_disk_leaves_the_previous_file(tmp_path, room):
    """On a real full disk (tmpfs): the copy, or the new run after the copy, does not fit. The
    write runs in a subprocess: HDF5 failing to write leaves its library state damaged in that
    process (later HDF5 calls there could crash), which must not reach the other tests."""
    with tiny_disk(tmp_path / "disk") as disk:
        path = disk / "a.h5"
        write_run(path, make_run("full/a"))
        before = path.read_bytes()
        _fill(disk, 8192 if room == "none" else len(before) + 8192)
        script = tmp_path / "full_disk.py"
        script.write_text(FULL_DISK)
        proc = subprocess.run([sys.executable, str(script), str(path), room, str(Path(__file__).resolve().parents[1])],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-2000:]
        assert path.read_bytes() == before


CONCURRENT = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, sys.argv[3])
    from conftest import make_run
    from fatigue_pin.io.results import write_run, write_search
    path, who = sys.argv[1], sys.argv[2]
    for i in range(6):
        write_run(path, make_run(f"p{who}/r{i}", cycles=1 + i % 3))
    write_search(path, f"p{who}", [{"n_cycles": 1, "converged": True, "status": "ok", "iterations": 1, "wall_time_s": 0.0}])
    """
)


def test_concurrent_writers_lose_nothing(tmp_path):
    path = tmp_path / "shared.h5"
    write_run(path, make_run("full/first"))
    script = tmp_path / "writer.py"
    script.write_text(CONCURRENT)
    procs = [subprocess.Popen([sys.executable, str(script), str(path), str(k), str(ROOT / "tests")], cwd=tmp_path) for k in range(4)]
    assert all(p.wait(timeout=120) == 0 for p in procs)
    assert list_runs(path) == sorted(["full/first"] + [f"p{k}/r{i}" for k in range(4) for i in range(6)])
    assert sorted(read_search(path)) == [f"p{k}" for k in range(4)]
    assert read_run(path, "p2/r4").n_cycles == 2
    assert (tmp_path / ".shared.h5.lock").exists() and not (tmp_path / "shared.h5.tmp").exists()


def test_replacing_a_run_many_times_keeps_the_file_small(tmp_path, monkeypatch):
    """A sliding run rewritten after every window: the file is compacted once it has doubled
    since its last compaction (here without the 1 MiB slack), so it stays within about twice its
    contents, and every run survives the compactions."""
    monkeypatch.setattr(results, "_COMPACT_SLACK", 0)
    path = tmp_path / "a.h5"
    write_run(path, make_run("full/a", cycles=20))
    sizes = []
    for w in range(1, 31):
        write_run(path, make_run("sliding/run", cycles=w + 2))
        sizes.append(path.stat().st_size)
    once = tmp_path / "b.h5"
    write_run(once, make_run("full/a", cycles=20))
    write_run(once, make_run("sliding/run", cycles=32))
    assert max(sizes) < 2.5 * once.stat().st_size and sizes[-1] < 2.5 * once.stat().st_size
    assert any(b < a for a, b in zip(sizes, sizes[1:]))  # compacted at least once
    assert list_runs(path) == ["full/a", "sliding/run"] and read_run(path, "sliding/run").n_cycles == 32
    assert np.array_equal(read_run(path, "full/a").q, make_run("full/a", cycles=20).q)


def test_check_output_dir(tmp_path):
    assert results.check_output_dir(tmp_path / "new" / "figures") == tmp_path / "new" / "figures"
    assert (tmp_path / "new" / "figures").is_dir()
    (tmp_path / "file").write_text("x")
    with pytest.raises(ResultFileError, match="is a file; expected a folder"):
        results.check_output_dir(tmp_path / "file")
    with pytest.raises(ResultFileError, match="cannot be created: .* is not a folder"):
        results.check_output_dir(tmp_path / "file" / "sub")


def test_an_output_that_is_a_symbolic_link_is_written_through(tmp_path):
    """``--out link.h5`` pointing at a result file elsewhere: the run is added to the target, the
    link stays a link (it was replaced by a regular file); a link whose target does not exist
    yet creates the target; other atomic writes (core.files.atomic_write) do the same."""
    from fatigue_pin.core.files import atomic_write_bytes
    from fatigue_pin.io.results import check_output

    store = tmp_path / "store"
    store.mkdir()
    target = store / "runs.h5"
    write_run(target, make_run("full/a"))
    link = tmp_path / "link.h5"
    link.symlink_to(target)
    assert check_output(link) == target
    write_run(link, make_run("full/b"))
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert list_runs(target) == ["full/a", "full/b"] == list_runs(link)
    dangling = tmp_path / "new.h5"
    dangling.symlink_to(store / "new_target.h5")
    write_run(dangling, make_run("full/c"))
    assert dangling.is_symlink() and list_runs(store / "new_target.h5") == ["full/c"]
    text_link = tmp_path / "notes.json"
    text_link.symlink_to(store / "notes.json")
    atomic_write_bytes(text_link, b"{}")
    assert text_link.is_symlink() and (store / "notes.json").read_bytes() == b"{}"
    assert not list(tmp_path.glob("*.tmp")) and not list(store.glob("*.tmp"))
