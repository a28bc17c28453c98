// Flat C ABI over Bullet's Featherstone btMultiBody (double precision) for diff-physics' `bullet` engine.
//
// The Rust side (src/bullet/) does every geometric conversion (principal inertia frames, joint frames, state
// conventions); this layer only builds Bullet objects from ready arrays, steps, and reads results back. Each
// exported function catches every C++ exception and returns a non-zero code with the message in `err`.
//
// Ownership: a UbtSim owns every Bullet object it creates (world, solver, broadphase, dispatcher, multibody,
// colliders, shapes, constraints) and the descriptions it was created from; ubt_destroy frees all of it.
// ubt_reset tears the whole Bullet world down and rebuilds it from those descriptions, so no warm start,
// contact manifold, broadphase pair order or solver history survives a reset.
#include <btBulletDynamicsCommon.h>
#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyConstraintSolver.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointLimitConstraint.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointMotor.h>
#include <BulletDynamics/Featherstone/btMultiBodyLinkCollider.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

static_assert(sizeof(btScalar) == sizeof(double), "diff-physics needs the double-precision Bullet (bullet-float64)");

extern "C" {

// One body of the tree. Index 0 is the floating base; parents precede children. Frames are Bullet's: each body
// frame sits at the body's centre of mass along its principal inertia axes.
struct UbtBody {
    int32_t parent;  // parent body index (0 = base); -1 for the base itself
    int32_t reserved;
    double mass;
    double inertia[3];              // principal moments (kg m^2)
    double rot_parent_to_this[4];   // x y z w: rotates parent-body-frame coordinates into this frame at q = 0
    double axis[3];                 // joint axis, this body frame (unit)
    double parent_com_to_pivot[3];  // parent body frame
    double pivot_to_com[3];         // this body frame
    double lower, upper;            // joint limits (rad), used when the config enables limits
    double friction_torque;         // dry joint friction (N m): zero-velocity motor; 0 = none
};

// A collision primitive attached to a body, placed in that body's frame.
struct UbtShape {
    int32_t body;
    int32_t kind;     // 0 box (half extents), 1 sphere (radius), 2 capsule along z (radius, half length),
                      // 3 cylinder along z (radius, half length)
    double dims[3];
    double pos[3];
    double quat[4];   // x y z w
};

struct UbtConfig {
    double timestep;
    double gravity[3];
    int32_t ground;                 // 0 none, 1 btStaticPlaneShape z = 0, 2 large box with its top face at z = 0
    int32_t collisions;             // 0: no robot shapes at all
    int32_t joint_limits;           // 1: a btMultiBodyJointLimitConstraint per joint
    int32_t self_collision;
    int32_t solver_iterations;
    int32_t gyroscopic;             // btMultiBody::setUseGyroTerm
    double friction;                // robot collider friction (the ground's is 1: Bullet multiplies the two)
    double restitution;
    double rolling_friction;
    double spinning_friction;
    double erp;                     // non-contact constraints (joint limits)
    double erp2;                    // contacts
    double global_cfm;
    double friction_erp;
    double warmstarting_factor;
    double articulated_warmstarting_factor;
    int32_t solver_mode;            // btContactSolverInfo::m_solverMode bit set
    int32_t reserved;
    double collision_margin;        // convex margin of boxes and cylinders (spheres and capsules: their radius)
    double max_coordinate_velocity;
    double joint_limit_max_impulse;
    double linear_damping;          // btMultiBody's own velocity damping (Bullet default 0.04)
    double angular_damping;
};

struct UbtBaseState {
    double pos[3];      // base body (COM) position, world
    double quat[4];     // x y z w, base-body-to-world
    double lin_vel[3];  // COM velocity, world
    double ang_vel[3];  // world
};

struct UbtContact {
    int32_t user_a;  // body index of the first object, -1 for the ground
    int32_t user_b;
    double point_a[3];
    double point_b[3];
    double normal_on_b[3];  // world, on object b pointing towards a
    double distance;        // < 0: penetration
    double impulse;         // normal impulse of the last step (N s)
};

}  // extern "C"

namespace {

void write_err(char* err, size_t len, const char* msg) {
    if (err == nullptr || len == 0) return;
    std::strncpy(err, msg, len - 1);
    err[len - 1] = '\0';
}

btVector3 v3(const double* v) { return btVector3(v[0], v[1], v[2]); }
btQuaternion q4(const double* q) { return btQuaternion(q[0], q[1], q[2], q[3]); }

// Bullet objects of one built world, destroyed in reverse order of dependency.
struct World {
    std::unique_ptr<btDefaultCollisionConfiguration> config;
    std::unique_ptr<btCollisionDispatcher> dispatcher;
    std::unique_ptr<btDbvtBroadphase> broadphase;
    std::unique_ptr<btMultiBodyConstraintSolver> solver;
    std::unique_ptr<btMultiBodyDynamicsWorld> world;
    std::unique_ptr<btMultiBody> body;
    std::vector<std::unique_ptr<btCollisionShape>> shapes;
    std::vector<std::unique_ptr<btCompoundShape>> compounds;
    std::vector<std::unique_ptr<btMultiBodyLinkCollider>> colliders;
    std::vector<std::unique_ptr<btMultiBodyConstraint>> constraints;
    std::vector<const btMultiBodyJointLimitConstraint*> limits;  // per link when limits are on (owned above)
    std::unique_ptr<btCollisionShape> ground_shape;
    std::unique_ptr<btCollisionObject> ground;

    ~World() {
        if (world) {
            for (auto& c : constraints) world->removeMultiBodyConstraint(c.get());
            for (auto& c : colliders) world->removeCollisionObject(c.get());
            if (ground) world->removeCollisionObject(ground.get());
            if (body) world->removeMultiBody(body.get());
        }
        world.reset();
        constraints.clear();
        colliders.clear();
        ground.reset();
        body.reset();
        compounds.clear();
        shapes.clear();
        ground_shape.reset();
        solver.reset();
        broadphase.reset();
        dispatcher.reset();
        config.reset();
    }
};

// Collision filter groups: robot shapes collide with the ground only (unless self-collision is on).
const int ROBOT_GROUP = 1 << 6;
const int GROUND_GROUP = 1 << 7;
const int PLACEHOLDER_GROUP = 1 << 8;

}  // namespace

struct UbtSim {
    UbtConfig cfg;
    std::vector<UbtBody> bodies;
    std::vector<UbtShape> shapes;
    std::unique_ptr<World> w;
    btAlignedObjectArray<btScalar> scratch_r;
    btAlignedObjectArray<btVector3> scratch_v;
    btAlignedObjectArray<btMatrix3x3> scratch_m;
    btAlignedObjectArray<btQuaternion> scratch_q;
    btAlignedObjectArray<btVector3> scratch_o;

    int nlinks() const { return static_cast<int>(bodies.size()) - 1; }

    void build() {
        w.reset();
        auto nw = std::make_unique<World>();
        nw->config = std::make_unique<btDefaultCollisionConfiguration>();
        nw->dispatcher = std::make_unique<btCollisionDispatcher>(nw->config.get());
        nw->broadphase = std::make_unique<btDbvtBroadphase>();
        nw->solver = std::make_unique<btMultiBodyConstraintSolver>();
        nw->world = std::make_unique<btMultiBodyDynamicsWorld>(nw->dispatcher.get(), nw->broadphase.get(),
                                                               nw->solver.get(), nw->config.get());
        btMultiBodyDynamicsWorld& world = *nw->world;
        world.setGravity(v3(cfg.gravity));
        btContactSolverInfo& si = world.getSolverInfo();
        si.m_timeStep = cfg.timestep;
        si.m_numIterations = cfg.solver_iterations;
        si.m_erp = cfg.erp;
        si.m_erp2 = cfg.erp2;
        si.m_globalCfm = cfg.global_cfm;
        si.m_frictionERP = cfg.friction_erp;
        si.m_warmstartingFactor = cfg.warmstarting_factor;
        si.m_articulatedWarmstartingFactor = cfg.articulated_warmstarting_factor;
        si.m_solverMode = cfg.solver_mode;

        const UbtBody& base = bodies[0];
        nw->body = std::make_unique<btMultiBody>(nlinks(), base.mass, v3(base.inertia), false, false);
        btMultiBody& mb = *nw->body;
        for (int i = 0; i < nlinks(); ++i) {
            const UbtBody& b = bodies[static_cast<size_t>(i) + 1];
            if (b.parent < 0 || b.parent > i) throw std::runtime_error("body parents must precede their children");
            mb.setupRevolute(i, b.mass, v3(b.inertia), b.parent - 1, q4(b.rot_parent_to_this), v3(b.axis),
                             v3(b.parent_com_to_pivot), v3(b.pivot_to_com), !cfg.self_collision);
        }
        mb.finalizeMultiDof();
        mb.setLinearDamping(cfg.linear_damping);
        mb.setAngularDamping(cfg.angular_damping);
        mb.setUseGyroTerm(cfg.gyroscopic != 0);
        mb.setMaxCoordinateVelocity(cfg.max_coordinate_velocity);
        mb.setHasSelfCollision(cfg.self_collision != 0);
        mb.setCanSleep(false);
        world.addMultiBody(&mb);

        // Every body gets a collider, also bodies without shapes and with collisions off: Bullet assigns joint
        // limits and motors to the simulation island of their link's collider and never solves a constraint
        // whose links have none (island id -1). Shape-less colliders are a 1 mm sphere that collides with
        // nothing (filter mask 0).
        std::vector<btCompoundShape*> compound_of(bodies.size(), nullptr);
        if (cfg.collisions) {
            for (const UbtShape& s : shapes) {
                if (s.body < 0 || static_cast<size_t>(s.body) >= bodies.size()) throw std::runtime_error("shape body out of range");
                std::unique_ptr<btCollisionShape> shape;
                switch (s.kind) {
                    case 0: shape = std::make_unique<btBoxShape>(v3(s.dims)); break;
                    case 1: shape = std::make_unique<btSphereShape>(s.dims[0]); break;
                    case 2: shape = std::make_unique<btCapsuleShapeZ>(s.dims[0], 2.0 * s.dims[1]); break;
                    case 3: shape = std::make_unique<btCylinderShapeZ>(btVector3(s.dims[0], s.dims[0], s.dims[1])); break;
                    default: throw std::runtime_error("unknown shape kind");
                }
                if (s.kind == 0 || s.kind == 3) shape->setMargin(cfg.collision_margin);
                size_t bi = static_cast<size_t>(s.body);
                if (compound_of[bi] == nullptr) {
                    nw->compounds.push_back(std::make_unique<btCompoundShape>());
                    compound_of[bi] = nw->compounds.back().get();
                }
                compound_of[bi]->addChildShape(btTransform(q4(s.quat), v3(s.pos)), shape.get());
                nw->shapes.push_back(std::move(shape));
            }
        }
        for (size_t bi = 0; bi < bodies.size(); ++bi) {
            const int link = static_cast<int>(bi) - 1;
            auto col = std::make_unique<btMultiBodyLinkCollider>(&mb, link);
            int group = ROBOT_GROUP;
            int mask = GROUND_GROUP | (cfg.self_collision ? ROBOT_GROUP : 0);
            if (compound_of[bi] != nullptr) {
                col->setCollisionShape(compound_of[bi]);
            } else {
                nw->shapes.push_back(std::make_unique<btSphereShape>(0.001));
                col->setCollisionShape(nw->shapes.back().get());
                group = PLACEHOLDER_GROUP;
                mask = 0;
            }
            col->setFriction(cfg.friction);
            col->setRestitution(cfg.restitution);
            col->setRollingFriction(cfg.rolling_friction);
            col->setSpinningFriction(cfg.spinning_friction);
            col->setUserIndex(static_cast<int>(bi));
            col->setActivationState(DISABLE_DEACTIVATION);
            if (link < 0) {
                mb.setBaseCollider(col.get());
            } else {
                mb.getLink(link).m_collider = col.get();
            }
            world.addCollisionObject(col.get(), group, mask);
            nw->colliders.push_back(std::move(col));
        }
        if (cfg.ground != 0) {
            if (cfg.ground == 1) {
                nw->ground_shape = std::make_unique<btStaticPlaneShape>(btVector3(0, 0, 1), 0.0);
            } else {
                auto box = std::make_unique<btBoxShape>(btVector3(1000.0, 1000.0, 1.0));
                box->setMargin(cfg.collision_margin);
                nw->ground_shape = std::move(box);
            }
            nw->ground = std::make_unique<btCollisionObject>();
            nw->ground->setCollisionShape(nw->ground_shape.get());
            btTransform g;
            g.setIdentity();
            if (cfg.ground == 2) g.setOrigin(btVector3(0, 0, -1.0));
            nw->ground->setWorldTransform(g);
            nw->ground->setFriction(1.0);
            nw->ground->setRestitution(1.0);
            nw->ground->setRollingFriction(0.0);
            nw->ground->setSpinningFriction(0.0);
            nw->ground->setUserIndex(-1);
            nw->ground->setCollisionFlags(btCollisionObject::CF_STATIC_OBJECT);
            world.addCollisionObject(nw->ground.get(), GROUND_GROUP, ROBOT_GROUP);
        }
        for (int i = 0; i < nlinks(); ++i) {
            const UbtBody& b = bodies[static_cast<size_t>(i) + 1];
            if (cfg.joint_limits) {
                auto lim = std::make_unique<btMultiBodyJointLimitConstraint>(&mb, i, b.lower, b.upper);
                lim->setMaxAppliedImpulse(cfg.joint_limit_max_impulse);
                lim->finalizeMultiDof();
                world.addMultiBodyConstraint(lim.get());
                nw->limits.push_back(lim.get());
                nw->constraints.push_back(std::move(lim));
            }
            if (b.friction_torque > 0.0) {
                // Coulomb joint friction: a motor driving the joint velocity to zero whose impulse per step is
                // bounded by friction x dt, solved together with contacts and limits.
                auto motor = std::make_unique<btMultiBodyJointMotor>(&mb, i, 0, 0.0, b.friction_torque * cfg.timestep);
                motor->setVelocityTarget(0.0, 1.0);
                motor->setPositionTarget(0.0, 0.0);
                motor->finalizeMultiDof();
                world.addMultiBodyConstraint(motor.get());
                nw->constraints.push_back(std::move(motor));
            }
        }
        w = std::move(nw);
    }

    void update_kinematics() {
        btMultiBody& mb = *w->body;
        scratch_q.resize(nlinks() + 1);
        scratch_o.resize(nlinks() + 1);
        mb.forwardKinematics(scratch_q, scratch_o);
        mb.updateCollisionObjectWorldTransforms(scratch_q, scratch_o);
    }
};

extern "C" {

int32_t ubt_version() { return btGetVersion(); }

int32_t ubt_create(const UbtConfig* cfg, const UbtBody* bodies, int32_t nbodies, const UbtShape* shapes,
                   int32_t nshapes, UbtSim** out, char* err, size_t errlen) {
    try {
        if (cfg == nullptr || bodies == nullptr || out == nullptr || nbodies < 1 || nshapes < 0 ||
            (nshapes > 0 && shapes == nullptr)) {
            throw std::runtime_error("invalid arguments");
        }
        auto sim = std::make_unique<UbtSim>();
        sim->cfg = *cfg;
        sim->bodies.assign(bodies, bodies + nbodies);
        sim->shapes.assign(shapes, shapes + nshapes);
        sim->build();
        sim->update_kinematics();
        *out = sim.release();
        return 0;
    } catch (const std::exception& e) {
        write_err(err, errlen, e.what());
        return 1;
    } catch (...) {
        write_err(err, errlen, "unknown C++ exception");
        return 1;
    }
}

void ubt_destroy(UbtSim* sim) {
    try {
        delete sim;
    } catch (...) {
    }
}

int32_t ubt_reset(UbtSim* sim, const UbtBaseState* base, const double* q, const double* qd, char* err, size_t errlen) {
    try {
        sim->build();
        btMultiBody& mb = *sim->w->body;
        // Set the quaternion itself (a btTransform would round-trip it through a matrix and may flip its sign).
        mb.setBasePos(v3(base->pos));
        mb.setWorldToBaseRot(q4(base->quat).inverse());
        mb.setBaseVel(v3(base->lin_vel));
        mb.setBaseOmega(v3(base->ang_vel));
        for (int i = 0; i < sim->nlinks(); ++i) {
            mb.setJointPos(i, q[i]);
            mb.setJointVel(i, qd[i]);
        }
        sim->update_kinematics();
        return 0;
    } catch (const std::exception& e) {
        write_err(err, errlen, e.what());
        return 1;
    } catch (...) {
        write_err(err, errlen, "unknown C++ exception");
        return 1;
    }
}

void ubt_get_state(const UbtSim* sim, UbtBaseState* base, double* q, double* qd) {
    const btMultiBody& mb = *sim->w->body;
    const btVector3& p = mb.getBasePos();
    // Bullet stores the world-to-base rotation; its conjugate is exact (no matrix round trip).
    const btQuaternion r = mb.getWorldToBaseRot().inverse();
    const btVector3 v = mb.getBaseVel();
    const btVector3 om = mb.getBaseOmega();
    for (int k = 0; k < 3; ++k) {
        base->pos[k] = p[k];
        base->lin_vel[k] = v[k];
        base->ang_vel[k] = om[k];
    }
    base->quat[0] = r.x();
    base->quat[1] = r.y();
    base->quat[2] = r.z();
    base->quat[3] = r.w();
    for (int i = 0; i < sim->nlinks(); ++i) {
        q[i] = mb.getJointPos(i);
        qd[i] = mb.getJointVel(i);
    }
}

// One step of the world with joint torques `tau` (one per link) and a force (world, through the base COM) and a
// torque (world) on the base; both 3-vectors, or null for none.
int32_t ubt_step(UbtSim* sim, const double* tau, const double* base_force, const double* base_torque, char* err,
                 size_t errlen) {
    try {
        btMultiBody& mb = *sim->w->body;
        for (int i = 0; i < sim->nlinks(); ++i) mb.addJointTorque(i, tau[i]);
        if (base_force) mb.addBaseForce(v3(base_force));
        if (base_torque) mb.addBaseTorque(v3(base_torque));
        // maxSubSteps = 0: exactly one internal step of `timestep`, no interpolation.
        sim->w->world->stepSimulation(sim->cfg.timestep, 0, sim->cfg.timestep);
        return 0;
    } catch (const std::exception& e) {
        write_err(err, errlen, e.what());
        return 1;
    } catch (...) {
        write_err(err, errlen, "unknown C++ exception");
        return 1;
    }
}

// World transforms of every body frame (base first): pos[3 n], quat[4 n] (x y z w).
void ubt_body_poses(UbtSim* sim, double* pos, double* quat) {
    sim->update_kinematics();
    btMultiBody& mb = *sim->w->body;
    for (int i = 0; i <= sim->nlinks(); ++i) {
        const btVector3 p = i == 0 ? mb.getBasePos() : mb.getLink(i - 1).m_cachedWorldTransform.getOrigin();
        const btQuaternion r = i == 0 ? mb.getWorldToBaseRot().inverse()
                                      : mb.getLink(i - 1).m_cachedWorldTransform.getRotation();
        for (int k = 0; k < 3; ++k) pos[3 * i + k] = p[k];
        quat[4 * i + 0] = r.x();
        quat[4 * i + 1] = r.y();
        quat[4 * i + 2] = r.z();
        quat[4 * i + 3] = r.w();
    }
}

// Contact-free accelerations from Bullet's own articulated-body algorithm at the current state, under gravity,
// joint torques `tau`, a force (world, through the base COM) and a torque (world) on the base.
// out = [d(omega_base)/dt (world), d(v_base_com)/dt (world), qdd] (6 + nlinks). The state is not changed.
int32_t ubt_accelerations(UbtSim* sim, const double* tau, const double* base_force, const double* base_torque,
                          double* out, char* err, size_t errlen) {
    try {
        btMultiBody& mb = *sim->w->body;
        const btVector3 g = v3(sim->cfg.gravity);
        mb.clearForcesAndTorques();
        mb.addBaseForce(g * mb.getBaseMass() + v3(base_force));
        mb.addBaseTorque(v3(base_torque));
        for (int i = 0; i < sim->nlinks(); ++i) {
            mb.addLinkForce(i, g * mb.getLinkMass(i));
            mb.addJointTorque(i, tau[i]);
        }
        // dt = 0: accelerations only, velocities untouched. The result is left at scratch_r[ndofs ..].
        mb.computeAccelerationsArticulatedBodyAlgorithmMultiDof(0.0, sim->scratch_r, sim->scratch_v, sim->scratch_m,
                                                                false, false, false);
        mb.clearForcesAndTorques();
        const int ndofs = mb.getNumDofs();
        for (int k = 0; k < 6 + ndofs; ++k) out[k] = sim->scratch_r[ndofs + k];
        return 0;
    } catch (const std::exception& e) {
        write_err(err, errlen, e.what());
        return 1;
    } catch (...) {
        write_err(err, errlen, "unknown C++ exception");
        return 1;
    }
}

// Kinetic energy 1/2 sum(m |v|^2 + w.I w) over Bullet's own bodies (COM frames, principal inertias).
double ubt_kinetic_energy(const UbtSim* sim) {
    const btMultiBody& mb = *sim->w->body;
    const int n = sim->nlinks();
    btAlignedObjectArray<btVector3> omega, vel;
    omega.resize(n + 1);
    vel.resize(n + 1);
    mb.compTreeLinkVelocities(&omega[0], &vel[0]);
    double ke = mb.getBaseMass() * vel[0].dot(vel[0]) + omega[0].dot(mb.getBaseInertia() * omega[0]);
    for (int i = 0; i < n; ++i) {
        ke += mb.getLinkMass(i) * vel[i + 1].dot(vel[i + 1]) + omega[i + 1].dot(mb.getLinkInertia(i) * omega[i + 1]);
    }
    return 0.5 * ke;
}

// Masses as built: base first, then every link.
void ubt_masses(const UbtSim* sim, double* out) {
    const btMultiBody& mb = *sim->w->body;
    out[0] = mb.getBaseMass();
    for (int i = 0; i < sim->nlinks(); ++i) out[i + 1] = mb.getLinkMass(i);
}

// Joint limits as built (per link); returns 0 when the world has no limit constraints.
int32_t ubt_joint_limits(const UbtSim* sim, double* lower, double* upper) {
    const auto& lims = sim->w->limits;
    if (static_cast<int>(lims.size()) != sim->nlinks()) return 0;
    for (int i = 0; i < sim->nlinks(); ++i) {
        lower[i] = lims[static_cast<size_t>(i)]->getLowerBound();
        upper[i] = lims[static_cast<size_t>(i)]->getUpperBound();
    }
    return 1;
}

// Contact points of the last step's manifolds. Returns the number of points; writes at most `cap`.
int32_t ubt_contacts(const UbtSim* sim, UbtContact* out, int32_t cap) {
    btCollisionDispatcher& d = *sim->w->dispatcher;
    int32_t n = 0;
    for (int m = 0; m < d.getNumManifolds(); ++m) {
        const btPersistentManifold* man = d.getManifoldByIndexInternal(m);
        for (int p = 0; p < man->getNumContacts(); ++p) {
            if (n < cap && out != nullptr) {
                const btManifoldPoint& pt = man->getContactPoint(p);
                UbtContact& c = out[n];
                c.user_a = man->getBody0()->getUserIndex();
                c.user_b = man->getBody1()->getUserIndex();
                for (int k = 0; k < 3; ++k) {
                    c.point_a[k] = pt.getPositionWorldOnA()[k];
                    c.point_b[k] = pt.getPositionWorldOnB()[k];
                    c.normal_on_b[k] = pt.m_normalWorldOnB[k];
                }
                c.distance = pt.getDistance();
                c.impulse = pt.getAppliedImpulse();
            }
            ++n;
        }
    }
    return n;
}

}  // extern "C"
