#include "walk.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "fastmath.h"
#include "geometry.h"
#include "hg.h"
#include "rng.h"

namespace stf {

Tally::Tally(int bins, std::int64_t n_cells) : cells(n_cells), alpha_bins(bins) {
  for (auto& c : counts) c.assign(std::size_t(bins) * std::size_t(n_cells), 0);
}

void Tally::add(const Tally& other) {
  for (int h = 0; h < 2; ++h)
    for (std::size_t i = 0; i < counts[h].size(); ++i) counts[h][i] += other.counts[h][i];
  escaped += other.escaped;
  absorbed += other.absorbed;
  truncated += other.truncated;
  collisions += other.collisions;
}

AlphaBins::AlphaBins(int bins) : cos_edges_(bins + 1) {
  for (int b = 0; b <= bins; ++b) cos_edges_[b] = std::cos(kPi * b / bins);
  cos_edges_.front() = 1;
  cos_edges_.back() = -1;
}

int AlphaBins::bin(double cos_alpha) const {
  // First edge with cos(edge) < cos_alpha, i.e. alpha < edge.
  auto it = std::upper_bound(cos_edges_.begin() + 1, cos_edges_.end() - 1, cos_alpha,
                             [](double z, double edge) { return z >= edge; });
  return int(it - cos_edges_.begin()) - 1;
}

std::int64_t chunk_paths(std::int64_t paths) {
  return std::clamp<std::int64_t>((paths + 63) / 64, 1024, 65536);
}

namespace {

// Paths in flight per thread, in structure-of-arrays form. Each step below is one loop over
// all lanes without branches, which the compiler turns into SIMD code; the rare events
// (escape, absorption, truncation) are handled afterwards, one lane at a time.
constexpr int kLanes = 64;

enum Event : std::int32_t { kNone = 0, kEscaped = 1, kAbsorbed = 2, kTruncated = 3 };

struct alignas(64) Lanes {
  float px[kLanes], py[kLanes], pz[kLanes];  // position in the unit sphere
  float wx[kLanes], wy[kLanes], wz[kLanes];  // direction of flight
  std::uint32_t collisions[kLanes];
  std::uint32_t s0[kLanes], s1[kLanes], s2[kLanes], s3[kLanes];  // xoshiro128+ per lane
  std::int32_t active[kLanes];
  std::int32_t event[kLanes];
  std::int64_t path[kLanes];
};

// Constants of the medium, narrowed once.
struct StepConstants {
  float inv_tau;
  std::uint32_t absorb_below;  // absorbed when the 32-bit draw is below this
  bool absorb_all;  // albedo 0: 2^32 does not fit the threshold
  std::uint32_t max_scatter;
  HgParams<float> hg;
};

StepConstants make_constants(const WalkSetup& s) {
  StepConstants k;
  // Clamp 1/tau so that tiny tau gives huge but finite flights (no inf * 0).
  k.inv_tau = float(std::min(1.0 / s.tau, 1e30));
  // Absorption decided on 32 bits (not a 24-bit float) keeps albedo = 1 - 1e-6 or 1e-6
  // accurate to 2^-32.
  double threshold = std::round((1 - s.albedo) * 4294967296.0);
  k.absorb_all = s.albedo <= 0;
  k.absorb_below = std::uint32_t(std::clamp(threshold, 0.0, 4294967295.0));
  k.max_scatter = std::uint32_t(std::min<std::int64_t>(s.max_scatter, kSafetyMaxScatter));
  k.hg = HgParams<float>::make(s.g);
  return k;
}

void launch(Lanes& L, int i, std::int64_t path) {
  L.px[i] = L.py[i] = L.pz[i] = 0;
  L.wx[i] = L.wy[i] = 0;
  L.wz[i] = 1;  // start at the centre heading +z
  L.collisions[i] = 0;
  L.path[i] = path;
  L.active[i] = 1;
}

// One free flight for every lane, then the collision it ends in: truncation, absorption or
// scattering. Directions of escaping lanes are kept for the record.
__attribute__((noinline)) void step(Lanes& L, const StepConstants& k) {
#pragma GCC ivdep
  for (int i = 0; i < kLanes; ++i) {
    std::uint32_t r_flight = xoshiro128_next(L.s0[i], L.s1[i], L.s2[i], L.s3[i]);
    std::uint32_t r_absorb = xoshiro128_next(L.s0[i], L.s1[i], L.s2[i], L.s3[i]);
    std::uint32_t r_theta = xoshiro128_next(L.s0[i], L.s1[i], L.s2[i], L.s3[i]);
    std::uint32_t r_phi = xoshiro128_next(L.s0[i], L.s1[i], L.s2[i], L.s3[i]);

    float px = L.px[i], py = L.py[i], pz = L.pz[i];
    float wx = L.wx[i], wy = L.wy[i], wz = L.wz[i];
    float flight = -fast_log(uniform01_open0(r_flight)) * k.inv_tau;

    // Distance to the sphere along w; the two forms avoid cancellation for b > 0 and b < 0.
    float b = px * wx + py * wy + pz * wz;
    float c = px * px + py * py + pz * pz - 1.0f;
    float root = std::sqrt(std::max(b * b - c, 0.0f));
    float exit_ahead = -c / (b + root), exit_behind = root - b;
    float to_exit = b > 0 ? exit_ahead : exit_behind;
    bool escaped = flight >= to_exit;
    float travel = escaped ? to_exit : flight;
    px += travel * wx;
    py += travel * wy;
    pz += travel * wz;

    // Masks combine with & and | (not && and ||) so that the loop has no branches.
    std::uint32_t n = L.collisions[i] + std::uint32_t(!escaped);
    bool truncated = !escaped & (n > k.max_scatter);
    bool absorbed = !escaped & !truncated & ((r_absorb < k.absorb_below) | k.absorb_all);

    // Scatter: HG polar angle about w, uniform azimuth, in the branch-free orthonormal basis of
    // Duff et al. (2017) around w.
    CosSin<float> hg = sample_hg(k.hg, uniform01(r_theta));
    SinCos azimuth = sincos_2pi(uniform01(r_phi));
    float sign = std::copysign(1.0f, wz);
    float a = -1.0f / (sign + wz);
    float bb = wx * wy * a;
    float e1x = 1.0f + sign * wx * wx * a, e1y = sign * bb, e1z = -sign * wx;
    float e2x = bb, e2y = sign + wy * wy * a, e2z = -wy;
    float u = hg.sin_theta * azimuth.cos, v = hg.sin_theta * azimuth.sin;
    float nx = u * e1x + v * e2x + hg.cos_theta * wx;
    float ny = u * e1y + v * e2y + hg.cos_theta * wy;
    float nz = u * e1z + v * e2z + hg.cos_theta * wz;
    // Renormalise so that rounding does not accumulate over millions of collisions.
    float inv_norm = 1.0f / std::sqrt(nx * nx + ny * ny + nz * nz);

    L.px[i] = px;
    L.py[i] = py;
    L.pz[i] = pz;
    L.wx[i] = escaped ? wx : nx * inv_norm;
    L.wy[i] = escaped ? wy : ny * inv_norm;
    L.wz[i] = escaped ? wz : nz * inv_norm;
    L.collisions[i] = n;
    std::int32_t ev = escaped ? kEscaped : truncated ? kTruncated : absorbed ? kAbsorbed : kNone;
    L.event[i] = ev * L.active[i];
  }
}

// Table increments wait in a short queue and are applied together after prefetching: the
// table is megabytes and escapes land at random cells, so one at a time each increment would
// wait for memory on its own.
class PendingCounts {
 public:
  explicit PendingCounts(Tally& tally) : tally_(tally) {}
  ~PendingCounts() { flush(); }
  void add(int half, std::size_t index) {
    pending_[size_++] = {half, index};
    if (size_ == kSize) flush();
  }
  void flush() {
    for (int j = 0; j < size_; ++j) __builtin_prefetch(&tally_.counts[pending_[j].half][pending_[j].index], 1);
    for (int j = 0; j < size_; ++j) ++tally_.counts[pending_[j].half][pending_[j].index];
    size_ = 0;
  }

 private:
  static constexpr int kSize = 64;
  struct Entry {
    int half;
    std::size_t index;
  };
  Tally& tally_;
  Entry pending_[kSize];
  int size_ = 0;
};

// Bins one escape: alpha bin from the exit point, cell from the exit direction after the
// -beta rotation.
void record_escape(const Lanes& L, int i, const WalkSetup& setup, const AlphaBins& alpha,
                   PendingCounts& counts) {
  Vec3 point = normalize({L.px[i], L.py[i], L.pz[i]});
  Vec3 direction = normalize({L.wx[i], L.wy[i], L.wz[i]});
  double rho = std::sqrt(point.x * point.x + point.y * point.y);
  int bin = alpha.bin(point.z);
  std::int64_t cell = setup.grid->cell(rotate_to_xz_plane(point, direction, rho));
  counts.add(int(L.path[i] & 1), std::size_t(bin) * std::size_t(setup.grid->cell_count()) + std::size_t(cell));
}

}  // namespace

bool walk_chunk(const WalkSetup& setup, std::uint64_t seed, std::uint64_t chunk,
                std::int64_t first_path, std::int64_t count, Tally& tally,
                const WalkControl& control) {
  const StepConstants k = make_constants(setup);
  const AlphaBins alpha(setup.alpha_bins);
  PendingCounts pending(tally);
  Lanes L;
  std::int64_t next = 0;
  int in_flight = 0;
  for (int i = 0; i < kLanes; ++i) {
    Xoshiro128State st = seed_stream(seed, chunk * kLanes + std::uint64_t(i));
    L.s0[i] = st.s[0];
    L.s1[i] = st.s[1];
    L.s2[i] = st.s[2];
    L.s3[i] = st.s[3];
    L.active[i] = 0;
    if (next < count) {
      launch(L, i, first_path + next++);
      ++in_flight;
    } else {
      launch(L, i, 0);
      L.active[i] = 0;
    }
  }
  std::int64_t finished_since_report = 0;
  for (std::uint64_t iteration = 0; in_flight > 0; ++iteration) {
    if ((iteration & 63) == 0 && control.cancel && control.cancel->load(std::memory_order_relaxed))
      return false;
    step(L, k);
    for (int i = 0; i < kLanes; ++i) {
      if (L.event[i] == kNone) continue;
      switch (L.event[i]) {
        case kEscaped: record_escape(L, i, setup, alpha, pending); ++tally.escaped; break;
        case kAbsorbed: ++tally.absorbed; break;
        default: ++tally.truncated; break;
      }
      tally.collisions += L.collisions[i];
      ++finished_since_report;
      if (next < count) {
        launch(L, i, first_path + next++);
      } else {
        L.active[i] = 0;
        --in_flight;
      }
    }
    if (control.paths_done && finished_since_report >= 4096) {
      control.paths_done->fetch_add(finished_since_report, std::memory_order_relaxed);
      finished_since_report = 0;
    }
  }
  if (control.paths_done) control.paths_done->fetch_add(finished_since_report, std::memory_order_relaxed);
  return true;
}

}  // namespace stf
