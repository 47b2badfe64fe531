// Pinocchio's RNEA evaluated on casadi::SX (a translation unit of its own: it compiles in parallel
// with ABA, the derivatives and the kinematics).
//
// pinocchio/autodiff/casadi.hpp must come before any other Pinocchio header.
#include "pinocchio/autodiff/casadi.hpp"

#include "pinocchio/multibody.hpp"
#include "pinocchio/algorithm/rnea.hpp"

#include "pinocchio_casadi.hpp"
#include "pinocchio_casadi_symbols.hpp"

namespace fatigue_pin
{
  std::string serialized_sx_rnea(const pinocchio::Model & model)
  {
    const ADModel ad_model = fixed_base_model(model).cast<SX>();
    ADData ad_data(ad_model);
    const ConfigSymbol q("q", model.nq);
    const TangentSymbol v("v", model.nv), a("a", model.nv);

    // Inverse dynamics: tau = RNEA(q, v, a).
    pinocchio::rnea(ad_model, ad_data, q.eigen, v.eigen, a.eigen);
    SX tau_out(model.nv, 1);
    pinocchio::casadi::copy(ad_data.tau, tau_out);
    const ::casadi::Function rnea(
      "rnea", {q.sx, v.sx, a.sx}, {tau_out}, {"q", "v", "a"}, {"tau"});
    return rnea.serialize();
  }
} // namespace fatigue_pin
