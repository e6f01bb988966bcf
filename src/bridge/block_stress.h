// Block stress estimates and the conversion region (docs/bridge.md, "Block stress estimates" and
// "Conversion region"). Pure functions of the loads a caller has gathered; no Bullet, no particles.
//
// Freeze bonds (per joint j with area A_j, tension T_j (> 0 pulls), shear S_j):
//   u_f = max_j max( max(T_j, 0) / (A_j sigma_t),  |S_j| / (A_j tau_s) )      (compression ignored)
// RigidWorld breaks a joint when either ratio exceeds 1, so u_f = 1 is exactly its breaking load.
//
// Flexure: the block (half extents h_0, h_1, h_2 along its local axes) is a free beam along each of
// its two longest local axes i. For the beam along i, with j = i+1, k = i+2 (cyclic, so (i, j, k) is
// right-handed), length 2 h_i, section 2 h_j x 2 h_k:
//   A = 4 h_j h_k,  S_j = I_j / h_k = 4 h_j h_k^2 / 3  (moment about j),  S_k = 4 h_k h_j^2 / 3,
//   sigma(s) = N(s)/A + |M_j(s)|/S_j + |M_k(s)|/S_k   (largest tensile fibre stress: a corner),
// N, M the section force and moment at s (local coordinate along i) of everything acting on the
// part of the block beyond s (x_i > s), about the section centre. The point loads are in general
// not in equilibrium (the block accelerates); their resultant F and moment M_c about the centre are
// balanced by d'Alembert loads distributed as a rigid box's inertia is. Per unit length, with
// x = x_i and the components taken along (i, j, k):
//   -F / (2 h_i)                             uniform line load (translation; axial and transverse)
//   -(0, beta_k x, -beta_j x)                 linear transverse line load (rotation about j and k)
//   -(0, beta_j h_k^2/3, beta_k h_j^2/3)      uniform couple about (j, k): the section's rotary inertia
//   beta_j = 3 M_c,j / (2 h_i (h_i^2 + h_k^2)),  beta_k = 3 M_c,k / (2 h_i (h_i^2 + h_j^2)),
// which sum exactly to -F and -M_c (about i the twist is torsion: not used), so N and M vanish at
// both free ends. Gyroscopic and centripetal inertia, torsion and transverse shear stress are not
// included. The mass cancels: no density is needed. u_b = max_{i, s} sigma / sigma_f, with
// sigma < 0 (compression everywhere) counted as 0.
//
// Conversion: converts(u, SF) is true when u * SF >= 1 (SF > 1 converts earlier, at u = 1/SF).
// A block lies in the conversion region when its bounding sphere (centre, radius |half extents|)
// meets the region; the region is fixed to the structure and moves with it.
// Units: SI (m, N, Pa).
#pragma once

#include "common/types.h"

#include <cstddef>
#include <span>

namespace hs::bridge {

// ---------------------------------------------------------------------------------------------
// Freeze bonds

/// One freeze joint of a block, as RigidWorld reports it: {joint_load(id).tension,
/// joint_load(id).shear, FreezeJointDef::area}.
struct FreezeJointSample {
  double tension = 0.0;  ///< N, > 0 pulls the blocks apart; < 0 (compression) never breaks a bond
  double shear = 0.0;    ///< N, magnitude of the tangential part (the sign is ignored)
  double area = 1.0;     ///< bonded area, m^2, > 0
};

/// Freeze-bond strengths (RigidWorldDef::freeze_bond_strength and ..._shear_strength).
struct FreezeBondStrength {
  double tensile = 50e3;  ///< sigma_t, Pa, > 0
  double shear = 50e3;    ///< tau_s, Pa, > 0
};

enum class FreezeBondMode { None, Tension, Shear };

struct FreezeBondEstimate {
  double utilisation = 0.0;  ///< u_f = max over joints and modes (0 without joints)
  double stress = 0.0;       ///< governing stress T/A or |S|/A, Pa
  std::size_t joint = kNoJoint;  ///< index of the governing joint in the input
  FreezeBondMode mode = FreezeBondMode::None;
  static constexpr std::size_t kNoJoint = static_cast<std::size_t>(-1);
};

/// u_f over a block's joints. Throws hs::InputError for a non-positive strength or area, or a
/// non-finite load. Ties keep the first joint, and tension before shear.
FreezeBondEstimate freeze_bond_estimate(std::span<const FreezeJointSample> joints, const FreezeBondStrength& strength);

// ---------------------------------------------------------------------------------------------
// Flexure

/// A rigid ice block: a box of half extents along its local axes, placed at `centre`.
struct BlockBox {
  Vec3 half_extents{0.5, 0.5, 0.5};  ///< m, > 0
  Vec3 centre = Vec3::Zero();        ///< m, world
  Quat orientation = Quat::Identity();  ///< body -> world (normalised here)
};

/// A force acting on the block at a world point: a particle contact, the structure, another block.
/// Application points outside the box (contact points inside an overlap) are moved to the nearest
/// point of the box before anything is computed. Do not pass gravity or full-submersion buoyancy:
/// a uniform body force is balanced exactly by its own share of the d'Alembert load and bends
/// nothing, while as a point load at the centre it would.
struct PointLoad {
  Vec3 point = Vec3::Zero();  ///< m, world
  Vec3 force = Vec3::Zero();  ///< N, world
};

struct FlexureOptions {
  /// Add the axial force N/A to the bending stress (the tensile fibre stress of a beam-column).
  /// false: bending alone, |M_j|/S_j + |M_k|/S_k, which does not let compression hide bending.
  bool axial = true;
};

/// Section forces of the beam along local axis `axis` at local coordinate s (everything on x_axis > s).
struct BeamSection {
  double axial = 0.0;                 ///< N, N; > 0 tension
  Vec3 moment_local = Vec3::Zero();   ///< N m, local frame; the component along `axis` (torsion) is 0
  double stress = 0.0;                ///< N/A (when axial) + |M_j|/S_j + |M_k|/S_k, Pa
};

struct FlexureEstimate {
  double utilisation = 0.0;           ///< u_b = max(stress, 0) / sigma_f
  double stress = 0.0;                ///< largest tensile fibre stress, Pa (>= 0)
  int axis = -1;                      ///< local axis of the governing beam (-1: no loads)
  double position = 0.0;              ///< s, local coordinate of the governing section, m
  Vec3 section_centre = Vec3::Zero(); ///< world position of that section's centre, m
  double axial = 0.0;                 ///< N at that section, N
  Vec3 moment_local = Vec3::Zero();   ///< M at that section, local frame, N m
};

/// The two beam axes used for `half_extents`: the two longest, longer first (ties: lower index).
void flexure_beam_axes(const Vec3& half_extents, int axes[2]);

/// Section forces at local coordinate s in [-h_axis, h_axis] for the beam along local `axis`.
BeamSection beam_section(const BlockBox& block, std::span<const PointLoad> loads, int axis, double s,
                         const FlexureOptions& options = {});

/// u_b: the largest tensile fibre stress over both beams and all sections (exact: the section
/// forces are cubic in s between load points; their extremes are found in closed form).
/// Throws hs::InputError for non-positive half extents or strength, or non-finite loads.
FlexureEstimate flexure_estimate(const BlockBox& block, std::span<const PointLoad> loads, double flexural_strength,
                                 const FlexureOptions& options = {});

// ---------------------------------------------------------------------------------------------
// The conversion rule (the criteria that combine the estimates: conversion_criteria.h)

/// True when u * safety_factor >= 1: a safety factor above 1 converts earlier (at u = 1/SF), below 1
/// later. Throws hs::InputError unless safety_factor is positive and finite.
bool converts(double utilisation, double safety_factor);

// ---------------------------------------------------------------------------------------------
// Conversion region

/// Where blocks may become particles: a box or a vertical cylinder fixed to the structure, axes
/// along the world's (the structure translates; it does not turn). Its reference point is the
/// structure's position (StructureDef::position + velocity t) plus `offset`.
struct ConversionRegion {
  enum class Shape { Box, Cylinder };
  Shape shape = Shape::Cylinder;
  Vec3 offset = Vec3::Zero();        ///< m, reference point relative to the structure's position
  Vec3 half_extents{10.0, 10.0, 10.0};  ///< Box: half sizes about the reference point, m
  double radius = 10.0;              ///< Cylinder: radius about the vertical line through it, m
  double z_min = -10.0, z_max = 5.0; ///< Cylinder: z range relative to the reference point, m

  /// Throws hs::InputError (path "conversion/region/...") for non-positive or non-finite sizes.
  void validate() const;
  /// Distance from p to the region (0 inside), m.
  double distance(const Vec3& structure_position, const Vec3& p) const;
  bool contains_point(const Vec3& structure_position, const Vec3& p) const {
    return distance(structure_position, p) <= 0.0;
  }
  /// The block lies in the region when its bounding sphere meets it:
  /// distance(centre) <= |half_extents|. Orientation does not matter (docs/bridge.md, why).
  bool contains_block(const Vec3& structure_position, const Vec3& centre, const Vec3& half_extents) const {
    return distance(structure_position, centre) <= half_extents.norm();
  }
};

}  // namespace hs::bridge
