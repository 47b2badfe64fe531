"""SIGINT and SIGTERM during a full-horizon solve (issue 25): ``fatigue-pin`` exits with 130 and
143, says so in one line, and the converged run of the same name already in the file is left
byte for byte as it was (the interrupted iterate is not stored)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from conftest import make_run, small_curl
from fatigue_pin.io.results import read_run, write_run



def _env() -> dict[str, str]:
    """The child imports the fatigue_pin this process imported (installed, or a tree on PYTHONPATH)."""
    import fatigue_pin

    home = str(Path(fatigue_pin.__file__).resolve().parents[1])
    return {**os.environ, "PYTHONPATH": home + os.pathsep + os.environ.get("PYTHONPATH", ""), "OMP_NUM_THREADS": "1"}


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_during_a_full_solve_keeps_the_converged_run(tmp_path, sig, code):
    study = tmp_path / "curl.toml"
    study.write_text(small_curl("full").to_toml())
    out = tmp_path / "runs.h5"
    write_run(out, make_run("full/keep"))
    before = out.read_bytes()
    proc = subprocess.Popen([sys.executable, "-c", "import sys; from fatigue_pin.cli.main import main; sys.exit(main())", "run", str(study), "--name", "full/keep",
                             "--set", "horizon.cycles=40", "--set", "solver.compile=false", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(), cwd=tmp_path)
    assert proc.stdout is not None
    sent = threading.Event()
    # 40 cycles uncompiled: IPOPT iterates for tens of seconds on any machine, so the signal sent a
    # second after the solve has started comes while it iterates (12 compiled cycles could end
    # within that second on a fast machine)
    for line in proc.stdout:  # the solve has started: IPOPT is iterating
        if "solving" in line and not sent.is_set():
            time.sleep(1.0)
            proc.send_signal(sig)
            sent.set()
    err = proc.stderr.read() if proc.stderr is not None else ""
    assert proc.wait(timeout=300) == code, err
    assert sent.is_set()
    assert err.strip().count("\n") == 0 and f"interrupted by {sig.name}" in err, err
    assert "Traceback" not in err
    assert out.read_bytes() == before
    assert read_run(out, "full/keep").n_cycles == 2
