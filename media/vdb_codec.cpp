// The grid codec module (grid_codec.h): .vdb files read and written through OpenVDB.
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>

#include "grid_codec.h"

namespace stf::media {

namespace {

using openvdb::FloatGrid;
using openvdb::GridBase;

std::string grid_list(const openvdb::GridPtrVec& grids) {
  std::string names;
  for (const auto& grid : grids) names += (names.empty() ? "" : ", ") + ("'" + grid->getName() + "' " + grid->valueType());
  return names.empty() ? "no grid" : names;
}

// The float grid named `density`, else the only float grid (its metadata and transform).
GridBase::Ptr pick_grid(const std::string& path, const openvdb::GridPtrVec& grids) {
  std::vector<GridBase::Ptr> floats;
  for (const auto& grid : grids)
    if (grid->isType<FloatGrid>()) floats.push_back(grid);
  if (floats.empty()) throw grid_error(path, "holds no float grid for the density (" + grid_list(grids) + ")");
  for (const auto& grid : floats)
    if (grid->getName() == "density") return grid;
  if (floats.size() > 1)
    throw grid_error(path, "holds " + std::to_string(floats.size()) + " float grids and none is named 'density' (" +
                               grid_list(grids) + ")");
  return floats[0];
}

// The active voxels' bounding box as the file's metadata records it (OpenVDB writes it unless told not to).
std::optional<Dims> metadata_dims(const GridBase& grid) {
  const auto lower = grid.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MIN);
  const auto upper = grid.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MAX);
  if (!lower || !upper) return std::nullopt;
  Dims dims;
  for (int a = 0; a < 3; ++a) dims[a] = std::max<std::int64_t>(0, std::int64_t(upper->value()[a]) - lower->value()[a] + 1);
  return dims;
}

// The index-to-world map, refused unless linear (x = A u + t with u from the box's lower corner).
void read_transform(const std::string& path, const FloatGrid& grid, const openvdb::CoordBBox& box, Lattice& lattice) {
  const auto map = grid.transform().baseMap();
  if (!map->isLinear())
    throw grid_error(path, "grid '" + grid.getName() + "' has a " + map->type() +
                               " transform: only linear (affine) index-to-world maps are read");
  const openvdb::Vec3d t = map->applyMap(box.min().asVec3d());
  for (int a = 0; a < 3; ++a) {
    openvdb::Vec3d unit(0, 0, 0);
    unit[a] = 1;
    const openvdb::Vec3d column = map->applyJacobian(unit);
    for (int r = 0; r < 3; ++r) lattice.to_world[r][a] = column[r];
  }
  for (int r = 0; r < 3; ++r) lattice.to_world[r][3] = t[r];
}

// Active voxels and tiles into the dense lattice over `box`; inactive ones stay 0 (the background is not density).
void densify(const FloatGrid& grid, const openvdb::CoordBBox& box, Lattice& lattice) {
  const auto& n = lattice.dims;
  lattice.values.assign(std::size_t(n[0] * n[1] * n[2]), 0.0f);
  const openvdb::Coord o = box.min();
  auto put = [&](const openvdb::Coord& c, float v) {
    lattice.values[std::size_t(((c.x() - o.x()) * n[1] + (c.y() - o.y())) * n[2] + (c.z() - o.z()))] = v;
  };
  for (auto it = grid.cbeginValueOn(); it; ++it) {
    if (it.isVoxelValue()) {
      put(it.getCoord(), *it);
      continue;
    }
    openvdb::CoordBBox tile;
    it.getBoundingBox(tile);
    tile.intersect(box);
    for (int x = tile.min().x(); x <= tile.max().x(); ++x)
      for (int y = tile.min().y(); y <= tile.max().y(); ++y)
        for (int z = tile.min().z(); z <= tile.max().z(); ++z) put(openvdb::Coord(x, y, z), *it);
  }
}

void read_grid(const std::string& path, FitsCheck fits, Lattice& lattice) {
  openvdb::io::File file(path);
  file.open(false);
  const GridBase::Ptr chosen = pick_grid(path, *file.readAllGridMetadata());
  if (const auto dims = metadata_dims(*chosen)) fits(path, *dims);  // before the tree is read
  const FloatGrid::Ptr grid = openvdb::gridPtrCast<FloatGrid>(file.readGrid(chosen->getName()));
  file.close();
  const openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
  if (box.empty()) throw grid_error(path, "grid '" + grid->getName() + "' has no active voxel");
  lattice.dims = {box.dim().x(), box.dim().y(), box.dim().z()};
  fits(path, lattice.dims);
  read_transform(path, *grid, box, lattice);
  densify(*grid, box, lattice);
  lattice.index_origin = {box.min().x(), box.min().y(), box.min().z()};
  lattice.vdb_index = true;
  lattice.clip = {{-1, -1, -1}, {double(lattice.dims[0]), double(lattice.dims[1]), double(lattice.dims[2])}};
}

void read_vdb(const std::string& path, FitsCheck fits, Lattice& lattice) {
  openvdb::initialize();
  try {
    read_grid(path, fits, lattice);
  } catch (const openvdb::Exception& e) {
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    throw grid_error(path, "unreadable .vdb file (" + what + ")");
  }
}

// x = A u + t as OpenVDB's matrix, which maps row vectors (world = index M): M's rows 0-2 are
// A's columns and row 3 is t.
openvdb::math::Transform::Ptr linear_transform(const Lattice& lattice) {
  openvdb::Mat4d m = openvdb::Mat4d::identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m[c][r] = lattice.to_world[r][c];
    m[3][r] = lattice.to_world[r][3];
  }
  return openvdb::math::Transform::createLinearTransform(m);
}

// The lattice as a sparse fog volume: value [i, j, k] at index (i, j, k), the voxels above the
// background 0 active (copyFromDense with tolerance 0 leaves those equal to it inactive).
FloatGrid::Ptr sparse_grid(const Lattice& lattice) {
  const auto& n = lattice.dims;
  if (std::max({n[0], n[1], n[2]}) > std::numeric_limits<std::int32_t>::max())
    throw grid_error(lattice.source, "a lattice past OpenVDB's 32-bit index coordinates");
  const openvdb::CoordBBox box(openvdb::Coord(0, 0, 0), openvdb::Coord(int(n[0] - 1), int(n[1] - 1), int(n[2] - 1)));
  // Layout ZYX (k fastest) is C order. Dense wants a mutable pointer; copyFromDense only reads it.
  const openvdb::tools::Dense<float, openvdb::tools::LayoutZYX> dense(box, const_cast<float*>(lattice.values.data()));
  FloatGrid::Ptr grid = FloatGrid::create(0.0f);
  openvdb::tools::copyFromDense(dense, *grid, 0.0f);
  grid->setName("density");
  grid->setGridClass(openvdb::GRID_FOG_VOLUME);
  grid->setTransform(linear_transform(lattice));
  return grid;
}

// io::File::write never looks at its stream once written, so a full disk would leave a cut file
// unnoticed: the same archive (seekable, as io::File writes it) into a stream that is checked.
class CheckedArchive : public openvdb::io::Archive {
 public:
  void write_to(std::ostream& out, const openvdb::GridCPtrVec& grids) const {
    Archive::write(out, grids, /*seekable=*/true);
  }
};

void write_vdb(const std::string& path, const Lattice& lattice) {
  openvdb::initialize();
  const auto cannot = [&path](const std::string& why) { return grid_error(path, "cannot write the .vdb file (" + why + ")"); };
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw cannot(std::strerror(errno));
  try {
    CheckedArchive().write_to(out, {sparse_grid(lattice)});
  } catch (const openvdb::Exception& e) {
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    throw cannot(what);
  }
  out.close();
  if (!out) throw cannot(std::strerror(errno));
}

const GridCodec kCodec{read_vdb, write_vdb};

}  // namespace

}  // namespace stf::media

extern "C" const stf::media::GridCodec* stf_grid_codec() { return &stf::media::kCodec; }
