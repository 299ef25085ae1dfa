// `import stf`: models, packs and their samplers in Python (docs/python.md). A thin layer over
// the sampler library: every draw is ShellSampler's, every stream SampleStream's, so the draws
// are those of `stf sample`, bit for bit; arrays go in and out as numpy arrays without copies
// of the inputs, and the work runs without the GIL, over threads for large counts.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "model_io.h"
#include "stf/lookup.h"
#include "stf/pack.h"
#include "stf/sampler.h"
#include "stf/stride.h"

namespace py = pybind11;

namespace stf::python {

namespace {

// Errors carry the command line's one line (without its "stf: error: ").
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;

std::string shape_of(const Doubles& a) {
  std::string shape;
  for (py::ssize_t d = 0; d < a.ndim(); ++d) shape += (d ? ", " : "") + std::to_string(a.shape(d));
  return "[" + shape + "]";
}

// The rows of an [n, 3] array (or [n] when `columns` is 0), checked; `what` names it.
const double* rows_of(const Doubles& a, py::ssize_t n, int columns, const char* what) {
  const bool ok = columns == 0 ? a.ndim() == 1 && a.shape(0) == n
                               : a.ndim() == 2 && a.shape(0) == n && a.shape(1) == columns;
  if (!ok)
    throw Error(std::string(what) + " must be an array of shape [" + std::to_string(n) +
                (columns ? ", " + std::to_string(columns) : "") + "], got " + shape_of(a));
  return a.data();
}

py::ssize_t count_of(const Doubles& a, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw Error(std::string(what) + " must be an array of shape [n, 3], got " + shape_of(a));
  return a.shape(0);
}

// Runs body(first, last) over `threads` threads (0: all cores) in contiguous pieces, without the
// GIL; pieces of fewer than 65536 items are not worth a thread.
template <typename Body>
void in_parallel(py::ssize_t n, int threads, Body body) {
  const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
  const int t = int(
      std::max<py::ssize_t>(1, std::min<py::ssize_t>(threads > 0 ? threads : cores, n / 65536)));
  py::gil_scoped_release release;
  std::vector<std::thread> pool;
  try {
    for (int k = 1; k < t; ++k) pool.emplace_back(body, n * k / t, n * (k + 1) / t);
  } catch (...) {  // no thread to be had: those started finish, the rest runs here
    for (int k = int(pool.size()) + 1; k < t; ++k) body(n * k / t, n * (k + 1) / t);
  }
  body(py::ssize_t(0), n / t);
  for (std::thread& th : pool) th.join();
}

Vec3 vec(const double* p, py::ssize_t i) {
  return {p[3 * i], p[3 * i + 1], p[3 * i + 2]};
}
void put(double* p, py::ssize_t i, const Vec3& v) {
  p[3 * i] = v.x, p[3 * i + 1] = v.y, p[3 * i + 2] = v.z;
}

// The arrays of n exits (as `stf sample -o` lays them out), filled without the GIL.
struct Exits {
  explicit Exits(py::ssize_t n)
      : point({n, py::ssize_t(3)}),
        direction({n, py::ssize_t(3)}),
        pdf(n),
        component(n),
        p(point.mutable_data()),
        d(direction.mutable_data()),
        f(pdf.mutable_data()),
        c(component.mutable_data()) {}
  void set(py::ssize_t i, const Vec3& exit_point, const Vec3& exit_direction, double density,
           int part) {
    put(p, i, exit_point), put(d, i, exit_direction), f[i] = density, c[i] = std::int8_t(part);
  }
  py::dict dict() const {
    py::dict out;
    out["exit_point"] = point, out["exit_direction"] = direction, out["pdf"] = pdf,
    out["component"] = component;
    return out;
  }
  Doubles point, direction, pdf;
  py::array_t<std::int8_t> component;
  double *p, *d, *f;
  std::int8_t* c;
};

}  // namespace

// A fitted model with its sampler (stf.Model).
class Model {
 public:
  explicit Model(StfModel model) : sampler_(std::make_shared<ShellSampler>(std::move(model))) {}
  static Model read(const std::string& path) {
    try {
      return Model(fit::read_model_or_pack(path));
    } catch (const std::runtime_error& e) {
      throw Error(e.what());
    }
  }
  const StfModel& model() const { return sampler_->model(); }

  py::dict sample(py::ssize_t n, std::uint64_t seed, int threads) const {
    if (n < 0) throw Error("n must be >= 0, got " + std::to_string(n));
    Exits out(n);
    in_parallel(n, threads, [&](py::ssize_t first, py::ssize_t last) {
      SampleStream stream(seed, std::uint64_t(first));
      for (py::ssize_t i = first; i < last; ++i) {
        const ExitSample s = stream.next(*sampler_);
        out.set(i, s.point, s.direction, s.pdf, s.component);
      }
    });
    return out.dict();
  }

  // As `stf sample --eval`: the smooth part's density, 0 off the unit sphere.
  Doubles pdf(const Doubles& points, const Doubles& directions, int threads) const {
    const py::ssize_t n = count_of(points, "exit_point");
    const double *p = rows_of(points, n, 3, "exit_point"),
                 *d = rows_of(directions, n, 3, "exit_direction");
    Doubles out(n);
    double* f = out.mutable_data();
    in_parallel(n, threads, [&](py::ssize_t first, py::ssize_t last) {
      for (py::ssize_t i = first; i < last; ++i) {
        const Vec3 y = vec(p, i), w = vec(d, i);
        const bool unit = std::abs(length(y) - 1) < 1e-6 && std::abs(length(w) - 1) < 1e-6;
        f[i] = unit ? sampler_->pdf(y, w) : 0.0;
      }
    });
    return out;
  }

  // ShellSampler::sample_world over arrays: paths at `positions` heading `directions` through
  // spheres of `radii` about them, with the uniforms [n, 4] of each draw.
  py::dict sample_world(const Doubles& positions, const Doubles& directions, const Doubles& radii,
                        const Doubles& uniforms, int threads) const {
    const py::ssize_t n = count_of(positions, "positions");
    const double *x = rows_of(positions, n, 3, "positions"),
                 *w = rows_of(directions, n, 3, "directions");
    const double *r = rows_of(radii, n, 0, "radii"), *u = rows_of(uniforms, n, 4, "uniforms");
    Exits out(n);
    in_parallel(n, threads, [&](py::ssize_t first, py::ssize_t last) {
      for (py::ssize_t i = first; i < last; ++i) {
        const double* v = u + 4 * i;
        const WorldExit e =
            sampler_->sample_world(vec(x, i), vec(w, i), r[i], v[0], v[1], v[2], v[3]);
        out.set(i, e.point, e.direction, e.pdf, e.component);
      }
    });
    return out.dict();
  }

 private:
  std::shared_ptr<const ShellSampler> sampler_;
};

// The spheres of one medium of a pack, as a renderer strides through them (stf.Spheres).
class Spheres {
 public:
  Spheres(const std::vector<PackEntry>& pack, const std::string& name)
      : lookup_(std::make_shared<SphereLookup>(pack, name)) {
    if (lookup_->size() == 0) throw Error("the pack holds no sphere of medium '" + name + "'");
  }
  int size() const { return lookup_->size(); }

  // One stride for every path that fits a sphere: the largest of tau <= sigma_t * free radius
  // about each position; the others keep their position and direction (sphere -1, weight 1).
  // The draw by ShellSampler::jump from the uniforms [n, 4] of each path.
  py::dict jump(const Doubles& positions, const Doubles& directions, const Doubles& free_radii,
                double sigma_t, const Doubles& uniforms, int threads) const {
    const double* u = rows_of(uniforms, count_of(positions, "positions"), 4, "uniforms");
    return strides_of(positions, directions, free_radii, sigma_t, threads,
                      [&](int k, const Vec3& x, const Vec3& w, double r, py::ssize_t i) {
                        const double* v = u + 4 * i;
                        const WorldExit e = lookup_->sampler(k).jump(x, w, r, v[0], v[1], v[2], v[3]);
                        return std::pair{e.point, e.direction};
                      });
  }

  // The same through each sphere's stride form (stf/stride.h, what stf render draws), path i
  // taking as many uniforms as its draw needs from its own stream (the SampleStream of `seed`
  // from draw i 2^20, 4 2^20 uniforms apart): the same strides for any thread count.
  py::dict stride(const Doubles& positions, const Doubles& directions, const Doubles& free_radii,
                  double sigma_t, std::uint64_t seed, int threads) const {
    return strides_of(positions, directions, free_radii, sigma_t, threads,
                      [&](int k, const Vec3& x, const Vec3& w, double r, py::ssize_t i) {
                        SampleStream stream(seed, std::uint64_t(i) << 20);
                        const Stride e = lookup_->stride_form(k).jump(x, w, r, [&] { return stream.uniform(); });
                        return std::pair{e.point, e.direction};
                      });
  }

 private:
  // The arrays of jump and stride around `draw(sphere, x, w, radius, i)`.
  template <typename Draw>
  py::dict strides_of(const Doubles& positions, const Doubles& directions, const Doubles& free_radii,
                      double sigma_t, int threads, Draw draw) const {
    const py::ssize_t n = count_of(positions, "positions");
    const double *x = rows_of(positions, n, 3, "positions"),
                 *w = rows_of(directions, n, 3, "directions");
    const double* r = rows_of(free_radii, n, 0, "free_radii");
    if (!(sigma_t > 0)) throw Error("sigma_t must be > 0");
    Doubles point({n, py::ssize_t(3)}), direction({n, py::ssize_t(3)}), weight(n);
    py::array_t<std::int32_t> sphere(n);
    double *p = point.mutable_data(), *d = direction.mutable_data(), *q = weight.mutable_data();
    std::int32_t* k = sphere.mutable_data();
    in_parallel(n, threads, [&](py::ssize_t first, py::ssize_t last) {
      for (py::ssize_t i = first; i < last; ++i) {
        double radius = 0;
        k[i] = lookup_->find(sigma_t, r[i], radius);
        if (k[i] < 0) {
          put(p, i, vec(x, i)), put(d, i, vec(w, i)), q[i] = 1;
          continue;
        }
        const auto [exit_point, exit_direction] = draw(k[i], vec(x, i), vec(w, i), radius, i);
        put(p, i, exit_point), put(d, i, exit_direction), q[i] = lookup_->sampler(k[i]).escape_probability();
      }
    });
    py::dict out;
    out["point"] = point, out["direction"] = direction, out["weight"] = weight,
    out["sphere"] = sphere;
    return out;
  }

  std::shared_ptr<const SphereLookup> lookup_;
};

// A pack: its entries as (name, Model) pairs (stf.Pack).
class Pack {
 public:
  explicit Pack(const std::string& path) {
    std::string error;
    if (!read_pack_file(path, entries_, error)) throw Error(path + ": " + error);
    for (const PackEntry& e : entries_) models_.emplace_back(e.model);
  }
  py::ssize_t size() const { return py::ssize_t(entries_.size()); }
  const std::string& name(py::ssize_t i) const { return entries_[std::size_t(i)].name; }
  const Model& model(py::ssize_t i) const { return models_[std::size_t(i)]; }

  // The entry of this albedo and g (relative difference below 1e-9) with the largest tau not
  // above `tau`: the sphere a renderer uses where tau fits; None when there is none.
  std::optional<Model> find(double tau, double albedo, double g) const {
    const Model* best = nullptr;
    auto close = [](double a, double b) {
      return std::abs(a - b) <= 1e-9 * std::max(1.0, std::abs(b));
    };
    for (const Model& m : models_)
      if (close(m.model().albedo, albedo) && close(m.model().g, g) &&
          m.model().tau <= tau * (1 + 1e-12) && (!best || m.model().tau > best->model().tau))
        best = &m;
    return best ? std::optional<Model>(*best) : std::nullopt;
  }
  Spheres spheres(const std::string& name) const { return Spheres(entries_, name); }

 private:
  std::vector<PackEntry> entries_;
  std::vector<Model> models_;
};

}  // namespace stf::python

namespace {

using stf::python::Model;
using stf::python::Pack;
using stf::python::Spheres;

py::array_t<double> array_of(const std::vector<double>& v) {
  return py::array_t<double>(py::ssize_t(v.size()), v.data());
}

void add_model(py::module_& m) {
  py::class_<Model>(m, "Model",
                    "A fitted model (stf fit -o) or a pack's first entry, with its sampler")
      .def(py::init(&Model::read), py::arg("path"))
      .def("sample", &Model::sample, py::arg("n"), py::arg("seed") = 1, py::arg("threads") = 0,
           "n exits as numpy arrays: the draws of `stf sample --count n --seed seed`, bit for bit")
      .def("pdf", &Model::pdf, py::arg("exit_point"), py::arg("exit_direction"),
           py::arg("threads") = 0,
           "The smooth part's density at [n, 3] exit points and directions, as `stf sample --eval`")
      .def("sample_world", &Model::sample_world, py::arg("positions"), py::arg("directions"),
           py::arg("radii"), py::arg("uniforms"), py::arg("threads") = 0,
           "Exits of paths at positions heading directions through spheres of these radii, one row "
           "of "
           "four uniforms in [0, 1) per draw")
      .def_property_readonly("tau", [](const Model& s) { return s.model().tau; })
      .def_property_readonly("albedo", [](const Model& s) { return s.model().albedo; })
      .def_property_readonly("g", [](const Model& s) { return s.model().g; })
      .def_property_readonly("sigma_s", [](const Model& s) { return s.model().sigma_s; })
      .def_property_readonly("sigma_a", [](const Model& s) { return s.model().sigma_a; })
      .def_property_readonly("radius", [](const Model& s) { return s.model().radius; })
      .def_property_readonly("escape_probability",
                             [](const Model& s) { return s.model().escape_probability; })
      // The singular parts' probabilities among the exits (component 1 and 2 of sample()).
      .def_property_readonly("uncollided_probability",
                             [](const Model& s) { return s.model().uncollided_probability(); })
      .def_property_readonly("once_probability",
                             [](const Model& s) { return s.model().once_fraction; })
      .def_property_readonly("alpha_bins", [](const Model& s) { return s.model().bins(); })
      .def_property_readonly("alpha_edges",
                             [](const Model& s) { return array_of(s.model().alpha_edges); })
      .def_property_readonly("alpha_probability",
                             [](const Model& s) { return array_of(s.model().alpha_probability); })
      .def_property_readonly("family",
                             [](const Model& s) { return s.model().family(); })
      .def_property_readonly("size",
                             [](const Model& s) {
                               return s.model().kind == stf::ModelKind::kSh ? s.model().band_limit
                                                                            : s.model().lobes;
                             })
      .def("__repr__", [](const Model& s) {
        return "<stf.Model tau " + std::to_string(s.model().tau) + " albedo " +
               std::to_string(s.model().albedo) + " g " + std::to_string(s.model().g) + ">";
      });
}

void add_pack(py::module_& m) {
  py::class_<Spheres>(m, "Spheres", "The spheres of one medium of a pack, for striding through it")
      .def("__len__", &Spheres::size)
      .def("jump", &Spheres::jump, py::arg("positions"), py::arg("directions"),
           py::arg("free_radii"), py::arg("sigma_t"), py::arg("uniforms"), py::arg("threads") = 0,
           "One stride per path through the largest sphere that fits its free radius: dict of "
           "point, "
           "direction, weight (the sphere's escape probability) and sphere (-1: none fits, path "
           "unchanged)")
      .def("stride", &Spheres::stride, py::arg("positions"), py::arg("directions"),
           py::arg("free_radii"), py::arg("sigma_t"), py::arg("seed"), py::arg("threads") = 0,
           "jump through each sphere's stride form (what stf render draws), each path's uniforms "
           "from its own stream of `seed`");
  py::class_<Pack>(m, "Pack", "A pack of models (stf pack, stf build)")
      .def(py::init<const std::string&>(), py::arg("path"))
      .def("__len__", &Pack::size)
      .def("__getitem__",
           [](const Pack& p, py::ssize_t i) {
             if (i < 0) i += p.size();
             if (i < 0 || i >= p.size()) throw py::index_error("pack entry out of range");
             return py::make_tuple(p.name(i), p.model(i));
           })
      .def("find", &Pack::find, py::arg("tau"), py::arg("albedo"), py::arg("g"),
           "The entry of this albedo and g with the largest tau not above tau, or None")
      .def("spheres", &Pack::spheres, py::arg("name"), "The spheres of the medium `name`");
}

}  // namespace

PYBIND11_MODULE(stf, m) {
  m.doc() = "stf: shell transport functions (models, packs and their samplers)";
  m.attr("__version__") = STF_VERSION;
  py::register_exception<stf::python::Error>(m, "Error", PyExc_ValueError);
  add_model(m);
  add_pack(m);
}
