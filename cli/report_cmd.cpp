// `stf report`: error against run time and the run-time studies (tools/report.py draws them),
// or with --stress the stiff and extreme sweep as a table.
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sys/stat.h>

#include "cli.h"
#include "stf/pack.h"
#include "stress.h"

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
std::string medium_json(const std::string& spec) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (std::size_t colon; (colon = spec.find(':', start)) != std::string::npos; start = colon + 1)
    parts.push_back(spec.substr(start, colon - start));
  parts.push_back(spec.substr(start));
  if (parts.size() != 4) fail("--medium must be NAME:SIGMA_S:SIGMA_A:G, got '" + spec + "'");
  char buf[512];
  try {
    double s = std::stod(parts[1]), a = std::stod(parts[2]), g = std::stod(parts[3]);
    if (!(s >= 0 && a >= 0 && s + a > 0 && g > -1 && g < 1)) throw std::invalid_argument("range");
    std::snprintf(buf, sizeof buf, "{\"name\": \"%s\", \"sigma_s\": %.17g, \"sigma_a\": %.17g, \"g\": %.17g}",
                  parts[0].c_str(), s, a, g);
  } catch (const std::exception&) {
    fail("--medium '" + spec + "': need sigma_s, sigma_a >= 0 (not both 0) and g in (-1, 1)");
  }
  return buf;
}

// The pack's media as unit-radius media, at most `n`: for each medium name its entry of the
// largest tau (the sphere a renderer uses deep inside, where stepping pays off most).
std::vector<std::string> pack_media(const std::string& path, int n) {
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
  std::vector<std::string> media;
  for (const PackEntry* e : chosen) {
    if (int(media.size()) == n) break;
    const StfModel& m = e->model;
    char spec[256];
    std::snprintf(spec, sizeof spec, "%s tau %g:%.17g:%.17g:%.17g", e->name.c_str(), m.tau, m.albedo * m.tau,
                  (1 - m.albedo) * m.tau, m.g);
    media.push_back(medium_json(spec));
  }
  return media;
}

void run_stress(const ReportOptions& o) {
  const int threads = int(parse_count(o.threads, "--threads", 0, 4096));
  std::string table = scene::stress_table_header() + "\n";
  std::fprintf(stderr, "%s\n", scene::stress_table_header().c_str());
  int failed = 0;
  for (const scene::StressCase& c : scene::stress_cases()) {
    scene::StressResult r = scene::run_stress_case(c, 400, 20000, threads);
    failed += !r.finite;
    std::fprintf(stderr, "%s\n", scene::stress_table_row(r).c_str());
    table += scene::stress_table_row(r) + "\n";
  }
  if (!o.output.empty()) {
    ::mkdir(o.output.c_str(), 0755);
    std::ofstream(o.output + "/stress.md") << "# Stiff and extreme sweep (400 paths, at most 20000 collisions each)\n\n```\n"
                                            << table << "```\n";
  }
  if (failed) fail(std::to_string(failed) + " stress cases produced non-finite numbers");
}

void run_report(const ReportOptions& o) {
  if (o.stress) return run_stress(o);
  if (o.output.empty()) fail("-o must name the report folder");
  std::vector<std::string> media;
  if (!o.pack.empty()) media = pack_media(o.pack, o.max_media);
  for (const std::string& m : o.media) media.push_back(medium_json(m));
  if (media.empty()) fail("give a pack or --medium NAME:SIGMA_S:SIGMA_A:G");
  ::mkdir(o.output.c_str(), 0755);
  const std::string list = o.output + "/media.json";
  {
    std::ofstream f(list);
    f << "[";
    for (std::size_t i = 0; i < media.size(); ++i) f << (i ? ", " : "") << media[i];
    f << "]\n";
    if (!f) fail("-o '" + o.output + "' is not writable");
  }
  std::string command = "/usr/bin/python3 '" + tools_dir() + "/report.py' --stf '" + self_path() + "' --media '" +
                        list + "' --out '" + o.output + "'" + (o.full ? " --full" : "");
  if (std::system(command.c_str()) != 0) fail("report failed: " + command);
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
