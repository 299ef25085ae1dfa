// Carrying out a plan: compute what is missing into the cache, then pack what the scene needs.
#pragma once

#include <atomic>
#include <functional>
#include <cstdint>
#include <string>
#include <vector>

#include "stf/scene/plan.h"

namespace stf::scene {

// Called before each entry is computed: (index among the entries to compute, their count, entry).
using BuildProgress = std::function<void(int, int, const PlanEntry&)>;

// Computes the "compute" entries (precompute, then fit) into the cache, atomically per file,
// and writes the pack: for every medium in scene order, its entries by increasing tau, named
// after the medium. Returns the number of entries computed. When `cancel` is set it stops
// with std::runtime_error; finished entries stay in the cache.
int build(const Scene& scene, const Plan& plan, const std::string& pack_path, int threads,
          const BuildProgress& progress = {}, const std::atomic<bool>* cancel = nullptr);

// The two halves of build(). compute_entries computes the "compute" entries numbered part,
// part + parts, ... (all of them by default; MPI ranks share them out this way) and returns
// how many it computed; write_scene_pack packs the scene once every entry is cached.
int compute_entries(const Plan& plan, int threads, const BuildProgress& progress = {},
                    const std::atomic<bool>* cancel = nullptr, int part = 0, int parts = 1);
// The pack of the scene's cached entries, and the same written to `pack_path` (replace_file).
std::vector<std::uint8_t> scene_pack(const Scene& scene, const Plan& plan);
void write_scene_pack(const Scene& scene, const Plan& plan, const std::string& pack_path);

}  // namespace stf::scene
