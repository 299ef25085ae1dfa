// `stf report`: error against run time and the run-time studies (tools/report.py draws them),
// or with --stress the stiff and extreme sweep as a table.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sys/stat.h>

#include "cli.h"
#include "stf/core/files.h"
#include "stf/precompute/precompute.h"
#include "stf/pack.h"
#include "stf/scene/stress.h"

namespace stf::cli {

namespace {

struct ReportOptions {
  std::string pack, output;
  std::vector<std::string> media;
  bool full = false, stress = false;
  int max_media = 2;
  std::string threads = "0";
};

std::string self_path() {
  char buf[4096];
  ssize_t n = ::readlink("/proc/self/exe", buf, sizeof buf - 1);
  return n > 0 ? std::string(buf, std::size_t(n)) : "stf";
}


// "name:sigma_s:sigma_a:g" -> JSON object.
nlohmann::ordered_json medium_json(const std::string& spec) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (std::size_t colon; (colon = spec.find(':', start)) != std::string::npos; start = colon + 1)
    parts.push_back(spec.substr(start, colon - start));
  parts.push_back(spec.substr(start));
  if (parts.size() != 4) fail("--medium must be NAME:SIGMA_S:SIGMA_A:G, got '" + spec + "'");
  if (parts[0].empty() || parts[0].find_first_of("\"\\") != std::string::npos)
    fail("--medium '" + spec + "': the NAME must be a non-empty name without quotes or backslashes");
  try {
    std::size_t used[3] = {};
    double s = std::stod(parts[1], &used[0]), a = std::stod(parts[2], &used[1]), g = std::stod(parts[3], &used[2]);
    if (used[0] != parts[1].size() || used[1] != parts[2].size() || used[2] != parts[3].size())
      throw std::invalid_argument("not a number");
    if (!(s >= 0 && a >= 0 && s + a > 0 && s + a <= kMaxTau && g > -1 && g < 1)) throw std::invalid_argument("range");
    return {{"name", parts[0]}, {"sigma_s", s}, {"sigma_a", a}, {"g", g}};
  } catch (const std::exception&) {
    fail("--medium '" + spec + "': need numbers sigma_s, sigma_a >= 0 (not both 0, their sum at most 1e7: a unit-radius medium) and g in (-1, 1)");
  }
}

// The pack's media as unit-radius media, at most `n`: for each medium name its entry of the
// largest tau (the sphere a renderer uses deep inside, where stepping pays off most).
nlohmann::ordered_json pack_media(const std::string& path, int n) {
  std::vector<PackEntry> entries;
  std::string error;
  if (!read_pack_file(path, entries, error)) fail(path + ": " + error);
  std::vector<const PackEntry*> chosen;
  for (const PackEntry& e : entries) {
    auto same = std::find_if(chosen.begin(), chosen.end(), [&](const PackEntry* c) { return c->name == e.name; });
    if (same == chosen.end()) chosen.push_back(&e);
    else if (e.model.tau > (*same)->model.tau) *same = &e;
  }
  if (chosen.empty()) fail(path + ": the pack holds no model");
  // The entry's own name, empty where the pack has none (tools/report.py heads each medium with
  // its name, if any, and its tau, albedo and g); no spec string, so any name passes through.
  nlohmann::ordered_json media = nlohmann::ordered_json::array();
  for (const PackEntry* e : chosen) {
    if (int(media.size()) == n) break;
    const StfModel& m = e->model;
    media.push_back({{"name", e->name}, {"sigma_s", m.albedo * m.tau}, {"sigma_a", (1 - m.albedo) * m.tau}, {"g", m.g}});
  }
  return media;
}

// A report folder filled as a whole: files are made in a working folder beside it and moved
// in by commit(); on failure or Ctrl-C the working folder goes and `folder` is left as it was.
class ReportFolder {
 public:
  explicit ReportFolder(std::string folder) : folder_(std::move(folder)) {
    while (folder_.size() > 1 && folder_.back() == '/') folder_.pop_back();
    struct stat st;
    if (::stat(folder_.c_str(), &st) == 0 && !S_ISDIR(st.st_mode))
      fail("-o '" + folder_ + "' exists and is not a folder");
    work_ = folder_ + ".tmp-" + std::to_string(::getpid());
    if (::mkdir(work_.c_str(), 0755) != 0)
      fail("-o '" + folder_ + "': cannot create a folder beside it: " + std::strerror(errno));
  }
  ~ReportFolder() {
    std::error_code ignored;
    std::filesystem::remove_all(work_, ignored);
  }
  const std::string& work() const { return work_; }
  void commit() {
    stop_if_interrupted();
    namespace fs = std::filesystem;
    std::error_code error;
    fs::create_directories(folder_, error);
    if (error) fail("-o '" + folder_ + "': " + error.message());
    for (const fs::directory_entry& e : fs::directory_iterator(work_)) {
      fs::rename(e.path(), fs::path(folder_) / e.path().filename(), error);
      if (error) fail("-o '" + folder_ + "': cannot move " + e.path().filename().string() + " in: " + error.message());
    }
  }

 private:
  std::string folder_, work_;
};

void run_stress(const ReportOptions& o) {
  const int threads = int(parse_count(o.threads, "--threads", 0, 4096));
  std::optional<ReportFolder> folder;
  if (!o.output.empty()) folder.emplace(o.output);
  std::string table = scene::stress_table_header() + "\n";
  std::printf("%s\n", scene::stress_table_header().c_str());
  int failed = 0;
  for (const scene::StressCase& c : scene::stress_cases()) {
    stop_if_interrupted();
    scene::StressResult r = scene::run_stress_case(c, 400, 20000, threads);
    failed += !r.finite;
    std::printf("%s\n", scene::stress_table_row(r).c_str());
    std::fflush(stdout);
    table += scene::stress_table_row(r) + "\n";
  }
  if (failed) fail(std::to_string(failed) + " stress cases produced non-finite numbers");
  if (folder) {
    write_durably(folder->work() + "/stress.md",
                  "# Stiff and extreme sweep (400 paths, at most 20000 collisions each)\n\n```\n" + table + "```\n",
                  "-o '" + o.output + "' (stress.md)");
    folder->commit();
  }
}

void run_report(const ReportOptions& o) {
  if (o.stress && (!o.media.empty() || !o.pack.empty() || o.full))
    fail("--stress runs its own fixed sweep; it takes no pack, --medium or --full");
  if (o.stress) return run_stress(o);
  if (o.max_media < 1) fail("--max-media must be at least 1, got " + std::to_string(o.max_media));
  if (o.output.empty()) fail("-o must name the report folder");
  if (o.output == "-" || written_in_place(o.output))
    fail("-o '" + o.output + "': a report is a folder of several files, not a stream or a device");
  nlohmann::ordered_json media = nlohmann::ordered_json::array();
  if (!o.pack.empty()) media = pack_media(o.pack, o.max_media);
  for (const std::string& m : o.media) media.push_back(medium_json(m));
  if (media.empty()) fail("give a pack or --medium NAME:SIGMA_S:SIGMA_A:G");
  refuse_same_file(o.output, "-o", {{o.pack, "the pack"}});
  ReportFolder folder(o.output);
  const std::string list = folder.work() + "/media.json";
  write_durably(list, media.dump(2) + "\n", "-o '" + o.output + "' (media.json)");
  std::vector<std::string> args{"--stf", self_path(), "--media", list, "--out", folder.work()};
  if (o.full) args.push_back("--full");
  run_python("report.py", args, "report");
  folder.commit();
}

}  // namespace

void add_report_command(CLI::App& app) {
  auto o = std::make_shared<ReportOptions>();
  CLI::App* cmd = app.add_subcommand("report", "Error against run time and run-time studies (PNG, JSON, markdown), or --stress");
  cmd->add_option("pack", o->pack, "A scene's pack: its first media, each at its largest tau, are studied")->check(CLI::ExistingFile);
  cmd->add_option("--medium", o->media, "NAME:SIGMA_S:SIGMA_A:G of a unit-radius medium to study (repeatable)");
  cmd->add_option("--max-media", o->max_media, "Entries of the pack to study")->capture_default_str();
  cmd->add_flag("--full", o->full, "1e4..1e7 paths, a 1e8-path reference and 90 alpha bins (long)");
  cmd->add_flag("--stress", o->stress, "Run the stiff and extreme sweep and print it as a table");
  cmd->add_option("--threads", o->threads, "Worker threads for --stress (0: all cores)")->capture_default_str();
  cmd->add_option("-o,--output", o->output, "Report folder");
  cmd->callback([o] { run_report(*o); });
}

}  // namespace stf::cli
