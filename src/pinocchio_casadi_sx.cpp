// Pinocchio's ABA and RNEA evaluated on casadi::SX (the compile-heavy half of the extension).
//
// pinocchio/autodiff/casadi.hpp must come before any other Pinocchio header: it teaches Eigen and
// Pinocchio how to use casadi::SX as a scalar type.
#include "pinocchio/autodiff/casadi.hpp"

#include "pinocchio/multibody.hpp"
#include "pinocchio/algorithm/aba.hpp"
#include "pinocchio/algorithm/rnea.hpp"

#include "pinocchio_casadi.hpp"

namespace fatigue_pin
{
  std::pair<std::string, std::string> serialized_sx_dynamics(const pinocchio::Model & model)
  {
    using SX = ::casadi::SX;
    using ADModel = pinocchio::ModelTpl<SX>;
    using ADData = ADModel::Data;

    // Same model (inertias, placements, gravity, ...) with every number turned into an SX constant.
    const ADModel ad_model = model.cast<SX>();
    ADData ad_data(ad_model);

    // CasADi symbols, and the Eigen vectors of SX scalars that Pinocchio works on.
    const SX q = SX::sym("q", model.nq);
    const SX v = SX::sym("v", model.nv);
    const SX tau = SX::sym("tau", model.nv);
    const SX a = SX::sym("a", model.nv);
    ADModel::ConfigVectorType q_ad(model.nq);
    ADModel::TangentVectorType v_ad(model.nv), tau_ad(model.nv), a_ad(model.nv);
    pinocchio::casadi::copy(q, q_ad);
    pinocchio::casadi::copy(v, v_ad);
    pinocchio::casadi::copy(tau, tau_ad);
    pinocchio::casadi::copy(a, a_ad);

    // Forward dynamics: ddq = ABA(q, v, tau).
    pinocchio::aba(ad_model, ad_data, q_ad, v_ad, tau_ad);
    SX ddq(model.nv, 1);
    pinocchio::casadi::copy(ad_data.ddq, ddq);
    const ::casadi::Function aba(
      "aba", {q, v, tau}, {ddq}, {"q", "v", "tau"}, {"ddq"});

    // Inverse dynamics: tau = RNEA(q, v, a).
    pinocchio::rnea(ad_model, ad_data, q_ad, v_ad, a_ad);
    SX tau_out(model.nv, 1);
    pinocchio::casadi::copy(ad_data.tau, tau_out);
    const ::casadi::Function rnea(
      "rnea", {q, v, a}, {tau_out}, {"q", "v", "a"}, {"tau"});

    return {aba.serialize(), rnea.serialize()};
  }
} // namespace fatigue_pin
