// Measured media a render scene may name (`preset = "wholemilk"`), per millimetre, RGB.
//
// Jensen, Marschner, Levoy, Hanrahan 2001, "A Practical Model for Subsurface Light Transport"
// (SIGGRAPH), Figure 5: the reduced scattering coefficient sigma_s' = sigma_s (1 - g) and the
// absorption coefficient sigma_a, in mm^-1; no g was measured. A preset uses them with g = 0
// (sigma_s = sigma_s'): by the similarity relation, the same light deep inside the medium; near
// the surface, where single scattering shows, a forward g would differ.
//
// Narasimhan, Gupta, Donner, Ramamoorthi, Nayar, Jensen 2006, "Acquiring Scattering Properties of
// Participating Media by Dilution" (SIGGRAPH), Table 1 (as the media are sold, not diluted): the
// full sigma_s, sigma_a in mm^-1 and g per channel.
#pragma once

#include <array>
#include <string>
#include <vector>

namespace stf::scene {

using Rgb = std::array<double, 3>;

struct MeasuredMedium {
  const char* name;
  Rgb sigma_s, sigma_a, g;  // per mm; sigma_s the full coefficient
  const char* source;       // "Jensen et al. 2001 (reduced, g = 0)" or "Narasimhan et al. 2006"
};

const std::vector<MeasuredMedium>& measured_media();
// The preset of that name, or nullptr.
const MeasuredMedium* find_measured_medium(const std::string& name);

}  // namespace stf::scene
