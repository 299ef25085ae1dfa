// Sampler speed: ns per full sample (alpha, direction, beta, pdf) and per pdf evaluation for
// vmf:1/4/8 and sh:8/16 models of 90 alpha bins, and vmf:8 with tilted bins blended over 1 and
// 3 bins, against a bare single-lobe vMF sample measured in the same run. Google Benchmark prints its table; the summary with the ratios
// is JSON on stdout (and in --out FILE).
//   sampler_bench [--out FILE] [google benchmark flags]
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "stf/core/rng.h"
#include "stf/sampler.h"
#include "stf/sh.h"
#include "stf/vmf.h"

namespace {

using namespace stf;

struct Uniforms {
  std::uint64_t state = 1;
  double operator()() { return double(splitmix64(state) >> 11) * 0x1p-53; }
};

StfModel model(ModelKind kind, int size, int blend = -1) {
  StfModel m;
  if (blend >= 0) {
    m.alpha_tilt.assign(90, -0.8);  // crowding towards each bin's lower edge
    m.alpha_blend = blend;
  }
  m.kind = kind;
  m.tau = 10, m.albedo = 1, m.escape_probability = 1;
  const int bins = 90;
  for (int b = 0; b <= bins; ++b) m.alpha_edges.push_back(kPi * b / bins);
  for (int b = 0; b < bins; ++b) m.alpha_probability.push_back(std::sin(kPi * (b + 0.5) / bins) / 57.29);
  double sum = 0;
  for (double p : m.alpha_probability) sum += p;
  for (double& p : m.alpha_probability) p /= sum;
  m.status.assign(bins, BinStatus::kFitted);
  if (kind == ModelKind::kVmf) {
    m.lobes = size;
    for (int b = 0; b < bins; ++b)
      for (int k = 0; k < size; ++k)
        m.vmf.push_back({1.0 / size, 2.0 + 3 * k, normalize({std::sin(0.3 * k + b * 0.03), 0.1 * k, std::cos(0.3 * k)})});
  } else {
    m.band_limit = size;
    m.sh_nz = std::max(32, 4 * size);
    const int count = sh_count(size);
    for (int b = 0; b < bins; ++b)
      for (int i = 0; i < count; ++i) m.sh.push_back(i == 0 ? 0.28 : 0.02 / (1 + i));
    m.rebuild_sh_tables();
  }
  return m;
}

void BareVmfLobe(benchmark::State& state) {
  VmfLobe lobe{1, 5, normalize({0.3, 0.2, 0.9})};
  Uniforms u;
  for (auto _ : state) benchmark::DoNotOptimize(sample_vmf(lobe, u(), u()));
}
BENCHMARK(BareVmfLobe);

void Sample(benchmark::State& state, ModelKind kind, int size, int blend = -1) {
  ShellSampler s(model(kind, size, blend));
  Uniforms u;
  for (auto _ : state) benchmark::DoNotOptimize(s.sample(u(), u(), u(), u()));
}

void Pdf(benchmark::State& state, ModelKind kind, int size, int blend = -1) {
  ShellSampler s(model(kind, size, blend));
  Uniforms u;
  std::vector<ExitSample> points;
  for (int i = 0; i < 1024; ++i) points.push_back(s.sample(u(), u(), u(), u()));
  std::size_t i = 0;
  for (auto _ : state) {
    const ExitSample& x = points[i++ & 1023];
    benchmark::DoNotOptimize(s.pdf(x.point, x.direction));
  }
}

BENCHMARK_CAPTURE(Sample, vmf1, ModelKind::kVmf, 1);
BENCHMARK_CAPTURE(Sample, vmf4, ModelKind::kVmf, 4);
BENCHMARK_CAPTURE(Sample, vmf8, ModelKind::kVmf, 8);
BENCHMARK_CAPTURE(Sample, sh8, ModelKind::kSh, 8);
BENCHMARK_CAPTURE(Sample, sh16, ModelKind::kSh, 16);
BENCHMARK_CAPTURE(Sample, vmf8_blend1, ModelKind::kVmf, 8, 1);
BENCHMARK_CAPTURE(Sample, vmf8_blend3, ModelKind::kVmf, 8, 3);
BENCHMARK_CAPTURE(Pdf, vmf1, ModelKind::kVmf, 1);
BENCHMARK_CAPTURE(Pdf, vmf4, ModelKind::kVmf, 4);
BENCHMARK_CAPTURE(Pdf, vmf8, ModelKind::kVmf, 8);
BENCHMARK_CAPTURE(Pdf, sh8, ModelKind::kSh, 8);
BENCHMARK_CAPTURE(Pdf, sh16, ModelKind::kSh, 16);
BENCHMARK_CAPTURE(Pdf, vmf8_blend1, ModelKind::kVmf, 8, 1);
BENCHMARK_CAPTURE(Pdf, vmf8_blend3, ModelKind::kVmf, 8, 3);

// Keeps each benchmark's ns per iteration for the summary.
class Collect : public benchmark::ConsoleReporter {
 public:
  std::map<std::string, double> ns;
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& r : runs)
      if (r.run_type == Run::RT_Iteration) ns[r.benchmark_name()] = r.GetAdjustedRealTime();  // default unit: ns
    ConsoleReporter::ReportRuns(runs);
  }
};

}  // namespace

int main(int argc, char** argv) {
  std::string out;
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--out") && i + 1 < argc) {
      out = argv[++i];
      continue;
    }
    args.push_back(argv[i]);
  }
  int n = int(args.size());
  benchmark::Initialize(&n, args.data());
  Collect collect;
  benchmark::RunSpecifiedBenchmarks(&collect);
  const double bare = collect.ns["BareVmfLobe"];
  std::ostringstream json;
  json << "{\n  \"bare_single_lobe_vmf_ns\": " << bare << ",\n  \"models\": [\n";
  const char* names[] = {"vmf1", "vmf4", "vmf8", "sh8", "sh16", "vmf8_blend1", "vmf8_blend3"};
  constexpr int kModels = 7;
  for (int i = 0; i < kModels; ++i) {
    double s = collect.ns[std::string("Sample/") + names[i]], p = collect.ns[std::string("Pdf/") + names[i]];
    json << "    {\"model\": \"" << names[i] << "\", \"sample_ns\": " << s << ", \"pdf_ns\": " << p
         << ", \"sample_vs_bare\": " << s / bare << "}" << (i + 1 < kModels ? ",\n" : "\n");
  }
  json << "  ]\n}\n";
  std::fputs(json.str().c_str(), stdout);
  if (!out.empty()) std::ofstream(out) << json.str();
  return 0;
}
