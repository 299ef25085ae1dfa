#include "stf/scene/presets.h"

namespace stf::scene {

const std::vector<MeasuredMedium>& measured_media() {
  static const char* jensen = "Jensen et al. 2001 (reduced sigma_s', used with g = 0)";
  static const char* narasimhan = "Narasimhan et al. 2006";
  static const std::vector<MeasuredMedium> media = {
      {"apple", {2.29, 2.39, 1.97}, {0.0030, 0.0034, 0.046}, {0, 0, 0}, jensen},
      {"cream", {7.38, 5.47, 3.15}, {0.0002, 0.0028, 0.0163}, {0, 0, 0}, jensen},
      {"ketchup", {0.18, 0.07, 0.03}, {0.061, 0.97, 1.45}, {0, 0, 0}, jensen},
      {"marble", {2.19, 2.62, 3.00}, {0.0021, 0.0041, 0.0071}, {0, 0, 0}, jensen},
      {"potato", {0.68, 0.70, 0.55}, {0.0024, 0.0090, 0.12}, {0, 0, 0}, jensen},
      {"skimmilk", {0.70, 1.22, 1.90}, {0.0014, 0.0025, 0.0142}, {0, 0, 0}, jensen},
      {"skin1", {0.74, 0.88, 1.01}, {0.032, 0.17, 0.48}, {0, 0, 0}, jensen},
      {"skin2", {1.09, 1.59, 1.79}, {0.013, 0.070, 0.145}, {0, 0, 0}, jensen},
      {"wholemilk", {2.55, 3.21, 3.77}, {0.0011, 0.0024, 0.014}, {0, 0, 0}, jensen},
      {"espresso", {7.78262, 8.13050, 8.53875}, {4.79838, 6.57512, 8.84925}, {0.907, 0.896, 0.880}, narasimhan},
      {"milk", {18.2052, 20.3826, 22.3698}, {0.00153, 0.00460, 0.01993}, {0.750, 0.714, 0.681}, narasimhan},
      {"lowfat_milk", {13.1157, 15.4445, 17.9572}, {0.00287, 0.00575, 0.01150}, {0.932, 0.902, 0.859}, narasimhan},
  };
  return media;
}

const MeasuredMedium* find_measured_medium(const std::string& name) {
  for (const MeasuredMedium& m : measured_media())
    if (name == m.name) return &m;
  return nullptr;
}

}  // namespace stf::scene
