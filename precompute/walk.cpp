#include "stf/precompute/walk.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "stf/core/fastmath.h"
#include "stf/core/geometry.h"
#include "stf/hg.h"
#include "stf/core/rng.h"

namespace stf {

Tally::Tally(int bins, std::int64_t n_cells) : cells(n_cells), alpha_bins(bins) {
  for (auto& c : counts) c.assign(std::size_t(bins) * std::size_t(n_cells), 0);
  for (auto& m : multiple_sub) m.assign(std::size_t(bins) * kSubBins, 0);
}

void SparseCounts::add(std::uint64_t key, double count) {
  if (2 * (used_ + 1) > keys_.size()) grow();
  const std::size_t mask = keys_.size() - 1;
  std::size_t slot = std::size_t((key * 0x9E3779B97F4A7C15ull) >> 24) & mask;
  while (keys_[slot] != kEmpty && keys_[slot] != key) slot = (slot + 1) & mask;
  if (keys_[slot] == kEmpty) keys_[slot] = key, ++used_;
  counts_[slot] += count;
}

void SparseCounts::grow() {
  std::vector<std::uint64_t> keys = std::move(keys_);
  std::vector<double> counts = std::move(counts_);
  keys_.assign(std::max<std::size_t>(64, 2 * keys.size()), kEmpty);
  counts_.assign(keys_.size(), 0.0);
  used_ = 0;
  for (std::size_t i = 0; i < keys.size(); ++i)
    if (keys[i] != kEmpty) add(keys[i], counts[i]);
}

std::map<std::uint64_t, double> SparseCounts::sorted() const {
  std::map<std::uint64_t, double> out;
  for (std::size_t i = 0; i < keys_.size(); ++i)
    if (keys_[i] != kEmpty) out.emplace(keys_[i], counts_[i]);
  return out;
}

void SparseCounts::assign(const std::map<std::uint64_t, double>& counts) {
  keys_.clear(), counts_.clear(), used_ = 0;
  for (const auto& [key, count] : counts) add(key, count);
}

void ChunkTally::add_to(Tally& tally) const {
  // A fine grid's table is far larger than the caches and escapes land at random cells: fetch
  // a few increments ahead so they do not each wait for memory.
  constexpr std::size_t kAhead = 128;
  for (std::size_t i = 0; i < escapes.size(); ++i) {
    if (i + kAhead < escapes.size())
      __builtin_prefetch(&tally.counts[escapes[i + kAhead] & 1][escapes[i + kAhead] >> 1], 1);
    tally.counts[escapes[i] & 1][escapes[i] >> 1] += 1;
  }
  for (int h = 0; h < 2; ++h) tally.counts[h][axis] += double(uncollided[h]);
  for (int h = 0; h < 2; ++h) tally.uncollided[h] += uncollided[h];
  for (std::uint64_t i : once) tally.once.add(i);
  for (std::uint32_t i : multiple_sub) tally.multiple_sub[i & 1][i >> 1] += 1;
  tally.escaped += escaped;
  tally.absorbed += absorbed;
  tally.truncated += truncated;
  tally.collisions += collisions;
  tally.absorbed_collisions += absorbed_collisions;
}

void ChunkTally::clear() {
  escapes.clear();
  once.clear();
  multiple_sub.clear();
  uncollided[0] = uncollided[1] = 0;
  escaped = absorbed = truncated = collisions = absorbed_collisions = 0;
}

AlphaBins::AlphaBins(int bins) : cos_edges_(bins + 1) {
  for (int b = 0; b <= bins; ++b) cos_edges_[b] = std::cos(kPi * b / bins);
  cos_edges_.front() = 1;
  cos_edges_.back() = -1;
}

int AlphaBins::bin(double cos_alpha) const {
  int b;
  bins(&cos_alpha, &b, 1);
  return b;
}

void AlphaBins::bins(const double* cos_alpha, int* out, int count) const {
  // An estimate from a fast acos is off by at most one bin; the exact edge comparisons settle
  // it, so the result depends only on cos_alpha against cos(edges). No branches: the loop
  // vectorises.
  const int n = bins();
  const double* edge = cos_edges_.data();
  for (int i = 0; i < count; ++i) {
    double z = std::clamp(cos_alpha[i], -1.0, 1.0);
    double alpha = fast_atan2(std::sqrt(std::max(0.0, 1 - z * z)), z);
    int b = std::clamp(int(alpha * (n / kPi)), 0, n - 1);
    b -= int((b > 0) & (z >= edge[b]));
    b += int((b < n - 1) & (z < edge[b + 1]));
    out[i] = b;
  }
}

int AlphaBins::sub_bin(double cos_alpha, int b) const {
  int sub;
  sub_bins(&cos_alpha, &b, &sub, 1);
  return sub;
}

void AlphaBins::sub_bins(const double* cos_alpha, const int* bin, int* out, int count) const {
  const double* edge = cos_edges_.data();
  for (int i = 0; i < count; ++i) {  // one loop the compiler vectorises, divisions and all
    const double u = (edge[bin[i]] - cos_alpha[i]) / (edge[bin[i]] - edge[bin[i] + 1]);
    out[i] = std::clamp(int(u * kSubBins), 0, kSubBins - 1);
  }
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
  // Position and direction at the start of the last flight: where an escaping lane left from.
  float from_px[kLanes], from_py[kLanes], from_pz[kLanes];
  float from_wx[kLanes], from_wy[kLanes], from_wz[kLanes];
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
// scattering.
void step(Lanes& L, const StepConstants& k) {
#pragma GCC ivdep
  for (int i = 0; i < kLanes; ++i) {
    std::uint32_t r_flight = xoshiro128_next(L.s0[i], L.s1[i], L.s2[i], L.s3[i]);
    std::uint32_t r_absorb = xoshiro128_next(L.s0[i], L.s1[i], L.s2[i], L.s3[i]);
    std::uint32_t r_theta = xoshiro128_next(L.s0[i], L.s1[i], L.s2[i], L.s3[i]);
    std::uint32_t r_phi = xoshiro128_next(L.s0[i], L.s1[i], L.s2[i], L.s3[i]);

    float px = L.px[i], py = L.py[i], pz = L.pz[i];
    float wx = L.wx[i], wy = L.wy[i], wz = L.wz[i];
    float flight = -fast_log(uniform01_open0(r_flight)) * k.inv_tau;

    // |p + s w|^2 is convex in s and below 1 at s = 0, so the flight leaves the sphere exactly
    // when it ends outside: no distance to the boundary (a sqrt and a division) is needed
    // here. EscapeBatch finds the exit point from where the flight started.
    float qx = px + flight * wx, qy = py + flight * wy, qz = pz + flight * wz;
    bool escaped = qx * qx + qy * qy + qz * qz >= 1.0f;

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
    // Renormalise so that rounding does not accumulate over millions of collisions. |n|^2 is
    // 1 + O(1e-7), so the first-order inverse square root (3 - |n|^2) / 2 is exact to O(1e-14).
    float inv_norm = 0.5f * (3.0f - (nx * nx + ny * ny + nz * nz));

    // Every lane moves and turns; lanes with an event are relaunched afterwards. Unconditional
    // stores: conditional ones become masked stores, which are slow on some x86 cores.
    L.from_px[i] = px, L.from_py[i] = py, L.from_pz[i] = pz;
    L.from_wx[i] = wx, L.from_wy[i] = wy, L.from_wz[i] = wz;
    L.px[i] = qx, L.py[i] = qy, L.pz[i] = qz;
    L.wx[i] = nx * inv_norm, L.wy[i] = ny * inv_norm, L.wz[i] = nz * inv_norm;
    L.collisions[i] = n;
    std::int32_t ev = escaped ? kEscaped : truncated ? kTruncated : absorbed ? kAbsorbed : kNone;
    L.event[i] = ev * L.active[i];
  }
}

// Escapes are binned in batches: the exit geometry runs as one loop the compiler vectorises
// and the grid looks up all cells in one call.
class EscapeBatch {
 public:
  EscapeBatch(const WalkSetup& setup, ChunkTally& tally)
      : setup_(setup), alpha_(setup.alpha_bins), tally_(tally) {
    x_[0] = y_[0] = z_[0] = 0;  // an uncollided escape
    dx_[0] = dy_[0] = 0, dz_[0] = 1;
    half_[0] = mirror_[0] = collisions_[0] = 0;
    n_ = 1;
    geometry();
    setup_.grid->cells(dx_, dy_, dz_, cell_, 1);
    alpha_.bins(z_, bin_, 1);
    tally_.axis = std::uint64_t(bin_[0]) * std::uint64_t(setup_.grid->cell_count()) + std::uint64_t(cell_[0]);
    n_ = 0;
  }
  ~EscapeBatch() { flush(); }

  // Queues lane i, which escapes from its last collision point along its direction. An
  // uncollided escape (from the centre along +z, in thin media a third of all paths) only
  // counts: its cell is the axis's, which the constructor found by the same steps.
  void add(const Lanes& L, int i) {
    x_[n_] = L.from_px[i], y_[n_] = L.from_py[i], z_[n_] = L.from_pz[i];
    dx_[n_] = L.from_wx[i], dy_[n_] = L.from_wy[i], dz_[n_] = L.from_wz[i];
    half_[n_] = int(L.path[i] & 1);
    mirror_[n_] = int((L.path[i] >> 1) & 1);
    collisions_[n_] = int(std::min<std::uint32_t>(L.collisions[i], 2));
    tally_.uncollided[half_[n_]] += L.collisions[i] == 0;
    n_ += L.collisions[i] != 0;
    if (n_ == kSize) flush();
  }

  void flush() {
    geometry();
    setup_.grid->cells(dx_, dy_, dz_, cell_, n_);
    alpha_.bins(z_, bin_, n_);
    alpha_.sub_bins(z_, bin_, sub_, n_);
    book(std::size_t(setup_.grid->cell_count()));
    n_ = 0;
  }

 private:
  // Replaces each queued escape's start point and direction by its exit direction in the
  // table's frame (dx_, dy_, dz_) and its cos(alpha) (z_).
  void geometry() {
    for (int j = 0; j < n_; ++j) {
      Vec3 w = normalize({dx_[j], dy_[j], dz_[j]}), p{x_[j], y_[j], z_[j]};
      double t = exit_distance(p, w);
      Vec3 exit = normalize({p.x + t * w.x, p.y + t * w.y, p.z + t * w.z});
      Vec3 d = rotate_to_xz_plane(exit, w);
      // The exit distribution is symmetric under y' -> -y'. Once-scattered paths leave exactly
      // in the plane y' = 0, a cell boundary of many grids, where rounding would pick one side
      // for all of them; every other path (by its number) is mirrored, and exact zeros take
      // the side of their path's parity, so no tie decides anything.
      if (d.x != 0 || d.y != 0) {  // on the axis (uncollided paths) the mirror changes nothing
        if (d.y == 0) d.y = 1e-300;
        if (mirror_[j]) d.y = -d.y;
      }
      dx_[j] = d.x, dy_[j] = d.y, dz_[j] = d.z;
      z_[j] = exit.z;  // cos(alpha)
    }
  }

  // Appends the batch to the chunk's lists. Which list an escape joins besides `escapes`
  // depends on its collisions, at random in thin media: the lists grow by masks, not branches.
  void book(std::size_t cells) {
    const std::size_t at = tally_.escapes.size();
    tally_.escapes.resize(at + std::size_t(n_));
    std::uint64_t* index = tally_.escapes.data() + at;
    for (int j = 0; j < n_; ++j)
      index[j] = 2 * (std::uint64_t(bin_[j]) * cells + std::uint64_t(cell_[j])) + std::uint64_t(half_[j]);
    std::uint64_t once[kSize];
    std::uint32_t multiple[kSize];
    int n_once = 0, n_multiple = 0;
    for (int j = 0; j < n_; ++j) {
      once[n_once] = index[j];
      multiple[n_multiple] = std::uint32_t(2 * (bin_[j] * kSubBins + sub_[j]) + half_[j]);
      n_once += collisions_[j] == 1;
      n_multiple += collisions_[j] == 2;
    }
    tally_.once.insert(tally_.once.end(), once, once + n_once);
    tally_.multiple_sub.insert(tally_.multiple_sub.end(), multiple, multiple + n_multiple);
  }

  static constexpr int kSize = 128;
  const WalkSetup& setup_;
  const AlphaBins alpha_;
  ChunkTally& tally_;
  int n_ = 0;
  double x_[kSize], y_[kSize], z_[kSize], dx_[kSize], dy_[kSize], dz_[kSize];
  int half_[kSize], mirror_[kSize], collisions_[kSize], bin_[kSize], sub_[kSize];  // collisions: 0, 1 or 2 (two or more)
  std::int64_t cell_[kSize];
};

}  // namespace

bool walk_chunk(const WalkSetup& setup, const ChunkPaths& chunk, ChunkTally& tally, const WalkControl& control) {
  const std::int64_t count = chunk.count;
  const StepConstants k = make_constants(setup);
  EscapeBatch escapes(setup, tally);
  Lanes L;
  std::int64_t next = 0;
  int in_flight = 0;
  for (int i = 0; i < kLanes; ++i) {
    Xoshiro128State st = seed_stream(chunk.seed, chunk.index * kLanes + std::uint64_t(i));
    L.s0[i] = st.s[0];
    L.s1[i] = st.s[1];
    L.s2[i] = st.s[2];
    L.s3[i] = st.s[3];
    L.active[i] = 0;
    if (next < count) {
      launch(L, i, chunk.first_path + next++);
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
    // Lanes with an event, gathered without a branch per lane: in thin media half the lanes
    // finish every step, a pattern no branch predictor learns.
    int finished[kLanes], n_finished = 0;
    for (int i = 0; i < kLanes; ++i) {
      finished[n_finished] = i;
      n_finished += L.event[i] != kNone;
    }
    for (int j = 0; j < n_finished; ++j) {
      const int i = finished[j];
      switch (L.event[i]) {
        case kEscaped: escapes.add(L, i); ++tally.escaped; break;
        case kAbsorbed: ++tally.absorbed, tally.absorbed_collisions += L.collisions[i]; break;
        default: ++tally.truncated; break;
      }
      tally.collisions += L.collisions[i];
      ++finished_since_report;
      if (next < count) {
        launch(L, i, chunk.first_path + next++);
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
