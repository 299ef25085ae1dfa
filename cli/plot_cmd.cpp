// `stf plot`: the thesis's theta-phi direction plots (its Fig. 4.2-4.5) for one alpha.
// This side looks up cells and densities; tools/plot_directions.py (matplotlib) draws them.
#include <CLI/CLI.hpp>
#include <H5Cpp.h>

#include <cmath>
#include <cstdlib>
#include <memory>

#include "cli.h"
#include "stf/core/files.h"
#include "stf/core/grid.h"
#include "stf/core/h5io.h"
#include "stf/measure/evaluate.h"
#include "stf/fit/model_io.h"
#include "stf/core/table.h"

namespace stf::cli {

namespace {

struct PlotOptions {
  std::vector<std::string> tables;
  double alpha_deg = 0;
  std::string output;
  std::string model;
  int width = 720;
};

// Density p(w' | alpha) per steradian of each cell in the alpha bin holding `alpha`.
std::vector<double> cell_density(const Table& t, int bin) {
  std::vector<double> weight = t.weight();
  double total = 0;
  for (std::int64_t c = 0; c < t.cells; ++c) total += weight[std::size_t(bin) * t.cells + c];
  std::vector<double> density(t.cells, 0.0);
  if (total <= 0) return density;
  for (std::int64_t c = 0; c < t.cells; ++c)
    density[c] = weight[std::size_t(bin) * t.cells + c] / (total * t.solid_angle[c]);
  return density;
}

// What one panel shows: a density per cell of the table's grid, and its title.
struct Panel {
  std::vector<double> density;
  std::string title;
};

// One panel's data: the density raster over (theta, phi) from each pixel's own cell, and the
// cell centres with their densities (what the thesis interpolated).
void write_panel(H5::H5File& file, int index, const Table& t, const DirectionGrid& grid, const Panel& panel,
                 int width) {
  const std::vector<double>& density = panel.density;
  const int height = width / 2;
  std::vector<double> raster(std::size_t(width) * height);
  for (int r = 0; r < height; ++r) {
    double theta = kPi * (r + 0.5) / height;
    for (int c = 0; c < width; ++c) {
      double phi = -kPi + 2 * kPi * (c + 0.5) / width;
      Vec3 d{std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
      raster[std::size_t(r) * width + c] = density[grid.cell(d)];
    }
  }
  std::vector<double> theta(t.cells), phi(t.cells);
  for (std::int64_t c = 0; c < t.cells; ++c) {
    const auto& v = t.direction[c];
    theta[c] = std::atan2(std::hypot(v[0], v[1]), v[2]);
    phi[c] = std::atan2(v[1], v[0]);
  }
  H5::Group g = file.createGroup("/panel" + std::to_string(index));
  h5::put_dataset(g, "raster", {hsize_t(height), hsize_t(width)}, raster.data());
  h5::put_dataset(g, "cell_theta", {hsize_t(t.cells)}, theta.data());
  h5::put_dataset(g, "cell_phi", {hsize_t(t.cells)}, phi.data());
  h5::put_dataset(g, "cell_density", {hsize_t(t.cells)}, density.data());
  h5::put_attr(g, "title", panel.title);
}

std::string describe(const Table& t, int bin, const std::string& what) {
  char title[256];
  std::snprintf(title, sizeof title, "%s  %s  sigma_s=%g sigma_a=%g g=%g  alpha [%.1f, %.1f) deg  %.3g paths",
                what.c_str(), t.grid.c_str(), t.medium.sigma_s, t.medium.sigma_a, t.medium.g,
                t.alpha_edges[bin] * 180 / kPi, t.alpha_edges[bin + 1] * 180 / kPi, double(t.paths));
  return title;
}

int alpha_bin(const Table& t, double alpha) { return std::min(int(alpha / kPi * t.alpha_bins), t.alpha_bins - 1); }


void run_plot(const PlotOptions& o) {
  if (!(o.alpha_deg >= 0 && o.alpha_deg <= 180)) fail("--alpha must be in [0, 180] degrees");
  if (o.width < 64 || o.width > 8192) fail("--width must be in 64..8192");
  std::vector<NamedFile> inputs;
  for (const std::string& t : o.tables) inputs.push_back({t, "table"});
  require_files(inputs);
  inputs.push_back({o.model, "--model"});
  AtomicOutput png(o.output, "-o", inputs);
  ScratchFile data;  // what the drawing script reads
  H5::Exception::dontPrint();
  h5::MemoryFile memory;
  {
    H5::H5File& file = memory.file();
    const double alpha = o.alpha_deg * kPi / 180;
    for (std::size_t i = 0; i < o.tables.size(); ++i) {
      Table t = read_table(o.tables[i]);
      std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);
      int bin = alpha_bin(t, alpha);
      write_panel(file, int(i), t, *grid, {cell_density(t, bin), describe(t, bin, "table")}, o.width);
      stop_if_interrupted();
    }
    if (!o.model.empty()) {
      // The model integrated over the first table's cells, beside it. A tolerance fit's alpha
      // bins may be groups of the table's: the table's bin is drawn from the group holding it.
      Table t = read_table(o.tables.front());
      std::unique_ptr<DirectionGrid> grid = make_grid(t.grid);
      int bin = alpha_bin(t, alpha);
      StfModel model = fit::read_model(o.model);
      std::unique_ptr<measure::BinnedModel> binned;
      try {
        binned = std::make_unique<measure::BinnedModel>(model, t, *grid);
      } catch (const std::invalid_argument& e) {
        fail("--model: " + std::string(e.what()));
      }
      const fit::QuadratureLevels levels(*grid);
      measure::SmoothCellCache smooth(model, levels);
      std::vector<double> density = binned->bin(bin, std::ref(smooth)).second;
      for (std::int64_t c = 0; c < t.cells; ++c) density[c] /= t.solid_angle[c];
      h5::put_attr(file, "side_by_side", 1);
      write_panel(file, int(o.tables.size()), t, *grid,
                  {density, describe(t, bin, "model " + o.model.substr(o.model.find_last_of('/') + 1))}, o.width);
    }
  }
  write_durably(data.path(), memory.bytes(), "the plot's data " + data.path());
  run_python("plot_directions.py", {data.path(), png.temp_path()}, "plotting");
  png.commit();
}

}  // namespace

void add_plot_command(CLI::App& app) {
  auto o = std::make_shared<PlotOptions>();
  CLI::App* cmd = app.add_subcommand(
      "plot", "Theta-phi plots of exit directions for one alpha (one row per table or model), PNG");
  cmd->add_option("tables", o->tables, "Raw tables (HDF5)")->required();
  cmd->add_option("--alpha", o->alpha_deg, "Exit-point angle alpha in degrees")->required();
  cmd->add_option("-o,--output", o->output, "Output image (PNG)")->required();
  cmd->add_option("--width", o->width, "Raster width in pixels")->capture_default_str();
  cmd->add_option("--model", o->model, "A fitted model of the (first) table: drawn beside it, integrated over its cells")
      ->check(CLI::ExistingFile);
  cmd->callback([o] {
    try {
      run_plot(*o);
    } catch (const H5::Exception& e) {
      fail("cannot write the plot's data to a temporary file: " + e.getDetailMsg());
    }
  });
}

}  // namespace stf::cli
