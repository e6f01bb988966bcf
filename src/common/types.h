// Basic types shared by every module (vectors, quaternions, ids). SI units throughout.
// Lives in common/ so that lower layers (mesh, rigid, parallel, analysis) need not include
// the particle engine for a vector type.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

namespace hs {

using Vec3 = Eigen::Vector3d;
using Quat = Eigen::Quaterniond;
using Mat3 = Eigen::Matrix3d;

/// Stable particle identity: never reused, survives reordering and (later) MPI migration.
using GlobalId = std::uint64_t;

inline constexpr double kPi = 3.14159265358979323846;

}  // namespace hs
