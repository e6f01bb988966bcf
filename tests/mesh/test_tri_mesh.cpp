// TriMesh: topology, closedness, STL/OBJ reading and writing, input errors.
#include "mesh_fixtures.h"

#include "common/error.h"
#include "mesh/pier.h"
#include "mesh/tri_mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

namespace hs::mesh {
namespace {

using test::tmp_file;
using test::write_text;

/// Runs f, expects an InputError whose path() is `path` and whose message contains
/// every string in `parts`.
template <class F>
void expect_input_error(F&& f, const std::string& path, std::initializer_list<std::string> parts) {
  try {
    f();
    ADD_FAILURE() << "no InputError thrown for " << path;
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), path);
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    for (const auto& p : parts) EXPECT_NE(what.find(p), std::string::npos) << what;
  }
}

TEST(TriMeshTopology, BoxIsClosedOrientedWithUnitVolume) {
  const TriMesh box = test::make_box(Vec3(0, 0, 0), Vec3(1, 2, 3));
  EXPECT_EQ(box.edges.size(), 18u);  // 12 cube edges + 6 face diagonals
  EXPECT_TRUE(is_closed(box));
  EXPECT_TRUE(is_consistently_oriented(box));
  EXPECT_NEAR(signed_volume(box), 6.0, 1e-12);
  const Aabb b = bounding_box(box);
  EXPECT_EQ(b.lo, Vec3(0, 0, 0));
  EXPECT_EQ(b.hi, Vec3(1, 2, 3));
  // Every triangle side maps to an edge with the same end vertices.
  for (std::size_t t = 0; t < box.triangles.size(); ++t) {
    for (int i = 0; i < 3; ++i) {
      const auto& e = box.edges[box.triangle_edges[t][i]];
      const auto a = box.triangles[t][i], c = box.triangles[t][(i + 1) % 3];
      EXPECT_EQ(e[0], std::min(a, c));
      EXPECT_EQ(e[1], std::max(a, c));
      const auto& et = box.edge_triangles[box.triangle_edges[t][i]];
      EXPECT_TRUE(et[0] == t || et[1] == t);
    }
  }
  // Vertex -> edge CSR: each cube corner has 3 cube edges plus 0..3 diagonals.
  std::size_t total = 0;
  for (std::size_t v = 0; v < box.vertices.size(); ++v) {
    total += box.vertex_edge_offsets[v + 1] - box.vertex_edge_offsets[v];
  }
  EXPECT_EQ(total, 2 * box.edges.size());
}

TEST(TriMeshTopology, OpenAndFlippedMeshesAreDetected) {
  const TriMesh square = test::make_square();
  EXPECT_FALSE(is_closed(square));
  EXPECT_TRUE(is_consistently_oriented(square));
  TriMesh box = test::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1));
  std::swap(box.triangles[3][0], box.triangles[3][1]);
  build_topology(box);
  EXPECT_TRUE(is_closed(box));
  EXPECT_FALSE(is_consistently_oriented(box));
}

TEST(TriMeshIo, BinaryStlRoundTripWeldsVertices) {
  const TriMesh box = test::make_box(Vec3(-1.5, 0.25, -2), Vec3(3, 1.75, 0.5));
  const std::string path = tmp_file("box_binary.stl");
  write_stl_binary(box, path);
  EXPECT_EQ(std::filesystem::file_size(path), 84u + 50u * 12u);
  const TriMesh back = load_stl(path);
  ASSERT_EQ(back.triangles.size(), 12u);
  EXPECT_EQ(back.vertices.size(), 8u);  // 36 STL corners welded back to 8
  EXPECT_TRUE(is_closed(back));
  EXPECT_TRUE(is_consistently_oriented(back));
  EXPECT_NEAR(signed_volume(back), signed_volume(box), 1e-12);  // coordinates exact in float
  ASSERT_EQ(back.part_names.size(), 1u);
  EXPECT_EQ(back.part_names[0], "box_binary");
  for (std::size_t t = 0; t < 12; ++t) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(back.vertices[back.triangles[t][c]], box.vertices[box.triangles[t][c]]);
    }
  }
}

TEST(TriMeshIo, BinaryStlRoundTripOfPierIsFloatExact) {
  const TriMesh pier = make_pier({});
  const std::string path = tmp_file("pier_binary.stl");
  write_stl_binary(pier, path);
  const TriMesh back = load_stl(path);
  EXPECT_EQ(back.triangles.size(), pier.triangles.size());
  EXPECT_EQ(back.vertices.size(), pier.vertices.size());
  EXPECT_TRUE(is_closed(back));
  EXPECT_TRUE(is_consistently_oriented(back));
  // Binary STL stores float32: coordinates round to ~1e-6 m at 20 m.
  EXPECT_NEAR(signed_volume(back) / signed_volume(pier), 1.0, 2.5e-8);  // measured 2.3e-9 (was 1e-6)
  for (std::size_t t = 0; t < pier.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      const Vec3& p = pier.vertices[pier.triangles[t][c]];
      const Vec3& q = back.vertices[back.triangles[t][c]];
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(static_cast<float>(q[k]), static_cast<float>(p[k]));  // same float
        EXPECT_LE(std::abs(q[k] - p[k]), 1e-6);                         // float32 rounding
      }
    }
  }
}

TEST(TriMeshIo, AsciiStlWithSolidsAsParts) {
  const std::string path = write_text("two_solids.stl",
                                      "solid lower\n"
                                      "  facet normal 0 0 1\n"
                                      "    outer loop\n"
                                      "      vertex 0 0 0\n"
                                      "      vertex 1 0 0\n"
                                      "      vertex 1 1 0\n"
                                      "    endloop\n"
                                      "  endfacet\n"
                                      "endsolid lower\n"
                                      "solid upper part\r\n"
                                      "  facet normal 0 0 1\r\n"
                                      "    outer loop\r\n"
                                      "      vertex 0 0 0\r\n"
                                      "      vertex +1.0e0 1 0\r\n"
                                      "      vertex 0 1 -0\r\n"
                                      "    endloop\r\n"
                                      "  endfacet\r\n"
                                      "endsolid upper part\r\n");
  const TriMesh m = load_stl(path);
  ASSERT_EQ(m.triangles.size(), 2u);
  EXPECT_EQ(m.vertices.size(), 4u);
  ASSERT_EQ(m.part_names.size(), 2u);
  EXPECT_EQ(m.part_names[0], "lower");
  EXPECT_EQ(m.part_names[1], "upper part");
  EXPECT_EQ(m.triangle_part[0], 0);
  EXPECT_EQ(m.triangle_part[1], 1);
  EXPECT_EQ(m.edges.size(), 5u);  // the diagonal is shared
  EXPECT_FALSE(is_closed(m));
  EXPECT_EQ(triangle_normal(m, 1), Vec3(0, 0, 1));
}

TEST(TriMeshIo, AsciiStlWriteReadIsExact) {
  const TriMesh pier = make_pier({});
  const std::string path = tmp_file("pier_ascii.stl");
  write_stl_ascii(pier, path);
  const TriMesh back = load_mesh(path);
  EXPECT_EQ(back.part_names, pier.part_names);
  EXPECT_EQ(back.vertices.size(), pier.vertices.size());
  EXPECT_TRUE(is_closed(back));
  EXPECT_EQ(signed_volume(back) > 0.0, true);
  EXPECT_NEAR(signed_volume(back), signed_volume(pier), 1e-12 * signed_volume(pier));
}

TEST(TriMeshIo, ObjWithGroupsPolygonsAndNegativeIndices) {
  const std::string path = write_text("cube.obj",
                                      "# unit cube, bottom and top as parts\n"
                                      "mtllib cube.mtl\n"
                                      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                                      "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                                      "vn 0 0 1\nvt 0 0\n"
                                      "g bottom\n"
                                      "f 1 4 3 2\n"
                                      "o sides\n"
                                      "f 1/1 2/1 6/1 5/1\n"
                                      "f 2//1 3//1 7//1 6//1\n"
                                      "f -6/1/1 -5/1/1 -1/1/1 -2/1/1\n"  // 3 4 8 7
                                      "f 4 1 5 8\n"
                                      "g bottom\n"
                                      "s off\n"
                                      "f 5 6 7 8\n");
  const TriMesh m = load_obj(path);
  ASSERT_EQ(m.triangles.size(), 12u);
  EXPECT_EQ(m.vertices.size(), 8u);
  ASSERT_EQ(m.part_names.size(), 2u);
  EXPECT_EQ(m.part_names[0], "bottom");
  EXPECT_EQ(m.part_names[1], "sides");
  int per_part[2] = {0, 0};
  for (auto p : m.triangle_part) ++per_part[p];
  EXPECT_EQ(per_part[0], 4);  // bottom quad + top quad (group "bottom" reopened)
  EXPECT_EQ(per_part[1], 8);
  EXPECT_TRUE(is_closed(m));
  EXPECT_TRUE(is_consistently_oriented(m));
  EXPECT_NEAR(signed_volume(m), 1.0, 1e-15);
}

TEST(TriMeshIo, FacesBeforeAnyGroupUseTheFileStem) {
  const std::string path =
      write_text("plate.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const TriMesh m = load_mesh(path);
  ASSERT_EQ(m.part_names.size(), 1u);
  EXPECT_EQ(m.part_names[0], "plate");
}

TEST(TriMeshIo, WeldToleranceMergesNearbyCorners) {
  // Second triangle's shared corners are off by 1e-9 m.
  const std::string path = write_text("near.obj",
                                      "v 0 0 0\nv 1 0 0\nv 1 1 0\n"
                                      "v 1e-9 0 0\nv 1 1.000000001 0\nv 0 1 0\n"
                                      "f 1 2 3\nf 4 5 6\n");
  EXPECT_EQ(load_obj(path).vertices.size(), 4u);
  MeshLoadOptions exact;
  exact.weld_tolerance = 0.0;
  EXPECT_EQ(load_obj(path, exact).vertices.size(), 6u);
}

// ---- malformed input ----

TEST(TriMeshErrors, MissingFile) {
  const std::string path = tmp_file("does_not_exist.stl");
  expect_input_error([&] { load_mesh(path); }, path, {"not found"});
  const std::string obj = tmp_file("does_not_exist.obj");
  expect_input_error([&] { load_obj(obj); }, obj, {"not found"});
}

TEST(TriMeshErrors, TruncatedBinaryStl) {
  const TriMesh box = test::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1));
  const std::string path = tmp_file("truncated.stl");
  write_stl_binary(box, path);
  std::filesystem::resize_file(path, 84 + 50 * 12 - 7);
  expect_input_error([&] { load_stl(path); }, path, {"12 triangles", "truncated"});
  // Same with a header that starts with "solid", as many exporters write.
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.write("solid box", 9);
  }
  expect_input_error([&] { load_stl(path); }, path, {"truncated"});
  std::filesystem::resize_file(path, 40);
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.write("SOLID", 5);
  }
  expect_input_error([&] { load_stl(path); }, path, {"too short"});
}

TEST(TriMeshErrors, ZeroTriangles) {
  const std::string bin = tmp_file("empty_binary.stl");
  {
    std::ofstream f(bin, std::ios::binary);
    char header[84] = {};
    f.write(header, sizeof header);
  }
  expect_input_error([&] { load_stl(bin); }, bin, {"zero triangles"});
  const std::string ascii = write_text("empty_ascii.stl", "solid nothing\nendsolid nothing\n");
  expect_input_error([&] { load_stl(ascii); }, ascii, {"zero triangles"});
  const std::string obj = write_text("only_vertices.obj", "v 0 0 0\nv 1 0 0\n");
  expect_input_error([&] { load_obj(obj); }, obj, {"zero triangles"});
}

TEST(TriMeshErrors, ObjFaceIndexOutOfRange) {
  const std::string path =
      write_text("bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n");
  expect_input_error([&] { load_obj(path); }, path, {"line 5", "index 4", "out of range"});
  const std::string neg = write_text("bad_neg.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
  expect_input_error([&] { load_obj(neg); }, neg, {"line 4", "-4"});
  const std::string zero = write_text("zero_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
  expect_input_error([&] { load_obj(zero); }, zero, {"line 4", "1-based"});
}

TEST(TriMeshErrors, CoordinatesSpanningMoreThanADoubleAreRefused) {
  // Finite, but the bounding box's size overflows: every vertex used to be welded into one
  // and the error blamed a "degenerate triangle (0, 0, 0), (0, 0, 0), (0, 0, 0)".
  const std::string obj = write_text("huge.obj", "v 0 0 0\nv 1e308 0 0\nv -1e308 1 0\nv 0 0 1\n"
                                                  "f 1 2 4\nf 1 4 3\nf 1 3 2\nf 2 3 4\n");
  expect_input_error([&] { load_obj(obj); }, obj, {"too large to measure", "metres"});
}

TEST(TriMeshErrors, BadNumbersAndNaN) {
  const std::string obj_nan =
      write_text("nan.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n");
  expect_input_error([&] { load_obj(obj_nan); }, obj_nan, {"line 3", "non-finite"});
  const std::string obj_bad = write_text("bad.obj", "v 0 0 0\nv 1 0,5 0\nv 0 1 0\nf 1 2 3\n");
  expect_input_error([&] { load_obj(obj_bad); }, obj_bad, {"line 2", "bad number '0,5'"});
  const std::string stl_nan = write_text("nan_ascii.stl",
                                         "solid s\nfacet normal 0 0 1\nouter loop\n"
                                         "vertex 0 0 0\nvertex 1 0 0\nvertex 0 NaN 0\n"
                                         "endloop\nendfacet\nendsolid s\n");
  expect_input_error([&] { load_stl(stl_nan); }, stl_nan, {"line 6", "non-finite"});

  // Binary STL with a NaN corner.
  TriMesh box = test::make_box(Vec3(0, 0, 0), Vec3(1, 1, 1));
  const std::string bin = tmp_file("nan_binary.stl");
  write_stl_binary(box, bin);
  {
    std::fstream f(bin, std::ios::in | std::ios::out | std::ios::binary);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    f.seekp(84 + 50 * 5 + 12 + 4);  // triangle 5, corner 0, y
    f.write(reinterpret_cast<const char*>(&nan), 4);
  }
  expect_input_error([&] { load_stl(bin); }, bin, {"triangle 5", "non-finite"});
}

TEST(TriMeshErrors, DegenerateTriangleAndUnknownExtension) {
  const std::string path =
      write_text("degenerate.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 4\nf 1 2 3\n");
  expect_input_error([&] { load_obj(path); }, path, {"triangle 1", "degenerate"});
  const std::string ply = write_text("mesh.ply", "ply\n");
  expect_input_error([&] { load_mesh(ply); }, ply, {".stl", ".obj"});
  const std::string facet4 = write_text("quad_facet.stl",
                                        "solid s\nfacet normal 0 0 1\nouter loop\n"
                                        "vertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\n"
                                        "endloop\nendfacet\nendsolid s\n");
  expect_input_error([&] { load_stl(facet4); }, facet4, {"line 2", "4 vertices"});
}

}  // namespace
}  // namespace hs::mesh
