// The SX model (on the fixed-base joint collection) and the symbols every SX translation unit
// starts from. Include it after
// pinocchio/autodiff/casadi.hpp and pinocchio/multibody.hpp.
#pragma once

#include <stdexcept>
#include <string>
#include <type_traits>

#include <boost/mpl/contains.hpp>

namespace fatigue_pin
{
  /// The joints a fixed-base URDF gives Pinocchio: revolute, continuous (unbounded revolute) and
  /// prismatic, about a frame axis or any axis (what fatigue_pin.robot.model accepts). Pinocchio's
  /// algorithms instantiated on casadi::SX for these 12 types (and the Mimic joint, which
  /// Model::addJoint needs in every collection) instead of its default 25 take about half the
  /// compiler time and two thirds of the memory (the ABA unit: 43 s against 95 s of CPU, 1.9
  /// against 3.0 GB).
  template<typename _Scalar, int _Options>
  struct FixedBaseJointCollectionTpl
  {
    typedef _Scalar Scalar;
    static constexpr int Options = _Options;
    typedef pinocchio::JointModelRevoluteTpl<Scalar, Options, 0> JointModelRX;
    typedef pinocchio::JointModelRevoluteTpl<Scalar, Options, 1> JointModelRY;
    typedef pinocchio::JointModelRevoluteTpl<Scalar, Options, 2> JointModelRZ;
    typedef pinocchio::JointModelRevoluteUnalignedTpl<Scalar, Options> JointModelRevoluteUnaligned;
    typedef pinocchio::JointModelRevoluteUnboundedTpl<Scalar, Options, 0> JointModelRUBX;
    typedef pinocchio::JointModelRevoluteUnboundedTpl<Scalar, Options, 1> JointModelRUBY;
    typedef pinocchio::JointModelRevoluteUnboundedTpl<Scalar, Options, 2> JointModelRUBZ;
    typedef pinocchio::JointModelRevoluteUnboundedUnalignedTpl<Scalar, Options> JointModelRevoluteUnboundedUnaligned;
    typedef pinocchio::JointModelPrismaticTpl<Scalar, Options, 0> JointModelPX;
    typedef pinocchio::JointModelPrismaticTpl<Scalar, Options, 1> JointModelPY;
    typedef pinocchio::JointModelPrismaticTpl<Scalar, Options, 2> JointModelPZ;
    typedef pinocchio::JointModelPrismaticUnalignedTpl<Scalar, Options> JointModelPrismaticUnaligned;
    // Pinocchio's Model::addJoint expects the Mimic joint in every collection
    typedef pinocchio::JointModelMimicTpl<Scalar, Options, FixedBaseJointCollectionTpl> JointModelMimic;
    typedef boost::variant<JointModelRX, JointModelRY, JointModelRZ, JointModelRevoluteUnaligned, JointModelRUBX,
                           JointModelRUBY, JointModelRUBZ, JointModelRevoluteUnboundedUnaligned, JointModelPX,
                           JointModelPY, JointModelPZ, JointModelPrismaticUnaligned,
                           boost::recursive_wrapper<JointModelMimic>>
      JointModelVariant;

    typedef pinocchio::JointDataRevoluteTpl<Scalar, Options, 0> JointDataRX;
    typedef pinocchio::JointDataRevoluteTpl<Scalar, Options, 1> JointDataRY;
    typedef pinocchio::JointDataRevoluteTpl<Scalar, Options, 2> JointDataRZ;
    typedef pinocchio::JointDataRevoluteUnalignedTpl<Scalar, Options> JointDataRevoluteUnaligned;
    typedef pinocchio::JointDataRevoluteUnboundedTpl<Scalar, Options, 0> JointDataRUBX;
    typedef pinocchio::JointDataRevoluteUnboundedTpl<Scalar, Options, 1> JointDataRUBY;
    typedef pinocchio::JointDataRevoluteUnboundedTpl<Scalar, Options, 2> JointDataRUBZ;
    typedef pinocchio::JointDataRevoluteUnboundedUnalignedTpl<Scalar, Options> JointDataRevoluteUnboundedUnaligned;
    typedef pinocchio::JointDataPrismaticTpl<Scalar, Options, 0> JointDataPX;
    typedef pinocchio::JointDataPrismaticTpl<Scalar, Options, 1> JointDataPY;
    typedef pinocchio::JointDataPrismaticTpl<Scalar, Options, 2> JointDataPZ;
    typedef pinocchio::JointDataPrismaticUnalignedTpl<Scalar, Options> JointDataPrismaticUnaligned;
    typedef pinocchio::JointDataMimicTpl<Scalar, Options, FixedBaseJointCollectionTpl> JointDataMimic;
    typedef boost::variant<JointDataRX, JointDataRY, JointDataRZ, JointDataRevoluteUnaligned, JointDataRUBX,
                           JointDataRUBY, JointDataRUBZ, JointDataRevoluteUnboundedUnaligned, JointDataPX,
                           JointDataPY, JointDataPZ, JointDataPrismaticUnaligned,
                           boost::recursive_wrapper<JointDataMimic>>
      JointDataVariant;
  };

  using FixedBaseModel = pinocchio::ModelTpl<double, 0, FixedBaseJointCollectionTpl>;
  using FixedBaseJoint = pinocchio::JointModelTpl<double, 0, FixedBaseJointCollectionTpl>;

  struct ToFixedBaseJoint : boost::static_visitor<FixedBaseJoint>
  {
    template<typename J>
    FixedBaseJoint operator()(const J & joint) const
    {
      if constexpr (boost::mpl::contains<FixedBaseJointCollectionTpl<double, 0>::JointModelVariant::types, J>::value
                    && !std::is_same<J, typename FixedBaseJointCollectionTpl<double, 0>::JointModelMimic>::value)
        return FixedBaseJoint(joint);
      else
        throw std::invalid_argument("joint type " + joint.shortname() + " is not supported (revolute, continuous and prismatic joints are)");
    }
  };

  /// The same model (joints, placements, inertias, armature, frames, gravity) on the fixed-base
  /// joint collection; std::invalid_argument names a joint of another type.
  inline FixedBaseModel fixed_base_model(const pinocchio::Model & model)
  {
    FixedBaseModel out;
    out.name = model.name;
    out.gravity = model.gravity;
    for (pinocchio::JointIndex i = 1; i < (pinocchio::JointIndex)model.njoints; ++i)
    {
      const FixedBaseJoint joint = boost::apply_visitor(ToFixedBaseJoint(), model.joints[i].toVariant());
      const pinocchio::JointIndex id = out.addJoint(model.parents[i], joint, model.jointPlacements[i], model.names[i]);
      out.appendBodyToJoint(id, model.inertias[i], pinocchio::SE3::Identity());
    }
    out.armature = model.armature;
    out.frames = model.frames; // the same frame ids
    out.nframes = model.nframes;
    return out;
  }

  using SX = ::casadi::SX;
  using ADModel = pinocchio::ModelTpl<SX, 0, FixedBaseJointCollectionTpl>;
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
