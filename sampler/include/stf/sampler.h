// Importance sampling of a fitted shell transport function, with exact pdfs.
//
// Measures (docs/design.md): a sample is an exit point y on the unit sphere and an exit direction
// w', in the local frame where the start direction is +z. pdf() is per unit area of the unit
// sphere per steradian and integrates to 1 over the (4 pi)^2 domain; for the smooth part
//   p(y, w') = P(bin of alpha) / (2 pi (cos a0 - cos a1)) * t(u) * p(R_z(-beta) w' | bin),
// alpha = angle(y, +z) in [a0, a1), beta = azimuth of y, u = (cos a0 - cos alpha) / (cos a0 -
// cos a1) and t the bin's tilted density (stf/tilt.h; 1 in models without tilts): beta is
// uniform, and the direction density is the fitted one in the frame where y lies in the x-z
// plane (in blended models mixed with neighbours', StfModel::alpha_blend; in turning models each
// turned about y to the exit angle, StfModel::alpha_turn). The singular parts carry their discrete probabilities (ExitSample::component). All
// methods are const, thread-safe, allocation-free.
#pragma once

#include <cstdint>
#include <vector>

#include "stf/alias.h"
#include "stf/hemisphere.h"
#include "stf/model.h"
#include "stf/draw_tables.h"
#include "stf/stride.h"
#include "stf/vec3.h"

namespace stf {

struct ExitSample {
  Vec3 point;      // on the unit sphere (local frame)
  Vec3 direction;  // unit exit direction (local frame)
  // kSmooth: density per unit area of the unit sphere per steradian (of the smooth part, times
  // its probability). kUncollided: the delta's discrete probability (point and direction +z).
  // kOnceScattered: that part's probability (it has no density on the (4 pi)^2 domain).
  double pdf = 0;
  int component = kSmooth;
};

struct WorldExit {
  Vec3 point;      // world exit point, at distance `radius` from the start
  Vec3 direction;  // world exit direction
  double pdf = 0;  // per unit area of the sphere of that radius per steradian (or, for the
                   // singular parts, their probabilities)
  int component = kSmooth;
};

class ShellSampler {
 public:
  // The model must be valid (as read_pack or fit/ produce it).
  // `tables`, when given, must be the draw tables of this model (make_draw_tables), shared with
  // its stride form; else they are built here.
  explicit ShellSampler(StfModel model, std::shared_ptr<const DrawTables> tables = nullptr);
  const std::shared_ptr<const DrawTables>& tables() const { return tables_; }

  // (u0, u1, u2, u3) in [0, 1)^4: u0 picks the part (once scattered or the rest) and then the
  // alpha bin (its remainder decides the uncollided delta in bin 0 and places alpha in the bin),
  // u1 the azimuth beta, u2 the lobe or SH cell (remainder reused), u3 the rest. The
  // once-scattered part uses them as OnceScattered::sample does.
  ExitSample sample(double u0, double u1, double u2, double u3) const;
  // The density of the smooth part (times its probability) that sample() draws from; 0 where
  // the model has no support. The singular parts have no density.
  double pdf(const Vec3& point, const Vec3& direction) const;
  // The smooth part's density of exit directions at the exit point `point` (unit sphere, local
  // frame): pdf(point, w) over the point's own density, per steradian, integrating to 1 over w.
  // What a stride's exit scatters by, for next-event estimation there (its "phase function").
  double exit_direction_pdf(const Vec3& point, const Vec3& direction) const;
  // The same for a world-space stride from `position` heading `direction` through the sphere of
  // `radius`, that left at `exit_point`.
  double exit_direction_pdf_world(const Vec3& position, const Vec3& direction, double radius, const Vec3& exit_point,
                                  const Vec3& exit_direction) const;
  // Probability that a path starting at the centre leaves the sphere at all.
  double escape_probability() const { return model_.escape_probability; }

  // World space: a path at `position` heading `direction` (unit) with free radius `radius`.
  WorldExit sample_world(const Vec3& position, const Vec3& direction, double radius, double u0, double u1,
                         double u2, double u3) const;
  double pdf_world(const Vec3& position, const Vec3& direction, double radius, const Vec3& exit_point,
                   const Vec3& exit_direction) const;
  // A draw of the same distribution as sample_world, without the pdf (WorldExit::pdf is 0), for
  // a renderer that only jumps: the model's stride form (stf/stride.h) draws it, which is 1.2-1.4
  // times faster than sample_world (bench/stride_cost). Its uniforms are u0 .. u3 and then a
  // stream seeded from them (as many as the draw takes), so the exit is not sample_world's.
  WorldExit jump(const Vec3& position, const Vec3& direction, double radius, double u0, double u1, double u2,
                 double u3) const;
  // The same with the uniforms from the renderer's own generator, `uniform()`, as many as it needs.
  template <typename Uniform>
  WorldExit jump(const Vec3& position, const Vec3& direction, double radius, Uniform&& uniform) const {
    const Stride s = form_.jump(position, direction, radius, uniform);
    return {s.point, s.direction, 0.0, s.component};
  }
  const StrideForm& stride_form() const { return form_; }

  // The parts, each a sample/pdf pair (for tests and for renderers that want them alone).
  int sample_alpha_bin(double u, double& remainder) const;
  double alpha_bin_probability(int bin) const { return model_.alpha_probability[bin]; }
  // Lifted lobes about the bin's middle normal; the overloads at an exit point's `normal`.
  Vec3 sample_direction(int bin, double u2, double u3) const;
  double direction_pdf(int bin, const Vec3& w) const;
  Vec3 sample_direction(int bin, double u2, double u3, const Vec3& normal) const;
  double direction_pdf(int bin, const Vec3& w, const Vec3& normal) const;

  const StfModel& model() const { return model_; }

 private:
  // Per lobe, what sampling and the pdf need, computed once (as Open PGL caches them).
  struct Lobe : VmfFrame {
    double weight = 0;
    double norm = 0;  // kappa / (2 pi (1 - e^{-2 kappa})): the density at the mean
  };
  double lobe_pdf(const Lobe& l, const Vec3& w) const;
  int alpha_bin_of(double cos_alpha) const;
  // The normal lifted lobes are mapped about at exit angle alpha in a bin turned by `turn` there:
  // the exit normal turned back with the direction ((0, 0, 1), unused, for other lobes).
  Vec3 lift_normal(double alpha, double turn) const;
  // The smooth part's density at an exit point of `bin` with cos(alpha) and the direction
  // `local` (in the exit point's x-z frame): the bin's probability spread by its tilt, times
  // the direction density (blended with the neighbour's in blended bins).
  double smooth_pdf(int bin, double cos_alpha, const Vec3& local) const;
  // Its direction density alone, at area fraction u of the bin.
  double exit_direction_pdf(int bin, double cos_alpha, double u, const Vec3& local) const;
  // The bin of an exit point, and the direction in the point's x-z frame.
  int exit_frame(const Vec3& point, const Vec3& direction, Vec3& local) const;
  // sample() less the pdf; `bin` is where the smooth part was drawn (-1: the delta).
  ExitSample draw(double u0, double u1, double u2, double u3, int& bin, Vec3& local) const;
  WorldExit to_world(const Vec3& position, const Vec3& direction, double radius, const ExitSample& s) const;

  StfModel model_;
  AliasTable alpha_;               // over the alpha bins
  std::vector<double> cos_edges_;  // [bins + 1], decreasing
  std::vector<double> tilt_expm1_;  // [bins], expm1 of each bin's tilt
  std::vector<Lobe> lobes_;        // vmf: [bins * lobes]
  std::shared_ptr<const DrawTables> tables_;  // shared with the model's stride form
  StrideForm form_;
};

// The uniforms of `stf sample --seed K`: SplitMix64 from K, four 53-bit uniforms per draw.
// Draw i starts at the state K + 4 i gamma, so the stream can be cut into pieces (threads)
// that give the same draws, bit for bit.
class SampleStream {
 public:
  SampleStream(std::uint64_t seed, std::uint64_t first_draw) : state_(seed + 4 * first_draw * kGamma) {}
  // The next draw of `sampler`.
  ExitSample next(const ShellSampler& sampler) {
    const double u0 = uniform(), u1 = uniform(), u2 = uniform(), u3 = uniform();
    return sampler.sample(u0, u1, u2, u3);
  }
  double uniform() {
    std::uint64_t z = (state_ += kGamma);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return double((z ^ (z >> 31)) >> 11) * 0x1p-53;
  }

 private:
  static constexpr std::uint64_t kGamma = 0x9e3779b97f4a7c15ull;
  std::uint64_t state_;
};

}  // namespace stf
