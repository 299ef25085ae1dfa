// `import stf`: models, packs and their samplers in Python (docs/python.md). A thin layer over
// the sampler library: every draw is ShellSampler's, every stream SampleStream's, so the draws
// are those of `stf sample`, bit for bit; arrays go in and out as numpy arrays without copies
// of the inputs, and the work runs without the GIL, over threads for large counts.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "arrays.h"
#include "stf/fit/model_io.h"
#include "stf/lookup.h"
#include "stf/pack.h"
#include "stf/sampler.h"
#include "stf/stride.h"

namespace py = pybind11;

namespace stf::python {

// A fitted model with its sampler (stf.Model).
class Model {
 public:
  explicit Model(StfModel model) : sampler_(std::make_shared<ShellSampler>(std::move(model))) {}
  static Model read(const py::object& path) { return Model(fit::read_model_or_pack(path_of(path))); }
  const StfModel& model() const { return sampler_->model(); }

  py::dict sample(const py::object& count, const py::object& seed_value, const py::object& threads) const {
    const py::ssize_t n = draws_of(count);
    const std::uint64_t seed = whole_in(seed_value, ~std::uint64_t(0), "seed");
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
  Doubles pdf(const Doubles& points, const Doubles& directions, const py::object& threads) const {
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
                        const Doubles& uniforms, const py::object& threads) const {
    const py::ssize_t n = count_of(positions, "positions");
    const double *x = rows_of(positions, n, 3, "positions"),
                 *w = rows_of(directions, n, 3, "directions");
    const double *r = rows_of(radii, n, 0, "radii"), *u = rows_of(uniforms, n, 4, "uniforms");
    check_paths(x, w, r, n, true);
    check_uniforms(u, n);
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
  Spheres(const std::vector<PackEntry>& pack, double albedo, double g)
      : lookup_(std::make_shared<SphereLookup>(pack, albedo, g)) {
    if (lookup_->size() == 0) throw Error("the pack holds no sphere of the medium " + medium_name(albedo, g));
  }
  int size() const { return lookup_->size(); }

  // One stride for every path that fits a sphere: the largest of tau <= sigma_t * free radius
  // about each position; the others keep their position and direction (sphere -1, weight 1).
  // The draw by ShellSampler::jump from the uniforms [n, 4] of each path.
  py::dict jump(const Doubles& positions, const Doubles& directions, const Doubles& free_radii,
                const py::object& sigma_t, const Doubles& uniforms, const py::object& threads) const {
    const double* u = rows_of(uniforms, count_of(positions, "positions"), 4, "uniforms");
    check_uniforms(u, count_of(positions, "positions"));
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
                  const py::object& sigma_t, const py::object& seed_value, const py::object& threads) const {
    const std::uint64_t seed = whole_in(seed_value, ~std::uint64_t(0), "seed");
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
                      const py::object& sigma_value, const py::object& threads, Draw draw) const {
    const py::ssize_t n = count_of(positions, "positions");
    const double *x = rows_of(positions, n, 3, "positions"),
                 *w = rows_of(directions, n, 3, "directions");
    const double* r = rows_of(free_radii, n, 0, "free_radii");
    const double sigma_t = number_of(sigma_value, "sigma_t");
    if (!(std::isfinite(sigma_t) && sigma_t > 0)) throw Error("sigma_t must be a finite number > 0");
    check_paths(x, w, r, n, false);
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
  explicit Pack(const py::object& path_value) {
    const std::string path = path_of(path_value);
    std::string error;
    if (!read_pack_file(path, entries_, error)) throw Error(path + ": " + error);
    for (const PackEntry& e : entries_) models_.emplace_back(e.model);
  }
  py::ssize_t size() const { return py::ssize_t(entries_.size()); }
  const std::string& name(py::ssize_t i) const { return entries_[std::size_t(i)].name; }
  const Model& model(py::ssize_t i) const { return models_[std::size_t(i)]; }

  // The entry of this albedo and g (stf::same_medium: as stored, to 1e-9 relative) with the
  // largest tau not above `tau`: the sphere a renderer uses where tau fits; None when there is none.
  std::optional<Model> find(double tau, double albedo, double g) const {
    const Model* best = nullptr;
    for (const Model& m : models_)
      if (same_medium(m.model(), albedo, g) && m.model().tau <= tau * (1 + 1e-12) &&
          (!best || m.model().tau > best->model().tau))
        best = &m;
    return best ? std::optional<Model>(*best) : std::nullopt;
  }
  Spheres spheres(double albedo, double g) const { return Spheres(entries_, albedo, g); }
  // The media of the pack's entries, each once, in pack order: (albedo, g) as stored.
  std::vector<std::pair<double, double>> media() const {
    std::vector<std::pair<double, double>> seen;
    for (const PackEntry& e : entries_)
      if (std::none_of(seen.begin(), seen.end(), [&](const auto& m) { return same_medium(e.model, m.first, m.second); }))
        seen.emplace_back(e.model.albedo, e.model.g);
    return seen;
  }

 private:
  std::vector<PackEntry> entries_;
  std::vector<Model> models_;
};

// `self` of a method: an object made by __new__ without __init__ holds nothing to use (pybind11
// would hand the method uninitialised memory), so its holder must have been constructed.
template <typename T>
const T& self(py::handle h) {
  if (!py::isinstance<T>(h)) throw Error("a method of an stf object called on another object");
  auto* instance = reinterpret_cast<py::detail::instance*>(h.ptr());
  const py::detail::value_and_holder v = instance->get_value_and_holder(py::detail::get_type_info(typeid(T)));
  if (!v.holder_constructed())
    throw Error("this object was never constructed: make it with stf.Model(path) or stf.Pack(path)");
  return *v.template value_ptr<T>();
}

// A const member function as a method whose `self` is checked.
template <typename C, typename R, typename... A>
auto checked(R (C::*f)(A...) const) {
  return [f](py::handle c, A... a) -> R { return (self<C>(c).*f)(std::forward<A>(a)...); };
}

}  // namespace stf::python

namespace {

using stf::python::checked;
using stf::python::self;

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
      .def("sample", checked(&Model::sample), py::arg("n"), py::arg("seed") = 1, py::arg("threads") = 0,
           "n exits as numpy arrays: the draws of `stf sample --count n --seed seed`, bit for bit")
      .def("pdf", checked(&Model::pdf), py::arg("exit_point"), py::arg("exit_direction"),
           py::arg("threads") = 0,
           "The smooth part's density at [n, 3] exit points and directions, as `stf sample --eval`")
      .def("sample_world", checked(&Model::sample_world), py::arg("positions"), py::arg("directions"),
           py::arg("radii"), py::arg("uniforms"), py::arg("threads") = 0,
           "Exits of paths at positions heading directions through spheres of these radii, one row "
           "of "
           "four uniforms in [0, 1) per draw")
      .def_property_readonly("tau", [](py::handle s) { return self<Model>(s).model().tau; })
      .def_property_readonly("albedo", [](py::handle s) { return self<Model>(s).model().albedo; })
      .def_property_readonly("g", [](py::handle s) { return self<Model>(s).model().g; })
      .def_property_readonly("sigma_s", [](py::handle s) { return self<Model>(s).model().sigma_s; })
      .def_property_readonly("sigma_a", [](py::handle s) { return self<Model>(s).model().sigma_a; })
      .def_property_readonly("radius", [](py::handle s) { return self<Model>(s).model().radius; })
      .def_property_readonly("escape_probability",
                             [](py::handle s) { return self<Model>(s).model().escape_probability; })
      // The singular parts' probabilities among the exits (component 1 and 2 of sample()).
      .def_property_readonly("uncollided_probability",
                             [](py::handle s) { return self<Model>(s).model().uncollided_probability(); })
      .def_property_readonly("once_probability",
                             [](py::handle s) { return self<Model>(s).model().once_fraction; })
      .def_property_readonly("alpha_bins", [](py::handle s) { return self<Model>(s).model().bins(); })
      .def_property_readonly("alpha_edges",
                             [](py::handle s) { return array_of(self<Model>(s).model().alpha_edges); })
      .def_property_readonly("alpha_probability",
                             [](py::handle s) { return array_of(self<Model>(s).model().alpha_probability); })
      .def_property_readonly("family",
                             [](py::handle s) { return self<Model>(s).model().family(); })
      .def_property_readonly("size",
                             [](py::handle p) {
                               const stf::StfModel& m = self<Model>(p).model();
                               return m.kind == stf::ModelKind::kSh ? m.band_limit : m.lobes;
                             })
      .def("__repr__", [](py::handle p) {
        auto* instance = reinterpret_cast<py::detail::instance*>(p.ptr());
        if (!instance->get_value_and_holder(py::detail::get_type_info(typeid(Model))).holder_constructed())
          return std::string("<stf.Model, not constructed>");
        const stf::StfModel& m = self<Model>(p).model();
        return "<stf.Model tau " + stf::round_trip(m.tau) + " " + stf::medium_name(m.albedo, m.g) + ">";
      });
}

void add_pack(py::module_& m) {
  py::class_<Spheres>(m, "Spheres", "The spheres of one medium of a pack, for striding through it")
      .def("__len__", checked(&Spheres::size))
      .def("jump", checked(&Spheres::jump), py::arg("positions"), py::arg("directions"),
           py::arg("free_radii"), py::arg("sigma_t"), py::arg("uniforms"), py::arg("threads") = 0,
           "One stride per path through the largest sphere that fits its free radius: dict of "
           "point, "
           "direction, weight (the sphere's escape probability) and sphere (-1: none fits, path "
           "unchanged)")
      .def("stride", checked(&Spheres::stride), py::arg("positions"), py::arg("directions"),
           py::arg("free_radii"), py::arg("sigma_t"), py::arg("seed"), py::arg("threads") = 0,
           "jump through each sphere's stride form (what stf render draws), each path's uniforms "
           "from its own stream of `seed`");
  py::class_<Pack>(m, "Pack", "A pack of models (stf pack, stf build)")
      .def(py::init<const py::object&>(), py::arg("path"))
      .def("__len__", checked(&Pack::size))
      .def("__getitem__",
           [](py::handle pack, const py::object& index) {
             const Pack& p = self<Pack>(pack);
             // Too large for an index is out of range too (IndexError, not TypeError).
             py::ssize_t i = PyNumber_AsSsize_t(index.ptr(), PyExc_IndexError);
             if (i == -1 && PyErr_Occurred()) throw py::error_already_set();
             if (i < 0) i += p.size();
             if (i < 0 || i >= p.size()) throw py::index_error("pack entry out of range");
             return py::make_tuple(p.name(i), p.model(i));
           })
      .def("find", checked(&Pack::find), py::arg("tau"), py::arg("albedo"), py::arg("g"),
           "The entry of this albedo and g with the largest tau not above tau, or None")
      .def("spheres", checked(&Pack::spheres), py::kw_only(), py::arg("albedo"), py::arg("g"),
           "The spheres of the medium of this albedo and g (as find matches them)")
      .def_property_readonly("media", checked(&Pack::media), "The (albedo, g) of the pack's media, each once");
}

}  // namespace

PYBIND11_MODULE(stf, m) {
  m.doc() = "stf: shell transport functions (models, packs and their samplers)";
  m.attr("__version__") = STF_VERSION;
  static py::exception<stf::python::Error> error = py::register_exception<stf::python::Error>(m, "Error", PyExc_ValueError);
  // Every error the library raises reaches Python as stf.Error with its one line; pybind11's own
  // (index and cast errors) and out-of-memory stay what they are.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const py::builtin_exception&) {
      throw;
    } catch (const std::bad_alloc&) {
      throw;
    } catch (const stf::python::Error&) {
      throw;
    } catch (const std::exception& e) {
      error(e.what());
    }
  });
  add_model(m);
  add_pack(m);
}
