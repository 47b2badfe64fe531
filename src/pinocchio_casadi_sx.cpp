// Pinocchio's ABA and RNEA evaluated on casadi::SX (the compile-heavy half of the extension).
//
// pinocchio/autodiff/casadi.hpp must come before any other Pinocchio header: it teaches Eigen and
// Pinocchio how to use casadi::SX as a scalar type.
#include "pinocchio/autodiff/casadi.hpp"

#include "pinocchio/multibody.hpp"
#include "pinocchio/algorithm/aba.hpp"
#include "pinocchio/algorithm/rnea.hpp"

#include "pinocchio_casadi.hpp"
#include "pinocchio_casadi_symbols.hpp"

namespace fatigue_pin
{
  std::pair<std::string, std::string> serialized_sx_dynamics(const pinocchio::Model & model)
  {
    // Same model (inertias, placements, gravity, ...) with every number turned into an SX constant.
    const ADModel ad_model = model.cast<SX>();
    ADData ad_data(ad_model);
    const ConfigSymbol q("q", model.nq);
    const TangentSymbol v("v", model.nv), tau("tau", model.nv), a("a", model.nv);

    // Forward dynamics: ddq = ABA(q, v, tau).
    pinocchio::aba(ad_model, ad_data, q.eigen, v.eigen, tau.eigen);
    SX ddq(model.nv, 1);
    pinocchio::casadi::copy(ad_data.ddq, ddq);
    const ::casadi::Function aba(
      "aba", {q.sx, v.sx, tau.sx}, {ddq}, {"q", "v", "tau"}, {"ddq"});

    // Inverse dynamics: tau = RNEA(q, v, a).
    pinocchio::rnea(ad_model, ad_data, q.eigen, v.eigen, a.eigen);
    SX tau_out(model.nv, 1);
    pinocchio::casadi::copy(ad_data.tau, tau_out);
    const ::casadi::Function rnea(
      "rnea", {q.sx, v.sx, a.sx}, {tau_out}, {"q", "v", "a"}, {"tau"});

    return {aba.serialize(), rnea.serialize()};
  }
} // namespace fatigue_pin
