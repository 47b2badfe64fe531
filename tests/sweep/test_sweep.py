"""Parameter sweeps on Dask (fatigue_pin.sweep.jobs): sweep files, a real scheduler with a worker killed
mid-job, the local cluster against single runs, SLURM job scripts, bad sweep files."""

from __future__ import annotations

import csv
import hashlib
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.cli.main import main
from fatigue_pin.io.results import read_run
from fatigue_pin.io.study import Study
from fatigue_pin.sweep.jobs import partial_path, read_job_file
from fatigue_pin.sweep.plan import Sweep, SweepError
from fatigue_pin.sweep.runner import run_sweep, sweep_command
from fatigue_pin.sweep.summary import SUMMARY_COLUMNS, read_summary, write_summary

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def _env() -> dict[str, str]:
    """The environment of child processes: they import the fatigue_pin this process imported
    (the installed package, with its compiled extension, or the tree named by PYTHONPATH)."""
    import fatigue_pin

    env = dict(os.environ)
    home = str(Path(fatigue_pin.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join([home, *filter(None, [env.get("PYTHONPATH")])])
    return env


def _write_sweep(tmp_path: Path, body: str, base=None, name: str = "sweep.toml") -> Path:
    """A sweep file beside ``base.toml`` (the small curl, or ``base``)."""
    (tmp_path / "base.toml").write_text((base or small_curl("full")).to_toml())
    path = tmp_path / name
    path.write_text(body)
    return path


def _csv_rows(out: Path) -> list[dict[str, str]]:
    with open(out / "summary.csv", newline="") as fh:
        return list(csv.DictReader(fh))


# -- sweep files ---------------------------------------------------------------------------------------


def test_grid_and_cases_make_every_combination(tmp_path):
    path = _write_sweep(tmp_path, """
base = "base.toml"
[grid]
"fatigue.S" = [10.0, 0.0]
costs.torque.weight = [1.0, 2.0, 3.0]
[[cases]]
"horizon.kind" = "full"
[[cases]]
horizon.kind = "sliding"
horizon.cycles = 2
""")
    sweep = Sweep.from_file(path)
    jobs = sweep.jobs()
    assert len(jobs) == 2 * 2 * 3
    assert sweep.keys == ["horizon.kind", "horizon.cycles", "fatigue.S", "costs.torque.weight"]
    assert [j.case for j in jobs] == [0] * 6 + [1] * 6
    j = jobs[7]
    assert j.values == {"horizon.kind": "sliding", "horizon.cycles": 2, "fatigue.S": 10.0, "costs.torque.weight": 2.0}
    assert j.study.data["fatigue"]["S"] == 10.0 and j.study.data["costs"]["torque"]["weight"] == 2.0
    assert j.study.horizon["kind"] == "sliding" and j.study.horizon["cycles"] == 2
    # ids: the hash of the resolved study's TOML text, stable across reads, distinct
    assert j.text == j.study.to_toml() and j.id == hashlib.sha256(j.text.encode()).hexdigest()[:16]
    assert [x.id for x in Sweep.from_file(path).jobs()] == [x.id for x in jobs]
    assert len({x.id for x in jobs}) == len(jobs)
    assert j.file == f"{j.id}.h5"


def test_inline_base_gives_the_same_jobs_as_a_base_file(tmp_path):
    study = small_curl("full")
    from_file = Sweep.from_file(_write_sweep(tmp_path, 'base = "base.toml"\n[grid]\n"fatigue.S" = [1.0, 2.0]\n'))
    inline = Sweep.from_dict({"base": study.data, "grid": {"fatigue.S": [1.0, 2.0]}})
    assert [j.id for j in inline.jobs()] == [j.id for j in from_file.jobs()]
    # no grid and no cases: the base study alone
    (alone,) = Sweep.from_dict({"base": study.data}).jobs()
    assert alone.text == study.to_toml() and alone.values == {} and alone.case is None


def test_a_table_adds_where_the_base_has_none(tmp_path):
    """``"fatigue.joints" = {...}`` sets a table the base lacks; tables the base has are merged into."""
    sweep = Sweep.from_file(_write_sweep(tmp_path, """
base = "base.toml"
[[cases]]
"fatigue.joints" = { elbow = { S = 0.0 } }
"costs.posture" = { weight = 5.0 }
"""))
    (job,) = sweep.jobs()
    assert job.study.data["fatigue"]["joints"]["elbow"]["S"] == 0.0
    assert job.study.data["costs"]["posture"]["weight"] == 5.0
    assert job.study.data["costs"]["posture"]["joints"] == ["shoulder"]  # kept from the base


def test_paper_reproduce_sweep_is_the_shipped_studies():
    sweep = Sweep.from_file(REPO / "studies" / "paper_reproduce.toml")
    jobs = sweep.jobs()
    assert len(jobs) == 12
    kinds = {(j.values["labels.cost"], j.study.horizon["kind"], j.values["fatigue.S"]) for j in jobs}
    assert len(kinds) == 12
    for job in jobs:
        horizon = "full" if job.study.horizon["kind"] == "max-cycles" else "sliding"
        shipped = Study.from_file(REPO / "studies" / f"curl_{horizon}_{job.values['labels.cost']}_paper.toml")
        assert job.text == shipped.replace({"fatigue.S": job.values["fatigue.S"]}).to_toml()


BAD_SWEEPS = [
    ('base = "missing.toml"\n', "base study not found: 'missing.toml'"),
    ('[grid]\n"fatigue.S" = [1.0]\n', "missing key 'base'"),
    ('base = "base.toml"\n[grid]\n"fatigue.Q" = [1.0]\n', "fatigue.Q"),
    ('base = "base.toml"\n[grid]\n"nothing.at.all" = [1]\n', "'nothing.at.all' does not exist"),
    ('base = "base.toml"\n[grid]\n"fatigue.S" = []\n', "[grid] fatigue.S is an empty list"),
    ('base = "base.toml"\n[grid]\n"fatigue.S" = 1.0\n', "expected a list of values"),
    ('base = "base.toml"\n[grid]\n"fatigue.S" = [1.0, "ten"]\n', "[grid] fatigue.S = 'ten': fatigue.S = 'ten': expected"),
    ('base = "base.toml"\n[grid]\n"task.intervals_per_cycle" = [1.5]\n', "task.intervals_per_cycle = 1.5: expected an integer"),
    ('base = "base.toml"\n[[cases]]\n"horizon.kind" = "sideways"\n', "cases[0]: horizon.kind = 'sideways'"),
    ('base = "base.toml"\ncases = []\n', "cases is an empty list"),
    ('base = "base.toml"\n[[cases]]\n', "cases[0] is empty"),
    ('base = "base.toml"\n[grid]\n"fatigue.S" = [1.0, 1.0]\n', "are the same study"),
    ('base = "base.toml"\n[grid]\n"fatigue.S" = [1.0]\n[[cases]]\n"fatigue.S" = 2.0\n', "both set 'fatigue.S'"),
    ('base = "base.toml"\n[grid]\n"horizon.kind" = ["sliding"]\n"horizon.advance" = [1, 2]\n', "horizon.advance = 2"),
    ('base = "base.toml"\ngird = 1\n', "unknown key 'gird'"),
    ('base = "base.toml"\n[grid\n', "not valid TOML"),
]


@pytest.mark.parametrize("body, message", BAD_SWEEPS)
def test_bad_sweep_files(tmp_path, body, message):
    path = _write_sweep(tmp_path, body)
    with pytest.raises(SweepError) as info:
        Sweep.from_file(path)
    text = str(info.value)
    assert message in text, text
    assert "\n" not in text and text.startswith(str(path))


def test_bad_sweep_on_the_command_line_is_one_line(tmp_path, capsys):
    path = _write_sweep(tmp_path, 'base = "base.toml"\n[grid]\n"fatigue.S" = []\n')
    assert main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "empty list" in err
    assert not (tmp_path / "out").exists()  # nothing done
    assert main(["sweep", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "out")]) == 2
    assert "sweep file not found" in capsys.readouterr().err
    good = _write_sweep(tmp_path, 'base = "base.toml"\n', name="good.toml")
    (tmp_path / "afile").write_text("x")
    assert main(["sweep", str(good), "--out", str(tmp_path / "afile")]) == 2
    assert "is a file; expected a folder" in capsys.readouterr().err
    assert main(["sweep", str(good), "--out", str(tmp_path / "out"), "--queue", "short"]) == 2
    assert "--queue applies to --slurm only" in capsys.readouterr().err
    assert main(["sweep", str(good), "--out", str(tmp_path / "out"), "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"]) == 2
    assert "--workers applies to" in capsys.readouterr().err


# -- running: in-process cluster (errors, damaged files, resume) -----------------------------------------


@pytest.fixture(scope="module")
def thread_client():
    """A Dask client with one single-threaded worker process on 127.0.0.1. (Workers on threads
    of this process would write HDF5 files while this thread writes the summary: HDF5 is not
    built thread-safe, and that crashed with a segmentation fault.)"""
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None) as cluster, \
            Client(cluster) as client:
        yield client


def test_errors_are_rows_and_damaged_files_are_run_again(tmp_path, thread_client):
    path = _write_sweep(tmp_path, 'base = "base.toml"\n[grid]\n"model.urdf" = ["arm26", "/nonexistent/robot.urdf"]\n')
    jobs = Sweep.from_file(path).jobs()
    out = tmp_path / "out"
    out.mkdir()
    (out / jobs[0].file).write_bytes(b"not a result file")  # a damaged file is not done
    partial_path(out, jobs[0].id).write_bytes(b"half a file")  # nor is a partial one
    outcome = run_sweep(jobs, out, thread_client)
    assert outcome.ran == 2 and outcome.errors == 1
    good, bad = (outcome.rows[j.id] for j in jobs)
    assert good["status"] == "converged" and good["repetitions"] == 1 and good["iterations"] > 0
    assert read_job_file(out / jobs[0].file, jobs[0].text)["iterations"] == good["iterations"]
    assert bad["status"] == "error" and "nonexistent" in bad["error"] and bad["file"] == ""
    assert sorted(p.name for p in out.iterdir()) == sorted([jobs[0].file, "summary.csv", "summary.h5"])
    rows = _csv_rows(out)
    assert [r["status"] for r in rows] == ["converged", "error"] and "nonexistent" in rows[1]["error"]
    assert rows[0]["model.urdf"] == "arm26" and rows[0]["file"] == jobs[0].file
    with h5py.File(out / "summary.h5", "r") as h5:
        table = h5["summary"][()]
        assert list(h5["summary"].attrs["columns"]) == list(rows[0])
    assert [s.decode() for s in table["status"]] == ["converged", "error"]
    assert table["iterations"][0] == good["iterations"]
    # rerun: the converged job is reused, the failed one tried again
    again = run_sweep(jobs, out, thread_client)
    assert again.ran == 1 and again.rows[jobs[0].id]["reused"] is True
    # the stored study must be the job's: a file with another study is not reused
    other = Sweep.from_dict({"base": small_curl("full", S=3.0).data}).jobs()[0]
    with pytest.raises(Exception, match="another study"):
        read_job_file(out / jobs[0].file, other.text)


def test_sweep_plot_from_the_summary(tmp_path):
    path = _write_sweep(tmp_path, """
base = "base.toml"
[grid]
"fatigue.S" = [0.0, 5.0, 10.0]
[[cases]]
name = "a"
"labels.cost" = "a"
[[cases]]
name = "b"
"labels.cost" = "b"
""")
    jobs = Sweep.from_file(path).jobs()
    out = tmp_path / "out"
    out.mkdir()
    rows = {j.id: {"job": j.id, "status": "converged" if j.index != 2 else "not converged", "repetitions": j.index,
                   "objective": 1.0, "iterations": 3, "file": j.file} for j in jobs}
    write_summary(out, jobs, rows)
    keys, columns, table = read_summary(out)
    assert keys == ["name", "labels.cost", "fatigue.S"] and columns[len(keys):] == list(SUMMARY_COLUMNS)
    assert table[1]["fatigue.S"] == 5.0 and table[1]["repetitions"] == 1 and table[4]["case"] == 1
    assert main(["plot", str(out), "--out", str(tmp_path / "fig")]) == 0
    # labels.cost follows from name in every case: drawn against fatigue.S and name only
    assert sorted(p.name for p in (tmp_path / "fig").iterdir()) == [
        "sweep_fatigue_S.pdf", "sweep_fatigue_S.png", "sweep_name.pdf", "sweep_name.png"]


# -- (a) a real scheduler and two workers; one killed while it holds a job ------------------------------


def _listening(pids: list[int]) -> list[tuple[int, str, int]]:
    import psutil

    found = []
    for pid in pids:
        try:
            procs = [psutil.Process(pid)]
            procs += procs[0].children(recursive=True)
        except psutil.NoSuchProcess:
            continue
        for p in procs:
            try:
                found += [(p.pid, c.laddr.ip, c.laddr.port) for c in p.net_connections(kind="inet") if c.status == psutil.CONN_LISTEN]
            except psutil.NoSuchProcess:
                pass
    return found


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=15)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def test_scheduler_sweep_survives_a_killed_worker_and_resumes(tmp_path):
    from distributed import Client

    base = small_curl("sliding", cycles=2, max_cycles=6)
    sweep_file = _write_sweep(tmp_path, 'base = "base.toml"\n[grid]\n"fatigue.S" = [10.0, 0.0]\n"costs.torque.weight" = [1.0, 2.0]\n',
                              base=base)
    jobs = Sweep.from_file(sweep_file).jobs()
    out = tmp_path / "out"
    scheduler_file = tmp_path / "scheduler.json"
    env = _env()
    logs = [open(tmp_path / f"{name}.log", "w") for name in ("scheduler", "worker1", "worker2")]
    procs = [subprocess.Popen([str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address", "127.0.0.1:0",
                               "--scheduler-file", str(scheduler_file)], env=env, stdout=logs[0], stderr=subprocess.STDOUT)]
    try:
        deadline = time.monotonic() + 120  # bounds, not delays: under load a worker starts slowly
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        for i in (1, 2):
            procs.append(subprocess.Popen([str(BIN / "dask"), "worker", "--scheduler-file", str(scheduler_file), "--nthreads", "1",
                                           "--nworkers", "1", "--host", "127.0.0.1", "--dashboard-address", "127.0.0.1:0", "--name", f"w{i}"],
                                          env=env, stdout=logs[i], stderr=subprocess.STDOUT))
        with Client(scheduler_file=str(scheduler_file), timeout="120s") as client:
            client.wait_for_workers(2, timeout=40)
            pids = client.run(os.getpid)  # worker address -> worker process id
            # nothing listens beyond 127.0.0.1 (scheduler, nannies, workers)
            sockets = _listening([p.pid for p in procs])
            assert sockets and all(ip == "127.0.0.1" for _, ip, _ in sockets), sockets
            address = client.scheduler.address
            cmd = [sys.executable, "-m", "fatigue_pin.cli.main", "sweep", str(sweep_file), "--out", str(out), "--scheduler", address]
            run = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp_path)
            killed = None
            deadline = time.monotonic() + 60
            while killed is None and run.poll() is None and time.monotonic() < deadline:
                for addr, keys in client.processing().items():
                    if addr in pids and any(str(k).startswith("fatigue-pin-job-") for k in keys):
                        time.sleep(0.3)  # well into the job
                        held = [k for k in client.processing().get(addr, ()) if str(k).startswith("fatigue-pin-job-")]
                        if held:
                            os.kill(pids[addr], signal.SIGKILL)
                            killed = (addr, held)
                        break
                time.sleep(0.05)
            stdout, _ = run.communicate(timeout=600)  # a guard against a hang, not a time limit
        print(f"killed {killed}\n{stdout}")
        assert killed is not None, f"no worker was seen holding a job:\n{stdout}"
        assert run.returncode == 0, stdout
        assert "4 jobs: 0 already done, 4 to run" in stdout
        rows = _csv_rows(out)
        assert len(rows) == 4 and all(r["status"] == "converged" for r in rows), rows
        assert [r["job"] for r in rows] == [j.id for j in jobs]
        for job in jobs:  # 4 complete, valid files, nothing partial left
            assert read_job_file(out / job.file, job.text)["status"] == "converged"
            assert read_run(out / job.file).study == job.text
        assert sorted(p.name for p in out.iterdir()) == sorted([j.file for j in jobs] + ["summary.csv", "summary.h5"])

        # the same command again: every job is reused, nothing is solved (the workers are not needed)
        again = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600, cwd=tmp_path)
        assert again.returncode == 0, again.stdout + again.stderr
        assert "4 jobs: 4 already done, 0 to run" in again.stdout and "(0 run now)" in again.stdout
        assert all(r["reused"] == "true" for r in _csv_rows(out))
    finally:
        _stop(procs)
        for log in logs:
            log.close()


def test_local_cluster_listens_on_127_0_0_1_only():
    import psutil
    from distributed import Client

    from fatigue_pin.sweep.cluster import local_cluster

    with local_cluster(2) as cluster, Client(cluster) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        assert all(w["nthreads"] == 1 for w in client.scheduler_info()["workers"].values())
        me = psutil.Process()
        sockets = _listening([me.pid])
    assert sockets and all(ip == "127.0.0.1" for _, ip, _ in sockets), sockets


# -- (b) the default local cluster gives what single runs give ------------------------------------------


def test_local_sweep_equals_single_runs(tmp_path, capsys):
    sweep_file = _write_sweep(tmp_path, """
base = "base.toml"
[[cases]]
"horizon.kind" = "full"
[[cases]]
"horizon.kind" = "sliding"
"horizon.cycles" = 2
"horizon.max_cycles" = 3
[[cases]]
"horizon.kind" = "max-cycles"
"horizon.max_cycles" = 2
""", base=small_curl("full", cycles=2))
    jobs = Sweep.from_file(sweep_file).jobs()
    out = tmp_path / "out"
    assert main(["sweep", str(sweep_file), "--out", str(out), "--cache", str(tmp_path / "cache")]) == 0
    printed = capsys.readouterr().out
    assert "3 jobs: 0 already done, 3 to run" in printed and "3 converged" in printed
    rows = {r["job"]: r for r in _csv_rows(out)}
    for job in jobs:
        alone = tmp_path / f"alone_{job.id}.h5"
        (tmp_path / f"{job.id}.toml").write_text(job.text)
        code = main(["run", str(tmp_path / f"{job.id}.toml"), "--out", str(alone)])
        kind = job.study.horizon["kind"]
        single = read_run(alone, job.study.run_name())
        swept = read_run(out / job.file, job.study.run_name())
        row = rows[job.id]
        if kind == "sliding":
            assert code == 0
            assert int(row["repetitions"]) == single.attrs["repetitions"]
            assert float(row["objective"]) == pytest.approx(float(single.cycle_costs.sum()), rel=1e-12)
        elif kind == "full":
            assert code == 0 and int(row["repetitions"]) == single.n_cycles
            assert float(row["objective"]) == pytest.approx(single.attrs["objective"], rel=1e-12)
        else:
            assert int(row["repetitions"]) == single.n_cycles == 2
            assert float(row["objective"]) == pytest.approx(single.attrs["objective"], rel=1e-12)
        assert swept.attrs["iterations"] == single.attrs["iterations"]
        if kind != "max-cycles":
            assert int(row["iterations"]) == single.attrs["iterations"]
        np.testing.assert_allclose(swept.q, single.q, rtol=0, atol=1e-10)
        assert swept.study == single.study == job.text
    capsys.readouterr()


# -- (c) SLURM ---------------------------------------------------------------------------------------------


def test_slurm_job_script_carries_the_request():
    pytest.importorskip("dask_jobqueue")
    from fatigue_pin.sweep.cluster import SlurmSettings, slurm_cluster

    cluster = slurm_cluster(SlurmSettings(queue="short", walltime="00:30:00", cores=4, memory="8GB"), host="127.0.0.1")
    try:
        script = cluster.job_script()
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
    finally:
        cluster.close()
    assert "#SBATCH -p short" in script
    assert "#SBATCH -t 00:30:00" in script
    assert "#SBATCH --cpus-per-task=4" in script
    assert "#SBATCH --mem=8G" in script
    assert "--nworkers 4" in script and "--nthreads 1" in script  # one single-threaded worker per core
    assert sys.executable in script and "OMP_NUM_THREADS=1" in script


def test_slurm_options_reach_the_cluster(tmp_path, monkeypatch):
    import fatigue_pin.sweep.cluster as sweep_module

    seen = {}

    class Stop(Exception):
        pass

    def fake(*args, **kwargs):
        seen["args"] = args
        raise Stop

    monkeypatch.setattr(sweep_module, "slurm_cluster", fake)
    path = _write_sweep(tmp_path, 'base = "base.toml"\n')
    with pytest.raises(Stop):
        sweep_command(path, tmp_path / "out", slurm=True, queue="long", walltime="02:00:00", cores=8, memory="16GB",
                      progress=lambda _: None)
    assert seen["args"] == (sweep_module.SlurmSettings(queue="long", walltime="02:00:00", cores=8, memory="16GB"),)
    with pytest.raises(Stop):  # options left out: the defaults of SlurmSettings
        sweep_command(path, tmp_path / "out", slurm=True, progress=lambda _: None)
    assert seen["args"] == (sweep_module.SlurmSettings(),)


def test_nothing_to_run_needs_no_cluster(tmp_path, thread_client):
    """A sweep whose files are all complete starts no cluster (here: an unreachable scheduler)."""
    path = _write_sweep(tmp_path, 'base = "base.toml"\n')
    jobs = Sweep.from_file(path).jobs()
    run_sweep(jobs, tmp_path / "out", thread_client)
    lines = []
    assert sweep_command(path, tmp_path / "out", scheduler="tcp://127.0.0.1:9", progress=lines.append) == 0
    assert lines[0].startswith("1 jobs: 1 already done, 0 to run")
    assert not math.isnan(float(_csv_rows(tmp_path / "out")[0]["objective"]))


# -- closed-loop studies -------------------------------------------------------------------------------


def test_a_closed_loop_study_sweeps_like_any_study(tmp_path, thread_client):
    """A sweep whose base is a closed-loop study (the small curl as a 3-cycle window against a
    plant, 2 cycles): its plant's fatigue rate swept over 2 points on the Dask worker. Each job
    is the closed loop `run_mpc` gives alone (same plant motion, repetitions and re-plans), in its
    own complete file; the summary has the swept key."""
    from conftest import small_mpc_study
    from fatigue_pin.io.mpc_study import MpcStudy, run_mpc

    base = MpcStudy.from_toml(small_mpc_study(seed=1, max_cycles=3)).replace({"horizon.cycles": 2, "horizon.max_cycles": 2})
    path = _write_sweep(tmp_path, 'base = "base.toml"\n[grid]\n"plant.fatigue.F" = [0.456, 2.0]\n', base=base)
    jobs = Sweep.from_file(path).jobs()
    assert [type(j.study) for j in jobs] == [MpcStudy, MpcStudy]
    assert [j.study.plant_study.data["fatigue"]["F"] for j in jobs] == [0.456, 2.0]
    assert all(j.study.study.data == base.study.data for j in jobs)  # the controller's model is the base's
    out = tmp_path / "out"
    out.mkdir()
    outcome = run_sweep(jobs, out, thread_client)
    assert outcome.ran == 2 and outcome.errors == 0, outcome.rows
    rows = _csv_rows(out)
    assert [r["plant.fatigue.F"] for r in rows] == ["0.456", "2.0"]
    for job in jobs:
        row = outcome.rows[job.id]
        assert row["status"] == "converged" and row["error"] == "", row
        assert read_job_file(out / job.file, job.text)["repetitions"] == row["repetitions"]  # complete, its study
        swept = read_run(out / job.file, job.study.run_name())
        alone = run_mpc(MpcStudy.from_toml(job.text))
        assert swept.study == job.text and swept.name == "mpc/" + base.study.name
        assert row["repetitions"] == swept.attrs["repetitions"] == alone.attrs["repetitions"]
        assert row["iterations"] == alone.attrs["iterations"]
        np.testing.assert_allclose(swept.q, alone.q, rtol=0, atol=1e-10)
    tired, fresh = (read_run(out / j.file, j.study.run_name()) for j in reversed(jobs))
    assert tired.fatigue["mf"][-1].max() > fresh.fatigue["mf"][-1].max()  # the swept key reached the plant
