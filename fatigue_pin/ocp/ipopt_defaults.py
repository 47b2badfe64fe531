"""Where fatigue_pin's solver settings differ from IPOPT's (and CasADi ``nlpsol``'s) defaults.

:data:`DEPARTURES` is the one list of them, each with its reason: docs/ocp.md ("Where the solver
settings differ from IPOPT's") lists every entry (a test holds it to this table and checks the
defaults against IPOPT's own documentation), and ``fatigue-pin run`` names, in one line
(:func:`departures_line`), those in force that change the solve and that the study does not set
(:func:`departures_in_force`, :meth:`fatigue_pin.io.study.Study.solver_defaults`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Collection, Sequence

from fatigue_pin.ocp.solver import WARM_START_OPTIONS, SolverOptions

__all__ = ["DEPARTURES", "EVERY_SOLVE", "WARM_STARTED", "Departure", "departures_in_force", "departures_line"]

#: A departure (:class:`Departure`) in force in every solve.
EVERY_SOLVE = "every solve"
#: A departure in force in warm-started solves only (``horizon.warm_start``: every window but the first).
WARM_STARTED = "warm-started solves"


@dataclass(frozen=True)
class Departure:
    """A setting fatigue_pin gives IPOPT (or CasADi's ``nlpsol``) that is not their own default.

    Attributes:
        option: the IPOPT option (or ``nlpsol`` option, ``owner`` CasADi).
        default: IPOPT's (CasADi's) default, as IPOPT's option documentation prints it.
        owner: ``IPOPT`` or ``CasADi``.
        field: the :class:`SolverOptions` field (study key ``solver.<field>``) that sets it, or ""
            (fixed by fatigue_pin).
        when: :data:`EVERY_SOLVE`, or :data:`WARM_STARTED` (``horizon.warm_start``: every window
            but the first, over the study's value).
        changes_solve: whether it changes IPOPT's iterates (and so, on a problem with several
            local optima, the optimum found); else it changes only what is printed or computed
            beside them.
        reason: why fatigue_pin departs.
    """

    option: str
    default: Any
    owner: str
    field: str
    when: str
    changes_solve: bool
    reason: str

    @property
    def value(self) -> Any:
        """fatigue_pin's value, read where it is set (the default :class:`SolverOptions`,
        :data:`WARM_START_OPTIONS`, :data:`NLPSOL_OPTIONS`), so this table never restates it."""
        if self.when == WARM_STARTED:
            return WARM_START_OPTIONS[self.option]
        if self.field == "linear_solver":  # IPOPT gets MA27 on the package's library, or MUMPS (linear_solver_options)
            return SolverOptions().linear_solver
        options = SolverOptions().ipopt_options()
        return options["ipopt"][self.option] if self.owner == "IPOPT" else options[self.option]


#: Every setting that fatigue_pin gives IPOPT or nlpsol unlike their defaults, with the reason
#: (docs/ocp.md "Where the solver settings differ from IPOPT's" lists them all, a test holds it to
#: this table; ``fatigue-pin run`` names those in force that change the solve, :func:`departures_in_force`).
DEPARTURES: tuple[Departure, ...] = (
    Departure("tol", 1e-8, "IPOPT", "tol", EVERY_SOLVE, True,
              "bioptim's default, which the authors' code ran with (docs/authors-code.md D10), so that runs compare with "
              "the paper's; the constraint tolerance constr_viol_tol = 1e-4 is IPOPT's"),
    Departure("mu_init", 0.1, "IPOPT", "mu_init", EVERY_SOLVE, True,
              "from the rest guess both torque halves sit at their common bound 0 and the first Newton steps drive the idle "
              "half through it; a larger first barrier keeps the halves off it until the motion is nearly feasible "
              "(16-cycle curl from rest: 98 iterations against 119)"),
    Departure("perturb_dec_fact", 1.0 / 3.0, "IPOPT", "perturb_dec_fact", EVERY_SOLVE, True,
              "the exact Hessian is indefinite on most iterations far from the solution; lowering the regularisation more "
              "slowly after such an iteration saves KKT factorisations (16 cycles: 108 iterations at 90 ms against 119 at 95 ms)"),
    Departure("linear_solver", "mumps", "IPOPT", "linear_solver", EVERY_SOLVE, True,
              "auto: the package's stage-wise solver of the augmented system (IPOPT's MA27 interface on its library, "
              "hsllib, without MC19 scaling) where its blocks are at most 100 rows, MUMPS otherwise; 25-45 % less solving "
              "on arm26 with the same iterates up to round-off, which can still decide a window at the iteration limit or "
              "which of several local optima a solve finds (docs/ocp.md, \"The KKT solve by stages\"); the paper's and "
              "bioptim's studies state mumps"),
    Departure("print_level", 5, "IPOPT", "print_level", EVERY_SOLVE, False,
              "quiet: fatigue_pin reports its own progress; solver.print_level = 5 shows IPOPT's iteration log"),
    Departure("sb", "no", "IPOPT", "", EVERY_SOLVE, False, "no IPOPT banner in the output of every solve"),
    Departure("warm_start_init_point", "no", "IPOPT", "", WARM_STARTED, True,
              "horizon.warm_start: a window starts from the previous window's primal and dual point, not from the guess alone"),
    Departure("mu_init", 0.1, "IPOPT", "", WARM_STARTED, True,
              "a warm start is near a solution and a small first barrier keeps it there (small curl: 30 % fewer iterations "
              "than cold windows; 1e-4 and 1e-6 gave 10-20 %); it replaces solver.mu_init in these solves"),
    Departure("calc_lam_p", True, "CasADi", "", EVERY_SOLVE, False, "no multipliers of the parameters: nothing uses them"),
    Departure("no_nlp_grad", False, "CasADi", "", EVERY_SOLVE, False,
              "no nlp_grad function, whose reverse sweep through the rigid-body step would put that step's adjoint code "
              "into the compiled library (818 kB of C and about 22 s of compiler time on the UR5)"),
    Departure("print_time", True, "CasADi", "", EVERY_SOLVE, False, "no timing table after every solve: runs store their times"),
)


def departures_in_force(options: SolverOptions, given: Collection[str] = (), warm_start: bool = False) -> list[Departure]:
    """The departures from IPOPT's defaults (:data:`DEPARTURES`) that change the solve and that
    nobody chose: those of every solve whose field is not in ``given`` (the :class:`SolverOptions`
    fields a study sets) and whose option ``options.ipopt`` does not set, and, if ``warm_start``,
    those of warm-started solves."""
    out = []
    for d in DEPARTURES:
        if not d.changes_solve:
            continue
        if d.when == WARM_STARTED:
            if warm_start:
                out.append(d)
        elif d.field not in given and d.option not in options.ipopt:
            out.append(d)
    return out


def departures_line(departures: Sequence[Departure]) -> str:
    """One line naming ``departures`` (:func:`departures_in_force`) with IPOPT's values beside,
    e.g. ``solver: non-IPOPT defaults in force: mu_init = 1.0 (IPOPT 0.1), ... (docs/ocp.md)``;
    "" when there are none."""

    def value(v: Any) -> str:
        return (repr(v) if len(repr(v)) <= 8 else f"{v:.6g}") if isinstance(v, float) else str(v)

    def named(ds: Sequence[Departure]) -> str:
        return ", ".join(f"{d.option} = {value(d.value)} ({d.owner} {value(d.default)})" for d in ds)

    every = [d for d in departures if d.when == EVERY_SOLVE]
    warm = [d for d in departures if d.when == WARM_STARTED]
    if not departures:
        return ""
    parts = [named(every)] if every else []
    if warm:
        parts.append(f"in warm-started windows {named(warm)}")
    return f"solver: non-IPOPT defaults in force: {'; '.join(parts)} (docs/ocp.md, solver settings)"
