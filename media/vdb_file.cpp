// Loads the grid codec module (grid_codec.h) on first use.
#include "grid_codec.h"
#include "stf/core/plugin.h"

namespace stf::media {

namespace {

constexpr const char* kCodecName = "libstf_grid_codec.so";

const GridCodec* load_codec() {
  const core::PluginPlace place{kCodecName, "STF_GRID_CODEC", STF_GRID_CODEC_LIBDIR, STF_GRID_CODEC_INSTALLED,
                                reinterpret_cast<const void*>(&grid_codec)};
  using Export = const GridCodec* (*)();
  const auto get = reinterpret_cast<Export>(core::plugin_export(
      place, "stf_grid_codec", std::string("the grid codec ") + kCodecName + " (.vdb files are read and written through it and OpenVDB)"));
  return get();
}

}  // namespace

const GridCodec& grid_codec() {
  static const GridCodec* codec = load_codec();  // tried again after a failure (the exception ends the initialisation)
  return *codec;
}

}  // namespace stf::media
