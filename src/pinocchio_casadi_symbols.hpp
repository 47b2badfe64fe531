// The SX model and the symbols every SX translation unit starts from. Include it after
// pinocchio/autodiff/casadi.hpp and pinocchio/multibody.hpp.
#pragma once

#include <string>

namespace fatigue_pin
{
  using SX = ::casadi::SX;
  using ADModel = pinocchio::ModelTpl<SX>;
  using ADData = ADModel::Data;

  /// A CasADi symbol of `n` rows named `name`, and the same as an Eigen vector of SX scalars
  /// (what Pinocchio's algorithms take).
  template<typename EigenVector>
  struct Symbol
  {
    SX sx;
    EigenVector eigen;

    Symbol(const std::string & name, int n)
    : sx(SX::sym(name, n))
    , eigen(n)
    {
      pinocchio::casadi::copy(sx, eigen);
    }
  };

  using ConfigSymbol = Symbol<ADModel::ConfigVectorType>;
  using TangentSymbol = Symbol<ADModel::TangentVectorType>;
} // namespace fatigue_pin
