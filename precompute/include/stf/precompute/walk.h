// The random walk of Algorithm 3.1 with the corrections of docs/design.md: analog absorption, stable HG
// sampling, truncation at a collision cap with its weight recorded.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <vector>

#include "stf/core/grid.h"

namespace stf {

// Collisions a path may reach when no --max-scatter is given. A path in the diffusive regime
// needs about (1 - g) tau^2 / 2 collisions (5e5 at tau = 1000, g = 0); the cap only stops
// runaways, and whatever it stops is booked as truncated weight.
inline constexpr std::int64_t kSafetyMaxScatter = 1'000'000'000;

// Everything a walk needs, in the unit sphere: distances are in units of the radius, so the
// extinction coefficient is tau.
struct WalkSetup {
  double tau = 1, albedo = 1, g = 0;
  // A path reaching collision number max_scatter + 1 stops there, before that collision's
  // absorption is decided, and is counted as truncated.
  std::int64_t max_scatter = kSafetyMaxScatter;
  int alpha_bins = 90;
  const DirectionGrid* grid = nullptr;
};

// Equal parts of an alpha bin's area, in which the walk also counts the escapes after two or
// more collisions: enough to fit how their density varies inside the bin (fit/alpha_tilt.h).
inline constexpr int kSubBins = 8;

// Linear alpha bins on [0, pi], looked up by cos(alpha) (no inverse trigonometry per escape).
class AlphaBins {
 public:
  explicit AlphaBins(int bins);
  int bins() const { return int(cos_edges_.size()) - 1; }
  // Bin of the exit point with z = cos(alpha): bin b holds cos(alpha) in
  // [cos(pi (b+1) / n), cos(pi b / n)), the first bin also z = 1.
  int bin(double cos_alpha) const;
  // bin() of `count` values at once.
  void bins(const double* cos_alpha, int* out, int count) const;
  // Which of the kSubBins equal-area parts of bin b holds cos(alpha), counted from the bin's
  // lower alpha edge.
  int sub_bin(double cos_alpha, int b) const;
  // sub_bin() of `count` values at once, in bins `bin`.
  void sub_bins(const double* cos_alpha, const int* bin, int* out, int count) const;

 private:
  std::vector<double> cos_edges_;  // decreasing, cos(pi b / n)
};

// Whole-number counts at sparse keys in one flat open-addressed table: an add is a probe or
// two, where a std::map chased a dozen pointers (at tau ~1 a third of all escapes scattered
// once, each an add). sorted() gives them ordered, as files store them.
class SparseCounts {
 public:
  void add(std::uint64_t key, double count = 1);
  std::map<std::uint64_t, double> sorted() const;
  void assign(const std::map<std::uint64_t, double>& counts);

 private:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t(0);
  void grow();
  std::vector<std::uint64_t> keys_;
  std::vector<double> counts_;
  std::size_t used_ = 0;
};

// Tallies of one or more chunks: escapes per (half, alpha bin, cell) and event counts. Counts
// are integers (held exactly in doubles, up to 2^53 per cell), so adding tallies in any order
// gives the same table: the result does not depend on the number of threads or processes.
struct Tally {
  std::int64_t cells = 0;
  int alpha_bins = 0;
  std::vector<double> counts[2];  // per half: [alpha_bins * cells]
  std::uint64_t uncollided[2] = {0, 0};  // per half: escapes without a collision (in counts too)
  // Escapes after exactly one collision (in counts too), by table index 2 (bin cells + cell) +
  // half. Their directions lie in the plane y' = 0, so few cells hold any: a sparse map keeps
  // a fine grid's table at one dense copy.
  SparseCounts once;
  // Escapes after two or more collisions per half, [alpha_bins * kSubBins] (in counts too).
  std::vector<double> multiple_sub[2];
  std::uint64_t escaped = 0, absorbed = 0, truncated = 0, collisions = 0;
  // The collisions of the absorbed paths, summed (their last one included): with `collisions`
  // it gives the covariance a fit needs to estimate the absorption from the collision count
  // (fit/fit_table.cpp, rest_probabilities). Unknown (false) when resumed from a checkpoint
  // written before stf tallied it.
  std::uint64_t absorbed_collisions = 0;
  bool absorbed_collisions_known = true;

  Tally(int alpha_bins, std::int64_t cells);
};

// What the walk of one chunk books: each escape as its table index 2 (bin cells + cell) + half,
// and the event counts. Threads add their chunks to one shared Tally (add_to), so a fine grid
// costs one table, not one per thread.
struct ChunkTally {
  std::vector<std::uint64_t> escapes;  // all but the uncollided ones
  std::uint64_t axis = 0;  // bin cells + cell of the uncollided escapes
  std::vector<std::uint64_t> once;  // the escapes after exactly one collision, again
  std::vector<std::uint32_t> multiple_sub;  // the others, as 2 (bin kSubBins + sub-bin) + half
  std::uint64_t uncollided[2] = {0, 0};
  std::uint64_t escaped = 0, absorbed = 0, truncated = 0, collisions = 0, absorbed_collisions = 0;

  // Adds the chunk to the shared tally (exact: whole numbers in any order).
  void add_to(Tally& tally) const;
  void clear();
};

// Paths per chunk for a run of `paths`: a function of `paths` alone, so that the chunks (and
// with them every random number) are the same for any thread count.
std::int64_t chunk_paths(std::int64_t paths);

struct WalkControl {
  const std::atomic<bool>* cancel = nullptr;      // stop early when set
  std::atomic<std::int64_t>* paths_done = nullptr;  // progress, updated every few paths
};

// The paths [first_path, first_path + count) of a run seeded `seed`, drawn from the random
// streams of its chunk `index`.
struct ChunkPaths {
  std::uint64_t seed = 0, index = 0;
  std::int64_t first_path = 0, count = 0;
};

// Walks a chunk's paths, adding to `tally`. Returns false if it was cancelled (the tally is
// then incomplete).
bool walk_chunk(const WalkSetup& setup, const ChunkPaths& chunk, ChunkTally& tally, const WalkControl& control = {});

}  // namespace stf
