// Kinematic meshes (the structure; rigid_world.h: KinematicMeshDef, MeshLoad; docs/rigid.md):
// Bullet kinematic bodies moved at a prescribed velocity, and the contact loads the blocks put on
// them.
#include "common/error.h"
#include "rigid/rigid_world_impl.h"

#include <algorithm>

namespace hs::rigid {

namespace detail {

// Kinematic meshes: pose at the end of the sub-step. stepSimulation's saveKinematicState turns the
// displacement into the body's velocity for the solver.
void WorldImpl::move_meshes(double h) {
  for (auto& mp : meshes) {
    MeshSlot& ms = *mp;
    ms.origin += h * ms.velocity;
    ms.body->setWorldTransform(btTransform(btQuaternion::getIdentity(), to_bt(ms.origin)));
  }
}

// Sums the impulses the solver applied at every contact point of a mesh body during
// the last step. Bullet applies +(n j_n + d1 j_1 + d2 j_2) to body 0 of a manifold and
// the opposite to body 1 (n = m_normalWorldOnB, d1, d2 the friction directions).
void WorldImpl::tally_mesh_loads(double h) {
  for (auto& mp : meshes) {
    MeshLoad& L = mp->load;
    L.force.setZero();
    L.moment.setZero();
    std::fill(L.part_force.begin(), L.part_force.end(), Vec3::Zero());
    std::fill(L.part_moment.begin(), L.part_moment.end(), Vec3::Zero());
    L.contacts = 0;
  }
  if (meshes.empty()) return;
  detail::sorted_manifolds_if(dispatcher.get(), manifolds_scratch,  // a fixed summation order
                              [](const btPersistentManifold* man) {
                                return (man->getBody0()->getUserIndex2() == kMeshTag) !=
                                       (man->getBody1()->getUserIndex2() == kMeshTag);
                              });
  for (const btPersistentManifold* man : manifolds_scratch) {
    const btCollisionObject* b0 = man->getBody0();
    const btCollisionObject* b1 = man->getBody1();
    const bool mesh0 = b0->getUserIndex2() == kMeshTag, mesh1 = b1->getUserIndex2() == kMeshTag;
    if (mesh0 == mesh1) continue;
    MeshSlot& ms = *meshes[static_cast<std::size_t>((mesh0 ? b0 : b1)->getUserIndex())];
    const double sign = mesh0 ? 1.0 : -1.0;  // impulse on the mesh = sign * (impulse on body 0)
    for (int c = 0; c < man->getNumContacts(); ++c) {
      const btManifoldPoint& p = man->getContactPoint(c);
      if (p.m_appliedImpulse == 0.0 && p.m_appliedImpulseLateral1 == 0.0 &&
          p.m_appliedImpulseLateral2 == 0.0)
        continue;
      const Vec3 j = from_bt(p.m_normalWorldOnB * p.m_appliedImpulse +
                             p.m_lateralFrictionDir1 * p.m_appliedImpulseLateral1 +
                             p.m_lateralFrictionDir2 * p.m_appliedImpulseLateral2);
      const Vec3 f = sign * j / h;
      const Vec3 at = from_bt(mesh0 ? p.getPositionWorldOnA() : p.getPositionWorldOnB());
      const Vec3 m = (at - ms.origin).cross(f);
      MeshLoad& L = ms.load;
      L.force += f;
      L.moment += m;
      ++L.contacts;
      const int tri = mesh0 ? p.m_index0 : p.m_index1;
      const std::size_t part =
          (tri >= 0 && static_cast<std::size_t>(tri) < ms.part.size()) ? ms.part[tri] : 0;
      L.part_force[part] += f;
      L.part_moment[part] += m;
    }
  }
}

}  // namespace detail

using namespace detail;

int RigidWorld::add_kinematic_mesh(const KinematicMeshDef& d) {
  Impl& m = *impl_;
  if (d.triangles.empty()) throw InputError("structure/mesh", "a kinematic mesh needs triangles");
  if (d.part_count < 1) throw InputError("structure/mesh", "part_count must be >= 1");
  if (!(d.friction >= 0.0)) throw InputError("structure/friction", "must be >= 0");
  if (!d.triangle_part.empty() && d.triangle_part.size() != d.triangles.size())
    throw InputError("structure/mesh", "triangle_part must have one entry per triangle");
  auto ms = std::make_unique<MeshSlot>();
  ms->origin = d.position;
  ms->velocity = d.velocity;
  ms->vertices.reserve(3 * d.vertices.size());
  for (const Vec3& v : d.vertices) ms->vertices.insert(ms->vertices.end(), {v.x(), v.y(), v.z()});
  ms->indices.reserve(3 * d.triangles.size());
  for (const auto& t : d.triangles) {
    for (std::uint32_t i : t) {
      if (i >= d.vertices.size())
        throw InputError("structure/mesh", "triangle vertex index out of range");
      ms->indices.push_back(static_cast<int>(i));
    }
  }
  ms->part = d.triangle_part;
  ms->lo = ms->hi = d.vertices.front();
  for (const Vec3& v : d.vertices) {
    ms->lo = ms->lo.cwiseMin(v);
    ms->hi = ms->hi.cwiseMax(v);
  }
  for (std::uint16_t p : ms->part)
    if (p >= d.part_count) throw InputError("structure/mesh", "triangle part out of range");
  btIndexedMesh im;
  im.m_numTriangles = static_cast<int>(d.triangles.size());
  im.m_triangleIndexBase = reinterpret_cast<const unsigned char*>(ms->indices.data());
  im.m_triangleIndexStride = 3 * sizeof(int);
  im.m_numVertices = static_cast<int>(d.vertices.size());
  im.m_vertexBase = reinterpret_cast<const unsigned char*>(ms->vertices.data());
  im.m_vertexStride = 3 * sizeof(btScalar);
  im.m_vertexType = PHY_DOUBLE;
  im.m_indexType = PHY_INTEGER;
  ms->array = std::make_unique<btTriangleIndexVertexArray>();
  ms->array->addIndexedMesh(im, PHY_INTEGER);
  ms->shape = std::make_unique<btBvhTriangleMeshShape>(ms->array.get(), true);
  ms->shape->setMargin(0.0);
  btRigidBody::btRigidBodyConstructionInfo info(0.0, nullptr, ms->shape.get());
  info.m_startWorldTransform = btTransform(btQuaternion::getIdentity(), to_bt(d.position));
  info.m_friction = d.friction;
  info.m_restitution = 0.0;
  ms->body = std::make_unique<btRigidBody>(info);
  ms->body->setCollisionFlags(ms->body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
  ms->body->setActivationState(DISABLE_DEACTIVATION);
  ms->body->setUserIndex(static_cast<int>(m.meshes.size()));
  ms->body->setUserIndex2(kMeshTag);
  ms->load.part_force.assign(d.part_count, Vec3::Zero());
  ms->load.part_moment.assign(d.part_count, Vec3::Zero());
  m.world->addRigidBody(ms->body.get());
  m.meshes.push_back(std::move(ms));
  return static_cast<int>(m.meshes.size() - 1);
}

std::size_t RigidWorld::kinematic_mesh_count() const { return impl_->meshes.size(); }
Vec3 RigidWorld::mesh_position(int k) const { return impl_->meshes.at(k)->origin; }
const MeshLoad& RigidWorld::mesh_load(int k) const { return impl_->meshes.at(k)->load; }

}  // namespace hs::rigid
