// Pinocchio's ABA, RNEA and frame kinematics evaluated on casadi::SX, in one translation unit:
// they instantiate the same SX model, data and joint visitors, which one unit compiles once (35 s
// of compiler CPU against about 70 s as three units; benchmarks/install_results_2cores_idle.txt).
// The ABA derivatives, the heaviest, are a unit of their own and compile beside this one.
//
// pinocchio/autodiff/casadi.hpp must come before any other Pinocchio header: it teaches Eigen and
// Pinocchio how to use casadi::SX as a scalar type.
#include "pinocchio/autodiff/casadi.hpp"

#include <stdexcept>
#include <string>

#include "pinocchio/multibody.hpp"
#include "pinocchio/algorithm/aba.hpp"
#include "pinocchio/algorithm/frames.hpp"
#include "pinocchio/algorithm/kinematics.hpp"
#include "pinocchio/algorithm/rnea.hpp"

#include "pinocchio_casadi.hpp"
#include "pinocchio_casadi_symbols.hpp"

namespace fatigue_pin
{
  std::string serialized_sx_aba(const pinocchio::Model & model)
  {
    SXModel s(model);
    const TangentSymbol tau("tau", model.nv);

    // Forward dynamics: ddq = ABA(q, v, tau).
    pinocchio::aba(s.model, s.data, s.q.eigen, s.v.eigen, tau.eigen);
    SX ddq(model.nv, 1);
    pinocchio::casadi::copy(s.data.ddq, ddq);
    return ::casadi::Function("aba", {s.q.sx, s.v.sx, tau.sx}, {ddq}, {"q", "v", "tau"}, {"ddq"}).serialize();
  }

  std::string serialized_sx_rnea(const pinocchio::Model & model)
  {
    SXModel s(model);
    const TangentSymbol a("a", model.nv);

    // Inverse dynamics: tau = RNEA(q, v, a).
    pinocchio::rnea(s.model, s.data, s.q.eigen, s.v.eigen, a.eigen);
    SX tau(model.nv, 1);
    pinocchio::casadi::copy(s.data.tau, tau);
    return ::casadi::Function("rnea", {s.q.sx, s.v.sx, a.sx}, {tau}, {"q", "v", "a"}, {"tau"}).serialize();
  }

  std::tuple<std::string, std::string, std::string>
  serialized_sx_frame_kinematics(const pinocchio::Model & model, std::size_t frame_id)
  {
    if (frame_id >= model.frames.size())
      throw std::out_of_range(
        "frame id " + std::to_string(frame_id) + " is not a frame of the model (it has "
        + std::to_string(model.frames.size()) + " frames)");

    SXModel s(model);
    const std::string & name = model.frames[frame_id].name;

    // Placement of the frame in the world: joint placements, then the frame's own placement.
    pinocchio::forwardKinematics(s.model, s.data, s.q.eigen, s.v.eigen);
    const auto & oMf = pinocchio::updateFramePlacement(s.model, s.data, frame_id);
    SX p(3, 1), R(3, 3);
    pinocchio::casadi::copy(oMf.translation(), p);
    pinocchio::casadi::copy(oMf.rotation(), R);

    // Velocity of the frame's origin in the world axes (LOCAL_WORLD_ALIGNED).
    const auto vel = pinocchio::getFrameVelocity(
      s.model, s.data, frame_id, pinocchio::LOCAL_WORLD_ALIGNED);
    SX pdot(3, 1);
    pinocchio::casadi::copy(vel.linear(), pdot);

    const ::casadi::Function position(
      name + "_position", {s.q.sx}, {p}, {"q"}, {"p"});
    const ::casadi::Function rotation(
      name + "_rotation", {s.q.sx}, {R}, {"q"}, {"R"});
    const ::casadi::Function velocity(
      name + "_velocity", {s.q.sx, s.v.sx}, {pdot}, {"q", "v"}, {"pdot"});
    return {position.serialize(), rotation.serialize(), velocity.serialize()};
  }
} // namespace fatigue_pin
