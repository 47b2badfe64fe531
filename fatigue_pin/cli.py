"""The ``fatigue-pin`` command: a thin layer over the Python API.

Each sub-command parses its arguments and calls one function of the package; no modelling or
solving happens here.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _cmd_info(args: argparse.Namespace) -> int:
    from fatigue_pin.model import load_model

    model = load_model(args.urdf)
    print(model.summary())
    return 0


def _cmd_forward(args: argparse.Namespace) -> int:
    from fatigue_pin.forward import run_forward_studies

    result = run_forward_studies(args.out)
    print(result.table)
    return 0


def _say(line: str) -> None:
    print(line, flush=True)


def _curl_study(args: argparse.Namespace, horizon: str):
    """The paper's curl as a study, from the options of the ``solve`` / ``max-cycles`` shortcuts."""
    from fatigue_pin.paper import curl_study_dict
    from fatigue_pin.study import Study

    solver = {"linear_solver": args.linear_solver, "compile": not args.no_compile, "print_level": args.print_level,
              "max_iter": args.max_iter}
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
    from fatigue_pin.results import check_output
    from fatigue_pin.study import run_study

    check_output(args.out)
    kind = study.horizon["kind"]
    result = run_study(study, args.out, name=args.name, resume=getattr(args, "resume", False), progress=_say,
                       cache_dir=getattr(args, "cache", None))
    if kind == "full":
        ok = result.converged
        print(f"{'converged' if ok else 'NOT CONVERGED (' + str(result.attrs['status']) + ')'}; wrote {args.out} [{result.name}]")
        return 0 if ok else 1
    if kind == "sliding":
        print(f"{result.attrs['repetitions']} repetitions ({result.attrs['converged_windows']} windows converged, "
              f"{result.attrs['wall_time_s']:.1f} s solving); wrote {args.out} [{result.name}]")
        return 0
    print(f"maximum repetitions: {result.max_cycles} (tried N = {[r['n_cycles'] for r in result.tried]}); wrote {args.out}")
    return 0


def _cmd_solve(args: argparse.Namespace) -> int:
    return _run(_curl_study(args, args.horizon), args)


def _cmd_max_cycles(args: argparse.Namespace) -> int:
    return _run(_curl_study(args, "max-cycles"), args)


def _parse_sets(pairs: list[str]) -> dict[str, object]:
    """``key=value`` pairs of ``--set``; values are read as TOML (numbers, strings, lists)."""
    import tomllib

    from fatigue_pin.study import StudyError

    out: dict[str, object] = {}
    for pair in pairs:
        if "=" not in pair:
            raise StudyError(f"--set {pair!r}: expected KEY=VALUE, e.g. fatigue.S=0")
        key, text = pair.split("=", 1)
        try:
            out[key.strip()] = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = text
    return out


def _cmd_run(args: argparse.Namespace) -> int:
    from fatigue_pin.study import Study

    study = Study.from_file(args.study)
    if args.set:
        study = study.replace(_parse_sets(args.set))
    return _run(study, args)


def _cmd_rerun(args: argparse.Namespace) -> int:
    from fatigue_pin.results import ResultFileError, list_runs, read_run
    from fatigue_pin.study import Study

    name = args.run
    if name is None:
        runs = [r for r in list_runs(args.file) if read_run(args.file, r).study]
        if len(runs) != 1:
            raise ResultFileError(f"{str(args.file)!r} holds {len(runs)} runs with a study {runs}; name one")
        name = runs[0]
    study = Study.from_file(args.file, name)
    args.name = args.name or name
    return _run(study, args)


def _cmd_demo(args: argparse.Namespace) -> int:
    from fatigue_pin.reproduce import demo

    demo(args.out, progress=_say, max_cycles=args.max_cycles)
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from fatigue_pin.reproduce import reproduce

    reproduce(args.out, preset=args.preset, quick=args.quick, jobs=args.jobs, progress=_say)
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    from fatigue_pin.replay import export_html, serve
    from fatigue_pin.results import ResultFileError, read_run

    run = read_run(args.file, args.run)
    if args.cycle is not None and not 1 <= args.cycle <= run.n_cycles:
        raise ResultFileError(f"--cycle {args.cycle}: run {run.name!r} has cycles 1 to {run.n_cycles}")
    cycles = None if args.cycle is None else [args.cycle - 1]
    if args.html:
        print(f"wrote {export_html(run, args.html, cycles)} (open it in a browser)")
        return 0
    serve(run, cycle=None if cycles is None else cycles[0], open_browser=args.open)
    return 0


def _cmd_plot(args: argparse.Namespace) -> int:
    from fatigue_pin.plots import plot_file

    for path in plot_file(args.file, args.out):
        print(f"wrote {path}")
    return 0


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
    p.add_argument("--urdf", type=Path, default=None, help="URDF file (default: bundled arm26)")
    _add_output_arguments(p)


def _add_output_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, required=True, help="HDF5 result file (runs are added or replaced)")
    p.add_argument("--name", default=None, help="run name in the file (default: <horizon>/<study name>)")
    p.add_argument("--cache", type=Path, default=None, help="folder of compiled code (default ~/.cache/fatigue_pin)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fatigue-pin",
        description="Predictive simulation of motion with actuator fatigue (Pinocchio + 3CC-S + CasADi).",
    )
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("info", help="print the model summary: joints, masses, bounds, holding torques")
    p.add_argument("--urdf", type=Path, default=None, help="URDF file (default: bundled arm26)")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("forward", help="forward studies of the 3CC / 3CC-S fatigue model (paper section 2)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.set_defaults(func=_cmd_forward)

    p = sub.add_parser("run", help="run a study file (TOML): full horizon, sliding horizon or maximum-repetitions search")
    p.add_argument("study", type=Path, help="study file (.toml), or an HDF5 result file whose run stores its study")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="change a key of the study, e.g. --set fatigue.S=0 --set horizon.max_cycles=5 (repeatable)")
    p.add_argument("--resume", action="store_true", help="continue the run (sliding) or search (max-cycles) stored in --out")
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
    p.add_argument("--n-max", type=int, default=33, help="largest N tried (default 33, the paper's range)")
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

    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fatigue-pin`` command."""
    from fatigue_pin.errors import FatiguePinError

    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv  # accepted anywhere on the line
    args = build_parser().parse_args([a for a in argv if a != "--debug"])
    args.debug = debug
    try:
        return int(args.func(args) or 0)
    except FatiguePinError as exc:
        if args.debug:
            raise
        print(f"fatigue-pin: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fatigue-pin: interrupted; finished work is in the output file", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
