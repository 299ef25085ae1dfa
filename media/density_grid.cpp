#include "stf/media/density_grid.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "grid_codec.h"
#include "lattice.h"
#include "npy.h"

namespace stf::media {

namespace {

using Affine = std::array<std::array<double, 4>, 3>;

double axis(const Vec3& v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }

// The inverse of x = A u + t, or nothing where A is singular or not finite.
bool invert(const Affine& m, Affine& inverse) {
  const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  if (!std::isfinite(det) || det == 0) return false;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {  // the cofactor of (c, r) over the determinant
      const int r1 = (c + 1) % 3, r2 = (c + 2) % 3, c1 = (r + 1) % 3, c2 = (r + 2) % 3;
      inverse[r][c] = (m[r1][c1] * m[r2][c2] - m[r1][c2] * m[r2][c1]) / det;
    }
  for (int r = 0; r < 3; ++r)
    inverse[r][3] = -(inverse[r][0] * m[0][3] + inverse[r][1] * m[1][3] + inverse[r][2] * m[2][3]);
  return true;
}

Vec3 apply(const Affine& m, const Vec3& p, double w) {
  return {m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + w * m[0][3], m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + w * m[1][3],
          m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + w * m[2][3]};
}

// A file that can be opened, else one line saying why not.
void check_readable(const std::string& path) {
  std::error_code error;
  const auto status = std::filesystem::status(path, error);
  if (!std::filesystem::exists(status)) throw grid_error(path, "cannot open (no such file)");
  if (std::filesystem::is_directory(status)) throw grid_error(path, "cannot open (a directory, not a file)");
  if (FILE* file = std::fopen(path.c_str(), "rb")) {
    std::fclose(file);
    return;
  }
  throw grid_error(path, "cannot open (not readable)");
}

// MemAvailable of /proc/meminfo in bytes, or 0 where it cannot be read.
double available_memory() {
  std::ifstream meminfo("/proc/meminfo");
  std::string key, unit;
  double kib = 0;
  while (meminfo >> key >> kib >> unit)
    if (key == "MemAvailable:") return kib * 1024;
  return 0;
}

std::string gib(double bytes) {
  std::ostringstream text;
  text.precision(3);
  text << bytes / double(1ull << 30) << " GiB";
  return text.str();
}

// Bytes of the values and bricks of a lattice of `dims` (double: past 2^64 for a damaged header).
double dense_bytes(const Dims& dims) {
  double values = 1, bricks = 1;
  for (std::int64_t n : dims) {
    values *= double(n);
    bricks *= std::ceil(double(n + 1) / DensityGrid::kBrick);  // cells from the padding's on
  }
  return values * sizeof(float) + bricks * sizeof(DensityGrid::Brick);
}

// 16 GiB: a dense 1600^3 grid, past which a grid wants a sparse store, not a dense copy; the
// ceiling also holds where /proc/meminfo says nothing.
constexpr double kMaxGridBytes = 16.0 * (1ull << 30);

// Refuses a lattice whose values and bricks would take more than half the available memory
// (the rest of a render needs room: the scene, the image, the sampler's tables) or the ceiling.
void check_fits(const std::string& source, const Dims& dims) {
  const double need = dense_bytes(dims);
  const double available = available_memory();
  const double limit = available > 0 ? std::min(available / 2, kMaxGridBytes) : kMaxGridBytes;
  if (need <= limit) return;
  std::ostringstream what;
  what << "a dense copy of the " << dims[0] << " x " << dims[1] << " x " << dims[2] << " grid needs " << gib(need)
       << ", more than the " << gib(limit) << " allowed (half the available memory, at most " << gib(kMaxGridBytes)
       << ")";
  throw grid_error(source, what.str());
}

std::string lowercase_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace

DensityGrid::DensityGrid(Lattice&& lattice) {
  check_values(lattice);
  if (!invert(lattice.to_world, to_lattice_))
    throw grid_error(lattice.source, "the grid's index-to-world map is singular or not finite");
  if (std::none_of(lattice.values.begin(), lattice.values.end(), [](float v) { return v > 0; }))
    throw grid_error(lattice.source, "the grid holds no non-zero density");
  for (std::size_t a = 0; a < 3; ++a) {
    const auto& row = to_lattice_[a];
    lattice_reach_[a] = std::sqrt(row[0] * row[0] + row[1] * row[1] + row[2] * row[2]);
  }
  dims_ = lattice.dims;
  values_ = std::move(lattice.values);
  to_world_ = lattice.to_world;
  clip_ = lattice.clip;
  find_support();
  build_bricks();
}

DensityGrid DensityGrid::read(const std::string& path, const std::optional<Box>& bounds) {
  const std::string ext = lowercase_extension(path);
  if (ext != ".npy" && ext != ".vdb") throw grid_error(path, "not a density grid: expected a .vdb or .npy file");
  if (ext == ".npy" && !bounds)
    throw grid_error(path, "a .npy grid needs bounds [[x0, y0, z0], [x1, y1, z1]] to place it");
  if (ext == ".vdb" && bounds)
    throw grid_error(path, "a .vdb grid is placed by its own transform: bounds are not taken");
  if (bounds) check_bounds(path, *bounds);
  check_readable(path);
  if (ext == ".npy") return DensityGrid(read_npy(path, *bounds, &check_fits));
  Lattice lattice;
  grid_codec().read_vdb(path, &check_fits, lattice);
  lattice.source = path;
  return DensityGrid(std::move(lattice));
}

DensityGrid DensityGrid::from_values(std::vector<float> values, int nx, int ny, int nz, const Box& bounds) {
  const std::string source = "density values";
  try {
    if (nx <= 0 || ny <= 0 || nz <= 0 || values.size() != std::size_t(nx) * std::size_t(ny) * std::size_t(nz))
      throw grid_error(source, std::to_string(values.size()) + " values are not a " + std::to_string(nx) + " x " +
                                   std::to_string(ny) + " x " + std::to_string(nz) + " grid");
    check_bounds(source, bounds);
    Lattice lattice;
    lattice.source = source;
    lattice.dims = {nx, ny, nz};
    lattice.values = std::move(values);
    place_in_bounds(lattice, bounds);
    return DensityGrid(std::move(lattice));
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());
  }
}

double DensityGrid::value(std::int64_t i, std::int64_t j, std::int64_t k) const {
  if (i < 0 || j < 0 || k < 0 || i >= dims_[0] || j >= dims_[1] || k >= dims_[2]) return 0;  // the padding
  return values_[std::size_t((i * dims_[1] + j) * dims_[2] + k)];
}

Vec3 DensityGrid::to_lattice(const Vec3& x) const { return apply(to_lattice_, x, 1); }
Vec3 DensityGrid::lattice_direction(const Vec3& w) const { return apply(to_lattice_, w, 0); }

double DensityGrid::lattice_density(const Vec3& u) const {
  if (!(u.x >= clip_.lower.x && u.y >= clip_.lower.y && u.z >= clip_.lower.z && u.x <= clip_.upper.x &&
        u.y <= clip_.upper.y && u.z <= clip_.upper.z))
    return 0;  // NaN too
  const double fx = std::floor(u.x), fy = std::floor(u.y), fz = std::floor(u.z);
  const double tx = u.x - fx, ty = u.y - fy, tz = u.z - fz;
  const std::int64_t i = std::int64_t(fx), j = std::int64_t(fy), k = std::int64_t(fz);
  double c[8];
  if (i >= 0 && j >= 0 && k >= 0 && i + 1 < dims_[0] && j + 1 < dims_[1] && k + 1 < dims_[2]) {
    const std::size_t row = std::size_t(dims_[2]), slab = std::size_t(dims_[1]) * row;
    const float* p = &values_[std::size_t(i) * slab + std::size_t(j) * row + std::size_t(k)];
    for (int n = 0; n < 8; ++n) c[n] = p[(n >> 2) * slab + ((n >> 1) & 1) * row + (n & 1)];
  } else {
    for (int n = 0; n < 8; ++n) c[n] = value(i + (n >> 2), j + ((n >> 1) & 1), k + (n & 1));
  }
  // Along z, then y, then x, as OpenVDB's BoxSampler.
  const double y0 = c[0] + tz * (c[1] - c[0]), y1 = c[2] + tz * (c[3] - c[2]);
  const double y2 = c[4] + tz * (c[5] - c[4]), y3 = c[6] + tz * (c[7] - c[6]);
  const double x0 = y0 + ty * (y1 - y0), x1 = y2 + ty * (y3 - y2);
  return x0 + tx * (x1 - x0);
}

// The box of the non-zero values, one cell wider (the trilinear ramp to the padding's zeros),
// within the clip region.
void DensityGrid::find_support() {
  std::int64_t lo[3] = {dims_[0], dims_[1], dims_[2]}, hi[3] = {-1, -1, -1};
  for (std::int64_t i = 0; i < dims_[0]; ++i)
    for (std::int64_t j = 0; j < dims_[1]; ++j) {
      const float* row = &values_[std::size_t((i * dims_[1] + j) * dims_[2])];
      for (std::int64_t k = 0; k < dims_[2]; ++k) {
        if (!(row[k] > 0)) continue;
        max_density_ = std::max(max_density_, double(row[k]));
        const std::int64_t at[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], at[a]), hi[a] = std::max(hi[a], at[a]);
      }
    }
  lattice_support_ = {{std::max(double(lo[0] - 1), clip_.lower.x), std::max(double(lo[1] - 1), clip_.lower.y),
                       std::max(double(lo[2] - 1), clip_.lower.z)},
                      {std::min(double(hi[0] + 1), clip_.upper.x), std::min(double(hi[1] + 1), clip_.upper.y),
                       std::min(double(hi[2] + 1), clip_.upper.z)}};
  min_density_ = min_over_support();
}

// The field is multilinear in each cell, so its extremes over a box are at the corners of the
// cells cut to the box: the lattice planes inside it and its faces, on each axis.
double DensityGrid::min_over_support() const {
  std::vector<double> planes[3];
  for (int a = 0; a < 3; ++a) {
    const double lo = axis(lattice_support_.lower, a), hi = axis(lattice_support_.upper, a);
    planes[a].push_back(lo);
    for (double p = std::floor(lo) + 1; p < hi; ++p) planes[a].push_back(p);
    planes[a].push_back(hi);
  }
  double least = std::numeric_limits<double>::infinity();
  for (double x : planes[0])
    for (double y : planes[1])
      for (double z : planes[2]) {
        least = std::min(least, lattice_density({x, y, z}));
        if (least == 0) return 0;  // a face of the support on the zeros around the values: the usual case
      }
  return least;
}

Box DensityGrid::support() const {
  const Vec3 corners[2] = {lattice_support_.lower, lattice_support_.upper};
  const double inf = std::numeric_limits<double>::infinity();
  Box box{{inf, inf, inf}, {-inf, -inf, -inf}};
  for (int n = 0; n < 8; ++n) {
    const Vec3 x = apply(to_world_, {corners[n & 1].x, corners[(n >> 1) & 1].y, corners[n >> 2].z}, 1);
    box.lower = {std::min(box.lower.x, x.x), std::min(box.lower.y, x.y), std::min(box.lower.z, x.z)};
    box.upper = {std::max(box.upper.x, x.x), std::max(box.upper.y, x.y), std::max(box.upper.z, x.z)};
  }
  return box;
}

std::size_t DensityGrid::bytes() const { return values_.size() * sizeof(float) + bricks_.size() * sizeof(Brick); }

}  // namespace stf::media
