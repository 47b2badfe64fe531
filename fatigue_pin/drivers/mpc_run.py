"""A closed-loop run as a stored run: the plant, the controller's prediction and the estimate
side by side, written after every re-plan and resumed from there.

The run (:class:`~fatigue_pin.drivers.run.RunResult`, horizon ``mpc``) holds the *plant*: its q,
qdot and fatigue states over its whole cycles, the torques it delivered, the cost terms of every
cycle evaluated on its trajectory; ``repetitions`` counts the cycles it achieved
(:meth:`ClosedLoop.repetitions`). Its ``extras`` hold the rest (nodes: every node the plant
reached, also past its last whole cycle)::

    measured     (nodes, nq + nv)     q and qdot as the controller measured them
    prediction   (nodes, nx)          the state the plan in force predicted
    estimate     (nodes, n_states)    the estimated fatigue states (after each re-plan's correction)
    u_command    (intervals, nu)      the commanded torques (the plant delivered tau_plus, tau_minus)
    replans      (re-plans,) table    node, phase, IPOPT status, iterations, solve and estimator
                                      wall time (s), objective, real-time factor
    params       (re-plans, n_params) the fatigue parameters each window was planned with
    probe_nodes, probes               nodes and values (halves) of the capacity probes
    task_error   (cycles,)            the plant's task error of every whole cycle
    flow_gap     (cycles, 2)          the largest gap of the plant's intervals of every whole
                                      cycle to the exact flow: q and qdot, fatigue states
    plan_x, plan_u                    the last converged plan (for resuming)
    tail_x, tail_u                    the plant's nodes and delivered torques past its last whole cycle

and, before them, what the actuation kind records of any run (a muscle run: each muscle's force
and the joint torque at the start of every interval, ``muscle_force``, ``joint_torque``).

:func:`prediction_run` and :func:`estimate_run` give the prediction and the estimate as runs of
their own (for figures and comparisons).
"""

from __future__ import annotations

import json
from dataclasses import asdict
from typing import Any

import numpy as np

from fatigue_pin.core.errors import ResultFileError
from fatigue_pin.core.progress import Progress, as_reporter
from fatigue_pin.core.signals import Interrupted, signal_name
from fatigue_pin.drivers.estimation import History
from fatigue_pin.drivers.mpc import REPLAN_DTYPE, ClosedLoop, LoopState, follows_flow, repetitions_achieved
from fatigue_pin.drivers.run import RunResult, RunStore, fatigue_parameters, run_attributes, to_run_result

#: What a resumed closed loop must share with the stored one.
FINGERPRINT_KEYS = ("model", "plant", "window", "mpc", "plant_settings", "transcription", "x_init")


def fingerprint(loop: ClosedLoop) -> str:
    """JSON text of everything a stored run depends on (the run cannot be resumed otherwise)."""

    def problem(p) -> dict[str, Any]:
        return {"weights": dict(zip(p.cost_names, p.weights.tolist())),
                "fatigue": {h.name: [h.params.kind, *h.params.as_vector().tolist()] for h in p.actuators.halves},
                "task": repr(p.task), "model": [p.model.name, repr(p.model.payload)]}

    s = loop.sliding
    data = {
        "model": problem(loop.problem), "plant": problem(loop.plant_problem),
        "window": [s.window, s.end_tolerance, s.failure_iterations, s.min_iterations, s.warmup, s.guess_fatigue],
        "mpc": _mpc_settings(loop),
        "plant_settings": json.loads(json.dumps(asdict(loop.plant_settings), default=list)),
        "transcription": repr(loop.transcription), "x_init": loop.problem.initial_state().tolist(),
    }
    return json.dumps(data, sort_keys=True)


def _mpc_settings(loop: ClosedLoop) -> dict[str, Any]:
    """The loop's settings as the fingerprint holds them; a key added since (real-time
    iterations) only where it is set, so that runs stored before keep their fingerprints."""
    settings = json.loads(json.dumps(asdict(loop.mpc), default=list)) | {"replan_every": loop.replan_every}
    if settings.get("iterations_per_replan") is None:
        settings.pop("iterations_per_replan", None)
    return settings


def _cycle_costs(loop: ClosedLoop, x: np.ndarray, u: np.ndarray, cycles: int) -> np.ndarray:
    """Weighted cost terms of every whole cycle of the plant's trajectory, (cycles, terms)."""
    fn, n = loop.ocp.functions, loop.n
    w = loop.problem.weights
    out = np.zeros((cycles, len(w)))
    for k in range(cycles * n):
        terms = np.asarray(fn.terms(x[k], u[k], u[k - 1] if k > 0 else u[k])).reshape(-1)
        out[k // n] += terms * w
    return out


def to_run(loop: ClosedLoop, state: LoopState, name: str, study: str = "", labels: dict[str, Any] | None = None,
           build_time: float = 0.0) -> RunResult:
    """The stored form of a closed loop's state (module docstring)."""
    n, L = loop.n, loop.problem.layout
    x, h = np.array(state.x), state.history
    u = np.array(h.u_delivered).reshape(-1, L.nu)
    cycles = loop.cycles(state)
    end = cycles * n
    table = np.array(state.replans, dtype=REPLAN_DTYPE)
    errors = loop.task_errors(state)
    gaps = loop.cycle_gaps(state)
    attrs = run_attributes(loop.ocp, "mpc", labels)
    attrs.update(
        n_cycles=cycles, repetitions=repetitions_achieved(errors, loop.mpc.target_tolerance, follows_flow(gaps)), replan_every=loop.replan_every, estimator=loop.mpc.estimator,
        probe_every=loop.mpc.probe_every, target_tolerance=loop.mpc.target_tolerance, window=loop.sliding.window,
        capacity_margin=loop.mpc.capacity_margin, iterations_per_replan=loop.mpc.iterations_per_replan or 0, finished=loop.finished(state), done=state.done, converged=bool(table["converged"].any()) if table.size else False,
        status=table["status"][-1].decode() if table.size else "not started",
        wall_time_s=float(table["wall_time_s"].sum() + table["estimator_time_s"].sum()) if table.size else 0.0,
        iterations=int(table["iterations"].sum()) if table.size else 0, build_time_s=build_time,
        real_time_factor_max=float(table["real_time_factor"].max()) if table.size else 0.0,
        real_time_factor_median=float(np.median(table["real_time_factor"])) if table.size else 0.0,
        plan_start=-1 if state.plan is None else int(state.plan[2]), fingerprint=fingerprint(loop),
        plant_fatigue_params=fatigue_parameters(loop.plant_problem.actuators.halves),
        plant_payload=repr(loop.plant_problem.model.payload), seed=loop.plant_settings.seed,
        fatigued_rows=np.array(loop.problem.actuators.fatigued_rows()),
    )
    wall = np.zeros(cycles)  # re-plan time attributed to the cycle it started in
    for row in table[table["node"] < end]:
        wall[int(row["node"]) // n] += row["wall_time_s"] + row["estimator_time_s"]
    probes = sorted(h.probes)
    plan_x, plan_u = (state.plan[0], state.plan[1]) if state.plan is not None else (np.zeros((0, L.nx)), np.zeros((0, L.nu)))
    run = to_run_result(loop.ocp, np.arange(end + 1) * loop.problem.task.dt, x[: end + 1], u[:end],
                        _cycle_costs(loop, x, u, cycles), name, attrs, wall, study=study)
    run.extras = {
        **run.extras,  # the actuation kind's record (a muscle run's forces and joint torques)
        "measured": np.array(state.y), "prediction": np.array(state.prediction), "estimate": np.array(h.m),
        "u_command": np.array(h.u_command).reshape(-1, L.nu), "replans": table,
        "params": np.array(state.params).reshape(len(state.params), loop.problem.actuators.n_params), "probe_nodes": np.array(probes, dtype=int),
        "probes": np.array([h.probes[k] for k in probes]).reshape(len(probes), L.n_halves), "task_error": errors,
        "flow_gap": gaps,
        "plan_x": plan_x, "plan_u": plan_u, "tail_x": x[end + 1 :].reshape(-1, L.nx), "tail_u": u[end:].reshape(-1, L.nu),
    }
    return run


def from_run(loop: ClosedLoop, run: RunResult) -> LoopState:
    """The closed loop's state from its stored run (the inverse of :func:`to_run`)."""
    L, e = loop.problem.layout, run.extras
    missing = [k for k in ("measured", "prediction", "estimate", "u_command", "replans", "params", "tail_x") if k not in e]
    if missing:
        raise ResultFileError(f"run {run.name!r} has no closed-loop arrays {missing}; it is not a closed-loop (mpc) run")
    x = np.vstack([L.assemble(run.q, run.qdot, run.fatigue), e["tail_x"]])
    u = np.vstack([L.actuators.controls(run.half_torques()), e["tail_u"]])
    history = History(list(e["estimate"]), list(e["u_command"]), list(u),
                      {int(k): v for k, v in zip(e["probe_nodes"], e["probes"])})
    plan = None
    if int(run.attrs.get("plan_start", -1)) >= 0:
        plan = (e["plan_x"], e["plan_u"], int(run.attrs["plan_start"]))
    return LoopState(list(x), list(e["measured"]), list(e["prediction"]), history,
                     [tuple(r) for r in e["replans"].tolist()], list(e["params"]), plan, bool(run.attrs.get("done", False)))


def prediction_run(loop: ClosedLoop, run: RunResult) -> RunResult:
    """The controller's prediction of a stored closed-loop run as a run (its whole cycles)."""
    return _view(loop, run, np.asarray(run.extras["prediction"]), np.asarray(run.extras["u_command"]), "prediction")


def estimate_run(loop: ClosedLoop, run: RunResult) -> RunResult:
    """What the controller knew, as a run: measured q and qdot, estimated fatigue states,
    delivered torques (its whole cycles)."""
    e, L = run.extras, loop.problem.layout
    x = np.hstack([np.asarray(e["measured"]), np.asarray(e["estimate"])])
    u = np.vstack([L.actuators.controls(run.half_torques()), e["tail_u"]]).reshape(-1, L.nu)
    return _view(loop, run, x, u, "estimate")


def _view(loop: ClosedLoop, run: RunResult, x: np.ndarray, u: np.ndarray, what: str) -> RunResult:
    end = run.n_cycles * loop.n
    attrs = dict(run.attrs) | {"horizon": f"mpc-{what}"}
    return to_run_result(loop.ocp, run.t, x[: end + 1], u[:end], run.cycle_costs, f"{run.name}_{what}", attrs,
                         run.cycle_wall_time_s, study=run.study)


def run_closed_loop(loop: ClosedLoop, store: RunStore | None = None, name: str = "mpc/run", resume: bool = False,
                    study: str = "", labels: dict[str, Any] | None = None, progress: Progress = None,
                    stop_after: int | None = None) -> RunResult:
    """Run ``loop``, storing the run in ``store`` after every re-plan; ``resume`` continues the
    run ``name`` stored there (same settings: its fingerprint must match). Returns the run."""
    rep = as_reporter(progress)
    state, stored = None, None
    if resume and store is not None and name in store.runs():
        stored = store.read(name)
        if stored.attrs.get("fingerprint") != fingerprint(loop):
            theirs = json.loads(stored.attrs.get("fingerprint") or "{}")
            mine = json.loads(fingerprint(loop))
            key = next((k for k in FINGERPRINT_KEYS if theirs.get(k) != mine.get(k)), "settings")
            raise ResultFileError(f"cannot resume run {name!r}: its {key} differ from this run's "
                                  f"({theirs.get(key)!r} stored, {mine.get(key)!r} now)")
        state = from_run(loop, stored)
        rep.line(f"resuming {name!r}: {len(state.replans)} re-plans done, node {state.node}")
    checkpoints = _Checkpoints(loop, store, name, study, labels, stored)
    state = state or loop.initial_state()
    try:
        state = loop.run(state, checkpoints, rep, stop_after)
    except Interrupted as exc:  # the last stored state, marked interrupted; --resume continues from it
        checkpoints.interrupted(signal_name(exc))
        raise
    return to_run(loop, state, name, study, labels, checkpoints.build_time_s)


class _Checkpoints:
    """The checkpoint of :meth:`ClosedLoop.run`: the run written to ``store`` after every re-plan,
    the last one written remembered (:attr:`last`), to be marked interrupted."""

    def __init__(self, loop: ClosedLoop, store: RunStore | None, name: str, study: str, labels: dict[str, Any] | None,
                 stored: RunResult | None) -> None:
        self.loop, self.store, self.name, self.study, self.labels = loop, store, name, study, labels
        self.build_time_s = loop.ocp.build_time_s
        #: the run as last stored (a resumed run's: as it was read), or None
        self.last = stored

    def __call__(self, state: LoopState) -> None:
        if self.store is not None:
            self.last = to_run(self.loop, state, self.name, self.study, self.labels, self.build_time_s)
            self.store.write(self.last)

    def interrupted(self, signal: str) -> None:
        """Store the run as last stored again, marked interrupted by ``signal`` (a finished run
        stays as it is)."""
        if self.store is not None and self.last is not None and not self.last.attrs.get("finished"):
            self.last.attrs.update(interrupted=signal, finished=False, converged=False)
            self.store.write(self.last)


def estimation_error(run: RunResult) -> np.ndarray:
    """Estimated minus true fatigued fraction of every half at every node the plant reached,
    (nodes, halves): positive where the controller thought a half more tired than it was."""
    e = run.extras
    rows = np.asarray(run.attrs["fatigued_rows"], dtype=int)  # in the fatigue states (n_states,)
    tail = np.asarray(e["tail_x"])
    nqv = run.q.shape[1] + run.qdot.shape[1]
    true = np.vstack([run.fatigued, tail[:, nqv + rows].reshape(-1, rows.size)])
    return np.asarray(e["estimate"])[:, rows] - true


def report(run: RunResult) -> str:
    """A Markdown report of a closed-loop run: repetitions, task error per cycle, estimation error
    of mf per half, the real-time factor of every re-plan."""
    a, e = run.attrs, run.extras
    lines = [f"# Closed loop {run.name}", "",
             f"- repetitions achieved by the plant: **{a['repetitions']}** of {run.n_cycles} whole cycles "
             f"(task error <= {a['target_tolerance']:g}, every interval within verify's gap tolerances of the exact flow)",
             f"- estimator: {a['estimator']}; re-plan every {a['replan_every']} intervals "
             f"({a['replan_every'] * a['dt']:g} s); window {a['window']} cycles",
             f"- re-plans: {len(e['replans'])}; real-time factor median {a['real_time_factor_median']:.2f}, "
             f"max {a['real_time_factor_max']:.2f}", "", "## Task error and flow gap per cycle", "",
             "| cycle | task error | gap q, qdot to the exact flow | gap fatigue states |", "|---:|---:|---:|---:|"]
    gaps = np.asarray(e.get("flow_gap", np.full((len(e["task_error"]), 2), np.nan))).reshape(-1, 2)
    lines += [f"| {c + 1} | {err:.3g} | {g[0]:.3g} | {g[1]:.3g} |" for c, (err, g) in enumerate(zip(e["task_error"], gaps))]
    err = estimation_error(run)
    lines += ["", "## Estimation error of mf per half (estimate - plant)", "",
              "| half | mean abs | max abs | at the end |", "|---|---:|---:|---:|"]
    lines += [f"| {h} | {np.abs(err[:, i]).mean():.3g} | {np.abs(err[:, i]).max():.3g} | {err[-1, i]:+.3g} |"
              for i, h in enumerate(run.actuator_names)]
    lines += ["", "## Re-plans", "", "| # | node | phase | status | iterations | solve (s) | estimator (s) | real-time factor |",
              "|---:|---:|---:|---|---:|---:|---:|---:|"]
    for r in e["replans"]:
        lines.append(f"| {r['index']} | {r['node']} | {r['phase']} | {r['status'].decode()} | {r['iterations']} | "
                     f"{r['wall_time_s']:.3f} | {r['estimator_time_s']:.3f} | {r['real_time_factor']:.2f} |")
    return "\n".join(lines) + "\n"
