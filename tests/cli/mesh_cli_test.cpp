// `stf mesh close` through the command line: an open mesh comes out closed and passes the check
// a scene makes; the input is never the output; what cannot be closed is refused in one line,
// with nothing written.
#include <cmath>

#include "cli_fixture.h"
#include "stf/geometry/mesh.h"

namespace {

// The unit cube without its top face, each face with its own four corners (as exporters write
// texture seams): 20 vertices, 12 of them repeats of others' positions.
const std::string kOpenCube =
    "v 0 0 0\nv 0 1 0\nv 1 1 0\nv 1 0 0\n"
    "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\n"
    "v 0 1 0\nv 0 1 1\nv 1 1 1\nv 1 1 0\n"
    "v 0 0 0\nv 0 0 1\nv 0 1 1\nv 0 1 0\n"
    "v 1 0 0\nv 1 1 0\nv 1 1 1\nv 1 0 1\n"
    "f 1 2 3 4\nf 5 6 7 8\nf 9 10 11 12\nf 13 14 15 16\nf 17 18 19 20\n";

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST_F(Cli, MeshCloseFillsTheHoleAndTheResultPassesTheCheck) {
  std::ofstream(out("open.obj")) << kOpenCube;
  const std::string why = stf::geometry::mesh_error(stf::geometry::read_obj(out("open.obj")));
  EXPECT_NE(why.find("not closed, it has 1 hole (rims of edges with a triangle on one side only): 4 edges"), std::string::npos) << why;
  const Result r = stf("mesh close '" + out("open.obj") + "' -o '" + out("closed.obj") + "'");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err,
            "stf mesh close: 1 hole closed with 2 triangles (0 by a fan about a new vertex), 12 vertices welded, "
            "enclosed volume 0.666667 before (open) and 1 after -> " + out("closed.obj") + "\n");
  const stf::geometry::TriangleMesh closed = stf::geometry::read_obj(out("closed.obj"));
  EXPECT_EQ(stf::geometry::mesh_error(closed), "");
  EXPECT_EQ(closed.vertices.size(), 8u);
  EXPECT_NEAR(stf::geometry::enclosed_volume(closed), 1, 1e-12);
  // A closed mesh goes through unchanged but for the joined vertices.
  const Result again = stf("mesh close --quiet '" + out("closed.obj") + "' -o '" + out("again.obj") + "'");
  ASSERT_EQ(again.status, 0) << again.err;
  EXPECT_EQ(again.err, "");
  EXPECT_EQ(slurp(out("again.obj")), slurp(out("closed.obj")));
  expect_no_litter("mesh close");
}

TEST_F(Cli, MeshCloseNeverWritesItsInput) {
  std::ofstream(out("open.obj")) << kOpenCube;
  fs::create_symlink(out("open.obj"), out("link.obj"));
  for (const std::string& target : {out("open.obj"), out("link.obj")}) {
    const Result r = stf("mesh close '" + out("open.obj") + "' -o '" + target + "'");
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("same file"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  EXPECT_EQ(slurp(out("open.obj")), kOpenCube);
  expect_no_litter("mesh close onto its input");
}

TEST_F(Cli, MeshCloseRefusesWhatItCannotCloseInOneLine) {
  // A fin: a third triangle on the cube's edge from (0, 0, 0) to (0, 1, 0).
  std::ofstream(out("fin.obj")) << kOpenCube << "v -1 0.5 0.5\nf 1 2 21\n";
  std::ofstream(out("broken.obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"fin.obj", "is in 3 triangles"}, {"broken.obj", "broken.obj:4:"}, {"missing.obj", "missing.obj"}};
  for (const auto& [name, expected] : cases) {
    const Result r = stf("mesh close '" + out(name) + "' -o '" + out("closed.obj") + "'");
    EXPECT_EQ(r.status, 2) << name << ": " << r.err;
    EXPECT_EQ(r.err.rfind("stf: error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(expected), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(out("closed.obj"))) << name;
  }
  expect_no_litter("mesh close refused");
}

}  // namespace
