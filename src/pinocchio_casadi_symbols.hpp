// The SX model (on the fixed-base joint collection) and the symbols every SX translation unit
// starts from. Include it after
// pinocchio/autodiff/casadi.hpp and pinocchio/multibody.hpp.
#pragma once

#include <stdexcept>
#include <string>

namespace fatigue_pin
{
  /// The joints a fixed-base URDF gives Pinocchio: revolute, continuous (unbounded revolute) and
  /// prismatic (what fatigue_pin.robot.model accepts), each as its any-axis type: a joint about a
  /// frame axis becomes the same joint about that unit axis. Pinocchio's algorithms are then
  /// instantiated on casadi::SX for 3 joint types (and the Mimic joint, which Model::addJoint needs
  /// in every collection) instead of its default 25. SX folds the products by the axis' zeros and
  /// ones, so the expressions are the aligned joints' to rounding; the compiler's time and memory
  /// fall with the number of types (benchmarks/install_results_2cores_idle.txt).
  template<typename _Scalar, int _Options>
  struct FixedBaseJointCollectionTpl
  {
    typedef _Scalar Scalar;
    static constexpr int Options = _Options;
    typedef pinocchio::JointModelRevoluteUnalignedTpl<Scalar, Options> JointModelRevoluteUnaligned;
    typedef pinocchio::JointModelRevoluteUnboundedUnalignedTpl<Scalar, Options> JointModelRevoluteUnboundedUnaligned;
    typedef pinocchio::JointModelPrismaticUnalignedTpl<Scalar, Options> JointModelPrismaticUnaligned;
    typedef pinocchio::JointModelMimicTpl<Scalar, Options, FixedBaseJointCollectionTpl> JointModelMimic;
    typedef boost::variant<JointModelRevoluteUnaligned, JointModelRevoluteUnboundedUnaligned, JointModelPrismaticUnaligned,
                           boost::recursive_wrapper<JointModelMimic>>
      JointModelVariant;

    typedef pinocchio::JointDataRevoluteUnalignedTpl<Scalar, Options> JointDataRevoluteUnaligned;
    typedef pinocchio::JointDataRevoluteUnboundedUnalignedTpl<Scalar, Options> JointDataRevoluteUnboundedUnaligned;
    typedef pinocchio::JointDataPrismaticUnalignedTpl<Scalar, Options> JointDataPrismaticUnaligned;
    typedef pinocchio::JointDataMimicTpl<Scalar, Options, FixedBaseJointCollectionTpl> JointDataMimic;
    typedef boost::variant<JointDataRevoluteUnaligned, JointDataRevoluteUnboundedUnaligned, JointDataPrismaticUnaligned,
                           boost::recursive_wrapper<JointDataMimic>>
      JointDataVariant;
  };

  using FixedBaseModel = pinocchio::ModelTpl<double, 0, FixedBaseJointCollectionTpl>;
  using FixedBaseJoint = pinocchio::JointModelTpl<double, 0, FixedBaseJointCollectionTpl>;

  /// A joint of Pinocchio's default collection as its any-axis type of the fixed-base collection.
  struct ToFixedBaseJoint : boost::static_visitor<FixedBaseJoint>
  {
    using Axis = Eigen::Vector3d;
    template<int axis>
    FixedBaseJoint operator()(const pinocchio::JointModelRevoluteTpl<double, 0, axis> &) const
    {
      return FixedBaseJoint(pinocchio::JointModelRevoluteUnalignedTpl<double, 0>(Axis::Unit(axis)));
    }
    template<int axis>
    FixedBaseJoint operator()(const pinocchio::JointModelRevoluteUnboundedTpl<double, 0, axis> &) const
    {
      return FixedBaseJoint(pinocchio::JointModelRevoluteUnboundedUnalignedTpl<double, 0>(Axis::Unit(axis)));
    }
    template<int axis>
    FixedBaseJoint operator()(const pinocchio::JointModelPrismaticTpl<double, 0, axis> &) const
    {
      return FixedBaseJoint(pinocchio::JointModelPrismaticUnalignedTpl<double, 0>(Axis::Unit(axis)));
    }
    FixedBaseJoint operator()(const pinocchio::JointModelRevoluteUnalignedTpl<double, 0> & joint) const
    {
      return FixedBaseJoint(joint);
    }
    FixedBaseJoint operator()(const pinocchio::JointModelRevoluteUnboundedUnalignedTpl<double, 0> & joint) const
    {
      return FixedBaseJoint(joint);
    }
    FixedBaseJoint operator()(const pinocchio::JointModelPrismaticUnalignedTpl<double, 0> & joint) const
    {
      return FixedBaseJoint(joint);
    }
    template<typename J>
    FixedBaseJoint operator()(const J & joint) const
    {
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

  /// What every SX algorithm starts from: the same model (inertias, placements, gravity, ...) on
  /// the fixed-base joint collection with every number turned into an SX constant, its data, and
  /// the symbols q (nq) and v (nv).
  struct SXModel
  {
    ADModel model;
    ADData data;
    ConfigSymbol q;
    TangentSymbol v;

    explicit SXModel(const pinocchio::Model & numeric)
    : model(fixed_base_model(numeric).cast<SX>())
    , data(model)
    , q("q", numeric.nq)
    , v("v", numeric.nv)
    {
    }
  };
} // namespace fatigue_pin
