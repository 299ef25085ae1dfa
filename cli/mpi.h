// MPI for `stf precompute` and `stf build` under mpirun: which rank this process is, and the
// few collective steps they need. Without MPI (or when not launched by an MPI launcher) this is
// one process of one rank, and every step is a no-op.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>

#include "cli.h"

#include "stf/core/table.h"

namespace stf::cli {

struct World {
  int rank = 0, size = 1;
  bool root() const { return rank == 0; }
};

// Starts MPI only when an MPI launcher started this process (mpirun, srun); call once, first.
World start_mpi(int& argc, char**& argv);
void finish_mpi();
const World& world();

// Collective: whether every rank was started with the same command line (one run's identity:
// its command, medium, grid, bins, paths and seed). Ranks that differ refuse together.
bool same_command_on_every_rank(int argc, char** argv);
// Collective: true on every rank when `flag` is true on any rank.
bool any_rank(bool flag);
// Collective: the ranks' parts of one run summed into rank 0's table, which becomes the whole
// run's (exact: the counts are integers).
void sum_to_root(Table& part);

// Runs `step` on every rank and stops them all when it fails on any: rank 0 reports (an
// interruption as such), the others leave quietly, naming their own failure only where rank 0
// had none (bad input fails alike on every rank: one line). With one process it is just `step`.
template <typename Step>
void on_every_rank(Step step) {
  std::string failure;
  bool stopped = false;
  try {
    step();
  } catch (const Interrupted& e) {
    stopped = true, failure = e.what();
  } catch (const std::exception& e) {
    failure = e.what();
  }
  if (!any_rank(!failure.empty())) return;
  const bool root_failed = any_rank(world().root() && !failure.empty());
  if (world().root()) {
    if (stopped) throw Interrupted();
    fail(failure.empty() ? "another MPI rank failed" : failure);
  }
  if (!failure.empty() && !root_failed) std::fprintf(stderr, "stf: error (rank %d): %s\n", world().rank, failure.c_str());
  finish_mpi();
  std::exit(stopped ? interrupted_status() : 2);
}

}  // namespace stf::cli
