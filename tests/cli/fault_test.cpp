// Faults a long job meets sooner or later: a full disk under every command that writes, signals
// at any moment, a second writer of the same output, tables whose datasets disagree, MPI ranks
// that disagree, and the small misuses that each cost a user an afternoon.
#include <H5Cpp.h>
#include <fcntl.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include <csignal>
#include <map>
#include <random>

#include "forget_checksum.h"
#include "cli_fixture.h"
#include "stf/core/table.h"

namespace {

const std::string kTable =
    "precompute --sigma-s 2 --sigma-a 0.5 --g 0.3 --alpha-bins 6 --grid healpix:2 --paths 4000 "
    "--quiet ";
const std::string kScene =
    "[settings]\npaths = 1e7\n[[media]]\nname = \"m\"\nsigma_s = 20.0\nsigma_a = 0.0\n"
    "g = 0.0\nradius_min = 0.5\nradius_max = 1.0\n";

bool has_plotting() {
  return std::system("/usr/bin/python3 -c 'import matplotlib, h5py' >/dev/null 2>&1") == 0;
}

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Runs stf with `args` in a child whose file size limit is `limit_bytes` (RLIMIT_FSIZE) and
// which ignores SIGXFSZ, so writes past it fail with EFBIG as on a full disk; stderr comes back
// through a pipe (a file would be limited too). With `signal_after_ms` >= 0 the child gets
// `signal` after that long instead.
Result run_child(const std::vector<std::string>& args, rlim_t limit_bytes, int signal_after_ms = -1,
                 int sig = SIGINT, const std::string& tmpdir = "") {
  int pipe_fds[2];
  if (::pipe(pipe_fds) != 0) return {-1, "pipe"};
  pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(pipe_fds[1], STDERR_FILENO);
    ::close(pipe_fds[0]);
    int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, STDOUT_FILENO);
    std::signal(SIGXFSZ, SIG_IGN);
    rlimit limit{limit_bytes, limit_bytes};
    if (limit_bytes != RLIM_INFINITY) ::setrlimit(RLIMIT_FSIZE, &limit);
    if (!tmpdir.empty()) ::setenv("TMPDIR", tmpdir.c_str(), 1);
    std::vector<char*> argv = {const_cast<char*>(STF_BINARY)};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(STF_BINARY, argv.data());
    ::_exit(127);
  }
  ::close(pipe_fds[1]);
  if (signal_after_ms >= 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(signal_after_ms));
    ::kill(pid, sig);
  }
  std::string err;
  char buf[4096];
  for (ssize_t n; (n = ::read(pipe_fds[0], buf, sizeof buf)) > 0;) err.append(buf, std::size_t(n));
  ::close(pipe_fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), err};
}

class Fault : public Cli {
 protected:
  void expect_one_line(const Result& r, const std::string& names, const std::string& what) {
    EXPECT_EQ(r.status, 2) << what << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << what << "\n" << r.err;
    EXPECT_NE(r.err.find(names), std::string::npos) << what << "\n" << r.err;
  }
  // The valid outputs every writing command is then run over with a full disk.
  void make_outputs() {
    ASSERT_EQ(stf(kTable + "-o " + out("t.h5")).status, 0);
    ASSERT_EQ(stf(kTable + "--seed 2 -o " + out("h.h5")).status, 0);
    ASSERT_EQ(stf(kTable + "--shard 0/2 -o " + out("p0.h5")).status, 0);
    ASSERT_EQ(stf(kTable + "--shard 1/2 -o " + out("p1.h5")).status, 0);
    ASSERT_EQ(stf("merge --quiet " + out("p0.h5") + " " + out("p1.h5") + " -o " + out("merged.h5"))
                  .status,
              0);
    ASSERT_EQ(stf("fit --quiet " + out("t.h5") + " --model vmf:2 -o " + out("m.h5") + " --report " +
                  out("r.json") + " --pack " + out("m.stfpack"))
                  .status,
              0);
    ASSERT_EQ(stf("eval " + out("m.h5") + " --reference " + out("h.h5") + " --json " +
                  out("e.json") + " --cells " + out("c.h5"))
                  .status,
              0);
    ASSERT_EQ(stf("pack " + out("m.h5") + " -o " + out("p.stfpack")).status, 0);
    ASSERT_EQ(stf("sample " + out("m.h5") + " --count 1000 -o " + out("s.h5")).status, 0);
    ASSERT_EQ(
        stf("sample " + out("m.h5") + " --eval " + out("s.h5") + " -o " + out("pdf.h5")).status, 0);
    ASSERT_EQ(stf("render --sigma-s 5 --sigma-a 0.1 --g 0.5 --spp 4 --width 16 --height 16 "
                  "--method brute -o " +
                  out("rd.h5") + " --png " + out("rd.png") + " --json " + out("rd.json"))
                  .status,
              0);
    std::ofstream(out("scene.toml")) << kScene;
    ASSERT_EQ(stf("build --quiet " + out("scene.toml") + " --cache " + out("cache") + " -o " +
                  out("b.stfpack"))
                  .status,
              0);
  }
};

struct Writer {
  std::vector<std::string> args;
  std::string output;  // the file the one error line must name
};

// Every command that writes, over its valid old output, with writes failing (EFBIG): exit 2,
// one line naming the output and the reason, every old file byte for byte as it was, and no
// temporary or lock left.
TEST_F(Fault, FullDiskLeavesEveryOldOutputAsItWas) {
  make_outputs();
  const std::vector<Writer> writers = {
      {{"precompute", "--sigma-s", "2", "--sigma-a", "0.5", "--g", "0.3", "--alpha-bins", "6",
        "--grid", "healpix:2", "--paths", "4000", "--quiet", "-o", out("t.h5")},
       "t.h5"},
      {{"merge", "--quiet", out("p0.h5"), out("p1.h5"), "-o", out("merged.h5")}, "merged.h5"},
      {{"fit", "--quiet", out("t.h5"), "--model", "vmf:2", "-o", out("m.h5")}, "m.h5"},
      {{"fit", "--quiet", out("t.h5"), "--model", "vmf:2", "-o", out("m.h5"), "--report",
        out("r.json")},
       "m.h5"},
      {{"eval", out("m.h5"), "--reference", out("h.h5"), "--json", out("e.json")}, "e.json"},
      {{"eval", out("m.h5"), "--reference", out("h.h5"), "--json", out("e.json"), "--cells",
        out("c.h5")},
       "c.h5"},
      {{"pack", out("m.h5"), "-o", out("p.stfpack")}, "p.stfpack"},
      {{"sample", out("m.h5"), "--count", "1000", "-o", out("s.h5")}, "s.h5"},
      {{"sample", out("m.h5"), "--eval", out("s.h5"), "-o", out("pdf.h5")}, "pdf.h5"},
      {{"render", "--sigma-s", "5",          "--sigma-a", "0.1",         "--g",    "0.5",
        "--spp",  "4",         "--width",    "16",        "--height",    "16",     "--method",
        "brute",  "-o",        out("rd.h5"), "--png",     out("rd.png"), "--json", out("rd.json")},
       "rd.h5"},
      {{"build", "--quiet", out("scene.toml"), "--cache", out("cache"), "-o", out("b.stfpack")},
       "b.stfpack"},
  };
  std::map<std::string, std::string> before;
  for (const auto& e : fs::recursive_directory_iterator(dir_))
    if (e.is_regular_file()) before[e.path().string()] = bytes_of(e.path().string());
  for (const Writer& w : writers) {
    const std::string what = w.args[0] + " -> " + w.output;
    Result r = run_child(w.args, 0);
    expect_one_line(r, w.output, what);
    EXPECT_NE(r.err.find("File too large"), std::string::npos) << what << ": " << r.err;
    for (const auto& [path, bytes] : before)
      EXPECT_EQ(bytes_of(path), bytes) << what << " changed " << path;
    expect_no_litter(what);
  }
  // A report's script runs stf, which meets the limit: its one line is the report's one line.
  Result report = run_child({"report", "--medium", "a:4:0.5:0.3", "-o", out("rep")}, 4096);
  expect_one_line(report, "File too large", "report over a 4 KiB limit");
  EXPECT_FALSE(fs::exists(out("rep")));
  expect_no_litter("report over a 4 KiB limit");
  // A file too large for the limit but not the first write: the same.
  Result part = run_child({"sample", out("m.h5"), "--count", "1e5", "-o", out("s.h5")}, 64 * 1024);
  expect_one_line(part, "s.h5", "sample of 1e5 over a 64 KiB limit");
  EXPECT_EQ(bytes_of(out("s.h5")), before[out("s.h5")]);
  expect_no_litter("sample of 1e5");
}

// The checkpoints of a run that cannot write: the last good one stays, and resumes.
TEST_F(Fault, FullDiskKeepsTheLastCheckpoint) {
  const std::vector<std::string> run = {
      "precompute", "--sigma-s", "50",       "--sigma-a", "0",
      "--g",        "0.5",       "--grid",   "healpix:2", "--alpha-bins",
      "6",          "--paths",   "1e8",      "--quiet",   "--checkpoint-seconds",
      "0.2",        "-o",        out("t.h5")};
  EXPECT_EQ(run_child(run, RLIM_INFINITY, 1500).status, 130);
  ASSERT_TRUE(fs::exists(out("t.h5.checkpoint")));
  const std::string checkpoint = bytes_of(out("t.h5.checkpoint"));
  std::vector<std::string> resume = run;
  resume.push_back("--resume");
  Result r = run_child(resume, 0, 1500);  // every save fails: one warning, the old one kept
  EXPECT_EQ(r.status, 130) << r.err;
  EXPECT_NE(r.err.find("File too large"), std::string::npos) << r.err;
  EXPECT_EQ(bytes_of(out("t.h5.checkpoint")), checkpoint);
  EXPECT_FALSE(fs::exists(out("t.h5")));
  for (const auto& e : fs::directory_iterator(dir_))
    EXPECT_EQ(e.path().string().find(".tmp-"), std::string::npos);
}

// A real full disk (ENOSPC) on a small tmpfs, where this test may mount one.
TEST_F(Fault, NoSpaceLeftOnADeviceKeepsTheOldTable) {
  const fs::path mnt = dir_ / "small";
  fs::create_directories(mnt);
  if (::mount("tmpfs", mnt.c_str(), "tmpfs", 0, "size=1m") != 0)
    GTEST_SKIP() << "cannot mount a tmpfs here";
  struct Unmount {
    fs::path at;
    ~Unmount() { ::umount(at.c_str()); }
  } unmount{mnt};
  const std::string table = (mnt / "t.h5").string();
  Result first =
      run_child({"precompute", "--sigma-s", "2", "--sigma-a", "0.5", "--g", "0.3", "--alpha-bins",
                 "6", "--grid", "healpix:2", "--paths", "4000", "--quiet", "-o", table},
                RLIM_INFINITY);
  ASSERT_EQ(first.status, 0) << first.err;
  const std::string old = bytes_of(table);
  {  // fill what is left
    std::ofstream fill((mnt / "filler").string(), std::ios::binary);
    std::string block(4096, 'x');
    while (fill.write(block.data(), std::streamsize(block.size()))) fill.flush();
  }
  Result r =
      run_child({"precompute", "--sigma-s", "2", "--sigma-a", "0.5", "--g", "0.3", "--alpha-bins",
                 "18", "--grid", "healpix:8", "--paths", "2e5", "--quiet", "-o", table},
                RLIM_INFINITY);
  expect_one_line(r, "t.h5", "precompute onto a full tmpfs");
  EXPECT_NE(r.err.find("No space left on device"), std::string::npos) << r.err;
  EXPECT_EQ(bytes_of(table), old);
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(mnt)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"filler", "t.h5"}));
}

// SIGINT and SIGTERM at seeded random moments into every long command: exit 130 or 143 (or 0
// when it finished first), never a crash, and no temporary, lock or scratch file left.
TEST_F(Fault, SignalsAtRandomMomentsNeverCrashOrLitter) {
  ASSERT_EQ(stf("precompute --sigma-s 4 --sigma-a 0.5 --g 0.3 --alpha-bins 18 --grid healpix:8 "
                "--paths 2e5 --quiet -o " +
                out("t.h5"))
                .status,
            0);
  ASSERT_EQ(stf("precompute --sigma-s 4 --sigma-a 0.5 --g 0.3 --alpha-bins 18 --grid healpix:8 "
                "--paths 2e5 --seed 2 "
                "--quiet -o " +
                out("h.h5"))
                .status,
            0);
  ASSERT_EQ(stf("fit " + out("t.h5") + " --model vmf:1 --quiet -o " + out("m.h5")).status, 0);
  std::ofstream(out("scene.toml")) << kScene;
  const std::string scene = std::string(STF_SOURCE_DIR) + "/data/scenes/default.toml";
  struct Long {
    std::vector<std::string> args;
    int from_ms, to_ms;
  };
  std::vector<Long> runs = {
      {{"precompute", "--sigma-s", "50", "--sigma-a", "0", "--g", "0.5", "--paths", "1e8",
        "--quiet", "-o", out("o.h5")},
       20,
       800},
      {{"fit", out("t.h5"), "--model", "hvmf:auto", "--quiet", "-o", out("o.h5")}, 20, 1500},
      {{"fit", out("t.h5"), "--model", "vmf:auto", "--tolerance", "0.05", "--heldout", out("h.h5"),
        "--quiet", "-o", out("o.h5")},
       20,
       1500},
      {{"sample", out("m.h5"), "--count", "4e6", "-o", out("o.h5")}, 20, 800},
      {{"build", out("scene.toml"), "--quiet", "--cache", out("cache"), "-o", out("o.stfpack")},
       20,
       1500},
      {{"build", scene, "--quiet", "--cache", out("cache2"), "-o", out("o.stfpack")}, 1500, 3500},
      {{"render", "--sigma-s", "50", "--sigma-a", "0.01", "--g", "0.9", "--spp", "1e5", "--method",
        "brute", "-o", out("o.h5"), "--png", out("o.png")},
       20,
       800},
      {{"render", "--sigma-s", "20", "--sigma-a", "0", "--g", "0", "--spp", "1e5", "--method",
        "stf", "--cache", out("cache"), "-o", out("o.h5")},
       20,
       1500},
  };
  if (has_plotting()) {
    runs.push_back({{"plot", out("t.h5"), "--alpha", "10", "-o", out("o.png")}, 20, 1200});
    runs.push_back({{"report", "--medium", "a:4:0.5:0.3", "-o", out("report")}, 20, 2000});
  }
  const fs::path scratch = dir_ / "scratch";
  fs::create_directories(scratch);
  std::mt19937 random(29);
  for (const Long& run : runs)
    for (int signal : {SIGINT, SIGTERM}) {
      const int ms = std::uniform_int_distribution<int>(run.from_ms, run.to_ms)(random);
      Result r = run_child(run.args, RLIM_INFINITY, ms, signal, scratch.string());
      const std::string what = run.args[0] + " " + run.args[1] + " with signal " +
                               std::to_string(signal) + " after " + std::to_string(ms) + " ms";
      EXPECT_TRUE(r.status == 128 + signal || r.status == 0)
          << what << ": status " << r.status << "\n"
          << r.err;
      if (r.status != 0) {
        EXPECT_EQ(r.err.find("TV <="), std::string::npos)
            << what << ": a result stated after the signal\n"
            << r.err;
        EXPECT_FALSE(fs::exists(out("o.h5")) || fs::exists(out("o.stfpack")) ||
                     fs::exists(out("report")))
            << what;
        EXPECT_FALSE(fs::exists(out("o.png"))) << what;
      }
      expect_no_litter(what);
      for (const char* name : {"o.h5", "o.png", "o.stfpack", "report"}) fs::remove_all(out(name));
    }
}

// One writer per output: a second stf writing the same file is refused at once, in one line,
// and the first finishes undisturbed.
TEST_F(Fault, ASecondWriterOfTheSameOutputIsRefused) {
  pid_t first = ::fork();
  if (first == 0) {
    int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, STDERR_FILENO);
    ::execl(STF_BINARY, STF_BINARY, "precompute", "--sigma-s", "50", "--sigma-a", "0", "--g", "0.5",
            "--grid", "healpix:2", "--alpha-bins", "6", "--paths", "1e6", "--quiet", "-o",
            out("t.h5").c_str(), nullptr);
    ::_exit(127);
  }
  for (int i = 0; i < 200 && !fs::exists(out("t.h5.lock")); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_TRUE(fs::exists(out("t.h5.lock")));
  Result second = stf(kTable + "-o " + out("t.h5"));
  EXPECT_EQ(second.status, 2) << second.err;
  EXPECT_EQ(std::count(second.err.begin(), second.err.end(), '\n'), 1) << second.err;
  EXPECT_NE(second.err.find("being written by another stf process"), std::string::npos)
      << second.err;
  // Through a symbolic link it is the same file.
  fs::create_symlink(out("t.h5"), out("link.h5"));
  EXPECT_EQ(stf(kTable + "-o " + out("link.h5")).status, 2);
  int status = 0;
  ::waitpid(first, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_EQ(stf::read_table(out("t.h5")).paths, 1000000);
  expect_no_litter("after both");
  // A lock file a killed process left is taken over.
  std::ofstream(out("u.h5.lock")) << "";
  EXPECT_EQ(stf(kTable + "-o " + out("u.h5")).status, 0);
  expect_no_litter("after a stale lock");
}

// Replaces row `bin` of a float64 dataset [bins, cells] by `value` everywhere.
void poke_row(const std::string& file, const char* dataset, hsize_t row, double value) {
  stf::test::forget_checksum(file);
  H5::H5File f(file, H5F_ACC_RDWR);
  H5::DataSet d = f.openDataSet(dataset);
  hsize_t dims[3] = {};
  const int rank = d.getSpace().getSimpleExtentDims(dims);
  std::vector<double> v(std::size_t(dims[0] * dims[1] * (rank == 3 ? dims[2] : 1)));
  d.read(v.data(), H5::PredType::NATIVE_DOUBLE);
  const std::size_t width = std::size_t(dims[rank - 1]);
  for (std::size_t c = 0; c < width; ++c) v[std::size_t(row) * width + c] = value;
  d.write(v.data(), H5::PredType::NATIVE_DOUBLE);
}

// /escape/weight is the table: an edit to it (or a NaN, a negative) is refused naming the
// datasets and the file, by every command that reads tables.
TEST_F(Fault, TablesWhoseDatasetsDisagreeAreRefused) {
  ASSERT_EQ(stf(kTable + "-o " + out("t.h5")).status, 0);
  struct Edit {
    const char* dataset;
    hsize_t row;
    double value;
    std::string names;
  };
  const std::vector<Edit> edits = {
      {"/escape/weight", 3, 1000, "/escape/weight and /escape/weight_half disagree"},
      {"/escape/weight", 4, std::nan(""), "/escape/weight holds a negative or non-finite"},
      {"/escape/weight", 2, -1, "/escape/weight holds a negative or non-finite"},
      {"/escape/weight_half", 1, -1, "/escape/weight_half holds a negative"}};
  for (const Edit& e : edits) {
    fs::copy_file(out("t.h5"), out("bad.h5"), fs::copy_options::overwrite_existing);
    poke_row(out("bad.h5"), e.dataset, e.row, e.value);
    for (const std::string& command : {"fit " + out("bad.h5") + " --model vmf:1 -o " + out("m.h5"),
                                       "eval " + out("bad.h5") + " --reference " + out("t.h5"),
                                       "merge " + out("bad.h5") + " -o " + out("m.h5")}) {
      Result r = stf(command);
      expect_one_line(r, e.names, command + " after editing " + e.dataset);
      EXPECT_NE(r.err.find("bad.h5"), std::string::npos) << r.err;
    }
  }
  // A missing dataset is named with its file.
  fs::copy_file(out("t.h5"), out("bad.h5"), fs::copy_options::overwrite_existing);
  {
    stf::test::forget_checksum(out("bad.h5"));
    H5::H5File f(out("bad.h5"), H5F_ACC_RDWR);
    f.unlink("/grid/solid_angle");
  }
  Result missing = stf("fit " + out("bad.h5") + " --model vmf:1 -o " + out("m.h5"));
  expect_one_line(missing, "bad.h5: missing dataset /grid/solid_angle", "missing dataset");
}

// Ranks that were started with different runs refuse together, before any work, in one line;
// commands that do not share work across ranks are refused under mpirun.
TEST_F(Fault, MpiRanksAgreeOnTheRunOrRefuse) {
  if (!have_mpi()) GTEST_SKIP() << "stf built without MPI, or no mpirun";
  const std::string b = STF_BINARY;
  auto mpi = [&](const std::string& line) {
    const std::string err = out("mpi_err.txt");
    int raw = std::system((line + " 2>'" + err + "' >/dev/null").c_str());
    // stf's own lines (mpirun adds a note of its own when a rank exits non-zero).
    std::istringstream all(bytes_of(err));
    std::string text;
    for (std::string line; std::getline(all, line);)
      if (line.rfind("stf", 0) == 0) text += line + "\n";
    fs::remove(err);
    return Result{WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw), text};
  };
  std::string run = kTable + "-o " + out("t.h5");
  std::string cmd = mpirun(1) + b + " " + run + " --seed 4 : -n 1 " + b + " " + run + " --seed 5";
  Result seeds = mpi(cmd);
  EXPECT_EQ(seeds.status, 2) << seeds.err;
  EXPECT_NE(seeds.err.find("different command lines"), std::string::npos) << seeds.err;
  EXPECT_FALSE(fs::exists(out("t.h5")));
  Result commands =
      mpi(mpirun(1) + b + " " + run + " : -n 1 " + b + " pack " + out("x") + " -o " + out("p"));
  EXPECT_EQ(commands.status, 2) << commands.err;
  ASSERT_EQ(stf(run).status, 0);
  Result fit = mpi(mpirun(2) + b + " fit " + out("t.h5") + " --model vmf:1 -o " + out("m.h5"));
  EXPECT_EQ(fit.status, 2);
  EXPECT_NE(fit.err.find("runs as one process"), std::string::npos) << fit.err;
  EXPECT_EQ(std::count(fit.err.begin(), fit.err.end(), '\n'), 1) << fit.err;  // once, not per rank
  Result bad = mpi(mpirun(2) + b + " precompute --sigma-s -1 --sigma-a 0 --g 0 -o " + out("u.h5"));
  EXPECT_EQ(bad.status, 2);
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  EXPECT_FALSE(fs::exists(out("m.h5")));
  // A rank without a checkpoint of its own (its share finished before the first save) is no
  // sign of a run on another number of ranks.
  std::ofstream(out("v.h5.rank-1-of-2.checkpoint")) << "damaged";
  Result resume = mpi(mpirun(2) + b + " " + kTable + "--resume -o " + out("v.h5"));
  EXPECT_EQ(resume.status, 2) << resume.err;  // rank 1's checkpoint is damaged
  EXPECT_EQ(resume.err.find("another number of MPI ranks"), std::string::npos) << resume.err;
  fs::remove(out("v.h5.rank-1-of-2.checkpoint"));
  expect_no_litter("mpi");
}

struct Misuse {
  std::string args;
  std::string names;  // the one stderr line must say it
};

// Each of these cost a user an afternoon: now one line, exit 2, nothing written.
TEST_F(Fault, SmallMisusesGetOneLine) {
  ASSERT_EQ(stf(kTable + "-o " + out("t.h5")).status, 0);
  ASSERT_EQ(stf("fit --quiet " + out("t.h5") + " --model vmf:1 -o " + out("m.h5")).status, 0);
  std::ofstream(out("scene.toml")) << kScene;
  std::ofstream(out("broken.toml")) << "[precompute\nsigma-s = 1\n";
  std::ofstream(out("empty.toml")) << "[precompute]\nsigma_s = \"\"\nsigma_a = 0.1\ng = 0\n";
  fs::create_directories(out("cache/sub"));
  const std::vector<Misuse> cases = {
      {"precompute --sigma-s '' --sigma-a 0.5 --g 0.3 -o " + out("x.h5"), "--sigma-s"},
      {"precompute --sigma-s 1 --sigma-a '' --g 0.3 -o " + out("x.h5"), "--sigma-a"},
      {"precompute --sigma-s 1 --sigma-a 0 --g '' -o " + out("x.h5"), "--g"},
      {"--config " + out("empty.toml") + " precompute -o " + out("x.h5"), "empty value"},
      {"--config " + out("broken.toml") + " precompute -o " + out("x.h5"),
       "broken.toml', line 1: not valid TOML"},
      {"plot " + out("t.h5") + " --alpha '' -o " + out("x.png"), "--alpha"},
      {"fit " + out("t.h5") + " --ablate '' -o " + out("x.h5"), "--ablate"},
      {"precompute --sigma-s 1 --sigma-a 0 --g 0 --shard 0/100000 --paths 1e4 -o " + out("x.h5"),
       "holds no paths"},
      {"fitt " + out("t.h5") + " -o " + out("x.h5"), "unknown command 'fitt'"},
      {"build " + out("scene.toml") + " --cache " + out("cache") + " -o " + out("cache/x.model.h5"),
       "inside the cache"},
      {"build " + out("scene.toml") + " --cache " + out("cache") + " -o " + out("cache/sub/x.stfpack"), "inside the cache"},
      {"build " + out("scene.toml") + " --json -o -", "--json and -o -"},
      {"report --medium n:1e300:0:0.5 -o " + out("rep"), "--medium"},
      {"report --medium :1:0:0.5 -o " + out("rep"), "NAME"},
      {"report --stress --medium n:1:0:0.5 -o " + out("rep"), "--stress"},
      {"sample " + out("m.h5") + " --count 4e9 -o " + out("x.h5"), "--count"},
      {"pack " + out("m.h5") + " " + out("m.h5") + " --name a --name a -o " + out("x.stfpack"),
       "one name"},
      {"precompute " + kTable.substr(11) + "--resume -o -", "--resume needs -o to name a file"},
  };
  for (const Misuse& c : cases) {
    Result r = stf(c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.names), std::string::npos) << c.args << "\n" << r.err;
  }
  for (const char* name : {"x.h5", "x.png", "x.stfpack", "rep", "cache/x.model.h5"})
    EXPECT_FALSE(fs::exists(out(name))) << name;
  expect_no_litter("misuse");
}

// sh:0 (the constant alone) fits and samples; an output of mode 600 stays 600; a table written
// to standard output leaves no checkpoint named '-'; a run of two ranks is not resumed by one.
TEST_F(Fault, CornersOfOutputsAndModels) {
  ASSERT_EQ(stf(kTable + "-o " + out("t.h5")).status, 0);
  Result sh0 = stf("fit --quiet " + out("t.h5") + " --model sh:0 -o " + out("sh0.h5"));
  ASSERT_EQ(sh0.status, 0) << sh0.err;
  EXPECT_EQ(stf("sample " + out("sh0.h5") + " --count 100 -o " + out("s.h5")).status, 0);
  EXPECT_EQ(stf("pack " + out("sh0.h5") + " --name '' -o " + out("p.stfpack")).status, 0);  // an entry without a name

  std::ofstream(out("scene.toml")) << kScene;
  std::ofstream(out("b.stfpack")) << "old";
  fs::permissions(out("b.stfpack"), fs::perms::owner_read | fs::perms::owner_write);
  ASSERT_EQ(stf("build --quiet " + out("scene.toml") + " --cache " + out("cache") + " -o " +
                out("b.stfpack"))
                .status,
            0);
  EXPECT_EQ(fs::status(out("b.stfpack")).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write);

  std::string table;
  Result piped = stf(kTable + "-o -", &table);
  EXPECT_EQ(piped.status, 0) << piped.err;
  EXPECT_EQ(table.substr(0, 13), "stf-checksum ");  // the user block
  EXPECT_EQ(table.substr(513, 3), "HDF");
  // An interrupted run to standard output keeps no checkpoint (it had nowhere to put one but
  // beside a file named '-' in the working folder).
  Result stopped = run_child({"precompute", "--sigma-s", "50", "--sigma-a", "0", "--g", "0.5", "--paths", "1e8",
                              "--quiet", "--checkpoint-seconds", "0.1", "-o", "-"},
                             RLIM_INFINITY, 1500);
  EXPECT_EQ(stopped.status, 130) << stopped.err;
  EXPECT_FALSE(fs::exists("-.checkpoint"));

  // Scratch files a kill -9 left (of a process that no longer runs) go with the next one made.
  const fs::path scratch = dir_ / "scratch";
  fs::create_directories(scratch);
  std::ofstream((scratch / "stf-4194399-AbCdEf").string()) << "left";
  EXPECT_EQ(run_child({"sample", out("sh0.h5"), "--count", "10", "-o", "-"}, RLIM_INFINITY, -1,
                      SIGINT, scratch.string())
                .status,
            0);
  EXPECT_TRUE(fs::is_empty(scratch));

  // So do the temporaries of a killed run's output and checkpoint.
  std::ofstream(out("v.h5.tmp-4194399")) << "left";
  std::ofstream(out("v.h5.checkpoint.tmp-4194399")) << "left";
  ASSERT_EQ(stf(kTable + "-o " + out("v.h5")).status, 0);
  EXPECT_FALSE(fs::exists(out("v.h5.tmp-4194399")));
  EXPECT_FALSE(fs::exists(out("v.h5.checkpoint.tmp-4194399")));

  std::ofstream(out("u.h5.rank-0-of-2.checkpoint")) << "x";
  Result one = stf(kTable + "--resume -o " + out("u.h5"));
  EXPECT_EQ(one.status, 2);
  EXPECT_NE(one.err.find("another number of MPI ranks"), std::string::npos) << one.err;
}

// A FIFO with no reader: the first Ctrl-C ends the wait.
TEST_F(Fault, AFifoWithoutAReaderYieldsToTheFirstCtrlC) {
  ASSERT_EQ(::mkfifo(out("fifo").c_str(), 0644), 0);
  Result r =
      run_child({"precompute", "--sigma-s", "2", "--sigma-a", "0.5", "--g", "0.3", "--alpha-bins",
                 "6", "--grid", "healpix:2", "--paths", "2000", "--quiet", "-o", out("fifo")},
                RLIM_INFINITY, 1500);
  EXPECT_EQ(r.status, 130) << r.err;
}

// An input that is a FIFO is refused at once, never waited on (a pack, a model, a table).
TEST_F(Fault, AFifoAsAnInputIsRefusedWithoutWaiting) {
  ASSERT_EQ(::mkfifo(out("stuck.h5").c_str(), 0644), 0);
  for (const std::string& args : {"fit " + out("stuck.h5") + " --model vmf:1 -o " + out("m.h5"),
                                  "sample " + out("stuck.h5") + " --count 10 -o " + out("s.h5")})
    expect_one_line(stf(args), "not a regular file", args);
  EXPECT_FALSE(fs::exists(out("m.h5")));
  EXPECT_FALSE(fs::exists(out("s.h5")));
  expect_no_litter("after a FIFO as input");
}

}  // namespace
