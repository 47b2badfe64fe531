"""Compiling a cache entry in a detached process, while the run that needed it goes on uncompiled.

A first run of a small model spends most of its time compiling: the pendulum of
``studies/bioptim_pendulum_xia.toml`` compiles its interval functions in 20-25 s on 2 cores
and then solves in 0.1 s, where CasADi's virtual machine solves the same NLP, uncompiled, in
about 1.2 s (``benchmarks/first_run.py``). With ``solver.first_compile = "background"`` (what ``auto`` picks for a small
full-horizon solve, :func:`fatigue_pin.ocp.solver.resolve_first_compile`) a cache miss writes the
generated C into a folder beside the cache entry and starts ``python -m
fatigue_pin.ocp.background <job.json>`` in a new session, so that it outlives the run and a
Ctrl-C of the run does not reach it. It compiles under the entry's lock with
:func:`fatigue_pin.ocp.compiled.cached_build` (atomic rename, checksum written last), logs to
``<entry>.log`` and removes its folder. The next run finds the library in the cache.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

from fatigue_pin.core.files import held

if TYPE_CHECKING:
    from fatigue_pin.ocp.compiled import BuildOptions


def compiling(entry: Path) -> bool:
    """Whether a process holds the build lock of cache entry ``entry`` (a compile under way)."""
    from fatigue_pin.ocp.compiled import lock_path

    return held(lock_path(entry))


def start(entry: Path, write_sources: Callable[[Path], Sequence[Path]], options: BuildOptions) -> bool:
    """Start compiling ``entry`` in a detached process; return False if one is already under way.

    Args:
        entry: the cache entry (``<cache>/<name>_<key>.so``).
        write_sources: writes the C files into the folder it is given and returns their paths.
        options: :class:`fatigue_pin.ocp.compiled.BuildOptions` of the compile.
    """
    if compiling(entry):
        return False
    entry.parent.mkdir(parents=True, exist_ok=True)
    folder = Path(tempfile.mkdtemp(dir=entry.parent, prefix=entry.name + ".src."))
    sources = [str(path) for path in write_sources(folder)]
    job = {"entry": str(entry), "sources": sources, "folder": str(folder), "compiler": options.compiler,
           "flags": list(options.flags), "openmp": bool(options.openmp), "jobs": options.jobs}
    (folder / "job.json").write_text(json.dumps(job))
    with open(entry.with_name(entry.name + ".log"), "w") as log:
        subprocess.Popen([sys.executable, "-m", "fatigue_pin.ocp.background", str(folder / "job.json")],
                         stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                         close_fds=True)
    return True


def run_job(job_file: Path) -> None:
    """Compile the job that :func:`start` wrote (in the detached process)."""
    from fatigue_pin.ocp.compiled import BuildOptions, cached_build, compile_shared

    job = json.loads(Path(job_file).read_text())
    entry = Path(job["entry"])
    options = BuildOptions(compiler=job["compiler"], flags=tuple(job["flags"]), cache_dir=entry.parent,
                           openmp=job["openmp"], jobs=job["jobs"])
    sources = [Path(src) for src in job["sources"]]
    try:
        built = cached_build(entry, lambda target: compile_shared(sources, target, options))
        print(f"{entry.name}: {'compiled' if built else 'already in the cache'}", flush=True)
    finally:
        shutil.rmtree(job["folder"], ignore_errors=True)


if __name__ == "__main__":
    run_job(Path(sys.argv[1]))
