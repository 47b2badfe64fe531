"""Every Python block and every shell command of README.md and docs/*.md runs, as the tutorial
notebooks do (tests/test_tutorials.py): on small settings, declared here per snippet, in a fresh
folder where ``studies/`` is the repository's.

* A ```python block runs in a subprocess, after the prelude :data:`PYTHON` gives it (what a
  fragment takes as defined on its page, e.g. ``base`` or ``problem``) and with its shrinking
  substitutions (e.g. 10 intervals per cycle, no compile).
* A ``fatigue-pin ...`` line (in a fenced or an indented block) is either a command, run in the
  order of its page with :data:`SMALL` appended to the commands that solve, or a synopsis (it has
  ``[...]``, ``|`` or a placeholder in capitals, e.g. ``STUDY.toml``): its sub-command's ``--help``
  must then name every option it shows.
* :data:`NOT_RUN` lists what cannot run here, each with its reason; it is short.

Every snippet is one of these: :func:`test_every_snippet_is_run_or_listed` fails on a new snippet
that is neither.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: Study keys that make a solve small: 10 intervals per cycle, 2 RK4 substeps, no compile, at
#: most 3 cycles kept (the window of the paper's sliding studies).
SMALL_KEYS = {"task.intervals_per_cycle": 10, "transcription.substeps": 2, "solver.compile": False, "horizon.max_cycles": 3}
SMALL = [a for k, v in SMALL_KEYS.items() for a in ("--set", f"{k}={str(v).lower()}")]
_SMALL_PY = repr(SMALL_KEYS)

#: The prelude and the substitutions of each Python block, by (page, index of the block on it).
PYTHON: dict[tuple[str, int], dict] = {
    ("getting-started.md", 0): {"subs": [('Study.from_file("studies/curl_sliding_fatigue_paper.toml")',
                                          f'Study.from_file("studies/curl_sliding_fatigue_paper.toml").replace({_SMALL_PY})')]},
    ("api.md", 0): {"subs": [('study.replace({"horizon.max_cycles": 5})', f'study.replace({_SMALL_PY})')]},
    ("extending.md", 0): {"prelude": "from fatigue_pin.io.study import Study\n"
                                     f"base = Study.from_file('studies/curl_full_fatigue_paper.toml').replace({_SMALL_PY}).problem()\n"},
    ("extending.md", 1): {"prelude": "from fatigue_pin.io.study import Study\n"
                                     f"problem = Study.from_file('studies/curl_full_fatigue_paper.toml').replace({_SMALL_PY}).problem()\n"},
    ("extending.md", 2): {"prelude": "from dataclasses import dataclass\nfrom typing import ClassVar\nimport casadi as ca\nimport numpy as np\n"
                                     "from fatigue_pin.fatigue.interface import FatigueModel\nfrom fatigue_pin.fatigue.models import XiaFatigue\n"
                                     "from fatigue_pin.ocp.problem import Problem\nfrom fatigue_pin.io.study import Study\n"
                                     f"study = Study.from_file('studies/curl_full_fatigue_paper.toml').replace({_SMALL_PY})\n"
                                     "model, task, costs = study.model(), study.task(), study.costs()\n",
                          "subs": [('XiaFatigue(...)', 'XiaFatigue(F=0.456, R=0.00094, LD=10.0, LR=10.0)')]},
    ("mpc.md", 0): {"subs": [('changes={"mpc.estimator": "open-loop"}', f'changes={{"mpc.estimator": "open-loop", **{_SMALL_PY}}}')]},
    ("replay.md", 0): {},   # results.h5 is made by the fixture
    ("verify.md", 0): {},
    ("muscles.md", 0): {},  # the geometry only: no solve
    ("muscles.md", 1): {},  # the muscle torque at one state: no solve
    ("muscles.md", 2): {},  # a muscle study and its layer: no solve
    ("motors.md", 0): {},  # a preset's steady state: no solve
    ("results.md", 0): {},  # results/forward/forward_studies.h5 is made by the fixture
    ("studies.md", 0): {"prelude": "from dataclasses import dataclass\nfrom fatigue_pin.core.settings import is_number, setting\n"
                                   "@dataclass(frozen=True)\nclass Example:\n", "indent": True},
}

#: Snippets that do not run here, and why: (page, the snippet's first line) -> reason.
NOT_RUN: dict[tuple[str, str], str] = {
    ("sweeps.md", "fatigue-pin sweep sweeps/stabiliser.toml --out /scratch/$USER/stabiliser --cache /scratch/$USER/fp-cache --slurm --queue compute --walltime 02:00:00 --cores 8 --memory 16GB --interface ib0"):
        "needs a SLURM cluster (partition compute, interface ib0)",
    ("sweeps.md", "fatigue-pin sweep SWEEP.toml --out DIR --scheduler tcp://127.0.0.1:8786"):
        "needs a running dask scheduler at that address",
}


# -- extraction -------------------------------------------------------------------------------------


def python_blocks(text: str) -> list[str]:
    """The ```python blocks of a page, in order."""
    return re.findall(r"^```python\n(.*?)^```", text, re.M | re.S)


def commands(text: str) -> list[str]:
    """The ``fatigue-pin`` lines of a page (fenced or indented blocks), continuations joined,
    comments cut, in order."""
    out = []
    lines = text.split("\n")
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        if re.match(r"^(\.venv/bin/)?fatigue-pin ", line):
            while line.endswith("\\") and i + 1 < len(lines):
                i += 1
                line = line[:-1].rstrip() + " " + lines[i].strip()
            out.append(re.sub(r"\s+#.*$", "", line).strip())
        i += 1
    return out


def is_synopsis(command: str) -> bool:
    """A usage line rather than a command: ``[...]``, ``|`` or a placeholder in capitals."""
    return bool(re.search(r"\[|\||\b[A-Z][A-Z_]+(\.[a-z0-9]+)?\b", command.replace("$USER", "")))


def _snippets() -> list[tuple[str, str, int, str]]:
    """(page, kind, index, text) of every snippet."""
    out = []
    for page in PAGES:
        text = page.read_text()
        out += [(page.name, "python", k, b) for k, b in enumerate(python_blocks(text))]
        out += [(page.name, "command", k, c) for k, c in enumerate(commands(text))]
    return out


SNIPPETS = _snippets()


# -- running ----------------------------------------------------------------------------------------


def _env() -> dict[str, str]:
    """The children import the fatigue_pin this process imported (installed, or a tree on
    PYTHONPATH), not the source tree beside the docs, which has no compiled extension."""
    import fatigue_pin

    home = str(Path(fatigue_pin.__file__).resolve().parents[1])
    return dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=home + os.pathsep + os.environ.get("PYTHONPATH", ""))


_MAIN = "import sys; from fatigue_pin.cli.main import main; sys.exit(main(sys.argv[1:]))"


def _cli(args: list[str], cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", _MAIN, *args], cwd=cwd, env=_env(), capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """A folder with ``studies/`` and the files the pages take as given: ``results.h5`` with the
    runs ``full/fatigue-torque_S10`` and ``sliding/fatigue-torque_S10`` (small curls), and the
    forward studies' file ``results/forward/forward_studies.h5`` of ``fatigue-pin forward
    --out results/forward`` (README.md), on a short grid (6 s, study 2 at S = 10 only). Built once
    for all workers (:func:`conftest.built_once`); the tests read it or work in a copy."""
    from conftest import built_once

    return built_once(tmp_path_factory, "docs", _prepare_folder)


def _prepare_folder(tmp: Path) -> None:
    tmp.mkdir()
    (tmp / "studies").symlink_to(ROOT / "studies")
    for kind in ("full", "sliding"):
        r = _cli(["run", f"studies/curl_{kind}_fatigue-torque_paper.toml", "--out", "results.h5", "--name", f"{kind}/fatigue-torque_S10",
                  *SMALL, *(["--set", "horizon.cycles=1"] if kind == "full" else [])], tmp)
        assert r.returncode == 0, r.stderr
    (tmp / "results" / "demo").mkdir(parents=True)  # the demo's run, as the pages that read it expect
    r = _cli(["run", "studies/curl_sliding_fatigue-torque_paper.toml", "--out", "results/demo/sliding.h5", *SMALL], tmp)
    assert r.returncode == 0, r.stderr
    from fatigue_pin.io.study import Study
    from fatigue_pin.paper.forward import ForwardStudyConfig, compute_forward_studies, write_h5

    (tmp / "results" / "forward").mkdir()
    forward = compute_forward_studies(ForwardStudyConfig(t_end=6.0, n_eval=601, study2_S=(10.0,)), progress=None)
    write_h5(forward, tmp / "results" / "forward" / "forward_studies.h5")
    base = Study.from_file(ROOT / "studies" / "curl_full_fatigue-torque_paper.toml").replace({**SMALL_KEYS, "horizon.cycles": 1})
    (tmp / "small_base.toml").write_text(base.to_toml())
    (tmp / "small_sweep.toml").write_text('base = "small_base.toml"\n[grid]\n"fatigue.S" = [0.0, 10.0]\n')


def _python_source(page: str, index: int, block: str) -> str:
    spec = PYTHON[(page, index)]
    for old, new in spec.get("subs", []):
        assert old in block, f"{page} block {index}: the substitution {old!r} no longer matches; update PYTHON"
        block = block.replace(old, new)
    if spec.get("indent"):
        block = "".join("    " + line + "\n" for line in block.splitlines())
    return spec.get("prelude", "") + block


PY_CASES = [(p, k, t) for p, kind, k, t in SNIPPETS if kind == "python"]


@pytest.mark.parametrize("page, index, block", PY_CASES, ids=[f"{p}-{k}" for p, k, _ in PY_CASES])
def test_python_block_runs(page, index, block, folder, tmp_path):
    import shutil

    if (page, block.splitlines()[0]) in NOT_RUN:
        pytest.skip(NOT_RUN[(page, block.splitlines()[0])])
    source = _python_source(page, index, block)
    work = tmp_path / "work"  # a copy: what a block writes stays its own
    shutil.copytree(folder, work, symlinks=True)
    r = subprocess.run([sys.executable, "-c", source], cwd=work, env=_env(), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"{page} block {index} failed:\n{source}\n--- stderr:\n{r.stderr[-3000:]}"


def _options(command: str) -> list[str]:
    return sorted(set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", command)))


SYN_CASES = [(p, t) for p, kind, _, t in SNIPPETS if kind == "command" and is_synopsis(t) and (p, t) not in NOT_RUN]


@pytest.mark.parametrize("page, command", SYN_CASES, ids=[f"{p}-{k}" for k, (p, _) in enumerate(SYN_CASES)])
def test_synopsis_names_real_options(page, command, folder):
    words = shlex.split(command.replace("$USER", "user"))[1:]
    sub = [w for w in words if not w.startswith("-")][:2]
    help_args = sub[:2] if sub[:1] == ["solve"] else sub[:1]
    r = _cli([*help_args, "--help"], folder, timeout=60)
    assert r.returncode == 0, f"{page}: {command}: {r.stderr}"
    missing = [o for o in _options(command) if o not in r.stdout]
    assert not missing, f"{page}: {command}: `fatigue-pin {' '.join(help_args)} --help` has no {missing}"


#: Text substitutions of the commands that would run long here, by (page, command).
COMMANDS: dict[tuple[str, str], list[tuple[str, str]]] = {
    ("README.md", "fatigue-pin solve full --cycles 4 --cost fatigue-torque --stabilization 10 --out full.h5"):
        [("--cycles 4", "--cycles 1 --no-compile")],
    ("getting-started.md", ".venv/bin/fatigue-pin demo"): [("demo", "demo --max-cycles 3")],
    ("README.md", "fatigue-pin rerun ur5.h5 --out again.h5"): [("ur5.h5", "results/demo/sliding.h5")],  # its run line is a synopsis
    ("README.md", "fatigue-pin plot sliding.h5 --out figures/"): [("sliding.h5", "results/demo/sliding.h5")],  # likewise
    ("replay.md", "fatigue-pin replay results.h5 --run full/fatigue-torque_S10 --cycle 12 --html c12.html"): [("--cycle 12", "--cycle 1")],
    ("robot-study.md", "fatigue-pin run studies/ur5_carry.toml --out carry.h5 --set horizon.kind='\"full\"' --set horizon.cycles=22"):
        [("horizon.cycles=22", "horizon.cycles=1")],
    ("sweeps.md", "fatigue-pin sweep studies/paper_reproduce.toml --out results/paper_sweep"):
        [("studies/paper_reproduce.toml", "small_sweep.toml"), ("--out", "--workers 1 --out")],
}
#: Arguments after :data:`SMALL`, by (page, command): the pendulum's LD = 100 needs RK4 steps of at
#: most 0.025 s, 4 per interval of the small grid.
AFTER: dict[tuple[str, str], list[str]] = {
    ("porting.md", "fatigue-pin run studies/bioptim_pendulum_xia.toml --out pendulum.h5"): ["--set", "transcription.substeps=4"],
    ("porting.md", "fatigue-pin run studies/bioptim_pendulum_xia.toml --out fine.h5 --set transcription.substeps=20"):
        ["--set", "transcription.substeps=20"],
    # the static arm's Gauss-Newton Hessian is a derivative block: uncompiled, the blocks evaluated by CasADi
    ("porting.md", "fatigue-pin run studies/bioptim_static_arm_xia.toml --out arm.h5"): ["--set", "solver.derivative_blocks=true"],
    # the UR5 carry's sliding run as one window of one cycle (the page's later commands read its run)
    ("robot-study.md", "fatigue-pin run studies/ur5_carry.toml --out carry.h5"):
        ["--set", "horizon.cycles=1", "--set", "horizon.max_cycles=1"],
}
#: Commands that take minutes even on small settings: marked slow.
SLOW = {("getting-started.md", ".venv/bin/fatigue-pin demo"),
        ("mpc.md", "fatigue-pin mpc studies/ur5_mpc.toml --out ur5_mpc.h5 --set horizon.max_cycles=4")}  # > 10 min on 2 cores


def _shrunk(page: str, command: str) -> list[str]:
    """The command's arguments after its substitutions, with :data:`SMALL` (then :data:`AFTER`) after
    ``run`` and ``mpc``."""
    for old, new in COMMANDS.get((page, command), []):
        assert old in command, f"{page}: {command}: the substitution {old!r} no longer matches"
        command = command.replace(old, new, 1)
    words = shlex.split(command)[1:]
    if words[0] in ("run", "mpc"):
        words += SMALL + AFTER.get((page, command), [])
    return words


RUN_CASES = [(p, t) for p, kind, _, t in SNIPPETS if kind == "command" and not is_synopsis(t) and (p, t) not in NOT_RUN]
_PAGES_RUN = sorted({p for p, _ in RUN_CASES})


@pytest.mark.parametrize("page", _PAGES_RUN)
def test_commands_of_a_page_run_in_order(page, folder, tmp_path):
    """A page's commands, in its order, in a copy of the prepared folder (a later command reads
    what an earlier one wrote, e.g. ``rerun curl.h5``)."""
    import shutil

    work = tmp_path / "work"
    shutil.copytree(folder, work, symlinks=True)
    for p, command in RUN_CASES:
        if p != page:
            continue
        if (p, command) in SLOW:
            continue  # run by test_slow_commands
        r = _cli(_shrunk(p, command), work, timeout=600)
        # verify's exit code 1 is its verdict (a gap above tolerance on the coarse small grid), not a failure to run
        ok = (0, 1) if shlex.split(command)[1] == "verify" else (0,)
        assert r.returncode in ok, f"{page}: {command} (run as {_shrunk(p, command)}) exited {r.returncode}:\n{r.stderr[-3000:]}"


@pytest.mark.slow
@pytest.mark.parametrize("page, command", sorted(SLOW))
def test_slow_commands(page, command, folder, tmp_path):
    r = _cli(_shrunk(page, command), tmp_path, timeout=1200)
    assert r.returncode == 0, f"{page}: {command}: {r.stderr[-3000:]}"


def test_every_snippet_is_run_or_listed():
    known = {(p, k) for p, k in PYTHON}
    for page, kind, index, text in SNIPPETS:
        if kind == "python":
            assert (page, index) in known or (page, text.splitlines()[0]) in NOT_RUN, f"{page}: python block {index} is neither run nor listed"
    assert len(NOT_RUN) <= 5
