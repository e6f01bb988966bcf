// From a scene to the hybrid system's inputs: the blocks (ridge file and/or list), the rigid
// world's settings, the structure's mesh for block contact, the conversion mode.
#pragma once

#include "bridge/hybrid.h"
#include "mesh/tri_mesh.h"
#include "scene/scene.h"
#include "sim/calibrated_ice.h"
#include "sim/iso_inputs.h"

#include <memory>
#include <optional>

#include <string>
#include <vector>

namespace hs::rigid {
struct RidgeResult;
}

namespace hs::sim {

struct BlockSetup {
  bridge::HybridDef def;
  std::vector<bridge::BlockInit> blocks;
  std::vector<bridge::JointInit> joints;         ///< ridge joints between kept blocks
  std::vector<bridge::IceJointInit> ice_joints;  ///< ridge joints from kept blocks to the ice sheet
  std::size_t ridge_blocks_in_file = 0;          ///< before keep_x / keep_y / keep_sail
  std::size_t loose_blocks_dropped = 0;          ///< kept ridge blocks without a joint, left out (blocks.loose_blocks)
  std::optional<RidgeKeel> ridge;                ///< the ridge file's keel (ISO inputs), if there is one
  std::vector<std::string> warnings;
};

/// Reads the scene's blocks (InputError at /blocks/ridge_file for a missing or bad file).
/// `structure` is the structure's mesh as built for the engine (nullptr without a structure),
/// `structure_radius` its widest radius (the default conversion region). A scene without a
/// "blocks" section gives an empty block list (no rigid world). `ice`: calibrate_ice(s), computed
/// once for the run (the freeze strengths and the conversion's flexural and crushing limits come
/// from it); without it, computed here. `ridge`: the scene's ridge file as the build read it
/// (Built::ridge, so the file is read once per build); null: read here when the scene has one.
BlockSetup block_setup(const scene::Scene& s, const CalibratedIce& ice, const mesh::TriMesh* structure,
                       double structure_radius, const rigid::RidgeResult* ridge = nullptr);
BlockSetup block_setup(const scene::Scene& s, const mesh::TriMesh* structure, double structure_radius);

/// Whether a block (centre, half extents) starting there would reach into a parametric pier
/// (its bounding sphere inside the pier's radius at a height it spans): such blocks are left out
/// of a run (with a warning) and of `bench hybrid`'s ridge at rest.
bool block_reaches_into_pier(const scene::StructureDef& st, const Vec3& half_extents, const Vec3& position);

/// The keel of the scene's ridge file (BlockSetup::ridge without building anything), or none
/// when the scene has no ridge file. InputError at /blocks/ridge_file for a missing or bad file.
std::optional<RidgeKeel> scene_ridge_keel(const scene::Scene& s);

}  // namespace hs::sim
