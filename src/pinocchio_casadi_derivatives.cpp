// Pinocchio's analytical derivatives of ABA evaluated on casadi::SX (its own translation unit:
// it compiles in parallel with the others).
//
// pinocchio/autodiff/casadi.hpp must come before any other Pinocchio header: it teaches Eigen and
// Pinocchio how to use casadi::SX as a scalar type.
#include "pinocchio/autodiff/casadi.hpp"

#include "pinocchio/multibody.hpp"
#include "pinocchio/algorithm/aba-derivatives.hpp"

#include "pinocchio_casadi.hpp"
#include "pinocchio_casadi_symbols.hpp"

namespace fatigue_pin
{
  std::string serialized_sx_aba_derivatives(const pinocchio::Model & model)
  {
    SXModel s(model);
    const TangentSymbol tau("tau", model.nv);

    // ddq and its partial derivatives (Carpentier & Mansard, RSS 2018); Minv = d ddq / d tau.
    pinocchio::computeABADerivatives(s.model, s.data, s.q.eigen, s.v.eigen, tau.eigen);
    // only the upper triangle of Minv is filled
    s.data.Minv.template triangularView<Eigen::StrictlyLower>() =
      s.data.Minv.transpose().template triangularView<Eigen::StrictlyLower>();
    SX ddq(model.nv, 1), ddq_dq(model.nv, model.nv), ddq_dv(model.nv, model.nv), minv(model.nv, model.nv);
    pinocchio::casadi::copy(s.data.ddq, ddq);
    pinocchio::casadi::copy(s.data.ddq_dq, ddq_dq);
    pinocchio::casadi::copy(s.data.ddq_dv, ddq_dv);
    pinocchio::casadi::copy(s.data.Minv, minv);
    const ::casadi::Function f(
      "aba_derivatives", {s.q.sx, s.v.sx, tau.sx}, {ddq, ddq_dq, ddq_dv, minv}, {"q", "v", "tau"},
      {"ddq", "ddq_dq", "ddq_dv", "Minv"});
    return f.serialize();
  }
} // namespace fatigue_pin
