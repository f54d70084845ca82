// preprocessing/polyhedron_file: OFF and OBJ reading, pose, merging, errors with file:line.
#include "preprocessing/polyhedron_file.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace rubble {
namespace {

std::string write_file(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / ("rubble_test_" + std::to_string(::getpid()) + "_" + name);
  std::ofstream(path) << text;
  return path.string();
}

const char* cube_off =
    "OFF\n"
    "# a 2 x 1 x 1 box centred at (10, 0, 0)\n"
    "8 6 0\n"
    "9 -0.5 -0.5\n11 -0.5 -0.5\n9 0.5 -0.5\n11 0.5 -0.5\n"
    "9 -0.5 0.5\n11 -0.5 0.5\n9 0.5 0.5\n11 0.5 0.5\n"
    "4 0 4 6 2\n4 1 3 7 5\n4 0 1 5 4\n4 2 6 7 3\n4 0 2 3 1\n4 4 5 7 6\n";

TEST(PolyhedronFile, ReadsAnOffBoxAndItsPose) {
  PolyhedronPose pose;
  const ConvexPolyhedron box = load_polyhedron_file(write_file("box.off", cube_off), {}, &pose);
  EXPECT_EQ(box.vertices.size(), 8u);
  EXPECT_EQ(box.faces.size(), 6u);
  EXPECT_NEAR(box.volume, 2.0, 1e-12);
  EXPECT_NEAR((pose.centroid - Vec3(10, 0, 0)).norm(), 0.0, 1e-12);
  // Reference: I_x = V (1 + 1)/12, I_y = I_z = V (4 + 1)/12 (the long axis is x).
  EXPECT_NEAR(box.principal_inertia_per_density.x(), 2.0 * 2.0 / 12.0, 1e-12);
  EXPECT_NEAR(box.principal_inertia_per_density.y(), 2.0 * 5.0 / 12.0, 1e-12);
}

TEST(PolyhedronFile, ReadsATriangulatedObjCubeAndMergesItsFaces) {
  // A unit cube as 12 triangles, 1-based and negative indices, with vt/vn decorations.
  const std::string obj =
      "# cube\no cube\n"
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n"
      "vn 0 0 1\n"
      "f 1 5 7\nf 1 7 3\nf 2 4 8\nf 2 8 6\nf 1 2 6\nf 1 6 5\n"
      "f 3 7/1/1 8//1\nf 3 8 4\nf 1 3 4\nf 1 4 2\nf -4 -3 -1\nf -4 -1 -2\n";
  const ConvexPolyhedron cube = load_polyhedron_file(write_file("cube.obj", obj));
  EXPECT_EQ(cube.faces.size(), 6u);  // coplanar triangles merged into squares
  EXPECT_NEAR(cube.volume, 1.0, 1e-12);
  EXPECT_NEAR(cube.principal_inertia_per_density.x(), 1.0 / 6.0, 1e-12);
}

TEST(PolyhedronFile, ClockwiseFilesAreTurnedAround) {
  std::string text = cube_off;
  // Reverse every face: "4 a b c d" -> "4 d c b a".
  text =
      "OFF\n8 6 0\n"
      "9 -0.5 -0.5\n11 -0.5 -0.5\n9 0.5 -0.5\n11 0.5 -0.5\n"
      "9 -0.5 0.5\n11 -0.5 0.5\n9 0.5 0.5\n11 0.5 0.5\n"
      "4 2 6 4 0\n4 5 7 3 1\n4 4 5 1 0\n4 3 7 6 2\n4 1 3 2 0\n4 6 7 5 4\n";
  const ConvexPolyhedron box = load_polyhedron_file(write_file("cw.off", text));
  EXPECT_NEAR(box.volume, 2.0, 1e-12);
}

std::string error_of(const std::string& name, const std::string& text) {
  try {
    (void)load_polyhedron_file(write_file(name, text));
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "no error";
}

TEST(PolyhedronFile, ErrorsNameTheFileAndLine) {
  const std::string bad_index = error_of("bad_index.off",
                                         "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                                         "3 0 2 1\n3 0 1 9\n3 0 3 2\n3 1 2 3\n");
  EXPECT_NE(bad_index.find("bad_index.off:8: vertex index 9 out of range"), std::string::npos) << bad_index;

  const std::string number = error_of("number.off", "OFF\n4 4 0\n0 0 0\n1 zero 0\n");
  EXPECT_NE(number.find("number.off:4: expected a finite number, got 'zero'"), std::string::npos) << number;

  const std::string header = error_of("header.off", "PLY\n");
  EXPECT_NE(header.find("header.off:1: expected 'OFF'"), std::string::npos) << header;

  const std::string truncated = error_of("truncated.off", "OFF\n8 6 0\n0 0 0\n");
  EXPECT_NE(truncated.find("truncated.off:3: unexpected end of file"), std::string::npos) << truncated;

  // A non-convex (dented) box: the error points at a face line.
  std::string dented = cube_off;
  dented.replace(dented.find("11 0.5 0.5"), 10, "10 0.2 0.2");
  const std::string concave = error_of("dented.off", dented);
  EXPECT_NE(concave.find("dented.off:1"), std::string::npos) << concave;  // lines 12..16
  EXPECT_NE(concave.find("face"), std::string::npos) << concave;

  const std::string obj_index = error_of("index.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n");
  EXPECT_NE(obj_index.find("index.obj:3: vertex index 3 out of range"), std::string::npos) << obj_index;

  const std::string format = error_of("shape.stl", "solid\n");
  EXPECT_NE(format.find("shape.stl:0: unknown mesh format '.stl'"), std::string::npos) << format;

  const std::string missing = [] {
    try {
      (void)load_polyhedron_file("/nonexistent/rubble.off");
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  }();
  EXPECT_NE(missing.find("/nonexistent/rubble.off:0: cannot open"), std::string::npos) << missing;
}

}  // namespace
}  // namespace rubble
