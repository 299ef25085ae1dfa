// A run past one process: MPI ranks, shards merged, and resuming a killed run all give the
// table of one uninterrupted process, bit for bit.
#include "cli_fixture.h"
#include "stf/core/table.h"

namespace {

const std::string kMedium = "--sigma-s 4 --sigma-a 0.5 --g 0.3 --alpha-bins 18 --grid healpix:4 --quiet ";

// The data a run must reproduce: every count, and the event totals.
void expect_same_table(const std::string& a_path, const std::string& b_path) {
  stf::Table a = stf::read_table(a_path), b = stf::read_table(b_path);
  EXPECT_EQ(a.weight_half[0], b.weight_half[0]) << b_path;
  EXPECT_EQ(a.weight_half[1], b.weight_half[1]) << b_path;
  // The singular parts' tallies too: MPI gathers the sparse once-scattered map, merge and
  // resume add it.
  EXPECT_EQ(a.once, b.once) << b_path;
  EXPECT_EQ(a.uncollided_half, b.uncollided_half) << b_path;
  EXPECT_EQ(a.sub_bins, b.sub_bins) << b_path;
  EXPECT_EQ(a.multiple_sub_half, b.multiple_sub_half) << b_path;
  EXPECT_EQ(a.alpha_edges, b.alpha_edges);
  EXPECT_EQ(a.solid_angle, b.solid_angle);
  EXPECT_EQ(a.paths, b.paths);
  EXPECT_EQ(a.collisions, b.collisions);
  EXPECT_EQ(a.absorbed_collisions, b.absorbed_collisions);
  EXPECT_GE(b.absorbed_collisions, 0);
  EXPECT_EQ(a.escaped_weight, b.escaped_weight);
  EXPECT_EQ(a.absorbed_weight, b.absorbed_weight);
  EXPECT_FALSE(b.is_part());
}

class Scale : public Cli {
 protected:
  Result mpi_stf(int ranks, const std::string& args) {
    std::string err = out("mpi_stderr.txt");
    int raw = std::system((mpirun(ranks) + STF_BINARY + " " + args + " 2>'" + err + "' >/dev/null").c_str());
    std::ifstream in(err);
    std::stringstream text;
    text << in.rdbuf();
    fs::remove(err);
    return {WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw), text.str()};
  }
};

TEST_F(Scale, MpiRanksWriteTheTableOfOneProcess) {
  if (!have_mpi()) GTEST_SKIP() << "stf built without MPI, or no mpirun";
  ASSERT_EQ(stf("precompute " + kMedium + "--paths 2e5 --seed 4 -o " + out("one.h5")).status, 0);
  for (int ranks : {2, 3}) {
    std::string name = "mpi" + std::to_string(ranks) + ".h5";
    Result r = mpi_stf(ranks, "precompute " + kMedium + "--paths 2e5 --seed 4 --threads 1 -o " + out(name));
    ASSERT_EQ(r.status, 0) << r.err;
    expect_same_table(out("one.h5"), out(name));
    EXPECT_FALSE(stf::read_table(out(name)).once.empty());
  }
  // A scene's entries spread over ranks: the same pack.
  std::ofstream(out("scene.toml")) << "[settings]\npaths = 2e4\ngrid = \"healpix:2\"\nalpha_bins = 6\nmodel = \"vmf:1\"\n"
                                      "[[media]]\nname = \"a\"\nsigma_s = 4.0\nsigma_a = 0.1\ng = 0.3\n"
                                      "radius_min = 0.5\nradius_max = 4.0\n";
  ASSERT_EQ(stf("build " + out("scene.toml") + " --quiet --cache " + out("c1") + " -o " + out("one.stfpack")).status, 0);
  Result r = mpi_stf(3, "build " + out("scene.toml") + " --quiet --cache " + out("c3") + " -o " + out("mpi.stfpack"));
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream a(out("one.stfpack"), std::ios::binary), b(out("mpi.stfpack"), std::ios::binary);
  EXPECT_TRUE(std::equal(std::istreambuf_iterator<char>(a), {}, std::istreambuf_iterator<char>(b)));
}

TEST_F(Scale, ThreeShardsMergeIntoTheTableOfOneRun) {
  ASSERT_EQ(stf("precompute " + kMedium + "--paths 2e5 -o " + out("one.h5")).status, 0);
  for (int k = 0; k < 3; ++k) {
    std::string part = out("part" + std::to_string(k) + ".h5");
    ASSERT_EQ(stf("precompute " + kMedium + "--paths 2e5 --shard " + std::to_string(k) + "/3 -o " + part).status, 0);
    EXPECT_TRUE(stf::read_table(part).is_part());
  }
  // In any order.
  Result r = stf("merge " + out("part2.h5") + " " + out("part0.h5") + " " + out("part1.h5") + " -o " + out("merged.h5"));
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_table(out("one.h5"), out("merged.h5"));
  EXPECT_FALSE(stf::read_table(out("merged.h5")).once.empty());
}

TEST_F(Scale, MergeRefusesDuplicatesGapsAndForeignParts) {
  for (int k = 0; k < 3; ++k)
    ASSERT_EQ(stf("precompute " + kMedium + "--paths 1e5 --shard " + std::to_string(k) + "/3 -o " +
                  out("p" + std::to_string(k) + ".h5")).status, 0);
  ASSERT_EQ(stf("precompute " + kMedium + "--paths 1e5 --seed 9 --shard 1/3 -o " + out("seed9.h5")).status, 0);
  ASSERT_EQ(stf("precompute " + kMedium.substr(0, kMedium.find("--g")) + "--g 0.5 --alpha-bins 18 --grid healpix:4 "
                "--quiet --paths 1e5 --shard 1/3 -o " + out("g05.h5")).status, 0);
  struct Case {
    std::string parts, says;
  };
  const Case cases[] = {
      {"p0 p1", "no part"},            // a gap
      {"p0 p1 p1 p2", "overlaps"},     // a duplicate
      {"p0 seed9 p2", "seed 9"},       // another seed
      {"p0 g05 p2", "g 0.5"},          // another medium
  };
  for (const Case& c : cases) {
    std::string args;
    for (std::size_t at = 0, space; at < c.parts.size(); at = space + 1) {
      space = std::min(c.parts.find(' ', at), c.parts.size());
      args += out(c.parts.substr(at, space - at) + ".h5") + " ";
    }
    Result r = stf("merge " + args + "-o " + out("x.h5"));
    EXPECT_EQ(r.status, 2) << c.parts;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << c.parts << ": " << r.err;
    EXPECT_FALSE(fs::exists(out("x.h5")));
  }
}

TEST_F(Scale, AKilledRunResumesToTheSameTable) {
  const std::string run = "precompute --sigma-s 30 --sigma-a 0 --g 0 --alpha-bins 18 --grid healpix:4 --quiet "
                          "--paths 3e6 --threads 2 ";
  ASSERT_EQ(stf(run + "-o " + out("full.h5")).status, 0);
  // Checkpoints every 0.1 s; SIGKILL (no handler runs) part-way.
  pid_t pid = ::fork();
  if (pid == 0) {
    std::string cmd = std::string("exec ") + STF_BINARY + " " + run + "--checkpoint-seconds 0.1 -o " + out("t.h5");
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), (char*)nullptr);
    ::_exit(127);
  }
  for (int i = 0; i < 100 && !fs::exists(out("t.h5.checkpoint")); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the run finished before it was killed";
  ASSERT_TRUE(fs::exists(out("t.h5.checkpoint")));
  EXPECT_FALSE(fs::exists(out("t.h5")));

  // Without --resume the checkpoint is not thrown away; another command's is refused.
  Result r = stf(run + "-o " + out("t.h5"));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--resume"), std::string::npos) << r.err;
  r = stf(run + "--seed 5 --resume -o " + out("t.h5"));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("seed 1, not seed 5"), std::string::npos) << r.err;

  r = stf(run + "--resume -o " + out("t.h5"));
  ASSERT_EQ(r.status, 0) << r.err;
  expect_same_table(out("full.h5"), out("t.h5"));
  EXPECT_FALSE(fs::exists(out("t.h5.checkpoint")));
  for (const auto& e : fs::directory_iterator(dir_))  // the killed run's temporary file is gone too
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

}  // namespace
