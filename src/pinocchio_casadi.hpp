// Shared declaration between the two translation units of fatigue_pin._pinocchio_casadi.
//
// The extension is split in two files only to halve the build time on small machines: the
// templated algorithms on casadi::SX (pinocchio_casadi_sx.cpp) take most of the compile time, and
// the Python module with the model deserialisation (pinocchio_casadi.cpp) compiles in parallel.
#pragma once

#include <cstddef>
#include <string>
#include <tuple>
#include <utility>

#include "pinocchio/multibody.hpp"

namespace fatigue_pin
{
  /// Runs pinocchio::aba and pinocchio::rnea on casadi::SX symbols over `model` and returns the
  /// serialized casadi Functions (aba(q, v, tau) -> ddq, rnea(q, v, a) -> tau).
  std::pair<std::string, std::string> serialized_sx_dynamics(const pinocchio::Model & model);

  /// Runs pinocchio::computeABADerivatives on casadi::SX symbols over `model` and returns the
  /// serialized casadi Function aba_derivatives(q, v, tau) -> (ddq, ddq_dq, ddq_dv, Minv), the
  /// accelerations and their analytical partial derivatives (Minv = d ddq / d tau, symmetric)
  /// (pinocchio_casadi_derivatives.cpp).
  std::string serialized_sx_aba_derivatives(const pinocchio::Model & model);

  /// Runs pinocchio::forwardKinematics, updateFramePlacement and getFrameVelocity
  /// (LOCAL_WORLD_ALIGNED) on casadi::SX symbols for frame `frame_id` of `model` and returns the
  /// serialized casadi Functions position(q) -> p (3), rotation(q) -> R (3x3) and
  /// velocity(q, v) -> pdot (3), all in the world frame (pinocchio_casadi_kinematics.cpp).
  std::tuple<std::string, std::string, std::string>
  serialized_sx_frame_kinematics(const pinocchio::Model & model, std::size_t frame_id);
} // namespace fatigue_pin
