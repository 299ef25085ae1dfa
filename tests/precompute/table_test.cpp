#include "stf/core/table.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <stdexcept>

#include "stf/precompute/parts.h"
#include "stf/precompute/precompute.h"

namespace stf {
namespace {

TEST(Table, WriteReadRoundTripIsExact) {
  PrecomputeSettings s;
  s.paths = 20'000;
  s.alpha_bins = 12;
  s.grid = "csc:4";
  s.max_scatter = 5;
  Table t = *precompute({3, 1, -0.2, 2}, s);
  std::string path = ::testing::TempDir() + "/roundtrip_" + std::to_string(::getpid()) + ".h5";
  write_table(t, path);
  Table r = read_table(path);
  std::remove(path.c_str());
  EXPECT_EQ(r.medium.sigma_s, 3);
  EXPECT_EQ(r.medium.radius, 2);
  EXPECT_EQ(r.paths, t.paths);
  EXPECT_EQ(r.max_scatter, 5);
  EXPECT_EQ(r.grid, "csc:4");
  EXPECT_EQ(r.weight_half[0], t.weight_half[0]);
  EXPECT_EQ(r.weight_half[1], t.weight_half[1]);
  EXPECT_EQ(r.sub_bins, t.sub_bins);
  EXPECT_EQ(r.multiple_sub_half, t.multiple_sub_half);
  EXPECT_EQ(r.alpha_edges, t.alpha_edges);
  EXPECT_EQ(r.solid_angle, t.solid_angle);
  EXPECT_EQ(r.direction, t.direction);
  EXPECT_EQ(r.escaped_weight, t.escaped_weight);
  EXPECT_EQ(r.truncated_weight, t.truncated_weight);
  EXPECT_EQ(r.collisions, t.collisions);
  EXPECT_EQ(r.absorbed_collisions, t.absorbed_collisions);
  EXPECT_GE(t.absorbed_collisions, std::int64_t(t.absorbed_weight));  // every absorbed path collided
  EXPECT_EQ(r.generator, t.generator);
}

// The sub-bin tallies must add up to each bin's escapes after two or more collisions.
// A small table of an absorbing medium (tau 2.5, albedo 0.8).
Table small_table() {
  PrecomputeSettings s;
  s.paths = 20'000;
  s.alpha_bins = 6;
  s.grid = "healpix:1";
  return *precompute({2, 0.5, 0.5, 1}, s);
}

TEST(Table, InconsistentSubBinsAreRefused) {
  Table t = small_table();
  EXPECT_EQ(table_error(t), "");
  t.multiple_sub_half[1][3] += 1;
  EXPECT_NE(table_error(t).find("multiple_sub_half"), std::string::npos) << table_error(t);
  t.multiple_sub_half[1][3] = -1;
  EXPECT_NE(table_error(t).find("multiple_sub_half"), std::string::npos) << table_error(t);
}

// The absorbed paths' collisions: checked against the absorbed paths and all collisions; unknown
// (-1, tables written before stf tallied it) survives a round trip and makes a merge unknown.
TEST(Table, AbsorbedCollisionsAreCheckedAndMayBeUnknown) {
  const Table t = small_table();
  ASSERT_GT(t.absorbed_collisions, std::int64_t(t.absorbed_weight));
  Table low = t, high = t;
  low.absorbed_collisions = std::int64_t(t.absorbed_weight) - 1;
  high.absorbed_collisions = t.collisions + 1;
  EXPECT_NE(table_error(low).find("absorbed_collisions"), std::string::npos) << table_error(low);
  EXPECT_NE(table_error(high).find("absorbed_collisions"), std::string::npos) << table_error(high);
  Table old = t;
  old.absorbed_collisions = -1;
  EXPECT_EQ(table_error(old), "");
  const std::string path = ::testing::TempDir() + "/old_" + std::to_string(::getpid()) + ".h5";
  write_table(old, path);
  EXPECT_EQ(read_table(path).absorbed_collisions, -1);
  std::remove(path.c_str());
  Table whole = t;
  add_part(whole, t);
  EXPECT_EQ(whole.absorbed_collisions, 2 * t.absorbed_collisions);
  add_part(whole, old);
  EXPECT_EQ(whole.absorbed_collisions, -1);
}

TEST(Table, ReadingANonTableFails) {
  EXPECT_THROW(read_table("/nonexistent/table.h5"), std::runtime_error);
  std::string path = ::testing::TempDir() + "/garbage_" + std::to_string(::getpid()) + ".h5";
  FILE* f = std::fopen(path.c_str(), "w");
  std::fputs("not hdf5", f);
  std::fclose(f);
  EXPECT_THROW(read_table(path), std::runtime_error);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace stf
