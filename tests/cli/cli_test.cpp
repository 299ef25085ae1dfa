// The `stf` command line as users and scripts see it: bad input gets one line naming the
// option and leaves no file; interruption leaves nothing half-written; plots render.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <functional>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "cli_fixture.h"
#include "stf/core/h5io.h"
#include "stf/core/table.h"


namespace {


TEST_F(Cli, ValidRunWritesAContractTable) {
  Result r = stf("precompute " + kGood + " --seed 9 -o " + out("t.h5"));
  ASSERT_EQ(r.status, 0) << r.err;
  stf::Table t = stf::read_table(out("t.h5"));
  EXPECT_EQ(t.paths, 2000);
  EXPECT_EQ(t.seed, 9);
  EXPECT_EQ(t.grid, "healpix:2");
  EXPECT_EQ(t.escaped_weight + t.absorbed_weight + t.truncated_weight, 2000);
  EXPECT_EQ(files(), std::vector<std::string>{"t.h5"});
}

TEST_F(Cli, ExponentNotationForCounts) {
  Result r = stf("precompute --sigma-s 1 --sigma-a 0 --g 0 --paths 2e3 --seed 1e1 --alpha-bins 4 "
                 "--grid csc:2 --quiet -o " + out("t.h5"));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(stf::read_table(out("t.h5")).paths, 2000);
  EXPECT_EQ(stf::read_table(out("t.h5")).seed, 10);
}

struct BadInput {
  std::string args;
  std::string option;  // the stderr line must name it
};

TEST_F(Cli, BadInputGetsOneLineNamingTheOptionAndNoFile) {
  const std::string medium = "--sigma-s 1 --sigma-a 0 --g 0 --paths 100 --quiet";
  const BadInput cases[] = {
      {"--sigma-s -1 --sigma-a 0 --g 0", "--sigma-s"},
      {"--sigma-s nan --sigma-a 0 --g 0", "--sigma-s"},
      {"--sigma-s 1 --sigma-a -0.5 --g 0", "--sigma-a"},
      {"--sigma-s 1 --sigma-a nan --g 0", "--sigma-a"},
      {"--sigma-s 1 --sigma-a inf --g 0", "--sigma-a"},
      {"--sigma-s 1 --sigma-a 0 --g 1", "--g"},
      {"--sigma-s 1 --sigma-a 0 --g -1", "--g"},
      {"--sigma-s 1 --sigma-a 0 --g 1.5", "--g"},
      {"--sigma-s 1 --sigma-a 0 --g nan", "--g"},
      {"--sigma-s 1 --sigma-a 0 --g 0 --radius 0", "--radius"},
      {"--sigma-s 1 --sigma-a 0 --g 0 --radius -2", "--radius"},
      {"--sigma-s 0 --sigma-a 0 --g 0", "--sigma-s"},
      {medium + " --paths 0", "--paths"},
      {medium + " --paths -5", "--paths"},
      {medium + " --paths 1.5", "--paths"},
      {medium + " --paths lots", "--paths"},
      {medium + " --grid csc:0", "--grid"},
      {medium + " --grid healpix:3", "--grid"},
      {medium + " --grid hexagons:4", "--grid"},
      {medium + " --alpha-bins 0", "--alpha-bins"},
      {medium + " --max-scatter -2", "--max-scatter"},
      {medium + " --threads -1", "--threads"},
      {"--sigma-a 0 --g 0", "--sigma-s"},
      {medium + " --bogus 3", "--bogus"},
  };
  for (const BadInput& c : cases) {
    Result r = stf("precompute " + c.args + " -o " + out("t.h5"));
    EXPECT_NE(r.status, 0) << c.args;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.option), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_TRUE(files().empty()) << c.args;
  }
}

TEST_F(Cli, UnwritableOutputIsRejectedBeforeWalking) {
  Result r = stf("precompute " + kGood + " -o /nonexistent-folder/t.h5");
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("-o"), std::string::npos) << r.err;
}

// Ctrl-C during a long walk: non-zero exit, no output and no temporary file, and an existing
// file at the output path is left as it was.
TEST_F(Cli, InterruptLeavesNothingHalfWrittenAndKeepsTheOldFile) {
  ASSERT_EQ(stf("precompute " + kGood + " -o " + out("t.h5")).status, 0);
  auto before = fs::file_size(out("t.h5"));
  pid_t pid = ::fork();
  if (pid == 0) {
    ::execl(STF_BINARY, STF_BINARY, "precompute", "--sigma-s", "200", "--sigma-a", "0", "--g", "0",
            "--paths", "1e8", "--quiet", "-o", out("t.h5").c_str(), (char*)nullptr);
    ::_exit(127);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_NE(WEXITSTATUS(status), 0);
  EXPECT_EQ(files(), std::vector<std::string>{"t.h5"});
  EXPECT_EQ(fs::file_size(out("t.h5")), before);
  EXPECT_EQ(stf::read_table(out("t.h5")).paths, 2000);
}

TEST_F(Cli, InterruptedFitAndBuildLeaveNothingHalfWritten) {
  ASSERT_EQ(stf("precompute --sigma-s 10 --sigma-a 0 --g 0.5 --grid csc:30 --paths 3e5 --quiet -o " + out("t.h5")).status, 0);
  EXPECT_NE(interrupt_after({"fit", out("t.h5"), "--model", "vmf:8", "--quiet", "-o", out("m.h5")}, 400), 0);
  EXPECT_EQ(files(), std::vector<std::string>{"t.h5"});

  std::ofstream(out("scene.toml")) << "[settings]\npaths = 1e7\n[[media]]\nname = \"m\"\nsigma_s = 20.0\n"
                                      "sigma_a = 0.0\ng = 0.0\nradius_min = 0.5\nradius_max = 1.0\n";
  EXPECT_NE(interrupt_after({"build", out("scene.toml"), "--quiet", "--cache", out("cache"), "-o", out("s.stfpack")}, 500), 0);
  for (const auto& e : fs::recursive_directory_iterator(dir_)) {
    std::string name = e.path().filename().string();
    EXPECT_EQ(name.find(".tmp-"), std::string::npos) << name;
    EXPECT_NE(name, "s.stfpack");
  }
}

TEST_F(Cli, HelpAndVersion) {
  EXPECT_EQ(stf("--help").status, 0);
  EXPECT_EQ(stf("precompute --help").status, 0);
  EXPECT_EQ(stf("plot --help").status, 0);
  EXPECT_EQ(stf("--version").status, 0);
  EXPECT_NE(stf("").status, 0);
}

TEST_F(Cli, FitAndEvalProduceModelAndJson) {
  const std::string medium = "precompute --sigma-s 2 --sigma-a 0.5 --g 0.3 --alpha-bins 6 --grid healpix:2 --quiet ";
  ASSERT_EQ(stf(medium + "--paths 20000 -o " + out("t.h5")).status, 0);
  ASSERT_EQ(stf(medium + "--paths 80000 --seed 2 -o " + out("ref.h5")).status, 0);
  Result fit = stf("fit " + out("t.h5") + " --model vmf:2 --quiet --report " + out("fit.json") + " -o " + out("m.h5"));
  ASSERT_EQ(fit.status, 0) << fit.err;
  Result eval = stf("eval " + out("m.h5") + " --reference " + out("ref.h5") + " --json " + out("e.json"));
  ASSERT_EQ(eval.status, 0) << eval.err;
  std::ifstream json(out("e.json"));
  std::string text((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  for (const char* key : {"\"tv_distance\"", "\"kl_divergence\"", "\"per_alpha\"", "\"model_bytes\""})
    EXPECT_NE(text.find(key), std::string::npos) << key;
  EXPECT_EQ(stf("eval " + out("t.h5") + " --reference " + out("ref.h5") + " --json " + out("raw.json")).status, 0);
}

// --cells: the candidate's exit distribution in the reference's layout, a distribution (it sums
// to 1) whose TV from the reference's is the joint TV that eval reports.
TEST_F(Cli, EvalCellsHoldTheCandidateInTheReferenceLayout) {
  const std::string medium = "precompute --sigma-s 2 --sigma-a 0.5 --g 0.3 --alpha-bins 6 --grid healpix:2 --quiet ";
  ASSERT_EQ(stf(medium + "--paths 20000 -o " + out("t.h5")).status, 0);
  ASSERT_EQ(stf(medium + "--paths 80000 --seed 2 -o " + out("ref.h5")).status, 0);
  ASSERT_EQ(stf("fit " + out("t.h5") + " --model hvmf:2 --quiet -o " + out("m.h5")).status, 0);
  const stf::Table reference = stf::read_table(out("ref.h5"));
  std::vector<double> q = reference.weight();
  double escaped = 0;
  for (double w : q) escaped += w;
  for (const char* candidate : {"m.h5", "t.h5"}) {
    Result eval = stf("eval " + out(candidate) + " --reference " + out("ref.h5") + " --json " + out("e.json") +
                      " --cells " + out("c.h5"));
    ASSERT_EQ(eval.status, 0) << eval.err;
    std::ifstream in(out("e.json"));
    const std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string key = "\"joint_tv_distance\": ";
    const double joint_tv = std::stod(json.substr(json.find(key) + key.size()));
    H5::H5File f(out("c.h5"), H5F_ACC_RDONLY);
    EXPECT_EQ(stf::h5::get_string(f, "format"), "stf-cells");
    const std::vector<double> p = stf::h5::get_dataset(f, "/escape/probability", {6, 48});
    EXPECT_EQ(stf::h5::get_dataset(f, "/escape/alpha_edges", {7}), reference.alpha_edges);
    EXPECT_EQ(stf::h5::dataset_shape(f, "/grid/direction"), (std::vector<hsize_t>{48, 3}));
    double total = 0, tv = 0;
    for (std::size_t i = 0; i < p.size(); ++i) total += p[i], tv += 0.5 * std::abs(p[i] - q[i] / escaped);
    EXPECT_NEAR(total, 1, 1e-9) << candidate;
    EXPECT_NEAR(tv, joint_tv, 1e-8) << candidate;
    EXPECT_GT(tv, 0) << candidate;
  }
}

// A sparse forward-scattering table: hvmf:auto tries neighbour pooling and says what it chose
// in the report; --ablate pooling fits every bin alone and the report has no pooling scores.
TEST_F(Cli, FitReportsNeighbourPoolingAndAblatingItTurnsItOff) {
  ASSERT_EQ(stf("precompute --sigma-s 4.275 --sigma-a 0.225 --g 0.9 --alpha-bins 18 --grid healpix:4 --quiet "
                "--paths 20000 -o " + out("t.h5")).status, 0);
  auto report = [&](const std::string& extra, const std::string& name) {
    Result fit = stf("fit " + out("t.h5") + " --model hvmf:auto --quiet " + extra + " --report " + out(name) + " -o " +
                     out(name + ".h5"));
    EXPECT_EQ(fit.status, 0) << fit.err;
    std::ifstream json(out(name));
    return std::string((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  };
  const std::string pooled = report("", "pooled.json"), alone = report("--ablate pooling", "alone.json");
  EXPECT_NE(pooled.find("\"neighbour_weight\": 0.5"), std::string::npos) << pooled.substr(0, 600);
  EXPECT_NE(pooled.find("\"pool_heldout_nll\""), std::string::npos);
  EXPECT_EQ(alone.find("\"pool_heldout_nll\""), std::string::npos) << alone.substr(0, 600);
}

// Without --model, stf fit fits what scenes and render use: auto, hemispherical lobes at their
// held-out size.
TEST_F(Cli, FitWithoutModelFitsAuto) {
  ASSERT_EQ(stf("precompute --sigma-s 4.275 --sigma-a 0.225 --g 0.5 --alpha-bins 9 --grid healpix:4 --quiet "
                "--paths 20000 -o " + out("t.h5")).status, 0);
  Result fit = stf("fit " + out("t.h5") + " --quiet --report " + out("r.json") + " -o " + out("m.h5"));
  ASSERT_EQ(fit.status, 0) << fit.err;
  std::ifstream json(out("r.json"));
  const std::string report((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_NE(report.find("\"model\": \"auto\""), std::string::npos) << report.substr(0, 300);
  EXPECT_NE(report.find("\"family\": \"hvmf\""), std::string::npos) << report.substr(0, 300);
  EXPECT_NE(report.find("\"candidates\""), std::string::npos) << report.substr(0, 300);
}

// --tolerance: a certified model with fewer or equal alpha bins, evaluable against the
// reference's bins, its bound and verdict stored with it.
TEST_F(Cli, FitToToleranceCertifiesOnTheHeldOutTable) {
  const std::string medium = "precompute --sigma-s 4 --sigma-a 0.01 --g 0.7 --alpha-bins 12 --grid healpix:4 --quiet ";
  ASSERT_EQ(stf(medium + "--paths 1e5 -o " + out("t.h5")).status, 0);
  ASSERT_EQ(stf(medium + "--paths 1e5 --seed 2 -o " + out("h.h5")).status, 0);
  ASSERT_EQ(stf(medium + "--paths 1e6 --seed 3 -o " + out("ref.h5")).status, 0);
  Result fit = stf("fit " + out("t.h5") + " --model vmf:auto --tolerance 0.3 --heldout " + out("h.h5") + " -o " + out("m.h5"));
  ASSERT_EQ(fit.status, 0) << fit.err;
  EXPECT_NE(fit.err.find("TV <="), std::string::npos) << fit.err;
  EXPECT_NE(fit.err.find("(within 0.3)"), std::string::npos) << fit.err;
  Result eval = stf("eval " + out("m.h5") + " --reference " + out("ref.h5") + " --json " + out("e.json"));
  ASSERT_EQ(eval.status, 0) << eval.err;
  std::ifstream json(out("e.json"));
  std::string text((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"joint_tv_distance\""), std::string::npos);
}

TEST_F(Cli, FitAndEvalRejectBadInput) {
  ASSERT_EQ(stf("precompute " + kGood + " -o " + out("t.h5")).status, 0);
  ASSERT_EQ(stf("precompute --sigma-s 1 --sigma-a 0 --g 0 --alpha-bins 5 --grid healpix:2 --paths 100 --quiet -o " +
                out("other.h5")).status, 0);
  ASSERT_EQ(stf("precompute --sigma-s 3 --sigma-a 0.5 --g 0.3 --alpha-bins 6 --grid healpix:2 --paths 100 --seed 2 "
                "--quiet -o " + out("denser.h5")).status, 0);
  const BadInput cases[] = {
      {"fit " + out("t.h5") + " --model vmf:0 -o " + out("m.h5"), "--model"},
      {"fit " + out("t.h5") + " --model gauss:3 -o " + out("m.h5"), "--model"},
      {"fit " + out("t.h5") + " --model hvmf:auto --ablate turn,blend,spin -o " + out("m.h5"), "--ablate"},
      {"fit " + out("missing.h5") + " -o " + out("m.h5"), "missing.h5"},
      {"fit " + out("t.h5") + " -o /nonexistent-folder/m.h5", "-o"},
      {"eval " + out("t.h5") + " --reference " + out("other.h5"), "--reference"},
      {"eval " + out("t.h5") + " --reference " + out("other.h5") + " --cells " + out("m.h5"), "--reference"},
      {"eval " + out("t.h5") + " --reference " + out("t.h5") + " --cells -", "--cells"},
      {"fit " + out("t.h5") + " --tolerance 0.1 -o " + out("m.h5"), "--heldout"},
      {"fit " + out("t.h5") + " --tolerance 1.5 --heldout " + out("t.h5") + " -o " + out("m.h5"), "--tolerance"},
      {"fit " + out("t.h5") + " --tolerance 0.1 --heldout " + out("t.h5") + " -o " + out("m.h5"), "--heldout"},
      {"fit " + out("t.h5") + " --tolerance 0.1 --heldout " + out("other.h5") + " -o " + out("m.h5"), "--heldout"},
      {"fit " + out("t.h5") + " --tolerance 0.1 --heldout " + out("denser.h5") + " -o " + out("m.h5"), "--heldout"},
  };
  for (const BadInput& c : cases) {
    Result r = stf(c.args);
    EXPECT_NE(r.status, 0) << c.args;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.option), std::string::npos) << c.args << "\n" << r.err;
  }
  auto names = files();
  EXPECT_EQ(std::count(names.begin(), names.end(), std::string("m.h5")), 0);
  for (const std::string& name : names) EXPECT_EQ(name.find(".tmp-"), std::string::npos) << name;
}

// stf sample's output layout (docs/formats.md, "Samples"), and --eval giving back the same pdfs.
TEST_F(Cli, PackSampleAndEvalFollowTheContract) {
  const std::string medium = "precompute --sigma-s 3 --sigma-a 0.3 --g 0.5 --alpha-bins 9 --grid healpix:4 --quiet ";
  ASSERT_EQ(stf(medium + "--paths 20000 -o " + out("t.h5")).status, 0);
  ASSERT_EQ(stf("fit " + out("t.h5") + " --model vmf:2 --quiet -o " + out("m.h5")).status, 0);
  ASSERT_EQ(stf("pack " + out("m.h5") + " --name milk -o " + out("m.stfpack")).status, 0);
  for (const char* model : {"m.h5", "m.stfpack"}) {
    Result r = stf("sample " + out(model) + " --count 500 --seed 3 -o " + out("s.h5"));
    ASSERT_EQ(r.status, 0) << r.err;
    H5::H5File f(out("s.h5"), H5F_ACC_RDONLY);
    EXPECT_EQ(stf::h5::dataset_shape(f, "/samples/exit_point"), (std::vector<hsize_t>{500, 3}));
    EXPECT_EQ(stf::h5::dataset_shape(f, "/samples/exit_direction"), (std::vector<hsize_t>{500, 3}));
    EXPECT_EQ(stf::h5::dataset_shape(f, "/samples/pdf"), (std::vector<hsize_t>{500}));
    EXPECT_GT(stf::h5::get_double(f, "escape_probability"), 0);
    Result e = stf("sample " + out(model) + " --eval " + out("s.h5") + " -o " + out("e.h5"));
    ASSERT_EQ(e.status, 0) << e.err;
    H5::H5File g(out("e.h5"), H5F_ACC_RDONLY);
    std::vector<double> drawn = stf::h5::get_dataset(f, "/samples/pdf", {}), evaluated = stf::h5::get_dataset(g, "/samples/pdf", {});
    std::vector<std::int32_t> component = stf::h5::get_int_dataset(f, "/samples/component", {500});
    // The smooth part's samples: equal but for rounding of the stored directions (relative
    // 1e-6). The singular ones carry their discrete probability, which --eval (a density) does
    // not give: the uncollided delta e^{-tau} of the escapes, exactly; the once-scattered part
    // leaves in the plane of +z and its exit point.
    std::vector<double> point = stf::h5::get_dataset(f, "/samples/exit_point", {}),
                        direction = stf::h5::get_dataset(f, "/samples/exit_direction", {});
    int uncollided = 0, once = 0;
    for (std::size_t i = 0; i < drawn.size(); ++i) {
      if (component[i] == 1) {
        ++uncollided;
        EXPECT_NEAR(drawn[i], std::exp(-3.3) / stf::h5::get_double(f, "escape_probability"), 1e-6 * drawn[i]);
        continue;
      }
      if (component[i] == 2) {
        ++once;
        const double* y = &point[3 * i];
        const double* w = &direction[3 * i];
        EXPECT_NEAR(y[1] * w[0] - y[0] * w[1], 0, 1e-6) << "off the plane of +z and the exit point";
        continue;
      }
      EXPECT_EQ(component[i], 0);
      EXPECT_NEAR(evaluated[i], drawn[i], 1e-6 * drawn[i]);
    }
    EXPECT_GT(uncollided, 0);
    EXPECT_GT(once, 0);
  }
  Result bad = stf("sample " + out("t.h5") + " --count 10 -o " + out("x.h5"));
  EXPECT_NE(bad.status, 0);
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  Result zero = stf("sample " + out("m.h5") + " --count 0 -o " + out("x.h5"));
  EXPECT_NE(zero.err.find("--count"), std::string::npos) << zero.err;
}

// The default scene's plan: stdout is JSON with shared, skipped and (after a build) cached
// entries and their reasons; a bad scene gets one line with file, line and key.
TEST_F(Cli, BuildPlansTheDefaultScene) {
  const std::string scene = std::string(STF_SOURCE_DIR) + "/data/scenes/default.toml";
  std::string json;
  Result r = stf("build " + scene + " --plan-only --json --cache " + out("cache"), &json);
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json plan = nlohmann::json::parse(json);
  auto any = [&](const std::function<bool(const nlohmann::json&)>& is) {
    return std::any_of(plan["entries"].begin(), plan["entries"].end(), is);
  };
  EXPECT_TRUE(any([](const nlohmann::json& e) { return e["action"] == "skip" && !e["reason"].get<std::string>().empty(); }));
  EXPECT_TRUE(any([](const nlohmann::json& e) { return e["media"] == nlohmann::json{"haze"}; }));
  EXPECT_TRUE(any([](const nlohmann::json& e) { return e["media"] == nlohmann::json{"cloud_small", "cloud_large"}; }));
  EXPECT_EQ(json.front(), '{');
  EXPECT_EQ(json.find("stf build"), std::string::npos);  // logs stay on stderr

  std::ofstream(out("bad.toml")) << "[[media]]\nname = \"m\"\nsigma_s = 1.0\nsigma_a = 0.0\ng = 2.0\nsize = 1.0\n";
  Result bad = stf("build " + out("bad.toml") + " --plan-only");
  EXPECT_NE(bad.status, 0);
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  EXPECT_NE(bad.err.find("bad.toml:5: media[0].g"), std::string::npos) << bad.err;
}

bool have_matplotlib() {
  return std::system("/usr/bin/python3 -c 'import matplotlib, h5py' >/dev/null 2>&1") == 0;
}

TEST_F(Cli, ReportWritesPlotsJsonAndSummary) {
  if (!have_matplotlib()) GTEST_SKIP() << "Debian's python3-matplotlib / python3-h5py not installed";
  Result r = stf("report --medium dense:6:0.1:0.5 -o " + out("report"));
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* f : {"report.md", "report.json", "error_vs_runtime.png", "bytes_vs_error.png", "runtime_studies.png"})
    EXPECT_TRUE(fs::exists(dir_ / "report" / f)) << f;
  std::ifstream md(out("report/report.md"));
  std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("Error against run time"), std::string::npos);
  EXPECT_NE(text.find("thesis Fig. 4.7"), std::string::npos);
  EXPECT_NE(text.find("**dense: tau 6.1, albedo 0.9836, g 0.5**"), std::string::npos) << text;
  EXPECT_EQ(text.find("** tau"), std::string::npos) << text;
  Result bad = stf("report --medium dense:6:0.1:1.5 -o " + out("r2"));
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.err.find("--medium"), std::string::npos) << bad.err;
}

TEST_F(Cli, PlotDrawsCscAndHealpixSideBySide) {
  if (!have_matplotlib()) GTEST_SKIP() << "Debian's python3-matplotlib / python3-h5py not installed";
  ASSERT_EQ(stf("precompute --sigma-s 5 --sigma-a 0 --g 0.5 --grid csc:9 --alpha-bins 18 --paths 2e4 "
                "--quiet -o " + out("csc.h5")).status, 0);
  ASSERT_EQ(stf("precompute --sigma-s 5 --sigma-a 0 --g 0.5 --grid healpix:4 --alpha-bins 18 "
                "--paths 2e4 --quiet -o " + out("hpx.h5")).status, 0);
  Result r = stf("plot " + out("csc.h5") + " " + out("hpx.h5") + " --alpha 30 --width 128 -o " +
                 out("pair.png"));
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream png(out("pair.png"), std::ios::binary);
  char magic[8] = {};
  png.read(magic, 8);
  EXPECT_EQ(std::string(magic + 1, 3), "PNG");
  EXPECT_EQ(files().size(), 3u);  // the two tables and the plot; no temporary data left

  Result bad = stf("plot " + out("csc.h5") + " --alpha 200 -o " + out("x.png"));
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.err.find("--alpha"), std::string::npos);
}

}  // namespace
