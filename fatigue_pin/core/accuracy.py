"""What counts as the exact flow, and as an interval that follows it.

Shared by ``fatigue-pin verify`` (:class:`fatigue_pin.verify.report.VerifyTolerances`,
:class:`fatigue_pin.verify.report.ReferenceIntegration`) and the closed loop's repetition count
(:meth:`fatigue_pin.drivers.mpc.ClosedLoop.repetitions`), so that a repetition the plant is
credited with is one whose motion verify accepts.

* The reference integration: ``scipy.integrate.solve_ivp`` with :data:`REFERENCE_METHOD`,
  :data:`REFERENCE_RTOL` and :data:`REFERENCE_ATOL`, the control held over each interval.
* The gap tolerances: an interval follows the exact flow when the reference integration from its
  first node ends within :data:`GAP_TOLERANCE` of its last node in q (rad or m) and qdot (rad/s or
  m/s), and within :data:`GAP_TOLERANCE_FATIGUE` in the fatigue states (dimensionless).
"""

from __future__ import annotations

#: solve_ivp method of the reference integration.
REFERENCE_METHOD = "DOP853"
#: Relative tolerance of the reference integration.
REFERENCE_RTOL = 1e-10
#: Absolute tolerance of the reference integration (in each state's unit).
REFERENCE_ATOL = 1e-12
#: Gap tolerance of q (rad or m) and qdot (rad/s or m/s).
GAP_TOLERANCE = 1e-3
#: Gap tolerance of the fatigue states (dimensionless).
GAP_TOLERANCE_FATIGUE = 1e-5
