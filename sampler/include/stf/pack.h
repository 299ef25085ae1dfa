// The compact binary pack a renderer loads: one or many fitted models with their media.
//
// Layout (all little-endian):
//   header, 32 bytes: magic "STFPACK1", u32 version (kPackVersion), u32 model count,
//                     u64 payload bytes, u64 FNV-1a 64 checksum of the payload
//   payload: the model records back to back, each
//     u32 record bytes, u32 name bytes, name (UTF-8, no terminator),
//     u32 kind (0 vmf, 1 sh), u32 bins, u32 lobes or band limit, u32 SH table nz,
//     i32 alpha degree (-1: none), u32 flags (bit 0: hemispherical vMF lobes; bits 1-2: the
//         alpha blend width, 0-3, the widest where bins differ; bit 3: alpha turns follow;
//         bit 4: blend widths follow; bit 5: lifted vMF lobes, StfModel::lifted),
//     f64 tau, albedo, g, escape probability, absorbed fraction, truncated fraction,
//         uncollided fraction, once-scattered fraction,
//     f32 alpha probability [bins], u8 bin status [bins] padded to 4 bytes,
//     f32 alpha tilt [bins] (stf/tilt.h),
//     f32 alpha turn [bins] (with flag bit 3),
//     u8 alpha blend width [bins] padded to 4 bytes (with flag bit 4),
//     vmf: f32 [bins * lobes * 4] (weight, kappa, mean's polar and azimuthal angle)
//     sh:  f32 [bins * (L+1)^2], or with alpha degree D >= 0 f32 [(D+1) * (L+1)^2]
// Alpha bins are linear on [0, pi]. Loading validates everything: a truncated, corrupted or
// foreign file gives an error message, never undefined behaviour.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "stf/model.h"

namespace stf {

// The one layout this library reads. Packs of other versions are refused in one line naming
// theirs and the fix: build the pack again (stf pack, stf build), from models fitted again where
// they are older too.
inline constexpr std::uint32_t kPackVersion = 6;

struct PackEntry {
  std::string name;  // e.g. the medium's name in a scene; may be empty
  StfModel model;
};

// Whether `model` was precomputed for the medium of single-scattering albedo `albedo` and
// Henyey-Greenstein asymmetry `g`: both agree to 1e-9 relative. A pack stores them as doubles,
// so what was written matches itself; the slack covers an albedo recomputed as
// sigma_s / (sigma_s + sigma_a) in another order. Spheres are looked up by medium, never by
// name: a name cannot tell two media apart, and a sphere of another albedo is a wrong answer.
bool same_medium(const StfModel& model, double albedo, double g);

// Serialises entries (models must have linear alpha bins on [0, pi]). Throws
// std::invalid_argument where pack_entries_error objects.
std::vector<std::uint8_t> write_pack(const std::vector<PackEntry>& entries);

// Why `entries` would mislead a reader of the pack, or "": entries under one name must be of
// one medium (albedo and g, compared as same_medium does), so a name shown to a
// user never stands for two media.
std::string pack_entries_error(const std::vector<PackEntry>& entries);

// A name for the medium (albedo, g) in the digits that read back to the same doubles, e.g.
// "albedo 0.999042 g 0.85": what `stf pack` names entries given no --name.
std::string medium_name(double albedo, double g);

// `x` in the fewest digits that read back to the same double.
std::string round_trip(double x);

// Why read_pack would refuse a pack holding `entry` (it is written and read back: the pack
// reader's own rules), or "" when it would not. Writers check before they write.
std::string pack_entry_error(const PackEntry& entry);

// Parses a pack; on failure returns false and sets `error` (one line).
bool read_pack(const std::uint8_t* data, std::size_t size, std::vector<PackEntry>& entries, std::string& error);
bool read_pack_file(const std::string& path, std::vector<PackEntry>& entries, std::string& error);

// Bytes of one model's record in a pack (what StfModel::packed_bytes() reports, with an
// empty name, plus the pack header).
std::int64_t record_bytes(const StfModel& model, std::size_t name_bytes);

}  // namespace stf
