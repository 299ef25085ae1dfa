// Writes the procedural meshes of stf/geometry/shipped_meshes.h into a folder:
//   make_meshes data/scenes/meshes
#include <cstdio>
#include <fstream>

#include "stf/geometry/shipped_meshes.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_meshes FOLDER\n");
    return 2;
  }
  for (const auto& [name, mesh] : stf::geometry::shipped_meshes()) {
    const std::string path = std::string(argv[1]) + "/" + name;
    std::ofstream out(path);
    out << "# " << name << ": made by make_meshes (stf/geometry/shipped_meshes.h)\n" << stf::geometry::obj_text(mesh);
    if (!out.flush()) {
      std::fprintf(stderr, "make_meshes: cannot write %s\n", path.c_str());
      return 1;
    }
  }
  return 0;
}
