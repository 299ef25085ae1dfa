#include "mpi.h"

#include <cstdio>
#include <cstdlib>
#include <string>

#ifdef STF_WITH_MPI
#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <map>
#include <vector>
#endif

namespace stf::cli {

namespace {
World the_world;

bool launched_by_mpi() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
    if (std::getenv(name)) return true;
  return false;
}
}  // namespace

const World& world() { return the_world; }

#ifdef STF_WITH_MPI

World start_mpi(int& argc, char**& argv) {
  if (!launched_by_mpi()) return the_world;
  MPI_Init(&argc, &argv);
  MPI_Comm_rank(MPI_COMM_WORLD, &the_world.rank);
  MPI_Comm_size(MPI_COMM_WORLD, &the_world.size);
  return the_world;
}

void finish_mpi() {
  int started = 0;
  MPI_Initialized(&started);
  if (started) MPI_Finalize();
}

bool same_command_on_every_rank(int argc, char** argv) {
  if (the_world.size == 1) return true;
  std::string line;
  for (int i = 1; i < argc; ++i) line += std::string(argv[i]) + '\0';
  // Two 64-bit hashes of the line, compared by their minimum and maximum over the ranks.
  const std::uint64_t h = std::hash<std::string>{}(line), g = std::hash<std::string>{}(line + "stf");
  std::uint64_t mine[4] = {h, g, ~h, ~g}, lowest[4] = {};
  MPI_Allreduce(mine, lowest, 4, MPI_UINT64_T, MPI_MIN, MPI_COMM_WORLD);
  return lowest[0] == h && lowest[1] == g && lowest[2] == ~h && lowest[3] == ~g;
}

bool any_rank(bool flag) {
  if (the_world.size == 1) return flag;
  int mine = flag, any = 0;
  MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_LOR, MPI_COMM_WORLD);
  return any != 0;
}

namespace {

// The sparse once-scattered tallies of all ranks, added into rank 0's (whole numbers: exact in
// any order).
void sum_once_to_root(std::map<std::uint64_t, double>& once) {
  std::vector<std::uint64_t> keys;
  std::vector<double> values;
  for (const auto& [k, v] : once) keys.push_back(k), values.push_back(v);
  int mine = int(keys.size());
  std::vector<int> counts(std::size_t(the_world.size)), offsets(std::size_t(the_world.size));
  MPI_Gather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  int total = 0;
  for (int r = 0; r < the_world.size; ++r) offsets[std::size_t(r)] = total, total += counts[std::size_t(r)];
  std::vector<std::uint64_t> all_keys(the_world.root() ? std::size_t(total) : 0);
  std::vector<double> all_values(all_keys.size());
  MPI_Gatherv(keys.data(), mine, MPI_UINT64_T, all_keys.data(), counts.data(), offsets.data(), MPI_UINT64_T, 0,
              MPI_COMM_WORLD);
  MPI_Gatherv(values.data(), mine, MPI_DOUBLE, all_values.data(), counts.data(), offsets.data(), MPI_DOUBLE, 0,
              MPI_COMM_WORLD);
  if (!the_world.root()) return;
  once.clear();
  for (std::size_t i = 0; i < all_keys.size(); ++i) once[all_keys[i]] += all_values[i];
}

}  // namespace

void sum_to_root(Table& part) {
  if (the_world.size == 1) return;
  sum_once_to_root(part.once);
  // Counts are whole numbers below 2^53 held in doubles: their sum is exact in any order.
  constexpr std::size_t kSlice = std::size_t(1) << 26;  // MPI counts are ints
  std::vector<std::vector<double>*> arrays;
  for (std::vector<double>& half : part.weight_half) arrays.push_back(&half);
  for (std::vector<double>& half : part.multiple_sub_half) arrays.push_back(&half);
  for (std::vector<double>* half : arrays)
    for (std::size_t at = 0; at < half->size(); at += kSlice) {
      int n = int(std::min(kSlice, half->size() - at));
      if (the_world.root())
        MPI_Reduce(MPI_IN_PLACE, half->data() + at, n, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
      else
        MPI_Reduce(half->data() + at, nullptr, n, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
    }
  double totals[7] = {part.escaped_weight, part.absorbed_weight,  part.truncated_weight, double(part.paths),
                      part.runtime_s,      part.uncollided_half[0], part.uncollided_half[1]};
  double sum[7] = {};
  MPI_Reduce(totals, sum, 7, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
  // Collisions, the absorbed paths' collisions, and how many ranks do not know the latter.
  std::int64_t counts[3] = {part.collisions, std::max<std::int64_t>(part.absorbed_collisions, 0), part.absorbed_collisions < 0},
               all_counts[3] = {};
  MPI_Reduce(counts, all_counts, 3, MPI_INT64_T, MPI_SUM, 0, MPI_COMM_WORLD);
  double runtime = part.runtime_s, longest = 0;
  MPI_Reduce(&runtime, &longest, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
  if (!the_world.root()) return;
  part.escaped_weight = sum[0], part.absorbed_weight = sum[1], part.truncated_weight = sum[2];
  part.paths = std::int64_t(sum[3]);
  part.uncollided_half = {sum[5], sum[6]};
  part.collisions = all_counts[0];
  part.absorbed_collisions = all_counts[2] > 0 ? -1 : all_counts[1];
  part.runtime_s = longest;  // wall clock of the run: its slowest rank
  part.chunk_first = 0, part.chunk_last = part.chunk_count;
}

#else

World start_mpi(int&, char**&) {
  // N copies of one job would each do all of it and race for the output.
  const char* size = std::getenv("OMPI_COMM_WORLD_SIZE");
  if (launched_by_mpi() && !(size && std::string(size) == "1")) {
    std::fprintf(stderr, "stf: error: this stf was built without MPI; run it without mpirun, or split the run with --shard K/N\n");
    std::exit(2);
  }
  return the_world;
}
void finish_mpi() {}
bool same_command_on_every_rank(int, char**) { return true; }
bool any_rank(bool flag) { return flag; }
void sum_to_root(Table&) {}

#endif

}  // namespace stf::cli
