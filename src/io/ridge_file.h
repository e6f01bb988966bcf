// Ridge file (HDF5): a generated ridge (ridge/ridge.h; its data: ridge/ridge_data.h) that any
// scene can load.
//
// Layout (file_format "hybridsim-ridge/2", HDF5 1.8 format, all doubles native 64-bit):
//   /ridge                       attributes file_format, definition (RidgeDef as JSON,
//                                ridge_def_to_json), stats (RidgeStats as JSON), report
//                                (ridge_report, for people), generation (what it was made
//                                with, ridge_generation_json of ridge/ridge_json.h; docs/ridge.md)
//   /ridge/blocks/half_extents   n x 3  m
//   /ridge/blocks/position       n x 3  m (centre)
//   /ridge/blocks/orientation    n x 4  quaternion w, x, y, z (body -> world, w >= 0)
//   /ridge/blocks/part           n      int32: 0 keel, 1 sail
//   /ridge/joints/blocks         m x 2  int32 a, b (block rows; b < 0: ice box -1 - b)
//   /ridge/joints/anchor         m x 3  m
//   /ridge/joints/normal         m x 3  unit, from a to b
//   /ridge/joints/area           m      m^2
//   /ridge/ice/half_extents      k x 3  axis-aligned ice boxes: fixed, or floating plates
//   /ridge/ice/position          k x 3  (plates: final pose)
//   /ridge/ice/part              k      int32: 0 level ice, 1 consolidated layer
//   /ridge/ice/lift              k      m, a plate's final z - its rest z (fixed boxes: 0)
//   /ridge/profile/{x, keel_target, keel_depth, sail_target, sail_height}   1-D, m
// save_ridge -> load_ridge gives back the same RidgeResult bit for bit.
#pragma once

#include "ridge/ridge_data.h"

#include <string>

namespace hs::io {

/// Writes (truncates) the ridge file. Throws hs::InputError(path, ...) if it cannot be
/// created, std::runtime_error on other HDF5 failures.
void save_ridge(const std::string& path, const rigid::RidgeResult& r);
/// Reads a ridge file. Throws hs::InputError(path, ...) for a missing or malformed file, and
/// for a "hybridsim-ridge/1" file (no generation record: regenerate it).
rigid::RidgeResult load_ridge(const std::string& path);

}  // namespace hs::io
