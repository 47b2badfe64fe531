// fatigue_pin._pinocchio_casadi: Pinocchio's ABA and RNEA on casadi::SX, for Pinocchio builds
// (the PyPI `pin` wheels) that lack the `pinocchio.casadi` Python module.
//
// Python hands over the model as Pinocchio's own text serialization (`model.saveToString()`, a
// boost text archive), so every model built in Python, gravity included, is reproduced exactly.
// The symbolic functions come back as strings for `casadi.Function.deserialize`, which keeps
// CasADi objects out of the C++/Python boundary (the build-time and run-time casadi versions
// must match; both are pinned).
#include <string>
#include <utility>

#include <nanobind/nanobind.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>

#include <casadi/config.h>

#include "pinocchio/config.hpp"
#include "pinocchio/multibody.hpp"
#include "pinocchio/serialization.hpp"

#include "pinocchio_casadi.hpp"

namespace nb = nanobind;

namespace
{
  std::pair<std::string, std::string> dynamics_from_string(const std::string & model_text)
  {
    pinocchio::Model model;
    model.loadFromString(model_text); // throws boost::archive::archive_exception on bad input
    return {fatigue_pin::serialized_sx_aba(model), fatigue_pin::serialized_sx_rnea(model)};
  }

  std::string aba_derivatives_from_string(const std::string & model_text)
  {
    pinocchio::Model model;
    model.loadFromString(model_text);
    return fatigue_pin::serialized_sx_aba_derivatives(model);
  }

  std::tuple<std::string, std::string, std::string>
  frame_kinematics_from_string(const std::string & model_text, std::size_t frame_id)
  {
    pinocchio::Model model;
    model.loadFromString(model_text);
    return fatigue_pin::serialized_sx_frame_kinematics(model, frame_id);
  }
} // namespace

NB_MODULE(_pinocchio_casadi, m)
{
  m.doc() = "Pinocchio's ABA and RNEA on casadi::SX, returned as serialized casadi Functions.";
  m.attr("casadi_version") = CASADI_VERSION_STRING;
  m.attr("pinocchio_version") = PINOCCHIO_VERSION;
  m.def(
    "dynamics_from_string", &dynamics_from_string, nb::arg("model_text"),
    "Build (aba, rnea) for a model given as `pinocchio.Model.saveToString()`.\n\n"
    "Returns two strings for `casadi.Function.deserialize`: aba(q, v, tau) -> ddq and\n"
    "rnea(q, v, a) -> tau.");
  m.def(
    "aba_derivatives_from_string", &aba_derivatives_from_string, nb::arg("model_text"),
    "Analytical derivatives of ABA for a model given as `pinocchio.Model.saveToString()`.\n\n"
    "Returns a string for `casadi.Function.deserialize`: aba_derivatives(q, v, tau) ->\n"
    "(ddq, ddq_dq, ddq_dv, Minv).");
  m.def(
    "frame_kinematics_from_string", &frame_kinematics_from_string, nb::arg("model_text"),
    nb::arg("frame_id"),
    "Frame kinematics of frame `frame_id` of a model given as `pinocchio.Model.saveToString()`.\n\n"
    "Returns three strings for `casadi.Function.deserialize`: position(q) -> p (3),\n"
    "rotation(q) -> R (3x3) and velocity(q, v) -> pdot (3, LOCAL_WORLD_ALIGNED), world frame.");
}
