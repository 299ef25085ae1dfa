// A run past one process: checkpoints of an unfinished run, and parts (shards, MPI ranks) of one
// run's chunk stream merged into its table.
#pragma once

#include <string>
#include <vector>

#include "stf/precompute/precompute.h"
#include "stf/core/table.h"

namespace stf {

// What a checkpoint or a part must share with the run it claims to belong to: the medium, grid,
// alpha bins, paths, seed, --max-scatter, part and generator (not threads or progress output).
std::string run_fingerprint(const Medium& medium, const PrecomputeSettings& settings);

// Writes `progress` to `path` atomically (a temporary file beside it, then renamed), so a kill
// at any moment leaves the previous checkpoint or this one. Throws std::runtime_error.
void write_checkpoint(const std::string& path, const std::string& fingerprint, const Progress& progress);

// Reads a checkpoint of the run `fingerprint` over `range`. Throws std::runtime_error saying
// what differs when it belongs to another run, or is damaged.
Progress read_checkpoint(const std::string& path, const std::string& fingerprint, const ChunkRange& range,
                         int alpha_bins, std::int64_t cells);

// Checks that parts (their weights need not be loaded) are of one run and cover its chunks
// exactly once; returns their order along the chunk stream. Throws std::invalid_argument naming
// the part when parts belong to different runs, overlap, or leave chunks out. `names` label the
// parts in messages.
std::vector<std::size_t> check_parts(const std::vector<Table>& parts, const std::vector<std::string>& names);

// Adds a checked part to `whole` (the first part, which becomes the run's table once all parts
// are added): the same data as the run in one process, since counts are integers.
void add_part(Table& whole, const Table& part);

}  // namespace stf
