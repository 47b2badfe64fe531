// Shared declaration between the two translation units of fatigue_pin._pinocchio_casadi.
//
// The extension is split in two files only to halve the build time on small machines: the
// templated algorithms on casadi::SX (pinocchio_casadi_sx.cpp) take most of the compile time, and
// the Python module with the model deserialisation (pinocchio_casadi.cpp) compiles in parallel.
#pragma once

#include <string>
#include <utility>

#include "pinocchio/multibody.hpp"

namespace fatigue_pin
{
  /// Runs pinocchio::aba and pinocchio::rnea on casadi::SX symbols over `model` and returns the
  /// serialized casadi Functions (aba(q, v, tau) -> ddq, rnea(q, v, a) -> tau).
  std::pair<std::string, std::string> serialized_sx_dynamics(const pinocchio::Model & model);
} // namespace fatigue_pin
