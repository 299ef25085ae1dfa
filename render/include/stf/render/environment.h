// Light from an environment map: a latitude-longitude image of the radiance arriving from every
// direction, in place of a uniform sky.
//
// Layout: +y is up. Row v (0 at the top) holds polar angle theta = pi (v + 1/2) / height from
// +y; column u holds azimuth phi = 2 pi (u + 1/2) / width - pi, measured from -z toward +x, so
// the image's middle column looks down -z (where the default camera looks) and its left and
// right edges meet behind the camera. A direction's radiance is its texel's (no filtering: the
// same piecewise-constant function the map is sampled by).
//
// Sampling for next-event estimation: a texel with probability proportional to its mean over
// the three channels times sin(theta) at its row's middle (its solid angle up to a constant),
// then a uniform point of the texel in (phi, theta). The density per steradian of a direction is
// then P(texel) width height / (2 pi^2 sin theta), at the direction's own theta: exact, so
// the power heuristic against the phase function's density is too.
#pragma once

#include <string>
#include <vector>

#include "stf/alias.h"
#include "stf/vec3.h"

namespace stf::render {

class EnvironmentMap {
 public:
  // [height * width * 3] linear RGB, row 0 at the top; every value finite and >= 0 (else
  // std::invalid_argument naming the first pixel that is not).
  EnvironmentMap(int width, int height, std::vector<float> rgb);
  // The map in `path` (any image OpenImageIO reads: one channel is grey, else the first three
  // are RGB) times `scale`; throws std::runtime_error naming the path and why.
  static EnvironmentMap from_file(const std::string& path, double scale);

  double radiance(const Vec3& direction, int channel) const;
  // A direction drawn from (u1, u2) in [0, 1)^2, its density per steradian in `pdf` (0 and any
  // direction when the map is black).
  Vec3 sample(double u1, double u2, double& pdf) const;
  double pdf(const Vec3& direction) const;

 private:
  // The texel that holds a direction.
  std::size_t texel(const Vec3& direction, double& sin_theta) const;
  // The density per steradian of a draw in `texel` at polar angle theta.
  double density(std::size_t texel, double sin_theta) const;

  int width_ = 0, height_ = 0;
  std::vector<float> rgb_;
  std::vector<double> probability_;  // per texel, summing to 1 (all 0 for a black map)
  AliasTable texels_;
};

}  // namespace stf::render
