// The cumulus (stf/media/cloud.h): ellipsoidal blobs placed from the seed, their falloffs summed,
// the falloff zone displaced by fBm of gradient noise, sampled at the voxel centres.
#include "stf/media/cloud.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "stf/core/rng.h"
#include "stf/vec3.h"

namespace stf::media {

namespace {

// A blob's falloff, in its own unit: q = 1 on its ellipsoid. Density 1 for q <= kCore, falling
// smoothly to 0 at q = 1; the noise moves q by up to kSwell (both ways), growing from nothing at
// the core over kRamp, so the cores stay exactly 1 and the support ends at q = 1 + kSwell.
constexpr double kCore = 0.5;
constexpr double kRamp = 0.15;
constexpr double kSwell = 0.35;
// The flat base fades in over this height (cube units): a cumulus' condensation level.
constexpr double kBaseFade = 0.03;
// The support's half extent, which the cloud is scaled to fill: inside the outermost voxel layer
// (centres at +-(0.5 - 0.5 / size), +-0.469 at size 16), so that layer is 0.
constexpr double kReach = 0.42;

// fBm: octaves of gradient noise, the first of period 1/kFrequency (cube units). Lacunarity 2.03,
// not 2: the octaves' lattices do not line up. Its values rarely leave +-0.5, so it is stretched
// by kNoiseGain (and clamped to +-1) to use the displacement's range.
constexpr int kOctaves = 5;
constexpr double kFrequency = 5.0, kLacunarity = 2.03, kGain = 0.5, kNoiseGain = 2.5;

constexpr int kMaxBlobs = 7;

struct Blob {
  Vec3 centre, radii;
};

struct Shape {
  std::vector<Blob> blobs;
  double base = 0;  // the plane y = base under the cloud
  std::uint64_t noise_seed = 0;
};

double smoothstep(double edge0, double edge1, double x) {
  if (x <= edge0) return 0;
  if (x >= edge1) return 1;  // exactly: the cores are exactly 1
  const double t = (x - edge0) / (edge1 - edge0);
  return t * t * (3 - 2 * t);
}

double uniform(std::uint64_t& state, double lower, double upper) {
  return lower + (upper - lower) * double(splitmix64(state) >> 11) * 0x1p-53;
}

// The blobs over a base at y = 0, before the cloud is fitted to the cube: a wide body, 2 or 3
// lower flanks around it and 2 or 3 towers rising from its top (5 to 7 blobs).
std::vector<Blob> place_blobs(std::uint64_t& state) {
  const double width = uniform(state, 0.9, 1.1);
  std::vector<Blob> blobs{{{0, 0.13, 0}, {0.26 * width, 0.17, 0.22 / width}}};
  const int flanks = 2 + int(splitmix64(state) % 2), towers = 2 + int(splitmix64(state) % 2);
  const double turn = uniform(state, 0, 2 * kPi);
  for (int f = 0; f < flanks; ++f) {
    const double angle = turn + 2 * kPi * f / flanks + uniform(state, -0.4, 0.4);
    const double distance = uniform(state, 0.14, 0.22), r = uniform(state, 0.11, 0.15);
    blobs.push_back(
        {{distance * std::cos(angle), uniform(state, 0.07, 0.1), distance * std::sin(angle)},
         {r, 0.75 * r, r}});
  }
  for (int t = 0; t < towers; ++t) {
    const double r = uniform(state, 0.1, 0.14);  // a little taller than wide: rising
    blobs.push_back(
        {{uniform(state, -0.1, 0.1), uniform(state, 0.25, 0.36), uniform(state, -0.08, 0.08)},
         {r, 1.15 * r, r}});
  }
  return blobs;
}

// Moves and scales the cloud (blobs and base) so that its support, the blobs swollen by the
// noise above the base, is centred in the cube and reaches kReach on its widest axis.
void fit_to_cube(Shape& shape) {
  Vec3 lower{INFINITY, INFINITY, INFINITY}, upper{-INFINITY, -INFINITY, -INFINITY};
  for (const Blob& b : shape.blobs) {
    const Vec3 reach = (1 + kSwell) * b.radii;
    lower = {std::min(lower.x, b.centre.x - reach.x),
             std::min(lower.y, std::max(shape.base, b.centre.y - reach.y)),
             std::min(lower.z, b.centre.z - reach.z)};
    upper = {std::max(upper.x, b.centre.x + reach.x), std::max(upper.y, b.centre.y + reach.y),
             std::max(upper.z, b.centre.z + reach.z)};
  }
  const Vec3 middle = 0.5 * (lower + upper), extent = upper - lower;
  const double scale = 2 * kReach / std::max({extent.x, extent.y, extent.z});
  for (Blob& b : shape.blobs) b = {scale * (b.centre - middle), scale * b.radii};
  shape.base = scale * (shape.base - middle.y);
}

Shape cumulus_shape(std::uint64_t seed) {
  std::uint64_t state = seed;
  Shape shape;
  shape.blobs = place_blobs(state);
  shape.noise_seed = splitmix64(state);
  fit_to_cube(shape);
  return shape;
}

// Perlin's gradient noise: at each lattice point one of the 12 directions to a cube's edge
// midpoints, picked by a hash of the point and the seed; the quintic fade between them.
constexpr signed char kGradients[12][3] = {{1, 1, 0}, {-1, 1, 0}, {1, -1, 0}, {-1, -1, 0},
                                           {1, 0, 1}, {-1, 0, 1}, {1, 0, -1}, {-1, 0, -1},
                                           {0, 1, 1}, {0, -1, 1}, {0, 1, -1}, {0, -1, -1}};

double corner(std::int64_t i, std::int64_t j, std::int64_t k, std::uint64_t seed, const Vec3& f) {
  std::uint64_t h = seed ^ (std::uint64_t(i) * 0x9e3779b97f4a7c15ull) ^
                    (std::uint64_t(j) * 0xc2b2ae3d27d4eb4full) ^
                    (std::uint64_t(k) * 0x165667b19e3779f9ull);
  const signed char* g = kGradients[splitmix64(h) % 12];
  return g[0] * f.x + g[1] * f.y + g[2] * f.z;
}

double fade(double t) {
  return t * t * t * (t * (6 * t - 15) + 10);
}

double gradient_noise(const Vec3& p, std::uint64_t seed) {
  const Vec3 floor{std::floor(p.x), std::floor(p.y), std::floor(p.z)}, f = p - floor;
  const auto i = std::int64_t(floor.x), j = std::int64_t(floor.y), k = std::int64_t(floor.z);
  const Vec3 u{fade(f.x), fade(f.y), fade(f.z)};
  double along_x[2][2];
  for (int dj = 0; dj < 2; ++dj)
    for (int dk = 0; dk < 2; ++dk) {
      const double c0 = corner(i, j + dj, k + dk, seed, f - Vec3{0, double(dj), double(dk)});
      const double c1 = corner(i + 1, j + dj, k + dk, seed, f - Vec3{1, double(dj), double(dk)});
      along_x[dj][dk] = c0 + u.x * (c1 - c0);
    }
  const double y0 = along_x[0][0] + u.y * (along_x[1][0] - along_x[0][0]);
  const double y1 = along_x[0][1] + u.y * (along_x[1][1] - along_x[0][1]);
  return y0 + u.z * (y1 - y0);
}

// fBm stretched and clamped to [-1, 1]; each octave on its own lattice (seed) and offset, so
// that no point is a zero of every octave.
double fbm(const Vec3& p, std::uint64_t seed) {
  double sum = 0, amplitude = 1, total = 0, frequency = kFrequency;
  for (int o = 0; o < kOctaves; ++o) {
    sum += amplitude * gradient_noise(frequency * p + Vec3{0.37 * o, 0.61 * o, 0.83 * o},
                                      seed + std::uint64_t(o));
    total += amplitude;
    amplitude *= kGain;
    frequency *= kLacunarity;
  }
  return std::clamp(kNoiseGain * sum / total, -1.0, 1.0);
}

// The density at p: the blobs' falloffs summed (capped at 1) times the base's fade. The noise is
// only evaluated where it matters: in some blob's falloff zone and no blob's core.
double cloud_density(const Shape& shape, const Vec3& p) {
  const double base = smoothstep(shape.base, shape.base + kBaseFade, p.y);
  if (base == 0) return 0;
  std::array<double, kMaxBlobs> q{};
  bool near = false;
  for (std::size_t b = 0; b < shape.blobs.size(); ++b) {
    const Vec3 d = p - shape.blobs[b].centre, r = shape.blobs[b].radii;
    q[b] = length(Vec3{d.x / r.x, d.y / r.y, d.z / r.z});
    if (q[b] <= kCore) return base;
    near = near || q[b] < 1 + kSwell;
  }
  if (!near) return 0;
  const double n = fbm(p, shape.noise_seed);
  double sum = 0;
  for (std::size_t b = 0; b < shape.blobs.size(); ++b)
    sum += 1 - smoothstep(kCore, 1, q[b] + kSwell * smoothstep(kCore, kCore + kRamp, q[b]) * n);
  return std::min(1.0, sum) * base;
}

// The voxels [first, last) of the row at (x, y) along z that some blob's support (its
// ellipsoid swollen by kSwell) crosses: outside, the density is 0 without a look (most of the
// cube).
std::pair<std::size_t, std::size_t> row_span(const Shape& shape, double x, double y,
                                             std::size_t n) {
  double lower = INFINITY, upper = -INFINITY;
  for (const Blob& b : shape.blobs) {
    const Vec3 r = (1 + kSwell) * b.radii;
    const double dx = (x - b.centre.x) / r.x, dy = (y - b.centre.y) / r.y,
                 t = 1 - dx * dx - dy * dy;
    if (t <= 0) continue;
    lower = std::min(lower, b.centre.z - r.z * std::sqrt(t));
    upper = std::max(upper, b.centre.z + r.z * std::sqrt(t));
  }
  if (!(lower < upper) || y <= shape.base) return {0, 0};
  // Voxel k's centre is -0.5 + (k + 1/2) / n; a voxel more each side covers the rounding.
  const double first = std::floor((lower + 0.5) * double(n) - 0.5) - 1,
               last = std::ceil((upper + 0.5) * double(n) - 0.5) + 2;
  return {std::size_t(std::clamp(first, 0.0, double(n))),
          std::size_t(std::clamp(last, 0.0, double(n)))};
}

}  // namespace

Cumulus cumulus(int size, std::uint64_t seed, const RunContext& run) {
  if (size < kMinCloudSize || size > kMaxCloudSize)
    throw std::invalid_argument("a cloud of " + std::to_string(size) + "^3 voxels: the size is " +
                                std::to_string(kMinCloudSize) + " to " +
                                std::to_string(kMaxCloudSize));
  const Shape shape = cumulus_shape(seed);
  const std::size_t n = std::size_t(size);
  Cumulus cloud{size, {{-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}}, std::vector<float>(n * n * n, 0.0f)};
  const auto centre = [size](std::size_t i) { return -0.5 + (double(i) + 0.5) / size; };
  parallel_for(size, run, [&](std::int64_t item, int) {  // a slab of constant x per item
    const std::size_t i = std::size_t(item);
    for (std::size_t j = 0; j < n; ++j) {
      float* row = cloud.values.data() + (i * n + j) * n;
      const auto [first, last] = row_span(shape, centre(i), centre(j), n);
      for (std::size_t k = first; k < last; ++k)
        row[k] = float(cloud_density(shape, {centre(i), centre(j), centre(k)}));
    }
  });
  return cloud;
}

}  // namespace stf::media
