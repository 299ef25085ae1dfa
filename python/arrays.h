// The numpy side of `import stf`: arrays checked on their way in (shapes, values), the exits
// arrays on their way out, the module's one error type, and the loop that runs work over
// threads without the GIL.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

#include "stf/core/parallel.h"
#include "stf/vec3.h"

namespace stf::python {

namespace py = pybind11;


// Errors carry the command line's one line (without its "stf: error: ").
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;

inline std::string shape_of(const Doubles& a) {
  std::string shape;
  for (py::ssize_t d = 0; d < a.ndim(); ++d) shape += (d ? ", " : "") + std::to_string(a.shape(d));
  return "[" + shape + "]";
}

// The rows of an [n, 3] array (or [n] when `columns` is 0), checked; `what` names it.
inline const double* rows_of(const Doubles& a, py::ssize_t n, int columns, const char* what) {
  const bool ok = columns == 0 ? a.ndim() == 1 && a.shape(0) == n
                               : a.ndim() == 2 && a.shape(0) == n && a.shape(1) == columns;
  if (!ok)
    throw Error(std::string(what) + " must be an array of shape [" + std::to_string(n) +
                (columns ? ", " + std::to_string(columns) : "") + "], got " + shape_of(a));
  return a.data();
}

inline py::ssize_t count_of(const Doubles& a, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw Error(std::string(what) + " must be an array of shape [n, 3], got " + shape_of(a));
  return a.shape(0);
}

// A Python whole number (an int, or anything with __index__) in [0, hi], or an error naming
// `what`: pybind11 would raise TypeError for values that are merely out of range.
inline std::uint64_t whole_in(const py::object& v, std::uint64_t hi, const char* what) {
  PyObject* index = PyNumber_Index(v.ptr());
  const unsigned long long x = index ? PyLong_AsUnsignedLongLong(index) : 0;
  Py_XDECREF(index);
  if (PyErr_Occurred() || x > hi) {
    PyErr_Clear();
    throw Error(std::string(what) + " must be a whole number in 0.." + std::to_string(hi));
  }
  return x;
}

// A Python number as a double, or an error naming `what`.
inline double number_of(const py::object& v, const char* what) {
  const double x = PyFloat_AsDouble(v.ptr());
  if (PyErr_Occurred()) {
    PyErr_Clear();
    throw Error(std::string(what) + " must be a number");
  }
  return x;
}

// A count of draws whose arrays (57 bytes a draw) fit in this machine's memory.
inline py::ssize_t draws_of(const py::object& v) {
  const double memory = double(::sysconf(_SC_PHYS_PAGES)) * double(::sysconf(_SC_PAGESIZE));
  const auto most = std::uint64_t(std::min(0.5 * memory / 57, 9e18));
  return py::ssize_t(whole_in(v, most, "n (draws that fit in memory)"));
}

// A file name: a str, bytes or os.PathLike, without NUL bytes (which would name another file).
inline std::string path_of(const py::object& path) {
  try {
    const py::object name = py::module_::import("os").attr("fspath")(path);
    const std::string text = py::isinstance<py::bytes>(name) ? std::string(name.cast<py::bytes>()) : name.cast<std::string>();
    if (text.find('\0') != std::string::npos) throw Error("a file name holding a NUL byte: " + text.substr(0, text.find('\0')) + "...");
    return text;
  } catch (const py::error_already_set&) {
    throw Error("a file name must be a str, bytes or os.PathLike");
  } catch (const py::cast_error&) {
    throw Error("a file name must be text that encodes as UTF-8");
  }
}

// Runs body(first, last) over [0, n) on `threads` threads (0: all cores) in contiguous pieces
// (stf/core/parallel.h), without the GIL; pieces of fewer than 65536 items are not worth a
// thread. The work goes in rounds of 2^20 items a thread, and between rounds a Ctrl-C raises
// KeyboardInterrupt: a long draw stops within a fraction of a second. Every item depends on its
// index alone, so the rounds change no result.
template <typename Body>
void in_parallel(py::ssize_t n, const py::object& threads_value, Body body) {
  const int threads = int(whole_in(threads_value, 4096, "threads"));
  const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
  const py::ssize_t t = std::max<py::ssize_t>(1, std::min<py::ssize_t>(threads > 0 ? threads : cores, n / 65536));
  constexpr py::ssize_t kRound = py::ssize_t(1) << 20;
  for (py::ssize_t start = 0; start < n; start += kRound * t) {
    const py::ssize_t m = std::min(n - start, kRound * t);
    {
      py::gil_scoped_release release;
      parallel_for(t, RunContext{int(t), nullptr, {}}, [&](std::int64_t k, int) { body(start + m * k / t, start + m * (k + 1) / t); });
    }
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
  }
}

inline std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", v);
  return text;
}

// Every one of `count` values at p passes ok(v), or an error naming `what`, what it `must` be
// and the first value that does not.
template <typename Ok>
void check_values(const double* p, py::ssize_t count, const char* what, const char* must, Ok ok) {
  for (py::ssize_t i = 0; i < count; ++i)
    if (!(std::isfinite(p[i]) && ok(p[i])))
      throw Error(std::string(what) + " must be " + must + "; element " + std::to_string(i) + " is " + number(p[i]));
}

inline void check_uniforms(const double* u, py::ssize_t rows) {
  check_values(u, 4 * rows, "uniforms", "finite numbers in [0, 1)", [](double v) { return v >= 0 && v < 1; });
}

// Positions finite, directions unit vectors (as the sampler takes them), radii finite and > 0
// (free radii finite: at or below 0, as rounding makes them on a sphere's surface, none fits).
inline void check_paths(const double* x, const double* w, const double* r, py::ssize_t n, bool strictly_positive) {
  check_values(x, 3 * n, "positions", "finite numbers", [](double) { return true; });
  for (py::ssize_t i = 0; i < n; ++i) {
    const double len = std::sqrt(w[3 * i] * w[3 * i] + w[3 * i + 1] * w[3 * i + 1] + w[3 * i + 2] * w[3 * i + 2]);
    if (!(std::abs(len - 1) < 1e-6)) throw Error("directions must be unit vectors; row " + std::to_string(i) + " has length " + number(len));
  }
  // Densities per area go as 1 / r^2: radii stay where that is a number.
  if (strictly_positive)
    check_values(r, n, "radii", "numbers in [1e-150, 1e150]", [](double v) { return v >= 1e-150 && v <= 1e150; });
  else check_values(r, n, "free_radii", "finite numbers (at or below 0 no sphere fits)", [](double) { return true; });
}

inline Vec3 vec(const double* p, py::ssize_t i) {
  return {p[3 * i], p[3 * i + 1], p[3 * i + 2]};
}
inline void put(double* p, py::ssize_t i, const Vec3& v) {
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


}  // namespace stf::python
