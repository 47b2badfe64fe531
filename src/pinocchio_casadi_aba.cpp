// Pinocchio's ABA evaluated on casadi::SX (a translation unit of its own: it compiles in parallel
// with RNEA, the derivatives and the kinematics).
//
// pinocchio/autodiff/casadi.hpp must come before any other Pinocchio header: it teaches Eigen and
// Pinocchio how to use casadi::SX as a scalar type.
#include "pinocchio/autodiff/casadi.hpp"

#include "pinocchio/multibody.hpp"
#include "pinocchio/algorithm/aba.hpp"

#include "pinocchio_casadi.hpp"
#include "pinocchio_casadi_symbols.hpp"

namespace fatigue_pin
{
  std::string serialized_sx_aba(const pinocchio::Model & model)
  {
    // Same model (inertias, placements, gravity, ...) with every number turned into an SX constant.
    const ADModel ad_model = fixed_base_model(model).cast<SX>();
    ADData ad_data(ad_model);
    const ConfigSymbol q("q", model.nq);
    const TangentSymbol v("v", model.nv), tau("tau", model.nv);

    // Forward dynamics: ddq = ABA(q, v, tau).
    pinocchio::aba(ad_model, ad_data, q.eigen, v.eigen, tau.eigen);
    SX ddq(model.nv, 1);
    pinocchio::casadi::copy(ad_data.ddq, ddq);
    const ::casadi::Function aba(
      "aba", {q.sx, v.sx, tau.sx}, {ddq}, {"q", "v", "tau"}, {"ddq"});
    return aba.serialize();
  }
} // namespace fatigue_pin
