"""Pinocchio's rigid-body algorithms evaluated on CasADi symbols.

The dynamics of every model are Pinocchio's own ABA and RNEA, templated on ``casadi::SX``.
Two back ends give the same functions:

* ``pinocchio.casadi`` when the installed Pinocchio has it (conda-forge builds);
* otherwise the compiled extension ``fatigue_pin._pinocchio_casadi`` built at install time
  against the C++ headers shipped in the ``libpinocchio`` and ``casadi`` wheels. It runs
  ``pinocchio::aba`` / ``pinocchio::rnea`` on ``casadi::SX`` and hands the result to Python as a
  serialized ``casadi.Function``.

Both return functions with the signatures

* ``aba(q[nq], v[nv], tau[nv]) -> ddq[nv]``   (joint accelerations, rad/s^2 or m/s^2)
* ``rnea(q[nq], v[nv], a[nv]) -> tau[nv]``    (joint torques/forces, N m or N)
"""

from __future__ import annotations

import casadi as ca
import pinocchio as pin


def backend_name() -> str:
    """Name of the back end used to build the CasADi dynamics."""
    try:
        import pinocchio.casadi  # noqa: F401

        return "pinocchio.casadi"
    except ImportError:
        return "fatigue_pin._pinocchio_casadi"


def casadi_dynamics(model: pin.Model) -> tuple[ca.Function, ca.Function]:
    """Build ``(aba, rnea)`` as SX ``casadi.Function`` objects for a Pinocchio model.

    Args:
        model: a Pinocchio model (fixed base; the gravity stored in ``model.gravity`` is used).

    Returns:
        ``aba`` with inputs ``q`` (nq), ``v`` (nv), ``tau`` (nv) and output ``ddq`` (nv), and
        ``rnea`` with inputs ``q``, ``v``, ``a`` and output ``tau``.
    """
    raise NotImplementedError("casadi_dynamics: bridge not built yet")
