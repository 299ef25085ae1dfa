#include "stf/precompute/parts.h"

#include <fmt/format.h>

#include <H5Cpp.h>

#include <algorithm>
#include <cstdio>
#include <numeric>
#include <stdexcept>

#include "stf/core/files.h"
#include "stf/core/h5io.h"

namespace stf {

namespace {

// The run-identifying fields of a table, in the fingerprint's words.
std::string table_run(const Table& t) {
  return "sigma_s " + fmt::format("{:.17g}", t.medium.sigma_s) + ", sigma_a " + fmt::format("{:.17g}", t.medium.sigma_a) + ", g " + fmt::format("{:.17g}", t.medium.g) +
         ", radius " + fmt::format("{:.17g}", t.medium.radius) + ", grid " + t.grid + ", alpha bins " + std::to_string(t.alpha_bins) +
         ", paths " + std::to_string(t.run_paths) + ", seed " + std::to_string(t.seed) + ", max_scatter " +
         std::to_string(t.max_scatter) + ", " + t.generator;
}

// What differs between two descriptions of runs ("seed 7, not seed 1"), item by item.
std::string difference(const std::string& a, const std::string& b) {
  auto items = [](const std::string& text) {
    std::vector<std::string> out;
    std::size_t start = 0;
    for (std::size_t comma; (comma = text.find(", ", start)) != std::string::npos; start = comma + 2)
      out.push_back(text.substr(start, comma - start));
    out.push_back(text.substr(start));
    return out;
  };
  std::vector<std::string> x = items(a), y = items(b);
  std::string what;
  for (std::size_t i = 0; i < std::max(x.size(), y.size()); ++i) {
    std::string u = i < x.size() ? x[i] : "", v = i < y.size() ? y[i] : "";
    if (u != v) what += (what.empty() ? "" : "; ") + u + ", not " + v;
  }
  return what;
}

}  // namespace

std::string run_fingerprint(const Medium& m, const PrecomputeSettings& s) {
  return "sigma_s " + fmt::format("{:.17g}", m.sigma_s) + ", sigma_a " + fmt::format("{:.17g}", m.sigma_a) + ", g " + fmt::format("{:.17g}", m.g) + ", radius " +
         fmt::format("{:.17g}", m.radius) + ", grid " + s.grid + ", alpha bins " + std::to_string(s.alpha_bins) + ", paths " +
         std::to_string(s.paths) + ", seed " + std::to_string(s.seed) + ", max_scatter " +
         std::to_string(s.max_scatter) + ", stf " STF_VERSION + ", part " + std::to_string(s.part) + " of " +
         std::to_string(s.parts);
}

void write_checkpoint(const std::string& path, const std::string& fingerprint, const Progress& p) {
  using namespace h5;
  std::string bytes;
  try {
    H5::Exception::dontPrint();
    {
      MemoryFile memory;
      H5::H5File& file = memory.file();
      put_attr(file, "format", std::string("stf-checkpoint"));
      put_attr(file, "run", fingerprint);
      put_attr(file, "escaped", std::int64_t(p.tally.escaped));
      put_attr(file, "absorbed", std::int64_t(p.tally.absorbed));
      put_attr(file, "truncated", std::int64_t(p.tally.truncated));
      put_attr(file, "collisions", std::int64_t(p.tally.collisions));
      if (p.tally.absorbed_collisions_known)
        put_attr(file, "absorbed_collisions", std::int64_t(p.tally.absorbed_collisions));
      put_attr(file, "uncollided_even", std::int64_t(p.tally.uncollided[0]));
      put_attr(file, "uncollided_odd", std::int64_t(p.tally.uncollided[1]));
      H5::Group root = file.openGroup("/");
      std::vector<std::int32_t> done(p.done.begin(), p.done.end());
      put_dataset(root, "done", {hsize_t(done.size())}, done.data());
      const hsize_t bins = hsize_t(p.tally.alpha_bins), cells = hsize_t(p.tally.cells);
      put_rows(root, "counts", {2, bins, cells}, [&](hsize_t r) { return &p.tally.counts[r / bins][(r % bins) * cells]; });
      put_sparse_halves(root, "once", p.tally.alpha_bins, p.tally.cells, p.tally.once.sorted());
      put_rows(root, "multiple_sub", {2, bins, hsize_t(kSubBins)}, [&](hsize_t r) { return &p.tally.multiple_sub[r / bins][(r % bins) * kSubBins]; });
      root.close();
      bytes = memory.bytes();
    }
  } catch (const H5::Exception& e) {
    throw std::runtime_error("cannot write checkpoint " + path + ": " + e.getDetailMsg());
  }
  replace_file(path, bytes);
}

Progress read_checkpoint(const std::string& path, const std::string& fingerprint, const ChunkRange& range,
                         int alpha_bins, std::int64_t cells) {
  using namespace h5;
  try {
    H5::Exception::dontPrint();
    ReadingInput reading;
    H5::H5File file = open_file(path);
    if (!has_attr(file, "format") || get_string(file, "format") != "stf-checkpoint")
      throw std::runtime_error(path + " is not an stf checkpoint");
    if (std::string run = get_string(file, "run"); run != fingerprint)
      throw std::runtime_error("checkpoint " + path + " is of another command (" + difference(run, fingerprint) + ")");
    Progress p;
    p.tally = Tally(alpha_bins, cells);
    p.tally.escaped = std::uint64_t(get_int64(file, "escaped", 0));
    p.tally.absorbed = std::uint64_t(get_int64(file, "absorbed", 0));
    p.tally.truncated = std::uint64_t(get_int64(file, "truncated", 0));
    p.tally.collisions = std::uint64_t(get_int64(file, "collisions", 0));
    p.tally.absorbed_collisions_known = has_attr(file, "absorbed_collisions");
    if (p.tally.absorbed_collisions_known) p.tally.absorbed_collisions = std::uint64_t(get_int64(file, "absorbed_collisions", 0));
    p.tally.uncollided[0] = std::uint64_t(get_int64(file, "uncollided_even", 0));
    p.tally.uncollided[1] = std::uint64_t(get_int64(file, "uncollided_odd", 0));
    for (std::int32_t d : get_int_dataset(file, "/done", {hsize_t(range.last - range.first)})) p.done.push_back(char(d != 0));
    const hsize_t bins = hsize_t(alpha_bins);
    get_rows(file, "/counts", {2, bins, hsize_t(cells)},
             [&](hsize_t r) { return &p.tally.counts[r / bins][(r % bins) * std::size_t(cells)]; });
    p.tally.once.assign(get_sparse_halves(file, "/once", alpha_bins, cells));
    get_rows(file, "/multiple_sub", {2, bins, hsize_t(kSubBins)},
             [&](hsize_t r) { return &p.tally.multiple_sub[r / bins][(r % bins) * kSubBins]; });
    return p;
  } catch (const H5::Exception& e) {
    throw std::runtime_error("cannot read checkpoint " + path + ": " + e.getDetailMsg());
  }
}

std::vector<std::size_t> check_parts(const std::vector<Table>& parts, const std::vector<std::string>& names) {
  if (parts.empty()) throw std::invalid_argument("no parts to merge");
  std::vector<std::size_t> order(parts.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return parts[a].chunk_first < parts[b].chunk_first; });
  const Table& first = parts[order.front()];
  const std::string run = table_run(first);
  std::int64_t next = 0;
  for (std::size_t k : order) {
    const Table& p = parts[k];
    if (p.chunk_count == 0) throw std::invalid_argument("'" + names[k] + "' records no chunk range (not a part of stf precompute)");
    if (table_run(p) != run || p.chunk_count != first.chunk_count)
      throw std::invalid_argument("'" + names[k] + "' is a part of another run than '" + names[order.front()] + "' (" +
                                  difference(table_run(p), run) + ")");
    if (p.chunk_first < next)
      throw std::invalid_argument("'" + names[k] + "' overlaps another part: chunks " + std::to_string(p.chunk_first) +
                                  ".." + std::to_string(std::min(next, p.chunk_last) - 1) + " are in both");
    if (p.chunk_first > next)
      throw std::invalid_argument("chunks " + std::to_string(next) + ".." + std::to_string(p.chunk_first - 1) + " of " +
                                  std::to_string(p.chunk_count) + " are in no part (a shard is missing)");
    next = p.chunk_last;
  }
  if (next != first.chunk_count)
    throw std::invalid_argument("chunks " + std::to_string(next) + ".." + std::to_string(first.chunk_count - 1) + " of " +
                                std::to_string(first.chunk_count) + " are in no part (a shard is missing)");
  return order;
}

void add_part(Table& whole, const Table& p) {
  for (int h = 0; h < 2; ++h)
    for (std::size_t c = 0; c < whole.weight_half[h].size(); ++c) whole.weight_half[h][c] += p.weight_half[h][c];
  whole.paths += p.paths;
  for (int h = 0; h < 2; ++h) whole.uncollided_half[h] += p.uncollided_half[h];
  for (const auto& [key, w] : p.once) whole.once[key] += w;
  whole.once_tallied = whole.once_tallied && p.once_tallied;
  if (whole.sub_bins != p.sub_bins) throw std::invalid_argument("parts tally sub-bins differently (written by different stf versions)");
  for (int h = 0; h < 2; ++h)
    for (std::size_t i = 0; i < whole.multiple_sub_half[h].size(); ++i) whole.multiple_sub_half[h][i] += p.multiple_sub_half[h][i];
  whole.escaped_weight += p.escaped_weight;
  whole.absorbed_weight += p.absorbed_weight;
  whole.truncated_weight += p.truncated_weight;
  whole.collisions += p.collisions;
  whole.absorbed_collisions = whole.absorbed_collisions < 0 || p.absorbed_collisions < 0 ? -1 : whole.absorbed_collisions + p.absorbed_collisions;
  whole.runtime_s += p.runtime_s;  // compute time spent on the run, over all parts
  whole.chunk_first = std::min(whole.chunk_first, p.chunk_first);
  whole.chunk_last = std::max(whole.chunk_last, p.chunk_last);
}

}  // namespace stf
