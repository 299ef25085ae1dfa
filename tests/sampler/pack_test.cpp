// The binary pack: exact round trips, and the sampler's density equals the fitter's.
#include "stf/pack.h"

#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>

#include "stf/fit/fit_table.h"
#include "sh_fit.h"
#include "stf/precompute/precompute.h"
#include "stf/core/rng.h"
#include "stf/sampler.h"
#include "test_models.h"

namespace stf {
namespace {

Vec3 random_direction(std::uint64_t& s) {
  double z = 2 * (double(splitmix64(s) >> 11) * 0x1p-53) - 1, phi = 2 * kPi * (double(splitmix64(s) >> 11) * 0x1p-53);
  double r = std::sqrt(1 - z * z);
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// A pack of another version is refused in one line naming its version and the fix.
TEST(Pack, PacksOfOtherVersionsAreRefusedNamingTheFix) {
  std::vector<std::uint8_t> bytes = write_pack({PackEntry{"", test::make_vmf_model()}});
  std::vector<PackEntry> out;
  std::string error;
  ASSERT_TRUE(read_pack(bytes.data(), bytes.size(), out, error)) << error;
  bytes[8] = std::uint8_t(kPackVersion - 1);  // the header's version, outside the checksum
  EXPECT_FALSE(read_pack(bytes.data(), bytes.size(), out, error));
  EXPECT_NE(error.find("pack version " + std::to_string(kPackVersion - 1) + " is older"), std::string::npos) << error;
  EXPECT_NE(error.find("stf pack"), std::string::npos) << error;
  EXPECT_TRUE(out.empty());
  bytes[8] = std::uint8_t(kPackVersion + 1);
  EXPECT_FALSE(read_pack(bytes.data(), bytes.size(), out, error));
  EXPECT_NE(error.find("is newer"), std::string::npos) << error;
}

std::vector<PackEntry> round_trip(const std::vector<PackEntry>& in) {
  std::vector<std::uint8_t> bytes = write_pack(in);
  std::vector<PackEntry> out;
  std::string error;
  EXPECT_TRUE(read_pack(bytes.data(), bytes.size(), out, error)) << error;
  return out;
}

// The error read_pack gives for a pack of this one model ("" where it loads).
std::string read_error(const StfModel& m) {
  const std::vector<std::uint8_t> bytes = write_pack({{"", m}});
  std::vector<PackEntry> out;
  std::string error;
  const bool loaded = read_pack(bytes.data(), bytes.size(), out, error);
  EXPECT_EQ(loaded, error.empty());
  return error;
}

TEST(Pack, RoundTripKeepsModelsToFloatPrecision) {
  std::vector<PackEntry> in = {{"milk", test::make_vmf_model()}, {"", test::make_sh_model()}, {"h", test::make_vmf_model()},
                               {"l", test::lifted(test::make_vmf_model())}};
  in[2].model.hemispherical = true;
  in[2].model.rebuild_lobe_norms();
  in[0].model.once_fraction = 0.25;
  in[0].model.alpha_blend = 3;
  in[0].model.alpha_tilt = {-2.5, 1.0, 0.3, 0.0, -0.7, 4.0};
  in[0].model.uncollided_fraction = 0.1 * in[0].model.alpha_probability[0];
  in[2].model.alpha_turn = {1.5, -2.0, 3.0, 0.7, 1.0, -0.5};
  in[2].model.alpha_blend = 2;
  in[2].model.alpha_blend_width = {0, 2, 1, 2, 2, 0};
  std::vector<PackEntry> out = round_trip(in);
  ASSERT_EQ(out.size(), 4u);
  EXPECT_EQ(out[0].name, "milk");
  EXPECT_TRUE(out[2].model.hemispherical);
  EXPECT_FALSE(out[0].model.hemispherical);
  EXPECT_TRUE(out[3].model.lifted);
  EXPECT_FALSE(out[2].model.lifted);
  EXPECT_EQ(out[0].model.alpha_blend, 3);
  EXPECT_EQ(out[1].model.alpha_blend, 0);
  EXPECT_TRUE(out[0].model.alpha_blend_width.empty());  // one width for every bin packs none
  EXPECT_EQ(out[2].model.alpha_blend, 2);
  EXPECT_EQ(out[2].model.alpha_blend_width, in[2].model.alpha_blend_width);
  ASSERT_EQ(out[0].model.alpha_tilt.size(), 6u);
  for (int b = 0; b < 6; ++b) EXPECT_NEAR(out[0].model.alpha_tilt[b], in[0].model.alpha_tilt[b], 1e-6);
  EXPECT_TRUE(out[0].model.alpha_turn.empty());  // a model that does not turn packs no turns
  ASSERT_EQ(out[2].model.alpha_turn.size(), 6u);
  for (int b = 0; b < 6; ++b) EXPECT_NEAR(out[2].model.alpha_turn[b], in[2].model.alpha_turn[b], 1e-6);
  EXPECT_EQ(in[2].model.packed_bytes(), test::make_vmf_model().packed_bytes() + 6 * 4 + 8);  // turns, widths
  // One header; each record as packed_bytes() reports it, plus its name padded to 4 bytes.
  EXPECT_EQ(write_pack(in).size(), std::size_t(in[0].model.packed_bytes() + in[1].model.packed_bytes() + in[2].model.packed_bytes() +
                                               in[3].model.packed_bytes() - 3 * 32 + 4 + 4 + 4));
  std::uint64_t s = 61;
  for (std::size_t e = 0; e < in.size(); ++e) {
    EXPECT_EQ(out[e].model.tau, in[e].model.tau);
    EXPECT_EQ(out[e].model.escape_probability, in[e].model.escape_probability);
    EXPECT_EQ(out[e].model.once_fraction, in[e].model.once_fraction);
    EXPECT_EQ(out[e].model.uncollided_fraction, in[e].model.uncollided_fraction);
    for (int b = 0; b < in[e].model.bins(); ++b)
      for (int i = 0; i < 200; ++i) {
        Vec3 w = random_direction(s);
        double a = in[e].model.direction_pdf(b, w), p = out[e].model.direction_pdf(b, w);
        // float32 parameters: kappa (1 - cos) amplifies their 6e-8 rounding in the tails.
        EXPECT_NEAR(p, a, 1e-4 * a + 1e-9) << "entry " << e << " bin " << b;
      }
  }
}

// The same fitted model reaches a renderer through two paths, the fitter's double-precision
// StfModel and the float32 pack: their densities agree to float precision at random points.
TEST(Pack, SamplerDensityEqualsTheFittersDensity) {
  PrecomputeSettings settings;
  settings.paths = 40000;
  settings.grid = "healpix:4";
  settings.alpha_bins = 9;
  Table t = *precompute({4, 0.5, 0.5, 1}, settings);
  for (const char* spec : {"vmf:3", "hvmf:3", "lvmf:3", "sh:6"}) {
    StfModel fitted = fit::fit_table(t, fit::parse_model_spec(spec));
    ShellSampler from_pack(round_trip({{"", fitted}}).front().model), direct(fitted);
    std::uint64_t s = 62;
    for (int i = 0; i < 2000; ++i) {
      Vec3 y = random_direction(s), w = random_direction(s);
      double a = direct.pdf(y, w), p = from_pack.pdf(y, w);
      // float32 parameters: 1e-4 of the value, or of the mean density 1 / (4 pi)^2 where the
      // clamped SH density is near zero and the rounding of its coefficients dominates.
      ASSERT_NEAR(p, a, 1e-4 * std::max(a, 1 / (16 * kPi * kPi))) << spec;
    }
  }
}

TEST(Pack, AcrossAlphaSeriesIsPackedAndRebuilt) {
  StfModel m = test::make_sh_model();
  m.alpha_degree = 1;
  std::vector<double> escapes(m.bins(), 100);
  fit::compress_across_alpha(m, escapes);
  StfModel r = round_trip({{"", m}}).front().model;
  EXPECT_EQ(r.alpha_degree, 1);
  for (std::size_t i = 0; i < m.sh.size(); ++i) EXPECT_NEAR(r.sh[i], m.sh[i], 1e-6);
  EXPECT_EQ(write_pack({{"", m}}).size(), std::size_t(m.packed_bytes()));
}

// Turns (StfModel::alpha_turn) are one per bin and within [-8, 8] radians per radian: checked
// when a model is built and when a pack is read.
TEST(Pack, TurnsOfTheWrongCountOrOutOfRangeAreRefused) {
  StfModel m = test::make_vmf_model();
  m.alpha_turn = {1, 1, 1};
  EXPECT_EQ(model_error(m), "alpha turns of the wrong count");
  m.alpha_turn = {1, 1, 1, 1, 1, std::nan("")};
  EXPECT_EQ(model_error(m), "alpha turn (/alpha/turn) out of range [-8, 8]");
  m.alpha_turn = {1, 1, 1, 1, -9, 1};
  EXPECT_EQ(model_error(m), "alpha turn (/alpha/turn) out of range [-8, 8]");
  EXPECT_EQ(read_error(m), "model 0: alpha turn out of range");
  m.alpha_turn[4] = 8;
  EXPECT_EQ(model_error(m), "");
}

// Blend widths per bin (StfModel::alpha_blend_width) are one per bin and none wider than
// alpha_blend: checked when a model is built and when a pack is read.
TEST(Pack, BlendWidthsOfTheWrongCountOrWiderThanTheBlendAreRefused) {
  StfModel m = test::make_vmf_model();
  m.alpha_blend = 2;
  m.alpha_blend_width = {1, 2, 0};
  EXPECT_EQ(model_error(m), "alpha blend widths of the wrong count");
  m.alpha_blend_width = {1, 2, 0, 3, 2, 1};
  EXPECT_EQ(model_error(m), "alpha blend width (/alpha/blend) out of range [0, alpha_blend]");
  EXPECT_EQ(read_error(m), "model 0: alpha blend width out of range");
  m.alpha_blend_width[3] = 2;
  EXPECT_EQ(model_error(m), "");
  EXPECT_EQ(round_trip({{"", m}}).front().model.alpha_blend_width, m.alpha_blend_width);
}

TEST(Pack, RejectsForeignTruncatedAndCorruptedFiles) {
  std::vector<std::uint8_t> good = write_pack({{"x", test::make_vmf_model()}});
  std::vector<PackEntry> out;
  std::string error;
  for (std::size_t n = 0; n < good.size(); n += 7) {
    EXPECT_FALSE(read_pack(good.data(), n, out, error)) << n;
    EXPECT_FALSE(error.empty());
  }
  std::vector<std::uint8_t> bad = good;  // (other versions: PacksOfOtherVersionsAreRefusedNamingTheFix)
  bad[100] ^= 0x40;  // payload byte: checksum catches it
  EXPECT_FALSE(read_pack(bad.data(), bad.size(), out, error));
  EXPECT_NE(error.find("checksum"), std::string::npos);
  bad = good;
  bad[0] = 'X';
  EXPECT_FALSE(read_pack(bad.data(), bad.size(), out, error));
  EXPECT_TRUE(out.empty());
}

}  // namespace
}  // namespace stf

namespace stf {
namespace {

// Packs whose parts cannot be drawn from are refused at load, with their checksum right (the
// writer does not check; the reader must): nothing to draw, a once-scattered part at a tau where
// its draw never accepts.
TEST(Pack, PartsThatCannotBeDrawnFromAreRefusedAtLoad) {
  auto refused = [](const StfModel& m, const std::string& words) {
    const std::vector<std::uint8_t> bytes = write_pack({PackEntry{"", m}});
    std::vector<PackEntry> out;
    std::string error;
    EXPECT_FALSE(read_pack(bytes.data(), bytes.size(), out, error)) << words;
    EXPECT_NE(error.find(words), std::string::npos) << error;
    EXPECT_EQ(pack_entry_error({"", m}).find(words) != std::string::npos, true) << words;
  };
  StfModel nothing = test::make_vmf_model();
  nothing.alpha_probability.assign(nothing.alpha_probability.size(), 0.0);
  nothing.once_fraction = 0;
  refused(nothing, "nothing to draw");
  StfModel far = test::make_vmf_model();
  far.tau = 1e12, far.once_fraction = 0.2;
  refused(far, "medium parameters out of range");
  far.tau = 5000;
  refused(far, "once-scattered part");
  EXPECT_EQ(pack_entry_error({"", test::make_vmf_model()}), "");
}

// A model's sizes are held to the same limits by the model checks, the pack writer's check and
// the pack reader: an SH table of more rows than a pack holds is refused by all.
TEST(Pack, ModelSizesHaveOneSetOfLimits) {
  StfModel m = test::make_sh_model();
  EXPECT_EQ(model_error(m), "");
  m.sh_nz = kMaxShNz + 1;
  EXPECT_NE(model_error(m), "");
  EXPECT_NE(model_size_error(true, m.bins(), m.band_limit, m.sh_nz, m.alpha_degree), "");
  EXPECT_NE(pack_entry_error({"", m}), "");
  EXPECT_EQ(model_size_error(true, m.bins(), m.band_limit, kMaxShNz, m.alpha_degree), "");
  EXPECT_NE(model_size_error(false, m.bins(), kMaxLobes + 1, 1, -1), "");
  StfModel nan_series = test::make_sh_model();
  nan_series.alpha_degree = 1;
  nan_series.sh_chebyshev.assign(2 * nan_series.sh.size() / std::size_t(nan_series.bins()), 0.0);
  nan_series.sh_chebyshev[3] = std::nan("");
  EXPECT_NE(model_error(nan_series).find("not finite"), std::string::npos);
}

}  // namespace
}  // namespace stf
