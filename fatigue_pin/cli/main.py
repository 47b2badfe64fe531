"""The ``fatigue-pin`` command: a thin layer over the Python API.

Each sub-command parses its arguments and calls one function of the package; no modelling or
solving happens here.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from fatigue_pin.cli.options import DefaultsFormatter, check_options, given, option, owner_default
from fatigue_pin.core.errors import FatiguePinError, UsageError
from fatigue_pin.core.signals import Interrupted, watch


# -- options whose default belongs to a settings class or a function of the package -----------------

#: Where the settings the curl shortcuts set are defined ("module:owner", name): the defaults shown
#: in the help, and the checks of a value before the study is built.
_SOLVER = "fatigue_pin.ocp.solver:SolverOptions"
_HORIZON = "fatigue_pin.drivers.horizon:Horizon"
_SLIDING = "fatigue_pin.drivers.sliding:SlidingSettings"
_CURL = "fatigue_pin.paper.curl:curl_study_dict"


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (exit code 2), like every other error."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", DefaultsFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):  # type: ignore[override]
        raise UsageError(f"{message} (see '{self.prog} --help')")


def _cmd_info(args: argparse.Namespace) -> int:
    from fatigue_pin.robot.model import ModelSource, load_model

    if args.osim is None:
        if args.ignore_wraps:
            raise UsageError("--ignore-wraps: expected it with --osim (an OpenSim model)")
        print(load_model(args.urdf).summary())
        return 0
    if args.urdf is not None:
        raise UsageError("--urdf and --osim: expected one model")
    source = ModelSource(osim=str(args.osim), ignore_wraps=args.ignore_wraps)
    imported = source.read_osim()
    model = source.load()
    print(model.summary(0.5 * (model.q_lower + model.q_upper)))
    if imported.muscles:
        from fatigue_pin.muscles.files import read_muscles

        muscles = read_muscles(imported.muscles, str(imported.path))
        print(f"  muscles: {', '.join(muscles.names)}; wrap cylinders: {', '.join(w.name for w in muscles.wraps) or 'none'}")
    if imported.dropped_wraps:
        print(f"  wrap objects left out (--ignore-wraps): {', '.join(imported.dropped_wraps)}")
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


#: Options of the curl shortcuts checked before the study is built, by the setting each one sets.
_CHECKED_OPTIONS = {"cycles": (_HORIZON, "cycles"), "window": (_HORIZON, "cycles"), "advance": (_SLIDING, "advance"),
                    "max_cycles": (_SLIDING, "max_cycles"), "n_max": (_SLIDING, "max_cycles"),
                    "max_wall_time": (_SOLVER, "max_wall_time")}


def _curl_study(args: argparse.Namespace, horizon: str):
    """The paper's curl as a study, from the options of the ``solve`` / ``max-cycles`` shortcuts
    (options not given keep the defaults of the curl and of the settings classes)."""
    from fatigue_pin.paper.curl import curl_study_dict
    from fatigue_pin.io.study import Study

    check_options(args, _CHECKED_OPTIONS)
    solver = given(args, linear_solver="linear_solver", print_level="print_level", max_iter="max_iter",
                    max_wall_time="max_wall_time")
    if args.no_compile:
        solver["compile"] = False
    bound = "n_max" if horizon == "max-cycles" else "max_cycles"
    options = given(args, cost="cost", preset_name="preset", S="stabilization", guess="guess", max_cycles=bound)
    if horizon in ("full", "sliding"):  # the horizon, or the window
        options.update(given(args, cycles="cycles" if horizon == "full" else "window"))
    data = curl_study_dict(horizon, solver=solver, **options)
    if horizon == "sliding":
        data["horizon"].update(given(args, advance="advance"))
    if args.urdf is not None:
        data["model"]["urdf"] = str(args.urdf)
    return Study.from_dict(data)


def _run(study, args: argparse.Namespace) -> int:
    """Run a study, print its outcome in one line, and return the exit code (1: a full horizon
    that did not converge)."""
    from fatigue_pin.io.results import check_output
    from fatigue_pin.io.study import run_study

    check_output(args.out)
    result = run_study(study, args.out, name=args.name, resume=getattr(args, "resume", False), progress=_reporter(),
                       cache_dir=getattr(args, "cache", None))
    print(f"{result.outcome}; wrote {args.out}" + (f" [{result.run.name}]" if result.run is not None else ""))
    return 0 if result.answered else 1


def _cmd_solve(args: argparse.Namespace) -> int:
    return _run(_curl_study(args, args.horizon), args)


def _cmd_max_cycles(args: argparse.Namespace) -> int:
    return _run(_curl_study(args, "max-cycles"), args)


def _cmd_run(args: argparse.Namespace) -> int:
    from fatigue_pin.cli.mpc import run_closed_loop_study
    from fatigue_pin.io.mpc_study import is_closed_loop
    from fatigue_pin.io.study import Study, parse_changes

    if is_closed_loop(args.study):  # [plant] / [mpc] tables: the closed loop, as `fatigue-pin mpc`
        return run_closed_loop_study(args)
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

    out = args.out if args.out is not None else owner_default("fatigue_pin.paper.reproduce:demo", "out")
    check_output_dir(out)
    demo(out, progress=_reporter(), max_cycles=args.max_cycles)
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from fatigue_pin.paper.reproduce import reproduce
    from fatigue_pin.io.results import check_output_dir

    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: expected a number of worker processes >= 1")
    out = args.out if args.out is not None else owner_default("fatigue_pin.paper.reproduce:reproduce", "out")
    check_output_dir(out)
    reproduce(out, quick=args.quick, jobs=args.jobs, progress=_reporter(), **given(args, preset="preset"))
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
                         interface=args.interface, cache_dir=args.cache, progress=_say, **given(args, retries="retries"))


def _cmd_verify(args: argparse.Namespace) -> int:
    from fatigue_pin.core.progress import Reporter
    from fatigue_pin.io.results import ResultFileError, list_runs, read_run
    from fatigue_pin.verify import ReferenceIntegration, VerifyTolerances, verify_run

    reference = ReferenceIntegration(**given(args, rtol="rtol", atol="atol", method="method"))  # refused before reading anything
    tol = VerifyTolerances(gap=args.gap_tol, gap_fatigue=args.gap_fatigue_tol, task=args.task_tol, coupling=args.coupling_tol,
                           bound=args.bound_tol)
    if args.all and args.run is not None:
        raise ResultFileError(f"--all verifies every run of {str(args.file)!r}; do not name one ({args.run!r})")
    names = list_runs(args.file) if args.all else [read_run(args.file, args.run).name]
    if not names:
        raise ResultFileError(f"{str(args.file)!r} holds no OCP run")
    failed = []
    progress = Reporter.for_stream(sys.stderr)  # a bar over the intervals on a terminal, quiet otherwise
    for name in names:
        report = verify_run(read_run(args.file, name), tol, single_shooting=args.single_shooting, rtol=reference.rtol,
                            atol=reference.atol, method=reference.method, progress=progress)
        print(report.table(), end="\n\n" if len(names) > 1 else "\n", flush=True)
        if not report.passed:
            failed.append(name)
    if len(names) > 1:
        print(f"{len(names) - len(failed)} of {len(names)} runs passed" + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


def _add_ocp_arguments(p: argparse.ArgumentParser) -> None:
    option(p, "--cost", default_from=(_CURL, "cost"), choices=["fatigue-torque", "fatigue", "torque"], help="cost function")
    option(p, "--stabilization", "-S", type=float, default_from=(_CURL, "S"), help="stabiliser S of the 3CC-S model (1/s); 0: Xia's 3CC")
    option(p, "--preset", default_from=(_CURL, "preset_name"), choices=["paper", "authors-code"],
            help="values of the paper text or the authors' code")
    option(p, "--guess", default_from=(_HORIZON, "guess"), choices=["rest", "physical"],
            help="initial guess: the initial state everywhere with zero torque (the paper's), or a smooth motion through the targets")
    option(p, "--linear-solver", default_from=(_SOLVER, "linear_solver"), help="IPOPT linear solver")
    option(p, "--max-iter", type=int, default_from=(_SOLVER, "max_iter"), help="IPOPT iteration limit per solve")
    p.add_argument("--no-compile", action="store_true", help="evaluate the NLP without generating and compiling C")
    option(p, "--print-level", type=int, default_from=(_SOLVER, "print_level"), help="IPOPT print level")
    p.add_argument("--urdf", default=None, help="URDF file (default: bundled arm26)")
    _add_output_arguments(p)


def _add_output_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, required=True, help="HDF5 result file (runs are added or replaced)")
    p.add_argument("--name", default=None, help="run name in the file (default: <horizon>/<study name>)")
    p.add_argument("--cache", type=Path, default=None, help="folder of compiled code (default ~/.cache/fatigue_pin)")


def _add_model_commands(sub: Any) -> None:
    """info, forward."""
    p = sub.add_parser("info", help="print the model summary: joints, masses, bounds, holding torques")
    p.add_argument("--urdf", default=None, help="URDF file (default: bundled arm26)")
    p.add_argument("--osim", default=None, help="an OpenSim model (.osim) instead: its skeleton and muscles (docs/muscles.md)")
    p.add_argument("--ignore-wraps", action="store_true",
                   help="with --osim: leave out the wrap objects fatigue_pin cannot model instead of refusing them")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("forward", help="forward studies of the 3CC / 3CC-S fatigue model (paper section 2)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.set_defaults(func=_cmd_forward)


def _add_study_commands(sub: Any) -> None:
    """run, rerun."""
    p = sub.add_parser("run", help="run a study file (TOML): full horizon, sliding horizon or maximum-repetitions search; "
                                   "a study with [plant] or [mpc] tables runs as a closed loop (as `fatigue-pin mpc`)")
    p.add_argument("study", type=Path, help="study file (.toml), or an HDF5 result file whose run stores its study")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="change a key of the study, e.g. --set fatigue.S=0 --set task.targets[1].tolerance=0.1 (array elements from 0; repeatable)")
    p.add_argument("--resume", action="store_true", help="continue the run (sliding) or search (max-cycles) stored in --out")
    p.add_argument("--run", default=None, metavar="NAME", help="with an HDF5 result file as study: the run whose study to use")
    _add_output_arguments(p)
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("rerun", help="rebuild the study stored with a run and solve it again")
    p.add_argument("file", type=Path, help="HDF5 result file")
    p.add_argument("run", nargs="?", default=None, help="run name (needed when the file holds several)")
    _add_output_arguments(p)
    p.set_defaults(func=_cmd_rerun)


def _add_curl_commands(sub: Any) -> None:
    """solve, max-cycles: the paper's curl without a study file."""
    p = sub.add_parser("solve", help="shortcut: the paper's curl over the full horizon or window by window")
    p.add_argument("horizon", choices=["full", "sliding"])
    option(p, "--cycles", type=int, default_from=(_HORIZON, "cycles"), help="full horizon: number of cycles")
    option(p, "--window", type=int, default_from=("fatigue_pin.paper.curl:WINDOW", None), help="sliding: cycles per window")
    option(p, "--advance", type=int, default_from=(_SLIDING, "advance"), help="sliding: cycles the window advances")
    option(p, "--max-cycles", type=int, default_from=(_SLIDING, "max_cycles"), help="sliding: stop once this many cycles are kept")
    p.add_argument("--resume", action="store_true", help="sliding: continue the run stored in --out")
    _add_ocp_arguments(p)
    p.set_defaults(func=_cmd_solve)

    p = sub.add_parser("max-cycles", help="shortcut: largest number of cycles the curl's full-horizon OCP converges for")
    option(p, "--n-max", type=int, default_from=(_SLIDING, "max_cycles"),
            help="largest N tried; without it, gallop N = 1, 2, 4, ... until a failure, then bisect")
    option(p, "--max-wall-time", type=float, default_from=(_SOLVER, "max_wall_time"), help="wall-time limit of one solve, s")
    p.add_argument("--resume", action="store_true", help="continue the search stored in --out")
    _add_ocp_arguments(p)
    p.set_defaults(func=_cmd_max_cycles)


def _add_paper_commands(sub: Any) -> None:
    """demo, reproduce."""
    p = sub.add_parser("demo", help="solve the sliding-horizon curl to exhaustion; write HDF5, figures and a replay")
    option(p, "--out", type=Path, default_from=("fatigue_pin.paper.reproduce:demo", "out"), help="output folder")
    p.add_argument("--max-cycles", type=int, default=None, help="stop after this many cycles (default: exhaustion)")
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser("reproduce", help="run the paper's whole study and write report.md beside the results")
    option(p, "--out", type=Path, default_from=("fatigue_pin.paper.reproduce:reproduce", "out"), help="output folder")
    option(p, "--preset", default_from=("fatigue_pin.paper.reproduce:reproduce", "preset"), choices=["paper", "authors-code"],
            help="values of the paper text or the authors' code")
    p.add_argument("--quick", action="store_true", help="a subset that finishes in a few minutes")
    p.add_argument("--jobs", type=int, default=None, help="worker processes (default: the number of cores)")
    p.set_defaults(func=_cmd_reproduce)


def _add_result_commands(sub: Any) -> None:
    """replay, plot."""
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


def _add_sweep_command(sub: Any) -> None:
    p = sub.add_parser("sweep", help="run every study of a sweep file (grid / cases over a base study) on Dask; "
                                     "one result file per study, summary.csv and summary.h5; rerun to resume")
    p.add_argument("sweep", type=Path, help="sweep file (.toml), docs/sweeps.md")
    p.add_argument("--out", type=Path, required=True, help="output folder (shared with the workers)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT", help="use this running Dask scheduler")
    where.add_argument("--slurm", action="store_true", help="start workers as SLURM jobs (dask-jobqueue)")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: one per core); --slurm: at most this many")
    p.add_argument("--queue", default=None, help="--slurm: partition")
    slurm = "fatigue_pin.sweep.cluster:SlurmSettings"
    option(p, "--walltime", default_from=(slurm, "walltime"), help="--slurm: time limit of each SLURM job")
    option(p, "--cores", type=int, default_from=(slurm, "cores"), help="--slurm: cores (single-threaded workers) per SLURM job")
    option(p, "--memory", default_from=(slurm, "memory"), help="--slurm: memory per SLURM job")
    p.add_argument("--interface", default=None, help="--slurm: network interface the scheduler listens on (e.g. ib0)")
    p.add_argument("--cache", type=Path, default=None, help="folder of compiled code for every job (default ~/.cache/fatigue_pin)")
    option(p, "--retries", type=int, default_from=("fatigue_pin.sweep.runner:sweep_command", "retries"),
            help="Dask retries of a job that raised a file system error")
    p.set_defaults(func=_cmd_sweep)



def _add_verify_command(sub: Any) -> None:
    from fatigue_pin.verify.report import METHODS, VerifyTolerances

    tol = VerifyTolerances()
    run = "fatigue_pin.verify.report:ReferenceIntegration"
    p = sub.add_parser("verify", help="check a stored run independently (solve_ivp + pinocchio.aba): gaps, task, coupling, bounds, "
                                      "invariant; exit 1 when a check fails")
    p.add_argument("file", type=Path, help="HDF5 result file")
    p.add_argument("run", nargs="?", default=None, help="run name (needed when the file holds several)")
    p.add_argument("--all", action="store_true", help="verify every run of the file")
    p.add_argument("--single-shooting", action="store_true", help="also integrate the stored controls over the whole horizon")
    option(p, "--rtol", type=float, default_from=(run, "rtol"), help="solve_ivp rtol")
    option(p, "--atol", type=float, default_from=(run, "atol"), help="solve_ivp atol")
    option(p, "--method", default_from=(run, "method"), choices=list(METHODS),
            help="solve_ivp method (the paper's single shooting: RK45 --rtol 1e-3 --atol 1e-6)")
    p.add_argument("--gap-tol", type=float, default=tol.gap, help=f"gap of q (rad or m) and qdot (rad/s or m/s) (default {tol.gap:g})")
    p.add_argument("--gap-fatigue-tol", type=float, default=tol.gap_fatigue, help=f"gap of the fatigue states (default {tol.gap_fatigue:g})")
    p.add_argument("--task-tol", type=float, default=tol.task, help=f"task targets, ranges, initial state (default {tol.task:g})")
    p.add_argument("--coupling-tol", type=float, default=tol.coupling, help=f"TL + mf outside [0, 1] (default {tol.coupling:g})")
    p.add_argument("--bound-tol", type=float, default=tol.bound, help=f"q, qdot, torques, fatigue states (default {tol.bound:g})")
    p.set_defaults(func=_cmd_verify)


def build_parser() -> argparse.ArgumentParser:
    """The ``fatigue-pin`` parser: one sub-command per task, each calling one function of the package."""
    parser = _Parser(
        prog="fatigue-pin",
        description="Predictive simulation of motion with actuator fatigue (Pinocchio + 3CC-S + CasADi).",
    )
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", required=True)
    for add in (_add_model_commands, _add_study_commands, _add_curl_commands, _add_paper_commands, _add_result_commands,
                _add_sweep_command, _add_verify_command):
        add(sub)
    from fatigue_pin.cli.fatigue import register as register_fatigue_commands

    register_fatigue_commands(sub)  # endurance, calibrate
    from fatigue_pin.cli.mpc import register as register_mpc_command

    register_mpc_command(sub)  # mpc
    from fatigue_pin.cli.motors import register as register_motor_commands

    register_motor_commands(sub)  # calibrate-thermal
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
