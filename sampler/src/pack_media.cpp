// The media of pack entries: how entries are matched to a medium and named after it.
#include <algorithm>
#include <charconv>
#include <cmath>

#include "stf/pack.h"

namespace stf {

bool same_medium(const StfModel& model, double albedo, double g) {
  const auto close = [](double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(1.0, std::abs(b)); };
  return close(model.albedo, albedo) && close(model.g, g);
}

std::string round_trip(double x) {
  char text[32];
  const std::to_chars_result r = std::to_chars(text, text + sizeof text, x);
  return std::string(text, r.ptr);
}

std::string medium_name(double albedo, double g) { return "albedo " + round_trip(albedo) + " g " + round_trip(g); }

std::string pack_entries_error(const std::vector<PackEntry>& entries) {
  for (std::size_t i = 0; i < entries.size(); ++i)
    for (std::size_t j = 0; j < i; ++j) {
      const StfModel &a = entries[j].model, &b = entries[i].model;
      if (entries[j].name == entries[i].name && !same_medium(b, a.albedo, a.g))
        return "entries " + std::to_string(j) + " and " + std::to_string(i) + " are named '" + entries[i].name +
               "' but are of two media (" + medium_name(a.albedo, a.g) + "; " + medium_name(b.albedo, b.g) +
               "): give each medium its own name";
    }
  return "";
}

}  // namespace stf
