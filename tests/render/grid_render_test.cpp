// Media that vary, rendered by brute force against things the renderer did not compute: a purely
// absorbing grid against the transmittance of the trilinear field integrated here along each
// camera ray; a grid of constant density (clipped by a sphere inside its constant core) against
// the homogeneous medium of that density; the same field as .npy and as .vdb.
#include <gtest/gtest.h>
#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "image_compare.h"
#include "stf/render/medium.h"
#include "stf/pack.h"
#include "scene_fixture.h"

namespace stf::test {
namespace {

constexpr int kN = 20;  // voxels along each axis of the test grids, over [-1, 1]^3

// A blob: dense in the middle, 0 on the outermost layer of voxels (so .npy's clip at its bounds
// and .vdb's ramp past its last voxel see the same zero field).
std::vector<float> blob() {
  std::vector<float> v(std::size_t(kN * kN * kN));
  for (int i = 0; i < kN; ++i)
    for (int j = 0; j < kN; ++j)
      for (int k = 0; k < kN; ++k) {
        const bool edge = i == 0 || j == 0 || k == 0 || i == kN - 1 || j == kN - 1 || k == kN - 1;
        const double x = (i + 0.5) / kN * 2 - 1, y = (j + 0.5) / kN * 2 - 1, z = (k + 0.5) / kN * 2 - 1;
        v[std::size_t((i * kN + j) * kN + k)] = edge ? 0.0f : float(std::exp(-2.5 * (x * x + y * y + z * z)) * (1 + 0.3 * x));
      }
  return v;
}

// A C-order float32 .npy of shape [n, n, n] (format 1.0).
void write_npy(const std::string& path, const std::vector<float>& v, int n = kN) {
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(n) + ", " +
                       std::to_string(n) + ", " + std::to_string(n) + "), }";
  while ((10 + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::ofstream f(path, std::ios::binary);
  const std::uint16_t length = std::uint16_t(header.size());
  f.write("\x93NUMPY\x01\x00", 8);
  f.write(reinterpret_cast<const char*>(&length), 2);
  f << header;
  f.write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * sizeof(float)));
}

// The same values as an OpenVDB float grid named "density": voxel (i, j, k) at the centre of the
// .npy's voxel, x = -1 + (i + 1/2) 2 / kN.
void write_vdb(const std::string& path, const std::vector<float>& v) {
  openvdb::initialize();
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setName("density");
  const double h = 2.0 / kN;
  openvdb::math::Transform::Ptr xf = openvdb::math::Transform::createLinearTransform(h);
  xf->postTranslate(openvdb::Vec3d(-1 + h / 2, -1 + h / 2, -1 + h / 2));
  grid->setTransform(xf);
  auto acc = grid->getAccessor();
  for (int i = 0; i < kN; ++i)
    for (int j = 0; j < kN; ++j)
      for (int k = 0; k < kN; ++k)
        if (float x = v[std::size_t((i * kN + j) * kN + k)]; x != 0) acc.setValue(openvdb::Coord(i, j, k), x);
  openvdb::io::File(path).write({grid});
}

// The trilinear field of `v` with .npy's conventions, written here from the definition: values
// at voxel centres, a layer of zeros around them, 0 outside [-1, 1]^3.
double trilinear(const std::vector<float>& v, const Vec3& p) {
  if (std::abs(p.x) > 1 || std::abs(p.y) > 1 || std::abs(p.z) > 1) return 0;
  const double u[3] = {(p.x + 1) * kN / 2 - 0.5, (p.y + 1) * kN / 2 - 0.5, (p.z + 1) * kN / 2 - 0.5};
  int c[3];
  double f[3];
  for (int a = 0; a < 3; ++a) c[a] = int(std::floor(u[a])), f[a] = u[a] - c[a];
  double sum = 0;
  for (int corner = 0; corner < 8; ++corner) {
    int idx[3];
    double w = 1;
    for (int a = 0; a < 3; ++a) {
      const int bit = (corner >> a) & 1;
      idx[a] = c[a] + bit, w *= bit ? f[a] : 1 - f[a];
    }
    const bool inside = idx[0] >= 0 && idx[0] < kN && idx[1] >= 0 && idx[1] < kN && idx[2] >= 0 && idx[2] < kN;
    if (inside) sum += w * v[std::size_t((idx[0] * kN + idx[1]) * kN + idx[2])];
  }
  return sum;
}

const std::string kGridCamera = "[camera]\nposition = [0.3, 0.4, 4]\nlook_at = [0, 0, 0]\nfov = 36\n";

class GridRender : public SceneFixture {};

// The box of the grid's support as the object; no scattering: each sample is 0 or the sky's 1,
// with mean the transmittance exp(-sigma_a * integral of the density) along the camera ray.
TEST_F(GridRender, AbsorbingGridGivesTheExactTransmittance) {
  const std::vector<float> v = blob();
  write_npy(path("blob.npy"), v);
  const double sigma_a = 3;
  const std::string scene = kGridCamera + R"([light]
sky = 1
sun_radiance = 0
[[media]]
name = "smoke"
sigma_s = 0
sigma_a = 3
g = 0
grid = "blob.npy"
bounds = [[-1, -1, -1], [1, 1, 1]]
[[objects]]
medium = "smoke"
)";
  const int size = 32, spp = 384;
  const render::Image image = draw(scene, spp, 11, true, size);
  const scene::RenderScene sc = scene::read_render_scene(path("scene.toml"));
  // Exact block means: 4 x 4 camera rays per pixel through the midpoints of its sub-squares, the
  // optical depth by the midpoint rule over 2000 steps of the chord through [-2, 2]^3.
  std::vector<double> exact(std::size_t(size * size));
  for (int py = 0; py < size; ++py)
    for (int px = 0; px < size; ++px) {
      double sum = 0;
      for (int s = 0; s < 16; ++s) {
        const render::Ray ray = render::camera_ray(sc.camera, px + (s % 4 + 0.5) / 4, py + (s / 4 + 0.5) / 4, size, size);
        const double t0 = length(ray.origin) - 2, dt = 4.0 / 2000;
        double depth = 0;
        for (int k = 0; k < 2000; ++k) depth += trilinear(v, ray.origin + (t0 + (k + 0.5) * dt) * ray.direction) * dt;
        sum += std::exp(-sigma_a * depth);
      }
      exact[std::size_t(py * size + px)] = sum / 16;
    }
  double worst = 0, sum_image = 0, sum_exact = 0, sum_var = 0;
  for (int by = 0; by < size; by += 4)
    for (int bx = 0; bx < size; bx += 4) {
      double diff = 0, var = 0;
      for (int y = by; y < by + 4; ++y)
        for (int x = bx; x < bx + 4; ++x) {
          const std::size_t i = std::size_t(y * size + x);
          diff += image.mean[i * 3] - exact[i], var += image.variance_of_mean[i * 3];
          sum_image += image.mean[i * 3], sum_exact += exact[i], sum_var += image.variance_of_mean[i * 3];
        }
      if (var > 0) worst = std::max(worst, std::abs(diff) / std::sqrt(var));
    }
  EXPECT_LT(worst, 4.5);
  EXPECT_NEAR(sum_image / sum_exact, 1, 0.005) << "z " << (sum_image - sum_exact) / std::sqrt(sum_var);
  EXPECT_GT(image.null_collisions, 0);  // delta tracking ran
}

// Density 1 on a grid whose constant core holds the sphere that clips it: the homogeneous image.
TEST_F(GridRender, ConstantGridIsItsHomogeneousMedium) {
  const std::vector<float> ones(std::size_t(kN * kN * kN), 1.0f);
  write_npy(path("ones.npy"), ones);
  const std::string medium = "name = \"milky\"\nsigma_s = [6, 4, 2]\nsigma_a = [0.1, 0.3, 0.6]\ng = 0.5\n";
  const std::string rest = "[[objects]]\nshape = \"sphere\"\nradius = 0.85\nmedium = \"milky\"\n";
  const std::string light = "[light]\nsky = 0.5\nsun_direction = [1, 1, 1]\nsun_radiance = 40\n";
  const render::Image grid = draw(kGridCamera + light + "[[media]]\n" + medium +
                                      "grid = \"ones.npy\"\nbounds = [[-1, -1, -1], [1, 1, 1]]\n" + rest, 96, 3);
  const render::Image homogeneous = draw(kGridCamera + light + "[[media]]\n" + medium + rest, 96, 4);
  const ImageComparison c = compare_images(homogeneous.mean, homogeneous.variance_of_mean, grid.mean,
                                           grid.variance_of_mean, 24, 24, 3, 4);
  EXPECT_LT(c.max_block_z, 4.5);
  for (int k = 0; k < 3; ++k) EXPECT_LT(std::abs(c.mean_z[std::size_t(k)]), 4) << k;
}

// The blob as .npy and as .vdb, scattering under a sun: the same image within the noise.
TEST_F(GridRender, VdbAndNpyOfOneFieldGiveOneImage) {
  const std::vector<float> v = blob();
  write_npy(path("blob.npy"), v);
  write_vdb(path("blob.vdb"), v);
  const std::string head = kGridCamera + "[light]\nsky = 0.5\nsun_radiance = 40\n[[media]]\nname = \"cloud\"\n"
                           "sigma_s = 8\nsigma_a = 0.4\ng = 0.7\n";
  const std::string object = "[[objects]]\nmedium = \"cloud\"\n";
  const render::Image npy = draw(head + "grid = \"blob.npy\"\nbounds = [[-1, -1, -1], [1, 1, 1]]\n" + object, 96, 5);
  const render::Image vdb = draw(head + "grid = \"blob.vdb\"\n" + object, 96, 6);
  const ImageComparison c = compare_images(npy.mean, npy.variance_of_mean, vdb.mean, vdb.variance_of_mean, 24, 24, 3, 4);
  EXPECT_LT(c.max_block_z, 4.5);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(c.mean_ratio[std::size_t(k)], 1, 0.005) << k;
}

}  // namespace
}  // namespace stf::test

namespace stf::test {
namespace {

// 128^3 voxels over [-1, 1]^3: density 1 where every coordinate is within 0.97 (whole bricks of
// the majorant hold only it within about 0.87), and a thin varying shell around it.
std::vector<float> cored(int n = 128) {
  std::vector<float> v(std::size_t(n * n * n));
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const double x = (i + 0.5) / n * 2 - 1, y = (j + 0.5) / n * 2 - 1, z = (k + 0.5) / n * 2 - 1;
        const bool core = std::max({std::abs(x), std::abs(y), std::abs(z)}) <= 0.97;
        v[std::size_t((i * n + j) * n + k)] = core ? 1.0f : float(0.55 + 0.3 * std::sin(7 * x + 3 * y) * std::cos(5 * z));
      }
  return v;
}

const media::Box kCube{{-1, -1, -1}, {1, 1, 1}};

// Uniform points in the ball: a stride ball's density stays within its tolerance there, and the
// density its stride is scaled by lies within the ball's range.
TEST(GridStrides, ABallNeverHoldsADensityOutsideItsTolerance) {
  auto grid = std::make_shared<const media::DensityGrid>(media::DensityGrid::from_values(cored(), 128, 128, 128, kCube));
  render::PixelRng rng(5, 0);
  for (double tolerance : {0.0, 0.1, 0.3}) {
    const render::ChannelMedium m(7.92, 0.08, 0.5, {grid, 1.3, {0.2, -0.1, 0.4}, tolerance, nullptr});
    int balls = 0;
    for (int trial = 0; trial < 3000; ++trial) {
      const Vec3 x = Vec3{0.2, -0.1, 0.4} + 1.3 * Vec3{2 * rng.uniform() - 1, 2 * rng.uniform() - 1, 2 * rng.uniform() - 1};
      const render::StrideBall ball = m.stride_ball(x, 2 * rng.uniform(), 1, 8);
      if (ball.radius <= 0) continue;
      ++balls;
      double least = HUGE_VAL, most = 0;
      for (int k = 0; k < 200; ++k) {
        Vec3 d;
        do d = Vec3{2 * rng.uniform() - 1, 2 * rng.uniform() - 1, 2 * rng.uniform() - 1};
        while (dot(d, d) > 1);
        const double density = grid->density((x + ball.radius * d - Vec3{0.2, -0.1, 0.4}) / 1.3);
        least = std::min(least, density), most = std::max(most, density);
      }
      ASSERT_LE(most, (1 + tolerance) * least * (1 + 1e-6)) << "tolerance " << tolerance << ", ball of " << ball.radius;
      const double density = ball.sigma_t / 8;
      ASSERT_GE(density * (1 + tolerance), most * (1 - 1e-6));
      ASSERT_LE(density, (1 + tolerance) * least * (1 + 1e-6));
    }
    EXPECT_GT(balls, 100) << tolerance;  // the core holds balls at any tolerance
  }
}

// The most a segment from x may transmit (what the shadow rays' roulette weighs a ray by) is at
// least what it does: its optical depth, the trilinear field summed along it by the midpoint rule,
// is never below the bound (x's brick's least density over the part the brick must hold). In the
// constant core the bound is that depth itself where the segment stays in x's brick.
TEST(GridNextEvent, NoSegmentTransmitsMoreThanItsBound) {
  auto grid = std::make_shared<const media::DensityGrid>(media::DensityGrid::from_values(cored(), 128, 128, 128, kCube));
  const Vec3 translate{0.2, -0.1, 0.4};
  const double scale = 1.3;
  const render::ChannelMedium m(792, 8, 0.5, {grid, scale, translate, -1, nullptr});  // sigma_t 800 a unit density
  render::PixelRng rng(6, 0);
  int deep = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Vec3 x = translate + scale * Vec3{2 * rng.uniform() - 1, 2 * rng.uniform() - 1, 2 * rng.uniform() - 1};
    Vec3 d;
    do d = Vec3{2 * rng.uniform() - 1, 2 * rng.uniform() - 1, 2 * rng.uniform() - 1};
    while (dot(d, d) > 1 || dot(d, d) < 1e-4);
    d = normalize(d);
    const double length = 0.3 * rng.uniform(), bound = m.least_optical_depth(x, length);
    constexpr int kSteps = 2000;
    double depth = 0;
    for (int k = 0; k < kSteps; ++k)
      depth += 800 * grid->density((x + (k + 0.5) / kSteps * length * d - translate) / scale) * length / kSteps;
    ASSERT_GE(depth, bound * (1 - 1e-4)) << "trial " << trial << ", length " << length;
    deep += bound > 5;
  }
  EXPECT_GT(deep, 200);  // the bound is of use: deep in the core it turns shadow rays away
}

// In a grid of one density the ball is the free radius at that density: the homogeneous stride.
TEST(GridStrides, AStrideInAConstantGridIsTheHomogeneousStride) {
  // Over [-2, 2]^3 the grid is constant within about 0.94 of the centre (its outer bricks reach
  // the zero padding).
  auto grid = std::make_shared<const media::DensityGrid>(
      media::DensityGrid::from_values(std::vector<float>(32 * 32 * 32, 2.5f), 32, 32, 32, {{-2, -2, -2}, {2, 2, 2}}));
  const render::ChannelMedium homogeneous(2.5 * 7.92, 2.5 * 0.08, 0.5), in_grid(7.92, 0.08, 0.5, {grid, 1, {}, 0, nullptr});
  for (const Vec3& x : {Vec3{0, 0, 0}, Vec3{0.3, -0.2, 0.1}, Vec3{-0.25, 0.25, 0}})
    for (double free_radius : {0.05, 0.2, 0.4}) {
      const render::StrideBall a = homogeneous.stride_ball(x, free_radius, 1, 64), b = in_grid.stride_ball(x, free_radius, 1, 64);
      EXPECT_EQ(a.radius, b.radius) << free_radius;
      EXPECT_NEAR(a.sigma_t, b.sigma_t, 1e-12 * a.sigma_t);
    }
}

// At tolerance 0 strides go only through the constant core, exact up to the model: the strided
// image is the brute-force one in distribution, lit by a sun (next-event estimation at exits).
// The core is most of the ball and thin enough (tau 16) for its light to reach the image: strides
// at 1.3 times the core's density fail this test.
TEST_F(GridRender, StridesThroughAConstantCoreDrawTheBruteForceImage) {
  write_npy(path("cored.npy"), cored(), 128);
  std::vector<PackEntry> pack;
  std::string error;
  ASSERT_TRUE(read_pack_file(STF_RENDER_PACK, pack, error)) << error;
  const std::string scene = kGridCamera + R"([light]
sky = 0.4
sun_direction = [1, 1.5, 0.5]
sun_radiance = 40
[[media]]
name = "grey"
sigma_s = 15.84
sigma_a = 0.16
g = 0.5
grid = "cored.npy"
bounds = [[-1, -1, -1], [1, 1, 1]]
[[objects]]
medium = "grey"
)";
  render::PathOptions exact;
  exact.density_tolerance = 0;
  const render::Image brute = draw(scene, 192, 21), strided = draw_with(scene, &pack, exact, 192, 22);
  EXPECT_GT(strided.strides, strided.paths / 10);
  const ImageComparison c = compare_images(brute.mean, brute.variance_of_mean, strided.mean, strided.variance_of_mean, 24, 24, 3, 4);
  EXPECT_LT(c.max_block_z, 4.5);
  for (int k = 0; k < 3; ++k) EXPECT_LT(std::abs(c.mean_z[std::size_t(k)]), 4) << k;
}

}  // namespace
}  // namespace stf::test
