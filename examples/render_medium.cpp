// A renderer's medium integrator with stf: the radiance a camera sees through the centre of
// a sphere of homogeneous medium under a uniform sky of radiance 1, path traced twice:
//  - direct: every free flight and Henyey-Greenstein scattering tracked;
//  - strided: wherever a precomputed sphere fits around the path's point (stf::find_entry),
//    the path jumps to that sphere's exit (its stf::StrideForm, drawing from the renderer's own
//    generator) and its throughput takes the
//    sphere's escape probability; near the boundary, where none fits, it is tracked directly.
// Both estimate the same number (radiance is picked up only where paths leave the medium), so
// they agree within their noise if the pack's models are right.
//
//   render_medium PACK MEDIUM SIGMA_S SIGMA_A G RADIUS PATHS
#include <stf/lookup.h>
#include <stf/math.h>
#include <stf/pack.h>
#include <stf/stride.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

namespace {

struct Medium {
  double sigma_s, sigma_a, g, radius;
  double sigma_t() const { return sigma_s + sigma_a; }
  double albedo() const { return sigma_s / sigma_t(); }
};

using Uniform = std::uniform_real_distribution<double>;

// w turned by the Henyey-Greenstein phase function (the renderer's own).
stf::Vec3 scatter(const stf::Vec3& w, double g, double u0, double u1) {
  double c = 2 * u0 - 1;
  if (std::abs(g) > 1e-3) {
    const double s = (1 - g * g) / (1 + g - 2 * g * u0);
    c = (1 + g * g - s * s) / (2 * g);
  }
  c = std::fmax(-1.0, std::fmin(1.0, c));
  double sp, cp;
  stf::sincos_2pi(u1, sp, cp);
  const double s = std::sqrt(std::fmax(0.0, 1 - c * c));
  return stf::Frame::around(w).to_world({s * cp, s * sp, c});
}

// One camera path entering at the sphere's near pole heading +z; returns the radiance it
// carries out (sky 1), counting the strides taken. `pack` empty: direct tracking only.
double trace(const Medium& m, const std::vector<stf::PackEntry>& pack, const std::vector<stf::StrideForm>& forms,
             std::mt19937_64& rng, long& strides) {
  Uniform u(0.0, 1.0);
  stf::Vec3 x{0, 0, -m.radius}, w{0, 0, 1};
  double throughput = 1;
  for (;;) {
    double r = 0;
    const stf::PackEntry* e = pack.empty() ? nullptr : stf::find_entry(pack, m.albedo(), m.g, m.sigma_t(), m.radius - stf::length(x), r);
    if (e) {
      const stf::StrideForm& s = forms[std::size_t(e - pack.data())];
      const stf::Stride exit = s.jump(x, w, r, [&] { return u(rng); });
      x = exit.point, w = exit.direction;
      throughput *= s.escape_probability();
      ++strides;
    } else {
      const double t = -std::log(1 - u(rng)) / m.sigma_t();
      x = {x.x + t * w.x, x.y + t * w.y, x.z + t * w.z};
      if (stf::dot(x, x) > m.radius * m.radius) return throughput;  // out, into the sky
      throughput *= m.sigma_s / m.sigma_t();
      w = scatter(w, m.g, u(rng), u(rng));
    }
    if (throughput < 0.25) {  // Russian roulette keeps the estimate unbiased
      if (u(rng) * 0.25 >= throughput) return 0;
      throughput = 0.25;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 7) {
    std::fprintf(stderr, "usage: render_medium PACK SIGMA_S SIGMA_A G RADIUS PATHS\n");
    return 2;
  }
  std::vector<stf::PackEntry> pack;
  std::string error;
  if (!stf::read_pack_file(argv[1], pack, error)) {
    std::fprintf(stderr, "render_medium: %s\n", error.c_str());
    return 1;
  }
  const Medium m{std::atof(argv[2]), std::atof(argv[3]), std::atof(argv[4]), std::atof(argv[5])};
  const long paths = std::atol(argv[6]);
  double radius = 0;
  // The pack's spheres are found by the medium (albedo, g), never by a name.
  const bool known = m.sigma_t() > 0 && stf::find_entry(pack, m.albedo(), m.g, m.sigma_t(), m.radius, radius);
  if (!known || !(m.radius > 0 && paths > 1)) {
    std::fprintf(stderr, "render_medium: no sphere of %s in the pack, or a bad number\n",
                 stf::medium_name(m.albedo(), m.g).c_str());
    return 2;
  }
  std::vector<stf::StrideForm> forms;  // built once: each model's draw resolved for strides
  for (const stf::PackEntry& e : pack) forms.emplace_back(e.model);

  for (const bool strided : {false, true}) {
    std::mt19937_64 rng(strided ? 2 : 1);
    long strides = 0;
    double sum = 0, sum2 = 0;
    for (long p = 0; p < paths; ++p) {
      const double L = trace(m, strided ? pack : std::vector<stf::PackEntry>{}, forms, rng, strides);
      sum += L, sum2 += L * L;
    }
    const double mean = sum / double(paths);
    const double error_of_mean = std::sqrt((sum2 / double(paths) - mean * mean) / double(paths - 1));
    std::printf("%s radiance %.6f +- %.6f, %.2f strides per path\n", strided ? "strided" : "direct ", mean,
                error_of_mean, double(strides) / double(paths));
  }
  return 0;
}
