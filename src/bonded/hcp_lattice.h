// Hexagonal close packing (HCP) of identical spheres, spacing exactly D.
//
// Lattice (local frame, c-axis along z): triangular layers with in-plane vectors
//   a1 = (D, 0, 0), a2 = (D/2, D sqrt(3)/2, 0),
// stacked ABAB with layer spacing c = D sqrt(2/3); B layers are shifted by (a1+a2)/3.
// Every sphere touches 12 neighbours at distance D. The volume per sphere (its lattice
// cell) is V_cell = D^3 / sqrt(2), which is what a particle must weigh and displace for
// the lattice to weigh and float like the solid ice it stands for.
#pragma once

#include "common/hcp_geometry.h"
#include "common/types.h"

#include <vector>

namespace hs::bonded {

using ::hs::hcp_cell_volume;    // common/hcp_geometry.h
using ::hs::hcp_layer_spacing;  // common/hcp_geometry.h

struct Pose {
  Vec3 position = Vec3::Zero();
  Quat orientation = Quat::Identity();
};

/// Centres of an HCP lattice filling the box [-half, half] (local frame) placed at
/// `pose`. Layers are laid from the bottom face (first layer centre c/2 above it) and
/// in-plane rows from the -x,-y corner (first centre D/2 in); a centre is kept when it
/// lies inside the box. The number of layers is round(2*half.z / c), so a box of
/// thickness n*c holds exactly n layers.
std::vector<Vec3> hcp_fill_box(const Vec3& half, const Pose& pose, double D);

/// Centres filling a right prism: a convex or concave polygon (local x-y, counter-
/// clockwise) extruded over [0, height] along local z, placed at `pose`.
std::vector<Vec3> hcp_fill_prism(const std::vector<Eigen::Vector2d>& polygon, double height,
                                 const Pose& pose, double D);

/// Trims every layer of HCP centres (placed at `pose`, layers normal to its local z) to the
/// smallest layer's count. A box cut from HCP generally holds different counts in its A and B
/// layers; a solid block has the same area at every height, and with Column buoyancy the
/// waterline layer's count sets the waterplane area, so unequal layers float off the solid's
/// draft. The surplus is taken alternately from each layer's -x and +x ends (local frame).
/// Returns the number of centres removed; the others come out layer by layer from bottom to
/// top, each layer sorted by local x, then y, compared with a tolerance of D/8 so that a pose
/// differing by rounding gives the same order. Precondition: the centres are HCP sites of
/// spacing D (as hcp_fill_box gives), so that within a layer x values differ by ~0 or >= D/2.
std::size_t hcp_equalize_layers(std::vector<Vec3>& centres, const Pose& pose, double D);

}  // namespace hs::bonded
