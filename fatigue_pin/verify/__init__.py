"""fatigue_pin.verify: an independent check of a stored run (``fatigue-pin verify``).

Modules: ``report`` (tolerances, the reference integration's settings, the report), ``stored``
(what the run is checked against, rebuilt from what it stores), ``fatigue_rhs`` (the fatigue
models in numpy), ``dynamics`` (the re-integration: gaps, single shooting), ``task_checks``
(every task item kind, numeric Pinocchio kinematics), ``constraints`` (finite values, coupling,
bounds, invariant), ``verifier`` (:func:`verify_run`, the entry point).
"""

from fatigue_pin.verify.report import ReferenceIntegration, VerifyCheck, VerifyReport, VerifyTolerances
from fatigue_pin.verify.verifier import verify_run

__all__ = ["verify_run", "VerifyTolerances", "VerifyReport", "VerifyCheck", "ReferenceIntegration"]
