// Flat C ABI over DART 6.12 for diff-physics' `dart` engine (Rust side: src/dart/ffi.rs, which states the
// invariants). This layer only builds a DART world from arrays and forwards calls: every convention
// conversion (our state <-> DART's FreeJoint coordinates, slot order, armature, forces) is done in Rust.
//
// - One `UlabDart` owns one dart::simulation::World with the robot Skeleton (FreeJoint root + RevoluteJoints,
//   bodies in the caller's link order) and, optionally, a fixed ground Skeleton. DART's generalized
//   coordinates are used as they are: dofs 0..6 = FreeJoint [rotation vector (3), translation (3)],
//   velocities [angular (pelvis frame), linear of the pelvis origin (pelvis frame)], then one dof per link
//   1..n in link order.
// - Every function catches every C++ exception; functions that can fail return 0 on success and a non-zero
//   code with a NUL-terminated message in `err` (capacity `err_len`) otherwise.
// - Creation and destruction hold one process-wide mutex: ODE's global initialisation (dInitODE2/dCloseODE,
//   reference counted, not thread-safe) runs there, and so does the one-time set-up of DART's process-wide
//   contact constraint parameters (ContactConstraint statics: ERP, CFM, ...).
#include <dart/collision/CollisionObject.hpp>
#include <dart/collision/CollisionResult.hpp>
#include <dart/collision/dart/DARTCollisionDetector.hpp>
#include <dart/collision/fcl/FCLCollisionDetector.hpp>
#include <dart/collision/ode/OdeCollisionDetector.hpp>
#include <dart/config.hpp>
#include <dart/constraint/BoxedLcpConstraintSolver.hpp>
#include <dart/constraint/ContactConstraint.hpp>
#include <dart/constraint/DantzigBoxedLcpSolver.hpp>
#include <dart/constraint/JointLimitConstraint.hpp>
#include <dart/constraint/PgsBoxedLcpSolver.hpp>
#include <dart/dynamics/BodyNode.hpp>
#include <dart/dynamics/BoxShape.hpp>
#include <dart/dynamics/CapsuleShape.hpp>
#include <dart/dynamics/CylinderShape.hpp>
#include <dart/dynamics/FreeJoint.hpp>
#include <dart/dynamics/PlaneShape.hpp>
#include <dart/dynamics/RevoluteJoint.hpp>
#include <dart/dynamics/ShapeNode.hpp>
#include <dart/dynamics/Skeleton.hpp>
#include <dart/dynamics/SphereShape.hpp>
#include <dart/dynamics/WeldJoint.hpp>
#include <dart/simulation/World.hpp>
#include <dart/utils/urdf/DartLoader.hpp>
#include <ode/ode.h>

#include <cstdint>
#include <cstring>
#include <exception>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

using dart::dynamics::BodyNode;
using dart::dynamics::SkeletonPtr;

extern "C" {

/// One model link (parents before children; index 0 is the floating base, whose joint fields are ignored).
struct UlabDartLink {
  const char* name;        // link (BodyNode) name, NUL-terminated
  const char* joint_name;  // parent joint name (ignored for the base)
  int32_t parent;          // parent link index, -1 for the base
  double mass;
  double com[3];           // centre of mass in the link frame
  double inertia[9];       // inertia about the COM in the link frame, row-major
  double joint_pos[3];     // joint frame in the parent link frame at q = 0: translation
  double joint_quat[4];    // and rotation [w, x, y, z]; the child link frame is the joint frame
  double axis[3];          // unit rotation axis in the joint (= child link) frame
  double lower, upper;     // position limits (rad)
  double armature;         // reflected rotor inertia of the dof (see ArmatureRevoluteJoint)
  double damping;          // DART viscous damping coefficient of the dof (implicit in DART's ABA)
  double coulomb_friction; // DART Coulomb joint friction (a velocity constraint of the LCP)
  uint32_t first_shape;    // collision shapes of this link: shapes[first_shape .. first_shape + num_shapes]
  uint32_t num_shapes;
};

/// A collision primitive in its link's frame. kind: 0 box (half extents a, b, c), 1 sphere (radius a),
/// 2 capsule (radius a, half cylinder length b, along z), 3 cylinder (radius a, half length b, along z).
struct UlabDartShape {
  int32_t kind;
  double a, b, c;
  double pos[3];
  double quat[4];  // [w, x, y, z]
};

struct UlabDartWorldSettings {
  double timestep;
  double gravity[3];
  int32_t ground;          // add the fixed ground plane z = 0
  int32_t limits;          // Joint::setLimitEnforcement(true) on every revolute joint
  int32_t self_collision;  // robot self-collision (adjacent bodies excluded)
  double friction;         // Coulomb friction coefficient of every shape (DART combines pairs with min)
  double restitution;      // restitution coefficient of every shape (DART combines pairs with product)
  int32_t collision_detector;  // 0 ODE, 1 FCL, 2 DART
  int32_t lcp_solver;          // primary boxed LCP solver: 0 Dantzig, 1 PGS
  int32_t secondary_pgs;       // PGS fallback when the primary fails
  uint32_t pgs_iterations;     // max iterations of PGS (primary or fallback)
  uint32_t max_contacts;       // CollisionOption::maxNumContacts
  double error_allowance;      // ContactConstraint statics (process-wide)
  double error_reduction;
  double max_error_reduction_velocity;
  double constraint_force_mixing;
};

/// The state in DART's generalized coordinates.
struct UlabDartContact {
  int32_t link1;  // link index, or -1 for the ground
  int32_t link2;
  double point[3];
  double normal[3];  // DART: from body 2 to body 1 (world)
  double force[3];   // DART: force on body 1 (world)
  double depth;
};

struct UlabDart;

}  // extern "C"

namespace {

std::mutex& global_mutex() {
  static std::mutex m;
  return m;
}

struct ContactParams {
  bool set = false;
  double allowance = 0, erp = 0, erv = 0, cfm = 0;
};

ContactParams& contact_params() {
  static ContactParams p;
  return p;
}

void write_err(char* err, size_t len, const std::string& msg) {
  if (err == nullptr || len == 0) return;
  const size_t n = std::min(len - 1, msg.size());
  std::memcpy(err, msg.data(), n);
  err[n] = '\0';
}

Eigen::Isometry3d iso(const double p[3], const double q[4]) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  t.translation() = Eigen::Vector3d(p[0], p[1], p[2]);
  return t;
}

std::shared_ptr<dart::collision::CollisionDetector> make_detector(int32_t kind) {
  switch (kind) {
    case 0: return dart::collision::OdeCollisionDetector::create();
    case 1: return dart::collision::FCLCollisionDetector::create();
    case 2: return dart::collision::DARTCollisionDetector::create();
    default: throw std::invalid_argument("unknown collision detector " + std::to_string(kind));
  }
}

std::shared_ptr<dart::constraint::BoxedLcpSolver> make_pgs(uint32_t iterations) {
  auto pgs = std::make_shared<dart::constraint::PgsBoxedLcpSolver>();
  auto opt = pgs->getOption();
  opt.mMaxIteration = static_cast<int>(iterations);
  pgs->setOption(opt);
  return pgs;
}

}  // namespace

/// A RevoluteJoint with armature (reflected rotor inertia `a`), which DART 6.12 does not have. In Featherstone's
/// articulated-body algorithm armature enters exactly one place: the joint's projected articulated inertia
/// `SᵀIᴬS`, which becomes `SᵀIᴬS + a`. DART computes the inverse of that scalar in two protected virtuals of
/// GenericJoint (the plain one, used by impulse dynamics and the propagation of articulated inertia to the
/// parent, and the "implicit" one, which adds dt·damping + dt²·stiffness for the smooth step); both are
/// recomputed here with `+ a`, so forward dynamics, constraint impulses (contacts, limits, joint friction)
/// and the inertia propagated to the ancestors all see the armature, as `M + diag(a)` prescribes.
/// Only FORCE/PASSIVE actuation (the only one used here) goes through these functions.
class ArmatureRevoluteJoint : public dart::dynamics::RevoluteJoint {
 public:
  ArmatureRevoluteJoint(const Properties& properties, double armature)
      : dart::dynamics::RevoluteJoint(properties), mArmature(armature) {}
  explicit ArmatureRevoluteJoint(const Properties& properties) : ArmatureRevoluteJoint(properties, 0.0) {}
  double armature() const { return mArmature; }
  void setArmature(double a) { mArmature = a; }

 protected:
  void updateInvProjArtInertia(const Eigen::Matrix6d& artInertia) override {
    const Eigen::Vector6d s = dart::dynamics::GenericJoint<dart::math::R1Space>::getRelativeJacobianStatic();
    mInvProjArtInertia(0, 0) = 1.0 / (s.dot(artInertia * s) + mArmature);
  }
  void updateInvProjArtInertiaImplicit(const Eigen::Matrix6d& artInertia, double dt) override {
    const Eigen::Vector6d s = dart::dynamics::GenericJoint<dart::math::R1Space>::getRelativeJacobianStatic();
    const double damping = getDampingCoefficient(0);
    const double stiffness = getSpringStiffness(0);
    mInvProjArtInertiaImplicit(0, 0) = 1.0 / (s.dot(artInertia * s) + mArmature + dt * damping + dt * dt * stiffness);
  }
  dart::dynamics::Joint* clone() const override {
    return new ArmatureRevoluteJoint(getRevoluteJointProperties(), mArmature);
  }

 private:
  double mArmature;
};

struct UlabDart {
  dart::simulation::WorldPtr world;
  SkeletonPtr robot;
  SkeletonPtr ground;
  std::vector<BodyNode*> bodies;  // link order
  size_t ndofs = 0;
};

namespace {

void add_shapes(BodyNode* bn, const UlabDartLink& l, const UlabDartShape* shapes, size_t nshapes,
                const UlabDartWorldSettings& s) {
  for (uint32_t k = 0; k < l.num_shapes; ++k) {
    const size_t idx = static_cast<size_t>(l.first_shape) + k;
    if (idx >= nshapes) throw std::invalid_argument("shape index out of range");
    const UlabDartShape& sh = shapes[idx];
    dart::dynamics::ShapePtr shape;
    switch (sh.kind) {
      case 0: shape = std::make_shared<dart::dynamics::BoxShape>(Eigen::Vector3d(2 * sh.a, 2 * sh.b, 2 * sh.c)); break;
      case 1: shape = std::make_shared<dart::dynamics::SphereShape>(sh.a); break;
      case 2: shape = std::make_shared<dart::dynamics::CapsuleShape>(sh.a, 2 * sh.b); break;
      case 3: shape = std::make_shared<dart::dynamics::CylinderShape>(sh.a, 2 * sh.b); break;
      default: throw std::invalid_argument("unknown shape kind " + std::to_string(sh.kind));
    }
    auto* node = bn->createShapeNodeWith<dart::dynamics::CollisionAspect, dart::dynamics::DynamicsAspect>(
        shape, bn->getName() + ":collision" + std::to_string(k));
    node->setRelativeTransform(iso(sh.pos, sh.quat));
    node->getDynamicsAspect()->setFrictionCoeff(s.friction);
    node->getDynamicsAspect()->setRestitutionCoeff(s.restitution);
  }
}

UlabDart* build(const UlabDartLink* links, size_t nlinks, const UlabDartShape* shapes, size_t nshapes,
                const UlabDartWorldSettings& s) {
  if (nlinks == 0 || links[0].parent != -1) throw std::invalid_argument("link 0 must be the floating base");
  auto out = std::make_unique<UlabDart>();
  out->world = dart::simulation::World::create("ulab");
  out->world->setTimeStep(s.timestep);
  out->world->setGravity(Eigen::Vector3d(s.gravity[0], s.gravity[1], s.gravity[2]));

  // Constraint solver: boxed LCP (primary Dantzig or PGS, optional PGS fallback) with the chosen detector.
  std::shared_ptr<dart::constraint::BoxedLcpSolver> primary;
  if (s.lcp_solver == 0) {
    primary = std::make_shared<dart::constraint::DantzigBoxedLcpSolver>();
  } else if (s.lcp_solver == 1) {
    primary = make_pgs(s.pgs_iterations);
  } else {
    throw std::invalid_argument("unknown LCP solver " + std::to_string(s.lcp_solver));
  }
  auto solver = std::make_unique<dart::constraint::BoxedLcpConstraintSolver>(
      primary, s.secondary_pgs ? make_pgs(s.pgs_iterations) : nullptr);
  out->world->setConstraintSolver(std::move(solver));
  out->world->getConstraintSolver()->setCollisionDetector(make_detector(s.collision_detector));
  out->world->getConstraintSolver()->getCollisionOption().maxNumContacts = s.max_contacts;

  SkeletonPtr robot = dart::dynamics::Skeleton::create("robot");
  out->bodies.reserve(nlinks);
  for (size_t i = 0; i < nlinks; ++i) {
    const UlabDartLink& l = links[i];
    dart::dynamics::BodyNode::Properties body;
    body.mName = l.name;
    Eigen::Matrix3d inertia;
    inertia << l.inertia[0], l.inertia[1], l.inertia[2], l.inertia[3], l.inertia[4], l.inertia[5], l.inertia[6],
        l.inertia[7], l.inertia[8];
    body.mInertia = dart::dynamics::Inertia(l.mass, Eigen::Vector3d(l.com[0], l.com[1], l.com[2]), inertia);
    BodyNode* bn = nullptr;
    if (i == 0) {
      dart::dynamics::FreeJoint::Properties free;
      free.mName = "root_free_joint";
      bn = robot->createJointAndBodyNodePair<dart::dynamics::FreeJoint>(nullptr, free, body).second;
    } else {
      if (l.parent < 0 || static_cast<size_t>(l.parent) >= i) {
        throw std::invalid_argument("link " + std::string(l.name) + ": parent must precede it");
      }
      dart::dynamics::RevoluteJoint::Properties joint;
      joint.mName = l.joint_name;
      joint.mT_ParentBodyToJoint = iso(l.joint_pos, l.joint_quat);
      joint.mT_ChildBodyToJoint = Eigen::Isometry3d::Identity();
      joint.mAxis = Eigen::Vector3d(l.axis[0], l.axis[1], l.axis[2]);
      joint.mPositionLowerLimits[0] = l.lower;
      joint.mPositionUpperLimits[0] = l.upper;
      joint.mDampingCoefficients[0] = l.damping;
      joint.mFrictions[0] = l.coulomb_friction;
      joint.mIsPositionLimitEnforced = s.limits != 0;
      joint.mActuatorType = dart::dynamics::Joint::FORCE;
      auto pair = robot->createJointAndBodyNodePair<ArmatureRevoluteJoint>(out->bodies[l.parent], joint, body);
      pair.first->setArmature(l.armature);
      bn = pair.second;
    }
    if (bn == nullptr || bn->getName() != l.name) {
      throw std::invalid_argument("DART renamed or refused body " + std::string(l.name));
    }
    add_shapes(bn, l, shapes, nshapes, s);
    out->bodies.push_back(bn);
  }
  if (s.self_collision) {
    robot->enableSelfCollisionCheck();
    robot->disableAdjacentBodyCheck();
  } else {
    robot->disableSelfCollisionCheck();
  }
  out->ndofs = robot->getNumDofs();
  if (out->ndofs != 6 + (nlinks - 1)) throw std::runtime_error("unexpected number of dofs");
  out->world->addSkeleton(robot);
  out->robot = robot;

  if (s.ground) {
    SkeletonPtr ground = dart::dynamics::Skeleton::create("ground");
    dart::dynamics::BodyNode::Properties body;
    body.mName = "ground";
    BodyNode* bn = ground->createJointAndBodyNodePair<dart::dynamics::WeldJoint>(nullptr, {}, body).second;
    dart::dynamics::ShapePtr shape;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    if (s.collision_detector == 2) {
      // DART's own detector has no plane: a 1 m thick slab whose top face is z = 0.
      shape = std::make_shared<dart::dynamics::BoxShape>(Eigen::Vector3d(1000.0, 1000.0, 1.0));
      pose.translation() = Eigen::Vector3d(0.0, 0.0, -0.5);
    } else {
      shape = std::make_shared<dart::dynamics::PlaneShape>(Eigen::Vector3d::UnitZ(), 0.0);
    }
    auto* node = bn->createShapeNodeWith<dart::dynamics::CollisionAspect, dart::dynamics::DynamicsAspect>(
        shape, "ground:collision");
    node->setRelativeTransform(pose);
    node->getDynamicsAspect()->setFrictionCoeff(s.friction);
    node->getDynamicsAspect()->setRestitutionCoeff(s.restitution);
    ground->setMobile(false);
    out->world->addSkeleton(ground);
    out->ground = ground;
  }
  // addSkeleton hands the world's gravity and timestep to each skeleton; set them again to be explicit.
  out->world->setGravity(Eigen::Vector3d(s.gravity[0], s.gravity[1], s.gravity[2]));
  out->world->setTimeStep(s.timestep);
  return out.release();
}

int32_t link_index(const UlabDart* d, const dart::collision::CollisionObject* obj) {
  if (obj == nullptr) return -2;
  const auto* frame = obj->getShapeFrame();
  const auto* node = frame ? frame->asShapeNode() : nullptr;
  if (node == nullptr) return -2;
  const BodyNode* bn = node->getBodyNodePtr().get();
  if (d->ground && bn->getSkeleton() == d->ground) return -1;
  return static_cast<int32_t>(bn->getIndexInSkeleton());
}

template <typename F>
int guarded(char* err, size_t err_len, F&& f) {
  try {
    f();
    return 0;
  } catch (const std::exception& e) {
    write_err(err, err_len, e.what());
    return 1;
  } catch (...) {
    write_err(err, err_len, "unknown C++ exception");
    return 2;
  }
}

}  // namespace

extern "C" {

/// "DART <version>, ODE <configuration>".
void ulab_dart_version(char* out, size_t len) {
  std::ostringstream s;
  s << "DART " << DART_VERSION << " (ODE " << dGetConfiguration() << ")";
  write_err(out, len, s.str());
}

/// Builds a world. `base_pose` = pelvis position (3) + quaternion [w, x, y, z] (4); `q` = nlinks - 1 joint
/// angles in link order; `vel` = DART velocities (ndofs = 6 + nlinks - 1).
int ulab_dart_create(const UlabDartLink* links, size_t nlinks, const UlabDartShape* shapes, size_t nshapes,
                     const UlabDartWorldSettings* settings, const double* base_pose, const double* q,
                     const double* vel, UlabDart** out, char* err, size_t err_len) {
  return guarded(err, err_len, [&] {
    *out = nullptr;
    std::lock_guard<std::mutex> lock(global_mutex());
    ContactParams& cp = contact_params();
    const UlabDartWorldSettings& s = *settings;
    using CC = dart::constraint::ContactConstraint;
    if (!cp.set) {
      CC::setErrorAllowance(s.error_allowance);
      CC::setErrorReductionParameter(s.error_reduction);
      CC::setMaxErrorReductionVelocity(s.max_error_reduction_velocity);
      CC::setConstraintForceMixing(s.constraint_force_mixing);
      cp = ContactParams{true, s.error_allowance, s.error_reduction, s.max_error_reduction_velocity,
                         s.constraint_force_mixing};
    } else if (cp.allowance != s.error_allowance || cp.erp != s.error_reduction ||
               cp.erv != s.max_error_reduction_velocity || cp.cfm != s.constraint_force_mixing) {
      std::ostringstream m;
      m << "DART's contact parameters are process-wide and already set to allowance " << cp.allowance << ", ERP "
        << cp.erp << ", max ERV " << cp.erv << ", CFM " << cp.cfm << " by another engine in this process";
      throw std::invalid_argument(m.str());
    }
    std::unique_ptr<UlabDart> d(build(links, nlinks, shapes, nshapes, s));
    Eigen::VectorXd pos(d->ndofs);
    pos.head<6>() = dart::dynamics::FreeJoint::convertToPositions(iso(base_pose, base_pose + 3));
    for (size_t i = 0; i + 6 < d->ndofs; ++i) pos[6 + i] = q[i];
    d->robot->setPositions(pos);
    d->robot->setVelocities(Eigen::Map<const Eigen::VectorXd>(vel, d->ndofs));
    d->robot->setAccelerations(Eigen::VectorXd::Zero(d->ndofs));
    d->robot->resetGeneralizedForces();
    *out = d.release();
  });
}

void ulab_dart_destroy(UlabDart* d) {
  if (d == nullptr) return;
  std::lock_guard<std::mutex> lock(global_mutex());
  try {
    delete d;
  } catch (...) {
  }
}

size_t ulab_dart_ndofs(const UlabDart* d) { return d->ndofs; }

/// One World::step with generalized forces `forces` (ndofs, DART coordinates), cleared after the step.
int ulab_dart_step(UlabDart* d, const double* forces, char* err, size_t err_len) {
  return guarded(err, err_len, [&] {
    d->robot->setForces(Eigen::Map<const Eigen::VectorXd>(forces, d->ndofs));
    d->world->step(true);
  });
}

double ulab_dart_time(const UlabDart* d) { return d->world->getTime(); }

/// Pelvis pose (position 3 + quaternion [w, x, y, z] 4), joint angles (link order), DART velocities.
int ulab_dart_state(UlabDart* d, double* base_pose, double* q, double* vel, char* err, size_t err_len) {
  return guarded(err, err_len, [&] {
    const Eigen::Isometry3d& t = d->bodies[0]->getWorldTransform();
    Eigen::Quaterniond r(t.linear());
    for (int k = 0; k < 3; ++k) base_pose[k] = t.translation()[k];
    base_pose[3] = r.w();
    base_pose[4] = r.x();
    base_pose[5] = r.y();
    base_pose[6] = r.z();
    const Eigen::VectorXd& p = d->robot->getPositions();
    for (size_t i = 6; i < d->ndofs; ++i) q[i - 6] = p[i];
    Eigen::Map<Eigen::VectorXd>(vel, d->ndofs) = d->robot->getVelocities();
  });
}

size_t ulab_dart_num_contacts(const UlabDart* d) {
  return d->world->getLastCollisionResult().getNumContacts();
}

/// Contacts of the last step (detected before the step's position update), at most `cap`; returns the count.
size_t ulab_dart_contacts(const UlabDart* d, UlabDartContact* out, size_t cap) {
  const auto& r = d->world->getLastCollisionResult();
  const size_t n = std::min(cap, r.getNumContacts());
  for (size_t i = 0; i < n; ++i) {
    const auto& c = r.getContact(i);
    UlabDartContact& o = out[i];
    o.link1 = link_index(d, c.collisionObject1);
    o.link2 = link_index(d, c.collisionObject2);
    for (int k = 0; k < 3; ++k) {
      o.point[k] = c.point[k];
      o.normal[k] = c.normal[k];
      o.force[k] = c.force[k];
    }
    o.depth = c.penetrationDepth;
  }
  return n;
}

/// World pose of every body (link) frame: 7 values each (position, quaternion [w, x, y, z]).
void ulab_dart_link_poses(const UlabDart* d, double* out) {
  for (size_t i = 0; i < d->bodies.size(); ++i) {
    const Eigen::Isometry3d& t = d->bodies[i]->getWorldTransform();
    Eigen::Quaterniond r(t.linear());
    double* o = out + 7 * i;
    for (int k = 0; k < 3; ++k) o[k] = t.translation()[k];
    o[3] = r.w();
    o[4] = r.x();
    o[5] = r.y();
    o[6] = r.z();
  }
}

/// World axes of the revolute joints (link order, links 1..n), 3 values each.
void ulab_dart_joint_axes(const UlabDart* d, double* out) {
  for (size_t i = 1; i < d->bodies.size(); ++i) {
    const auto* j = static_cast<const dart::dynamics::RevoluteJoint*>(d->bodies[i]->getParentJoint());
    // The joint frame is the child body frame (identity child-to-joint transform).
    const Eigen::Vector3d a = d->bodies[i]->getWorldTransform().linear() * j->getAxis();
    for (int k = 0; k < 3; ++k) out[3 * (i - 1) + k] = a[k];
  }
}

/// Position limits as built (link order, links 1..n) and how many joints enforce them.
size_t ulab_dart_joint_limits(const UlabDart* d, double* lower, double* upper) {
  size_t enforced = 0;
  for (size_t i = 1; i < d->bodies.size(); ++i) {
    const auto* j = d->bodies[i]->getParentJoint();
    lower[i - 1] = j->getPositionLowerLimit(0);
    upper[i - 1] = j->getPositionUpperLimit(0);
    enforced += j->areLimitsEnforced() ? 1 : 0;
  }
  return enforced;
}

void ulab_dart_link_masses(const UlabDart* d, double* out) {
  for (size_t i = 0; i < d->bodies.size(); ++i) out[i] = d->bodies[i]->getMass();
}

void ulab_dart_com(const UlabDart* d, double* out) {
  const Eigen::Vector3d c = d->robot->getCOM();
  for (int k = 0; k < 3; ++k) out[k] = c[k];
}

/// Skeleton::computeKineticEnergy (rigid bodies) and computePotentialEnergy (gravity, springs).
void ulab_dart_energy(const UlabDart* d, double* kinetic, double* potential) {
  *kinetic = d->robot->computeKineticEnergy();
  *potential = d->robot->computePotentialEnergy();
}

/// Skeleton::getMassMatrix (ndofs x ndofs, row-major, DART coordinates).
int ulab_dart_mass_matrix(const UlabDart* d, double* out, char* err, size_t err_len) {
  return guarded(err, err_len, [&] {
    const Eigen::MatrixXd& m = d->robot->getMassMatrix();
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(out, d->ndofs, d->ndofs) = m;
  });
}

/// Skeleton::getCoriolisAndGravityForces (ndofs, DART coordinates).
int ulab_dart_bias_forces(const UlabDart* d, double* out, char* err, size_t err_len) {
  return guarded(err, err_len, [&] {
    Eigen::Map<Eigen::VectorXd>(out, d->ndofs) = d->robot->getCoriolisAndGravityForces();
  });
}

/// Skeleton::computeForwardDynamics under generalized forces `forces` (DART's articulated-body algorithm with
/// its implicit joint damping and springs; no constraints). Positions, velocities, forces and accelerations
/// are restored afterwards.
int ulab_dart_forward_dynamics(UlabDart* d, const double* forces, double* acc, char* err, size_t err_len) {
  return guarded(err, err_len, [&] {
    const Eigen::VectorXd saved_forces = d->robot->getForces();
    const Eigen::VectorXd saved_acc = d->robot->getAccelerations();
    d->robot->setForces(Eigen::Map<const Eigen::VectorXd>(forces, d->ndofs));
    d->robot->computeForwardDynamics();
    Eigen::Map<Eigen::VectorXd>(acc, d->ndofs) = d->robot->getAccelerations();
    d->robot->setForces(saved_forces);
    d->robot->setAccelerations(saved_acc);
  });
}

/// The process-wide constraint parameters in force: allowance, ERP, max ERV, CFM of contacts (out[0..4]), then
/// of joint limits (out[4..8], DART's defaults, never changed here).
void ulab_dart_constraint_params(double* out) {
  using CC = dart::constraint::ContactConstraint;
  using JL = dart::constraint::JointLimitConstraint;
  std::lock_guard<std::mutex> lock(global_mutex());
  out[0] = CC::getErrorAllowance();
  out[1] = CC::getErrorReductionParameter();
  out[2] = CC::getMaxErrorReductionVelocity();
  out[3] = CC::getConstraintForceMixing();
  out[4] = JL::getErrorAllowance();
  out[5] = JL::getErrorReductionParameter();
  out[6] = JL::getMaxErrorReductionVelocity();
  out[7] = JL::getConstraintForceMixing();
}

/// Independent route for tests: DART's own URDF loader (urdfdom + dart::utils::DartLoader, floating root).
/// Outputs the loaded skeleton's total mass, its mass matrix in DART coordinates ordered [free joint (6),
/// joints in `joint_names` order] at the given pelvis pose and joint angles (same order), and, per joint in
/// that order, whether DART enforces its limits, its damping and Coulomb friction as loaded.
int ulab_dart_urdf_probe(const char* urdf, const char* const* joint_names, size_t nj, const double* base_pose,
                         const double* q, double* total_mass, double* mass_matrix, int32_t* limits_enforced,
                         double* damping, double* friction, char* err, size_t err_len) {
  return guarded(err, err_len, [&] {
    std::lock_guard<std::mutex> lock(global_mutex());
    dart::utils::DartLoader loader;
    SkeletonPtr skel = loader.parseSkeletonString(urdf, dart::common::Uri("file:///ulab/robot.urdf"));
    if (!skel) throw std::runtime_error("DartLoader could not parse the URDF");
    if (skel->getNumDofs() != 6 + nj) {
      throw std::runtime_error("URDF skeleton has " + std::to_string(skel->getNumDofs()) + " dofs");
    }
    std::vector<size_t> dof(6 + nj);
    for (size_t k = 0; k < 6; ++k) dof[k] = k;
    Eigen::VectorXd pos = Eigen::VectorXd::Zero(skel->getNumDofs());
    pos.head<6>() = dart::dynamics::FreeJoint::convertToPositions(iso(base_pose, base_pose + 3));
    for (size_t i = 0; i < nj; ++i) {
      auto* j = skel->getJoint(joint_names[i]);
      if (j == nullptr || j->getNumDofs() != 1) throw std::runtime_error(std::string("joint ") + joint_names[i]);
      dof[6 + i] = j->getIndexInSkeleton(0);
      pos[dof[6 + i]] = q[i];
      limits_enforced[i] = j->areLimitsEnforced() ? 1 : 0;
      damping[i] = j->getDampingCoefficient(0);
      friction[i] = j->getCoulombFriction(0);
    }
    skel->setPositions(pos);
    *total_mass = skel->getMass();
    const Eigen::MatrixXd& m = skel->getMassMatrix();
    const size_t n = 6 + nj;
    for (size_t r = 0; r < n; ++r)
      for (size_t c = 0; c < n; ++c) mass_matrix[r * n + c] = m(dof[r], dof[c]);
  });
}

}  // extern "C"
