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
import numpy as np
import pinocchio as pin

from fatigue_pin.core.errors import ModelError


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

    Raises:
        ModelError: neither ``pinocchio.casadi`` nor the compiled extension is available, or the
            extension was built against other casadi/Pinocchio versions than the ones imported.
    """
    model = aligned_model(model)
    try:
        import pinocchio.casadi as cpin
    except ImportError:
        return _extension_dynamics(model)
    return _pinocchio_casadi_dynamics(cpin, model)


_UNALIGNED = {"JointModelRevoluteUnaligned": pin.JointModelRZ, "JointModelPrismaticUnaligned": pin.JointModelPZ}


def aligned_model(model: pin.Model) -> pin.Model:
    """An exactly equivalent model whose unaligned revolute/prismatic joints act along z.

    A joint about an arbitrary unit axis ``a`` makes Pinocchio's algorithms work with general
    rotations; on ``casadi::SX`` that costs many operations (arm26's ABA: 915, against 108 with
    z-aligned joints). Here the body frame B of every such joint is replaced by B' = B R with
    R e_z = a. Then B'(q) = P R exp(q e_z^) = P exp(q a^) R: the same motion for the same q, with a
    ``JointModelRZ``/``PZ``. Inertias and child joint placements are re-expressed in B'. Velocities,
    accelerations and torques are joint-space quantities, so ABA and RNEA of both models are
    equal (tests/test_dynamics.py checks them against ``pinocchio.aba`` of the original).
    Operational frames and geometry are not copied: the result serves the dynamics only.
    """
    if all(model.joints[i].shortname() not in _UNALIGNED for i in range(1, model.njoints)):
        return model
    out = pin.Model()
    out.name = model.name
    out.gravity = model.gravity
    turn = [pin.SE3.Identity() for _ in range(model.njoints)]  # old body frame -> new body frame
    for i in range(1, model.njoints):
        joint, parent = model.joints[i], model.parents[i]
        placement = turn[parent].actInv(model.jointPlacements[i])
        kind = joint.shortname()
        if kind in _UNALIGNED:
            axis = np.asarray(joint.extract().axis, dtype=float)
            R = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), axis / np.linalg.norm(axis)).matrix()
            turn[i] = pin.SE3(R, np.zeros(3))
            placement = placement * turn[i]
            joint_model = _UNALIGNED[kind]()
        else:
            joint_model = joint.extract()
        jid = out.addJoint(parent, joint_model, placement, model.names[i])
        out.appendBodyToJoint(jid, turn[i].actInv(model.inertias[i]), pin.SE3.Identity())
    out.lowerPositionLimit, out.upperPositionLimit = model.lowerPositionLimit, model.upperPositionLimit
    out.velocityLimit, out.effortLimit = model.velocityLimit, model.effortLimit
    return out


def casadi_aba_derivatives(model: pin.Model) -> ca.Function | None:
    """Pinocchio's analytical derivatives of ABA (``computeABADerivatives``) on SX.

    Returns ``aba_derivatives(q[nq], v[nv], tau[nv]) -> (ddq[nv], ddq_dq[nv x nv],
    ddq_dv[nv x nv], Minv[nv x nv])``: the accelerations (rad/s^2 or m/s^2), their partial
    derivatives in q (1/s^2) and v (1/s), and d ddq / d tau = M(q)^-1 (symmetric), or None when
    the model has joints whose configuration is not their tangent (nq != nv: continuous joints),
    where d/dq is not the derivative in q.

    Raises:
        ModelError: as :func:`casadi_dynamics`.
    """
    model = aligned_model(model)
    if model.nq != model.nv:
        return None
    try:
        import pinocchio.casadi as cpin
    except ImportError:
        ext = compiled_extension("aba_derivatives_from_string")
        return ca.Function.deserialize(ext.aba_derivatives_from_string(model.saveToString()))
    cmodel = cpin.Model(model)
    cdata = cmodel.createData()
    q, v, tau = (ca.SX.sym(n, model.nv) for n in ("q", "v", "tau"))
    cpin.computeABADerivatives(cmodel, cdata, q, v, tau)
    minv = ca.triu(cdata.Minv) + ca.triu(cdata.Minv, False).T
    return ca.Function("aba_derivatives", [q, v, tau], [cdata.ddq, cdata.ddq_dq, cdata.ddq_dv, minv], ["q", "v", "tau"],
                       ["ddq", "ddq_dq", "ddq_dv", "Minv"])


def _pinocchio_casadi_dynamics(cpin, model: pin.Model) -> tuple[ca.Function, ca.Function]:
    """Same functions through Pinocchio's own Python bindings on casadi (conda-forge builds)."""
    cmodel = cpin.Model(model)
    cdata = cmodel.createData()
    q = ca.SX.sym("q", model.nq)
    v = ca.SX.sym("v", model.nv)
    tau = ca.SX.sym("tau", model.nv)
    a = ca.SX.sym("a", model.nv)
    ddq = cpin.aba(cmodel, cdata, q, v, tau)
    aba = ca.Function("aba", [q, v, tau], [ddq], ["q", "v", "tau"], ["ddq"])
    tau_out = cpin.rnea(cmodel, cdata, q, v, a)
    rnea = ca.Function("rnea", [q, v, a], [tau_out], ["q", "v", "a"], ["tau"])
    return aba, rnea


def _extension_dynamics(model: pin.Model) -> tuple[ca.Function, ca.Function]:
    """Same functions through the compiled extension (PyPI wheels without ``pinocchio.casadi``).

    The model crosses to C++ as Pinocchio's text serialization, so everything in it (inertias,
    placements, joint types, gravity) is reproduced exactly; the functions come back serialized.
    """
    ext = compiled_extension("dynamics_from_string")
    aba_text, rnea_text = ext.dynamics_from_string(model.saveToString())
    return ca.Function.deserialize(aba_text), ca.Function.deserialize(rnea_text)


def compiled_extension(function: str):
    """The compiled extension ``fatigue_pin._pinocchio_casadi``, checked against the running
    casadi and Pinocchio and for ``function`` (an extension built before it was added lacks it).

    Raises:
        ModelError: missing, unloadable, built against other versions, or without ``function``.
    """
    # casadi and pinocchio are imported above this point, which also loads libcasadi and
    # libboost_serialization for the extension if its RPATH cannot find them.
    try:
        from fatigue_pin import _pinocchio_casadi as ext
    except ImportError as exc:
        raise ModelError(
            "the compiled extension fatigue_pin._pinocchio_casadi is missing or cannot be loaded "
            f"({exc}); install fatigue_pin with pip (`pip install .` or `pip install -e .`) so "
            "that it is built, or use a Pinocchio build that has pinocchio.casadi"
        ) from exc
    for name, built, running in (
        ("casadi", ext.casadi_version, ca.__version__),
        ("pinocchio", ext.pinocchio_version, pin.__version__),
    ):
        if built != running:
            raise ModelError(
                f"fatigue_pin._pinocchio_casadi was built against {name} {built} but {name} "
                f"{running} is imported; reinstall fatigue_pin with pip to rebuild it"
            )
    if not hasattr(ext, function):
        raise ModelError(f"the compiled extension fatigue_pin._pinocchio_casadi predates {function}; "
                         "reinstall fatigue_pin with pip to rebuild it")
    return ext
