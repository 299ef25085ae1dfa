// `stf mesh close`: a user's repair step for meshes that are to bound media, which must be
// closed (geometry/mesh.cpp, mesh_error): every hole filled with flat triangles turned as their
// neighbours, the result checked as a scene would check it, and written as OBJ.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "cli.h"
#include "stf/geometry/mesh.h"
#include "stf/geometry/mesh_repair.h"

namespace stf::cli {

namespace {

struct CloseOptions {
  std::string input, output;
  bool quiet = false;
};

geometry::TriangleMesh read_as_written(const std::string& path) {
  try {
    return geometry::read_obj_as_written(path);
  } catch (const std::runtime_error& e) {
    fail(e.what());  // the reader's line names the file and line
  }
}

geometry::ClosedMesh closed(const geometry::TriangleMesh& mesh, const std::string& path) {
  try {
    return geometry::close_holes(mesh);
  } catch (const std::runtime_error& e) {
    fail(fmt::format("{}: cannot close the mesh: {}", path, e.what()));
  }
}

void run_close(const CloseOptions& o) {
  require_files({{o.input, "IN"}});
  // Before any work: the output is never the input (nor the --config file), and takes its lock.
  AtomicOutput out(o.output, "-o", {{o.input, "the input mesh"}});
  const geometry::TriangleMesh as_written = read_as_written(o.input);
  const geometry::TriangleMesh mesh = geometry::welded(as_written);
  const geometry::ClosedMesh c = closed(mesh, o.input);
  // What a scene would refuse (a degenerate triangle, no volume) is refused here, not written.
  if (const std::string why = geometry::mesh_error(c.mesh); !why.empty()) {
    // A flat sheet (a 2D mesh) closes onto its own back: no volume, and nothing to fill it.
    const bool flat = !(std::abs(geometry::enclosed_volume(c.mesh)) > 0);
    fail(fmt::format("{}: the mesh, its holes filled, still cannot bound a medium: {}{}", o.input, why,
                     flat ? " (a flat sheet, not the surface of a solid)" : ""));
  }
  stop_if_interrupted();
  out.write(geometry::obj_text(c.mesh));
  if (o.quiet) return;
  // The open mesh's volume counts its triangles' tetrahedra to the origin: where it differs
  // from the closed one's is what the filling added, measured from the origin.
  const auto count = [](std::size_t n, const char* one, const char* many) { return fmt::format("{} {}", n, n == 1 ? one : many); };
  std::fprintf(stderr, "stf mesh close: %s closed with %s (%zu by a fan about a new vertex), %s welded, "
               "enclosed volume %.6g before (open) and %.6g after -> %s\n",
               count(c.holes, "hole", "holes").c_str(), count(c.triangles_added, "triangle", "triangles").c_str(), c.fans,
               count(as_written.vertices.size() - mesh.vertices.size(), "vertex", "vertices").c_str(),
               geometry::enclosed_volume(mesh), geometry::enclosed_volume(c.mesh), o.output.c_str());
}

}  // namespace

void add_mesh_command(CLI::App& app) {
  CLI::App* mesh = app.add_subcommand("mesh", "Repair meshes that are to bound media (OBJ)");
  mesh->require_subcommand(1);
  auto o = std::make_shared<CloseOptions>();
  CLI::App* cmd = mesh->add_subcommand(
      "close", "Fill every hole of an OBJ mesh with flat triangles turned as their neighbours, check it, write OBJ");
  cmd->add_option("input", o->input, "The mesh (OBJ, read strictly; vertices at the same position joined)")->required();
  cmd->add_option("-o,--output", o->output, "The closed mesh (OBJ: v and f lines)")->required();
  cmd->add_flag("--quiet", o->quiet, "No summary line");
  cmd->callback([o] { run_close(*o); });
}

}  // namespace stf::cli
