// Geometry of the hexagonal close packing of identical spheres of diameter D (no engine types),
// so that scene reading, the builder and the lattice share one definition.
#pragma once

namespace hs {

/// Distance between close-packed layers: c = D sqrt(2/3).
inline double hcp_layer_spacing(double D) { return D * 0.81649658092772603; }
/// Volume per sphere (Voronoi cell) of the HCP lattice: D^3 / sqrt(2).
inline double hcp_cell_volume(double D) { return D * D * D * 0.70710678118654752; }

}  // namespace hs
