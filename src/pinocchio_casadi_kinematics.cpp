// Frame kinematics evaluated on casadi::SX: Pinocchio's forwardKinematics, updateFramePlacement
// and getFrameVelocity on CasADi symbols (a translation unit of its own, so that it compiles in
// parallel with the dynamics).
//
// pinocchio/autodiff/casadi.hpp must come before any other Pinocchio header.
#include "pinocchio/autodiff/casadi.hpp"

#include <stdexcept>
#include <string>

#include "pinocchio/multibody.hpp"
#include "pinocchio/algorithm/frames.hpp"
#include "pinocchio/algorithm/kinematics.hpp"

#include "pinocchio_casadi.hpp"
#include "pinocchio_casadi_symbols.hpp"

namespace fatigue_pin
{
  std::tuple<std::string, std::string, std::string>
  serialized_sx_frame_kinematics(const pinocchio::Model & model, std::size_t frame_id)
  {
    if (frame_id >= model.frames.size())
      throw std::out_of_range(
        "frame id " + std::to_string(frame_id) + " is not a frame of the model (it has "
        + std::to_string(model.frames.size()) + " frames)");

    const ADModel ad_model = fixed_base_model(model).cast<SX>();
    ADData ad_data(ad_model);
    const std::string & name = model.frames[frame_id].name;

    const ConfigSymbol q("q", model.nq);
    const TangentSymbol v("v", model.nv);

    // Placement of the frame in the world: joint placements, then the frame's own placement.
    pinocchio::forwardKinematics(ad_model, ad_data, q.eigen, v.eigen);
    const auto & oMf = pinocchio::updateFramePlacement(ad_model, ad_data, frame_id);
    SX p(3, 1), R(3, 3);
    pinocchio::casadi::copy(oMf.translation(), p);
    pinocchio::casadi::copy(oMf.rotation(), R);

    // Velocity of the frame's origin in the world axes (LOCAL_WORLD_ALIGNED).
    const auto vel = pinocchio::getFrameVelocity(
      ad_model, ad_data, frame_id, pinocchio::LOCAL_WORLD_ALIGNED);
    SX pdot(3, 1);
    pinocchio::casadi::copy(vel.linear(), pdot);

    const ::casadi::Function position(
      name + "_position", {q.sx}, {p}, {"q"}, {"p"});
    const ::casadi::Function rotation(
      name + "_rotation", {q.sx}, {R}, {"q"}, {"R"});
    const ::casadi::Function velocity(
      name + "_velocity", {q.sx, v.sx}, {pdot}, {"q", "v"}, {"pdot"});
    return {position.serialize(), rotation.serialize(), velocity.serialize()};
  }
} // namespace fatigue_pin
