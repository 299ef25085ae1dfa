// Meshes that bound media: the checks refuse what cannot bound one and name the element; the
// procedural shapes are valid and enclose their analytic volumes; Embree's rays and distances
// agree with brute force over every triangle; the free radius (exact query and distance grid)
// is never above the true distance, on convex, concave and thin meshes.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <tuple>

#include "stf/geometry/boundary.h"
#include "stf/geometry/distance_grid.h"
#include "stf/geometry/mesh.h"
#include "stf/geometry/mesh_repair.h"
#include "stf/geometry/shipped_meshes.h"

namespace {

using namespace stf;
using namespace stf::geometry;
namespace fs = std::filesystem;

const fs::path kMeshes = fs::path(STF_SOURCE_DIR) / "data/scenes/meshes";

// The winding number of the mesh about p (the sum of the triangles' signed solid angles over
// 4 pi, Van Oosterom and Strackee 1983): 1 inside, 0 outside; no ray is cast.
double winding_number(const TriangleMesh& m, const Vec3& p) {
  double sum = 0;
  for (const auto& t : m.triangles) {
    const Vec3 a = m.vertices[t[0]] - p, b = m.vertices[t[1]] - p, c = m.vertices[t[2]] - p;
    const double la = length(a), lb = length(b), lc = length(c);
    sum += 2 * std::atan2(dot(a, cross(b, c)), la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la);
  }
  return sum / (4 * kPi);
}

double segment_distance(const Vec3& p, const Vec3& a, const Vec3& b) {
  const double t = std::clamp(dot(p - a, b - a) / dot(b - a, b - a), 0.0, 1.0);
  return length(p - (a + t * (b - a)));
}

// The distance to the triangle another way: the plane's distance where p projects inside the
// triangle (all three edge tests agree), else the nearest of the three edges.
double triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = normalize(cross(b - a, c - a));
  const double h = dot(p - a, n);
  const Vec3 q = p - h * n;
  const bool in = dot(cross(b - a, q - a), n) >= 0 && dot(cross(c - b, q - b), n) >= 0 && dot(cross(a - c, q - c), n) >= 0;
  if (in) return std::abs(h);
  return std::min({segment_distance(p, a, b), segment_distance(p, b, c), segment_distance(p, c, a)});
}

double brute_distance(const TriangleMesh& m, const Vec3& p) {
  double d = HUGE_VAL;
  for (const auto& t : m.triangles) d = std::min(d, triangle_distance(p, m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]));
  return d;
}

// Points inside the mesh, uniform in its volume (by the winding number).
std::vector<Vec3> interior_points(const TriangleMesh& m, int count, unsigned seed) {
  const Bounds b = bounds_of(m);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> points;
  while (int(points.size()) < count) {
    const Vec3 e = b.extent();
    const Vec3 p = b.lower + Vec3{e.x * u(rng), e.y * u(rng), e.z * u(rng)};
    if (winding_number(m, p) > 0.5) points.push_back(p);
  }
  return points;
}

std::vector<std::pair<std::string, TriangleMesh>> test_meshes() {
  std::vector<std::pair<std::string, TriangleMesh>> meshes = shipped_meshes();
  meshes.emplace_back("spot.obj", oriented_outward(read_obj((kMeshes / "spot.obj").string())));
  return meshes;
}

TEST(Mesh, ShapesAreClosedOrientedAndEncloseTheirVolumes) {
  const double r = 0.5, R = 0.35, rt = 0.15;
  // Steiner's formula for a box of inner sides a, b, c grown by a ball of radius s.
  auto rounded = [](double a, double b, double c, double s) {
    return a * b * c + 2 * s * (a * b + b * c + c * a) + kPi * s * s * (a + b + c) + 4.0 / 3 * kPi * s * s * s;
  };
  const std::vector<double> exact{4.0 / 3 * kPi * r * r * r, 2 * kPi * kPi * R * rt * rt,
                                  rounded(0.84, 0.54, 0.34, 0.08), rounded(0.96, 0.04, 0.76, 0.02)};
  const auto meshes = shipped_meshes();
  for (std::size_t i = 0; i < meshes.size(); ++i) {
    const auto& [name, m] = meshes[i];
    EXPECT_EQ(mesh_error(m), "") << name;
    const double v = enclosed_volume(m);
    // Inscribed tessellations: a little below the exact volume, by under 1%.
    EXPECT_LT(v, exact[i]) << name;
    EXPECT_GT(v, 0.99 * exact[i]) << name;
  }
}

TEST(Mesh, ShippedFilesAreTheProceduralMeshes) {
  for (const auto& [name, m] : shipped_meshes()) {
    const TriangleMesh read = read_obj((kMeshes / name).string());
    ASSERT_EQ(read.vertices.size(), m.vertices.size()) << name;
    ASSERT_EQ(read.triangles.size(), m.triangles.size()) << name;
    for (std::size_t i = 0; i < m.vertices.size(); ++i) EXPECT_EQ(length(read.vertices[i] - m.vertices[i]), 0) << name << i;
    EXPECT_EQ(read.triangles, m.triangles) << name;
  }
  EXPECT_EQ(mesh_error(read_obj((kMeshes / "spot.obj").string())), "");
}

// Each defect in a small closed mesh, and the element its message names.
TEST(Mesh, DefectsAreNamed) {
  const TriangleMesh good = icosphere(1, 0);
  ASSERT_EQ(mesh_error(good), "");
  TriangleMesh open = good;
  open.triangles.pop_back();
  EXPECT_NE(mesh_error(open).find("not closed"), std::string::npos) << mesh_error(open);
  TriangleMesh flipped = good;
  std::swap(flipped.triangles[3][1], flipped.triangles[3][2]);
  EXPECT_NE(mesh_error(flipped).find("not consistently oriented"), std::string::npos) << mesh_error(flipped);
  TriangleMesh repeated = good;
  repeated.triangles[5][2] = repeated.triangles[5][0];
  EXPECT_NE(mesh_error(repeated).find("triangle 6"), std::string::npos) << mesh_error(repeated);
  TriangleMesh flat = good;
  flat.vertices[flat.triangles[0][2]] = 0.5 * (flat.vertices[flat.triangles[0][0]] + flat.vertices[flat.triangles[0][1]]);
  EXPECT_NE(mesh_error(flat).find("degenerate"), std::string::npos) << mesh_error(flat);
  TriangleMesh nan = good;
  nan.vertices[7].y = std::nan("");
  EXPECT_NE(mesh_error(nan).find("vertex 8 is not finite"), std::string::npos) << mesh_error(nan);
  TriangleMesh doubled = good;  // a second copy of every triangle: each edge four times
  doubled.triangles.insert(doubled.triangles.end(), good.triangles.begin(), good.triangles.end());
  EXPECT_NE(mesh_error(doubled).find("same way"), std::string::npos) << mesh_error(doubled);
  TriangleMesh inward = good;
  for (auto& t : inward.triangles) std::swap(t[1], t[2]);
  EXPECT_EQ(mesh_error(inward), "");  // consistent, only the other way round
  EXPECT_LT(enclosed_volume(inward), 0);
  EXPECT_GT(enclosed_volume(oriented_outward(inward)), 0);
}

TEST(Mesh, FilesThatAreNoMeshesAreRefusedNamingTheFile) {
  const fs::path dir = fs::temp_directory_path() / ("stf-geometry-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::vector<std::pair<std::string, std::string>> files = {
      {"empty.obj", ""}, {"points.obj", "v 0 0 0\nv 1 0 0\n"}, {"bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"}};
  for (const auto& [name, text] : files) {
    std::ofstream((dir / name).string()) << text;
    try {
      read_obj((dir / name).string());
      ADD_FAILURE() << name << " was read";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(read_obj((dir / "missing.obj").string()), std::runtime_error);
  fs::remove_all(dir);
}

// The reader's verdict on `text` as an OBJ file: "" when read, else its message.
std::string obj_verdict(const std::string& text, TriangleMesh* mesh = nullptr) {
  const fs::path file = fs::temp_directory_path() / ("stf-obj-" + std::to_string(::getpid()) + ".obj");
  std::ofstream(file.string(), std::ios::binary) << text;
  std::string why;
  try {
    const TriangleMesh m = read_obj(file.string());
    if (mesh) *mesh = m;
  } catch (const std::runtime_error& e) {
    why = e.what();
  }
  fs::remove(file);
  return why;
}

const std::string kTetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";

// Each statement the reader cannot read exactly is refused naming the file, its line and what
// is wrong; nothing is read as zero, wrapped or dropped.
TEST(Obj, EveryMisreadableStatementIsRefusedByLine) {
  const std::vector<std::tuple<std::string, int, std::string>> cases = {
      {"v nan 0 0\n", 1, "not finite"},
      {"v 0 inf 0\n", 1, "not finite"},
      {"v x y z\n", 1, "'x' is not a number"},
      {"v 0 0\n", 1, "three numbers"},
      {"v 0 0 0 0 0\n", 1, "three numbers"},
      {"v 1e39 0 0\n", 1, "range of float"},
      {"v 1e400 0 0\n", 1, "out of range"},
      {"v 0x1 0 0\n", 1, "not a number"},
      {kTetra + "f 1 2 99999999999999999999\n", 5, "out of range"},
      {kTetra + "f 1 2 5\n", 5, "names vertex 5, but 4"},
      {kTetra + "f 1 2 0\n", 5, "count from 1"},
      {kTetra + "f 1 2 -5\n", 5, "names vertex -5"},
      {kTetra + "f 1 2 3 999999\n", 5, "names vertex 999999"},
      {kTetra + "f 1 2\n", 5, "at least three"},
      {kTetra + "f 1 2 3.5\n", 5, "not a vertex index"},
      {kTetra + "f 1/a 2 3\n", 5, "not a face corner"},
      {"v 0 0 0\nv 2 0 0\nv 1 0.2 0\nv 1 2 0\nf 1 2 3 4\n", 5, "not convex"},
      {kTetra + "curv 0 1 1 2\n", 5, "free-form"},
      {std::string("v 0 0 0\nv 1 0 0\0\n", 19), 2, "NUL"},
  };
  for (const auto& [text, line, what] : cases) {
    const std::string why = obj_verdict(text);
    EXPECT_NE(why.find("stf-obj-"), std::string::npos) << text << " -> " << why;
    EXPECT_NE(why.find(".obj:" + std::to_string(line) + ": "), std::string::npos) << text << " -> " << why;
    EXPECT_NE(why.find(what), std::string::npos) << text << " -> " << why;
    EXPECT_EQ(why.find('\n'), std::string::npos) << why;
  }
}

// What a mesh may carry beside its surface is read past; negative and slashed corners name the
// same vertices as plain ones; a convex quad becomes two triangles; CRLF ends lines too.
TEST(Obj, EverythingElseIsReadAsTheSameSurface) {
  TriangleMesh plain, decorated;
  ASSERT_EQ(obj_verdict(kTetra + "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n", &plain), "");
  const std::string text =
      "# a comment\r\nmtllib /dev/zero missing.mtl\r\no tetra\r\ng side\r\ns 1\r\nusemtl stone\r\n"
      "v 0 0 0 1\r\nv 1 0 0 0.5 0.5 0.5\r\nv 0 1 0\r\nv 0 0 1  # the apex\r\nvt 0 0\r\nvn 0 0 1\r\n"
      "f -4/1 -2/1/1 -3//1\r\nf 1 2 4\r\nf 1 4 3\r\nf 2 3 4\r\nl 1 2\r\n";
  ASSERT_EQ(obj_verdict(text, &decorated), "");
  EXPECT_EQ(decorated.vertices.size(), plain.vertices.size());
  EXPECT_EQ(decorated.triangles, plain.triangles);
  TriangleMesh quad;
  ASSERT_EQ(obj_verdict("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", &quad), "");
  EXPECT_EQ(quad.triangles.size(), 2u);
}

// A mesh file that is a FIFO, a folder or a device is refused as such before it is opened (a
// FIFO would block), and an mtllib naming a FIFO is never opened.
TEST(Obj, FilesThatAreNotRegularAreRefusedAsSuch) {
  const fs::path dir = fs::temp_directory_path() / ("stf-obj-fifo-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string fifo = (dir / "pipe").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& path : {fifo, dir.string(), std::string("/dev/zero")}) {
    try {
      read_obj(path);
      ADD_FAILURE() << path << " was read";
    } catch (const std::runtime_error& e) {
      const std::string why = e.what();
      EXPECT_TRUE(why.find("not a regular file") != std::string::npos || why.find("is a folder") != std::string::npos) << why;
    }
  }
  std::ofstream((dir / "m.obj").string()) << "mtllib pipe\n" << kTetra << "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
  EXPECT_EQ(read_obj((dir / "m.obj").string()).triangles.size(), 4u);
  fs::remove_all(dir);
}

TEST(Boundary, DistanceIsALowerBoundWithinRoundingOfBruteForce) {
  for (const auto& [name, m] : test_meshes()) {
    const Boundary boundary({m});
    for (const Vec3& p : interior_points(m, 150, 7)) {
      const double exact = brute_distance(m, p), d = boundary.distance(p);
      EXPECT_LE(d, exact) << name;
      // The margins for float: Embree's search about p rounded (1e-7 here) and its culling.
      EXPECT_GE(d, exact * (1 - 1e-5) - 2e-7) << name;
    }
  }
}

TEST(Boundary, GridBoundIsNeverAboveTheTrueDistance) {
  for (const auto& [name, m] : test_meshes()) {
    const Boundary boundary({m});
    const DistanceGrid grid(boundary, bounds_of(m), 48);
    double slack = 0;
    const std::vector<Vec3> points = interior_points(m, 300, 11);
    for (const Vec3& p : points) {
      const double exact = brute_distance(m, p), g = grid.lower_bound(p);
      EXPECT_LE(g, exact) << name;
      const double tight = grid.tight_lower_bound(p);
      EXPECT_LE(tight, exact) << name;
      // The eight centres include the one-cell bound's; their offsets are summed in another
      // order, so the two may differ by rounding.
      EXPECT_GE(tight, g - 1e-12) << name;
      // Exact at the centres within the band, so within a cell's diagonal there; deeper within
      // a coarse cell's.
      EXPECT_GE(g, exact - std::sqrt(3.0) * (exact < grid.band() ? 1 : 5) * grid.cell()) << name;
      slack += exact - g;
    }
    // On average within 1.25 cells: 0.4-1.0 here, where the bound from the one coarse centre
    // that holds a deep cell fell 1.3-1.6 cells short in the icosphere and the rounded box.
    EXPECT_LT(slack / double(points.size()), 1.25 * grid.cell()) << name;
    EXPECT_EQ(grid.bytes() % 128, 0u);  // whole bricks of 64 16-bit values
  }
}

TEST(Boundary, RaysFromInsideLeaveThroughTheirMeshFacingOut) {
  for (const auto& [name, m] : test_meshes()) {
    const Boundary boundary({m});
    std::mt19937_64 rng(3);
    std::normal_distribution<double> n;
    for (const Vec3& p : interior_points(m, 100, 13)) {
      const Vec3 w = normalize({n(rng), n(rng), n(rng)});
      const Hit h = boundary.intersect(p, w);
      ASSERT_TRUE(h.found) << name;
      EXPECT_EQ(h.object, 0);
      EXPECT_GE(h.t, brute_distance(m, p) * (1 - 1e-5)) << name;  // no nearer than the nearest triangle
      EXPECT_GT(dot(h.normal, w), 0) << name;                      // leaving: the outward normal ahead
      EXPECT_TRUE(boundary.inside(p, 0)) << name;
      const Vec3 out = boundary.spawn(p + h.t * w, h.normal, w);
      EXPECT_LT(winding_number(m, out), 0.5) << name;
    }
  }
}

// The unit cube [0, 1]^3, outward, as two triangles per face (vertex x + 2y + 4z); face k is
// triangles 2k and 2k + 1 (-z, +z, -y, +y, -x, +x).
TriangleMesh unit_cube() {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i) m.vertices.push_back({double(i & 1), double((i >> 1) & 1), double((i >> 2) & 1)});
  const std::uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  return m;
}

TriangleMesh without_faces(TriangleMesh m, std::vector<int> faces) {
  std::sort(faces.rbegin(), faces.rend());
  for (int f : faces) m.triangles.erase(m.triangles.begin() + 2 * f, m.triangles.begin() + 2 * f + 2);
  return m;
}

// The side walls of a prism of height h over the counter-clockwise polygon (x, y): open at both
// ends, outward.
TriangleMesh open_prism(const std::vector<std::pair<double, double>>& polygon, double h) {
  TriangleMesh m;
  const auto n = std::uint32_t(polygon.size());
  for (const auto& [x, y] : polygon) m.vertices.push_back({x, y, 0});
  for (const auto& [x, y] : polygon) m.vertices.push_back({x, y, h});
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t j = (i + 1) % n;
    m.triangles.push_back({i, j, n + j});
    m.triangles.push_back({i, n + j, n + i});
  }
  return m;
}

double polygon_area(const std::vector<std::pair<double, double>>& p) {
  double twice = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    twice += p[i].first * p[(i + 1) % p.size()].second - p[(i + 1) % p.size()].first * p[i].second;
  return twice / 2;
}

TEST(MeshClose, CubeWithAFaceRemovedIsClosedAsItWas) {
  const TriangleMesh open = without_faces(unit_cube(), {1});
  const std::string why = mesh_error(open);
  EXPECT_NE(why.find("not closed"), std::string::npos) << why;
  EXPECT_NE(why.find("1 hole (rims of edges with a triangle on one side only): 4 edges, 4 long, about (0.5, 0.5, 1)"), std::string::npos) << why;
  EXPECT_NE(why.find("stf mesh close"), std::string::npos) << why;
  const ClosedMesh c = close_holes(open);
  EXPECT_EQ(mesh_error(c.mesh), "");
  EXPECT_EQ(c.holes, 1u);
  EXPECT_EQ(c.triangles_added, 2u);
  EXPECT_EQ(c.fans, 0u);
  EXPECT_EQ(c.mesh.vertices.size(), 8u);
  EXPECT_NEAR(enclosed_volume(c.mesh), 1, 1e-12);
}

TEST(MeshClose, TwoHolesAreNamedAndBothFilled) {
  const TriangleMesh open = without_faces(unit_cube(), {0, 1});
  EXPECT_EQ(boundary_loops(open).size(), 2u);
  const std::string why = mesh_error(open);
  EXPECT_NE(why.find("2 holes (rims"), std::string::npos) << why;
  EXPECT_NE(why.find("; 4 edges, 4 long, about (0.5, 0.5, 1)"), std::string::npos) << why;
  EXPECT_EQ(why.find('\n'), std::string::npos);
  const ClosedMesh c = close_holes(open);
  EXPECT_EQ(mesh_error(c.mesh), "");
  EXPECT_EQ(c.holes, 2u);
  EXPECT_EQ(c.triangles_added, 4u);
  EXPECT_NEAR(enclosed_volume(c.mesh), 1, 1e-12);
}

// Five holes: the line names three and counts the rest.
TEST(MeshClose, TheMessageNamesTheFirstThreeHoles) {
  TriangleMesh ico = icosphere(1, 2);
  std::vector<bool> used(ico.vertices.size());
  std::vector<std::size_t> removed;  // five triangles that share no vertex: five holes
  for (std::size_t k = 0; k < ico.triangles.size() && removed.size() < 5; ++k) {
    const auto& t = ico.triangles[k];
    if (used[t[0]] || used[t[1]] || used[t[2]]) continue;
    for (std::uint32_t i : t) used[i] = true;
    removed.push_back(k);
  }
  for (auto k = removed.rbegin(); k != removed.rend(); ++k) ico.triangles.erase(ico.triangles.begin() + std::ptrdiff_t(*k));
  const std::string why = mesh_error(ico);
  EXPECT_NE(why.find("5 holes (rims of edges with a triangle on one side only): 3 edges"), std::string::npos) << why;
  EXPECT_NE(why.find("; and 2 more"), std::string::npos) << why;
  const ClosedMesh c = close_holes(ico);
  EXPECT_EQ(mesh_error(c.mesh), "");
  EXPECT_EQ(c.holes, 5u);
  // Five faces of the cube gone leave one rim, round the face that is left.
  const TriangleMesh open = without_faces(unit_cube(), {0, 1, 2, 3, 4});
  ASSERT_EQ(boundary_loops(open).size(), 1u);
  EXPECT_EQ(boundary_loops(open)[0].size(), 4u);
}

// A loop of 200 edges (a cylinder's rim) and a star-shaped rim whose ears are not all corners:
// every cap is cut from the rim's own vertices and encloses the prism's exact volume.
TEST(MeshClose, LongAndConcaveRimsAreFilledFromTheirOwnVertices) {
  std::vector<std::pair<double, double>> circle, star;
  for (int i = 0; i < 200; ++i) circle.emplace_back(std::cos(2 * kPi * i / 200), std::sin(2 * kPi * i / 200));
  for (int i = 0; i < 14; ++i) {
    const double r = i % 2 ? 0.4 : 1.0;
    star.emplace_back(r * std::cos(2 * kPi * i / 14), r * std::sin(2 * kPi * i / 14));
  }
  for (const auto& polygon : {circle, star}) {
    const TriangleMesh open = open_prism(polygon, 0.5);
    ASSERT_EQ(boundary_loops(open).size(), 2u);
    EXPECT_EQ(boundary_loops(open)[0].size(), polygon.size());
    const ClosedMesh c = close_holes(open);
    EXPECT_EQ(mesh_error(c.mesh), "") << polygon.size();
    EXPECT_EQ(c.triangles_added, 2 * (polygon.size() - 2));
    EXPECT_EQ(c.fans, 0u);
    EXPECT_NEAR(enclosed_volume(c.mesh), 0.5 * polygon_area(polygon), 1e-12) << polygon.size();
  }
}

// The new triangles turn as their neighbours: outward meshes stay outward, inward ones inward.
TEST(MeshClose, NewTrianglesTurnAsTheirNeighbours) {
  TriangleMesh inward = without_faces(unit_cube(), {3});
  for (auto& t : inward.triangles) std::swap(t[1], t[2]);
  const ClosedMesh c = close_holes(inward);
  EXPECT_EQ(mesh_error(c.mesh), "");
  EXPECT_NEAR(enclosed_volume(c.mesh), -1, 1e-12);
  TriangleMesh ico = icosphere(1, 1);
  const double whole = enclosed_volume(ico);
  ico.triangles.erase(ico.triangles.begin() + 7, ico.triangles.begin() + 12);
  const ClosedMesh d = close_holes(ico);
  EXPECT_EQ(mesh_error(d.mesh), "");
  EXPECT_GT(enclosed_volume(d.mesh), 0.95 * whole);
  EXPECT_LE(enclosed_volume(d.mesh), whole + 1e-12);
}

TEST(MeshClose, ClosedMeshIsUnchanged) {
  const TriangleMesh ico = icosphere(1, 2);
  EXPECT_TRUE(boundary_loops(ico).empty());
  const ClosedMesh c = close_holes(ico);
  EXPECT_EQ(c.holes, 0u);
  EXPECT_EQ(c.triangles_added, 0u);
  EXPECT_EQ(c.mesh.triangles, ico.triangles);
  ASSERT_EQ(c.mesh.vertices.size(), ico.vertices.size());
  for (std::size_t i = 0; i < ico.vertices.size(); ++i) EXPECT_EQ(length(c.mesh.vertices[i] - ico.vertices[i]), 0);
}

// Two triangles that share only a vertex, removed: the rim passes that vertex twice and is cut
// there into two loops of three edges, each filled by one triangle.
TEST(MeshClose, HolesMeetingAtAVertexAreCutThere) {
  TriangleMesh ico = icosphere(1, 1);
  const std::uint32_t v = ico.triangles[0][0];
  std::vector<std::size_t> at_v;
  for (std::size_t k = 0; k < ico.triangles.size(); ++k)
    if (std::find(ico.triangles[k].begin(), ico.triangles[k].end(), v) != ico.triangles[k].end()) at_v.push_back(k);
  ASSERT_EQ(at_v.size(), 5u);
  // Around a vertex of valence 5, two triangles share an edge only when next to each other;
  // find two that share nothing but v.
  std::size_t a = at_v[0], b = a;
  for (std::size_t k : at_v) {
    int shared = 0;
    for (std::uint32_t i : ico.triangles[k])
      shared += std::count(ico.triangles[a].begin(), ico.triangles[a].end(), i);
    if (shared == 1) b = k;
  }
  ASSERT_NE(a, b);
  ico.triangles.erase(ico.triangles.begin() + std::ptrdiff_t(std::max(a, b)));
  ico.triangles.erase(ico.triangles.begin() + std::ptrdiff_t(std::min(a, b)));
  const std::vector<BoundaryLoop> loops = boundary_loops(ico);
  ASSERT_EQ(loops.size(), 2u);
  EXPECT_EQ(loops[0].size() + loops[1].size(), 6u);
  const ClosedMesh c = close_holes(ico);
  EXPECT_EQ(mesh_error(c.mesh), "");
  EXPECT_EQ(c.triangles_added, 2u);
}

// Where both diagonals of a rim are edges already (two tetrahedra on the open cube's top
// corners), no ear can be cut without repeating an edge: a fan about the centroid closes it.
TEST(MeshClose, AFanClosesWhatNoEarCan) {
  TriangleMesh m = without_faces(unit_cube(), {1});
  for (const auto& [a, b] : {std::pair<std::uint32_t, std::uint32_t>{4, 7}, {5, 6}}) {
    const auto p = std::uint32_t(m.vertices.size());
    const Vec3 mid = 0.5 * (m.vertices[a] + m.vertices[b]);
    m.vertices.push_back(mid + Vec3{0.1, -0.1, 1});
    m.vertices.push_back(mid + Vec3{-0.1, 0.1, 1.2});
    const std::uint32_t q = p + 1;
    for (const auto& t : {std::array<std::uint32_t, 3>{a, b, p}, {a, p, q}, {a, q, b}, {b, q, p}}) m.triangles.push_back(t);
  }
  ASSERT_EQ(boundary_loops(m).size(), 1u);
  const ClosedMesh c = close_holes(m);
  EXPECT_EQ(c.fans, 1u);
  EXPECT_EQ(c.triangles_added, 4u);
  EXPECT_EQ(c.mesh.vertices.size(), m.vertices.size() + 1);
  EXPECT_EQ(mesh_error(c.mesh), "");
}

TEST(MeshClose, WhatCannotBeClosedIsRefusedInOneLine) {
  TriangleMesh fin = without_faces(unit_cube(), {1});
  fin.vertices.push_back({0.5, 0.5, 2});
  fin.triangles.push_back({0, 1, 8});  // a third triangle on the cube's edge from vertex 0 to 1
  try {
    close_holes(fin);
    ADD_FAILURE() << "a non-manifold edge was closed";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("is in 3 triangles"), std::string::npos) << e.what();
  }
  TriangleMesh flipped = without_faces(unit_cube(), {1});
  std::swap(flipped.triangles[4][1], flipped.triangles[4][2]);
  try {
    close_holes(flipped);
    ADD_FAILURE() << "a mesh whose triangles disagree was closed";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("disagree on which side is outside"), std::string::npos) << e.what();
  }
}

TEST(Boundary, InsideAgreesWithTheWindingNumber) {
  const TriangleMesh m = oriented_outward(read_obj((kMeshes / "spot.obj").string()));
  const Boundary boundary({m});
  const Bounds b = bounds_of(m);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  int inside = 0;
  for (int i = 0; i < 400; ++i) {
    const Vec3 e = b.extent();
    const Vec3 p = b.lower + Vec3{e.x * u(rng), e.y * u(rng), e.z * u(rng)};
    const bool in = winding_number(m, p) > 0.5;
    inside += in;
    EXPECT_EQ(boundary.inside(p, 0), in) << p.x << " " << p.y << " " << p.z;
  }
  EXPECT_GT(inside, 40);
  EXPECT_LT(inside, 360);
}

}  // namespace
