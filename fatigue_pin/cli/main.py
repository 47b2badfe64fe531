"""The ``fatigue-pin`` command: a thin layer over the Python API.

Each sub-command parses its arguments and calls one function of the package; no modelling or
solving happens here.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.core.signals import Interrupted, watch


class UsageError(FatiguePinError, ValueError):
    """A command line that does not parse (unknown command or option, bad value)."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (exit code 2), like every other error."""

    def error(self, message: str):  # type: ignore[override]
        raise UsageError(f"{message} (see '{self.prog} --help')")


def _cmd_info(args: argparse.Namespace) -> int:
    from fatigue_pin.robot.model import load_model

    model = load_model(args.urdf)
    print(model.summary())
    return 0


def _cmd_forward(args: argparse.Namespace) -> int:
    from fatigue_pin.paper.forward import run_forward_studies
    from fatigue_pin.io.results import check_output_dir

    check_output_dir(args.out)
    result = run_forward_studies(args.out)
    print(result.table)
    return 0


def _say(line: str) -> None:
    print(line, flush=True)


def _reporter():
    """Progress on standard output: bars and a live compile line on a terminal, plain lines else."""
    from fatigue_pin.core.progress import Reporter

    return Reporter.for_stream(sys.stdout)


def _curl_study(args: argparse.Namespace, horizon: str):
    """The paper's curl as a study, from the options of the ``solve`` / ``max-cycles`` shortcuts."""
    from fatigue_pin.paper.curl import curl_study_dict
    from fatigue_pin.io.study import Study

    for option in ("cycles", "window", "advance", "max_cycles", "n_max"):
        value = getattr(args, option, None)
        if value is not None and value < 1:
            raise UsageError(f"--{option.replace('_', '-')} {value}: expected an integer number of cycles >= 1")
    solver = {"linear_solver": args.linear_solver, "compile": not args.no_compile, "print_level": args.print_level,
              "max_iter": args.max_iter}
    if getattr(args, "max_wall_time", None) is not None:
        if not args.max_wall_time > 0:
            raise UsageError(f"--max-wall-time {args.max_wall_time}: expected seconds > 0")
        solver["max_wall_time"] = args.max_wall_time
    cycles = {"full": getattr(args, "cycles", None), "sliding": getattr(args, "window", None)}.get(horizon)
    max_cycles = args.n_max if horizon == "max-cycles" else getattr(args, "max_cycles", None)
    data = curl_study_dict(horizon, args.cost, args.preset, args.stabilization, cycles=cycles, max_cycles=max_cycles,
                           guess=args.guess, solver=solver)
    if horizon == "sliding":
        data["horizon"]["advance"] = args.advance
    if args.urdf is not None:
        data["model"]["urdf"] = str(args.urdf)
    return Study.from_dict(data)


def _run(study, args: argparse.Namespace) -> int:
    """Run a study, print its outcome in one line, and return the exit code (1: not converged)."""
    from fatigue_pin.io.results import check_output
    from fatigue_pin.io.study import run_study

    check_output(args.out)
    kind = study.horizon["kind"]
    result = run_study(study, args.out, name=args.name, resume=getattr(args, "resume", False), progress=_reporter(),
                       cache_dir=getattr(args, "cache", None))
    if kind == "full":
        ok = result.converged
        print(f"{'converged' if ok else 'NOT CONVERGED (' + str(result.attrs['status']) + ')'}; wrote {args.out} [{result.name}]")
        return 0 if ok else 1
    if kind == "sliding":
        print(f"{result.attrs['repetitions']} repetitions ({result.attrs['converged_windows']} windows converged, "
              f"{result.attrs['wall_time_s']:.1f} s solving); wrote {args.out} [{result.name}]")
        return 0
    failed = ", ".join(f"{n}: {k}" for n, k in result.failures.items()) or "none"
    print(f"maximum repetitions: {result.max_cycles} (tried N = {[r['n_cycles'] for r in result.tried]}; failed: {failed}); wrote {args.out}")
    return 0


def _cmd_solve(args: argparse.Namespace) -> int:
    return _run(_curl_study(args, args.horizon), args)


def _cmd_max_cycles(args: argparse.Namespace) -> int:
    return _run(_curl_study(args, "max-cycles"), args)


def _cmd_run(args: argparse.Namespace) -> int:
    from fatigue_pin.io.study import Study, parse_changes

    study = Study.from_file(args.study, args.run)
    if args.set:
        study = study.replace(parse_changes(args.set))
    return _run(study, args)


def _cmd_rerun(args: argparse.Namespace) -> int:
    from fatigue_pin.io.results import ResultFileError, list_runs, read_run
    from fatigue_pin.io.study import Study

    name = args.run
    if name is None:
        runs = [r for r in list_runs(args.file) if read_run(args.file, r).study]
        if not runs:
            raise ResultFileError(f"{str(args.file)!r} holds no run with a stored study (its runs were built in Python); "
                                  "expected a file written from a study")
        if len(runs) != 1:
            raise ResultFileError(f"{str(args.file)!r} holds {len(runs)} runs with a study {runs}; name one")
        name = runs[0]
    study = Study.from_file(args.file, name)
    args.name = args.name or name
    return _run(study, args)


def _cmd_demo(args: argparse.Namespace) -> int:
    from fatigue_pin.paper.reproduce import demo
    from fatigue_pin.io.results import check_output_dir

    check_output_dir(args.out)
    demo(args.out, progress=_reporter(), max_cycles=args.max_cycles)
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from fatigue_pin.paper.reproduce import reproduce
    from fatigue_pin.io.results import check_output_dir

    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: expected a number of worker processes >= 1")
    check_output_dir(args.out)
    reproduce(args.out, preset=args.preset, quick=args.quick, jobs=args.jobs, progress=_reporter())
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    from fatigue_pin.viz.replay import export_html
    from fatigue_pin.viz.server import serve
    from fatigue_pin.io.results import ResultFileError, read_run

    run = read_run(args.file, args.run)
    if args.html is not None:
        from fatigue_pin.io.results import check_output_dir

        if args.html.is_dir():
            raise ResultFileError(f"--html {str(args.html)!r} is a folder; expected the path of an HTML file")
        check_output_dir(args.html.parent)
    if args.cycle is not None and not 1 <= args.cycle <= run.n_cycles:
        raise ResultFileError(f"--cycle {args.cycle}: run {run.name!r} has cycles 1 to {run.n_cycles}")
    cycles = None if args.cycle is None else [args.cycle - 1]
    if args.html:
        print(f"wrote {export_html(run, args.html, cycles)} (open it in a browser)")
        return 0
    serve(run, cycle=None if cycles is None else cycles[0], open_browser=args.open)
    return 0


def _cmd_plot(args: argparse.Namespace) -> int:
    from fatigue_pin.io.results import check_output_dir
    from fatigue_pin.paper.forward_file import is_forward_file, plot_forward_file
    from fatigue_pin.viz.plots import plot_file

    check_output_dir(args.out)
    plot = plot_forward_file if is_forward_file(args.file) else plot_file
    for path in plot(args.file, args.out):
        print(f"wrote {path}")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from fatigue_pin.sweep.runner import sweep_command

    return sweep_command(args.sweep, args.out, scheduler=args.scheduler, slurm=args.slurm, workers=args.workers,
                         queue=args.queue, walltime=args.walltime, cores=args.cores, memory=args.memory,
                         interface=args.interface, cache_dir=args.cache, retries=args.retries, progress=_say)


def _cmd_verify(args: argparse.Namespace) -> int:
    from fatigue_pin.io.results import ResultFileError, list_runs, read_run
    from fatigue_pin.verify import ReferenceIntegration, VerifyTolerances, verify_run

    ReferenceIntegration(args.rtol, args.atol, args.method)  # refuse bad tolerances before reading anything
    tol = VerifyTolerances(gap=args.gap_tol, gap_fatigue=args.gap_fatigue_tol, task=args.task_tol, coupling=args.coupling_tol,
                           bound=args.bound_tol)
    if args.all and args.run is not None:
        raise ResultFileError(f"--all verifies every run of {str(args.file)!r}; do not name one ({args.run!r})")
    names = list_runs(args.file) if args.all else [read_run(args.file, args.run).name]
    if not names:
        raise ResultFileError(f"{str(args.file)!r} holds no OCP run")
    failed = []
    for name in names:
        report = verify_run(read_run(args.file, name), tol, single_shooting=args.single_shooting, rtol=args.rtol, atol=args.atol,
                            method=args.method)
        print(report.table(), end="\n\n" if len(names) > 1 else "\n", flush=True)
        if not report.passed:
            failed.append(name)
    if len(names) > 1:
        print(f"{len(names) - len(failed)} of {len(names)} runs passed" + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


def _add_ocp_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--cost", default="fatigue-torque", choices=["fatigue-torque", "fatigue", "torque"], help="cost function")
    p.add_argument("--stabilization", "-S", type=float, default=10.0, help="stabiliser S of the 3CC-S model (1/s); 0: Xia's 3CC")
    p.add_argument("--preset", default="paper", choices=["paper", "authors-code"], help="values of the paper text or the authors' code")
    p.add_argument("--guess", default="rest", choices=["rest", "physical"],
                   help="initial guess: the initial state everywhere with zero torque (the paper's), or a smooth motion through the targets")
    p.add_argument("--linear-solver", default="mumps", help="IPOPT linear solver (default mumps)")
    p.add_argument("--max-iter", type=int, default=3000, help="IPOPT iteration limit per solve (default 3000)")
    p.add_argument("--no-compile", action="store_true", help="evaluate the NLP without generating and compiling C")
    p.add_argument("--print-level", type=int, default=0, help="IPOPT print level")
    p.add_argument("--urdf", default=None, help="URDF file (default: bundled arm26)")
    _add_output_arguments(p)


def _add_output_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, required=True, help="HDF5 result file (runs are added or replaced)")
    p.add_argument("--name", default=None, help="run name in the file (default: <horizon>/<study name>)")
    p.add_argument("--cache", type=Path, default=None, help="folder of compiled code (default ~/.cache/fatigue_pin)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="fatigue-pin",
        description="Predictive simulation of motion with actuator fatigue (Pinocchio + 3CC-S + CasADi).",
    )
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("info", help="print the model summary: joints, masses, bounds, holding torques")
    p.add_argument("--urdf", default=None, help="URDF file (default: bundled arm26)")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("forward", help="forward studies of the 3CC / 3CC-S fatigue model (paper section 2)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.set_defaults(func=_cmd_forward)

    p = sub.add_parser("run", help="run a study file (TOML): full horizon, sliding horizon or maximum-repetitions search")
    p.add_argument("study", type=Path, help="study file (.toml), or an HDF5 result file whose run stores its study")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="change a key of the study, e.g. --set fatigue.S=0 --set horizon.max_cycles=5 (repeatable)")
    p.add_argument("--resume", action="store_true", help="continue the run (sliding) or search (max-cycles) stored in --out")
    p.add_argument("--run", default=None, metavar="NAME", help="with an HDF5 result file as study: the run whose study to use")
    _add_output_arguments(p)
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("rerun", help="rebuild the study stored with a run and solve it again")
    p.add_argument("file", type=Path, help="HDF5 result file")
    p.add_argument("run", nargs="?", default=None, help="run name (needed when the file holds several)")
    _add_output_arguments(p)
    p.set_defaults(func=_cmd_rerun)

    p = sub.add_parser("solve", help="shortcut: the paper's curl over the full horizon or window by window")
    p.add_argument("horizon", choices=["full", "sliding"])
    p.add_argument("--cycles", type=int, default=1, help="full horizon: number of cycles")
    p.add_argument("--window", type=int, default=3, help="sliding: cycles per window")
    p.add_argument("--advance", type=int, default=1, help="sliding: cycles the window advances")
    p.add_argument("--max-cycles", type=int, default=None, help="sliding: stop once this many cycles are kept")
    p.add_argument("--resume", action="store_true", help="sliding: continue the run stored in --out")
    _add_ocp_arguments(p)
    p.set_defaults(func=_cmd_solve)

    p = sub.add_parser("demo", help="solve the sliding-horizon curl to exhaustion; write HDF5, figures and a replay")
    p.add_argument("--out", type=Path, default=Path("results/demo"), help="output folder (default results/demo)")
    p.add_argument("--max-cycles", type=int, default=None, help="stop after this many cycles (default: exhaustion)")
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser("reproduce", help="run the paper's whole study and write report.md beside the results")
    p.add_argument("--out", type=Path, default=Path("results/reproduce"), help="output folder")
    p.add_argument("--preset", default="paper", choices=["paper", "authors-code"])
    p.add_argument("--quick", action="store_true", help="a subset that finishes in a few minutes")
    p.add_argument("--jobs", type=int, default=None, help="worker processes (default: the number of cores)")
    p.set_defaults(func=_cmd_reproduce)

    p = sub.add_parser("max-cycles", help="shortcut: largest number of cycles the curl's full-horizon OCP converges for")
    p.add_argument("--n-max", type=int, default=None,
                   help="largest N tried (default: no cap; gallop N = 1, 2, 4, ... until a failure, then bisect)")
    p.add_argument("--max-wall-time", type=float, default=None, help="wall-time limit of one solve, s (default: none)")
    p.add_argument("--resume", action="store_true", help="continue the search stored in --out")
    _add_ocp_arguments(p)
    p.set_defaults(func=_cmd_max_cycles)

    p = sub.add_parser("replay", help="replay a run in the browser (meshcat, local only) or write it as one HTML file")
    p.add_argument("file", type=Path, help="HDF5 result file")
    p.add_argument("--run", default=None, help="run name in the file (needed when it holds several)")
    p.add_argument("--cycle", type=int, default=None, help="play only this cycle (1 = first; default: all)")
    p.add_argument("--html", type=Path, default=None, help="write a self-contained HTML replay here and exit")
    p.add_argument("--open", action="store_true", help="open the served page in the default browser")
    p.set_defaults(func=_cmd_replay)

    p = sub.add_parser("plot", help="write every figure of a result file (OCP runs or forward studies), PNG and PDF")
    p.add_argument("file", type=Path, help="HDF5 result file")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.set_defaults(func=_cmd_plot)

    p = sub.add_parser("sweep", help="run every study of a sweep file (grid / cases over a base study) on Dask; "
                                     "one result file per study, summary.csv and summary.h5; rerun to resume")
    p.add_argument("sweep", type=Path, help="sweep file (.toml), docs/sweeps.md")
    p.add_argument("--out", type=Path, required=True, help="output folder (shared with the workers)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT", help="use this running Dask scheduler")
    where.add_argument("--slurm", action="store_true", help="start workers as SLURM jobs (dask-jobqueue)")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: one per core); --slurm: at most this many")
    p.add_argument("--queue", default=None, help="--slurm: partition")
    p.add_argument("--walltime", default=None, help="--slurm: time limit of each SLURM job (default 01:00:00)")
    p.add_argument("--cores", type=int, default=None, help="--slurm: cores (single-threaded workers) per SLURM job (default 1)")
    p.add_argument("--memory", default=None, help="--slurm: memory per SLURM job (default 4GB)")
    p.add_argument("--interface", default=None, help="--slurm: network interface the scheduler listens on (e.g. ib0)")
    p.add_argument("--cache", type=Path, default=None, help="folder of compiled code for every job (default ~/.cache/fatigue_pin)")
    p.add_argument("--retries", type=int, default=2, help="Dask retries of a job that raised a file system error (default 2)")
    p.set_defaults(func=_cmd_sweep)

    from fatigue_pin.verify.report import DEFAULT_ATOL, DEFAULT_RTOL, METHODS, VerifyTolerances

    tol = VerifyTolerances()
    p = sub.add_parser("verify", help="check a stored run independently (solve_ivp + pinocchio.aba): gaps, task, coupling, bounds, "
                                      "invariant; exit 1 when a check fails")
    p.add_argument("file", type=Path, help="HDF5 result file")
    p.add_argument("run", nargs="?", default=None, help="run name (needed when the file holds several)")
    p.add_argument("--all", action="store_true", help="verify every run of the file")
    p.add_argument("--single-shooting", action="store_true", help="also integrate the stored controls over the whole horizon")
    p.add_argument("--rtol", type=float, default=DEFAULT_RTOL, help=f"solve_ivp rtol (default {DEFAULT_RTOL:g})")
    p.add_argument("--atol", type=float, default=DEFAULT_ATOL, help=f"solve_ivp atol (default {DEFAULT_ATOL:g})")
    p.add_argument("--method", default="DOP853", choices=list(METHODS),
                   help="solve_ivp method (default DOP853; the paper's single shooting: RK45 --rtol 1e-3 --atol 1e-6)")
    p.add_argument("--gap-tol", type=float, default=tol.gap, help=f"gap of q (rad) and qdot (rad/s) (default {tol.gap:g})")
    p.add_argument("--gap-fatigue-tol", type=float, default=tol.gap_fatigue, help=f"gap of the fatigue states (default {tol.gap_fatigue:g})")
    p.add_argument("--task-tol", type=float, default=tol.task, help=f"task targets, ranges, initial state (default {tol.task:g})")
    p.add_argument("--coupling-tol", type=float, default=tol.coupling, help=f"TL + mf outside [0, 1] (default {tol.coupling:g})")
    p.add_argument("--bound-tol", type=float, default=tol.bound, help=f"q, qdot, torques, fatigue states (default {tol.bound:g})")
    p.set_defaults(func=_cmd_verify)

    from fatigue_pin.cli.fatigue import register as register_fatigue_commands

    register_fatigue_commands(sub)  # endurance, calibrate
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fatigue-pin`` command."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv  # accepted anywhere on the line
    try:
        args = build_parser().parse_args([a for a in argv if a != "--debug"])
        args.debug = debug
        with watch():  # SIGINT and SIGTERM: Interrupted, exit code 130 and 143
            return int(args.func(args) or 0)
    except (FatiguePinError, OSError) as exc:  # OSError: a file problem no check foresaw
        if debug:
            raise
        text = str(exc) if isinstance(exc, FatiguePinError) or not exc.strerror else \
            f"{exc.strerror}: {exc.filename!r}" if exc.filename else exc.strerror
        print("fatigue-pin: error: " + " ".join(text.split()), file=sys.stderr)  # one line
        return 2
    except KeyboardInterrupt as exc:  # Interrupted (SIGINT, SIGTERM), or Ctrl-C outside a watch
        code = exc.exit_code if isinstance(exc, Interrupted) else 130
        what = exc.args[0] if isinstance(exc, Interrupted) else "interrupted"
        print(f"fatigue-pin: {what}; finished work (windows, searched N) is in the output file, the interrupted "
              "solve is not (--resume continues)", file=sys.stderr)
        return code


if __name__ == "__main__":
    sys.exit(main())
