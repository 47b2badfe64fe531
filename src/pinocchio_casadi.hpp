// Shared declarations between the translation units of fatigue_pin._pinocchio_casadi.
//
// The extension is split into one file per Pinocchio algorithm on casadi::SX only to shorten the
// build on small machines: each file's template instantiations take tens of seconds of compiler
// time, and separate files compile in parallel (CMakeLists.txt).
#pragma once

#include <cstddef>
#include <string>
#include <tuple>
#include <utility>

#include "pinocchio/multibody.hpp"

namespace fatigue_pin
{
  /// Runs pinocchio::aba on casadi::SX symbols over `model` and returns the serialized casadi
  /// Function aba(q, v, tau) -> ddq (pinocchio_casadi_rigid_body.cpp).
  std::string serialized_sx_aba(const pinocchio::Model & model);

  /// Runs pinocchio::rnea on casadi::SX symbols over `model` and returns the serialized casadi
  /// Function rnea(q, v, a) -> tau (pinocchio_casadi_rigid_body.cpp).
  std::string serialized_sx_rnea(const pinocchio::Model & model);

  /// Runs pinocchio::computeABADerivatives on casadi::SX symbols over `model` and returns the
  /// serialized casadi Function aba_derivatives(q, v, tau) -> (ddq, ddq_dq, ddq_dv, Minv), the
  /// accelerations and their analytical partial derivatives (Minv = d ddq / d tau, symmetric)
  /// (pinocchio_casadi_derivatives.cpp).
  std::string serialized_sx_aba_derivatives(const pinocchio::Model & model);

  /// Runs pinocchio::forwardKinematics, updateFramePlacement and getFrameVelocity
  /// (LOCAL_WORLD_ALIGNED) on casadi::SX symbols for frame `frame_id` of `model` and returns the
  /// serialized casadi Functions position(q) -> p (3), rotation(q) -> R (3x3) and
  /// velocity(q, v) -> pdot (3), all in the world frame (pinocchio_casadi_rigid_body.cpp).
  std::tuple<std::string, std::string, std::string>
  serialized_sx_frame_kinematics(const pinocchio::Model & model, std::size_t frame_id);
} // namespace fatigue_pin
