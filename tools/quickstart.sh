#!/usr/bin/env bash
# stf Quick start on Debian 12.
#   tools/quickstart.sh          install what is missing (apt), build stf, build the default scene
#                                of data/ into a pack and report on it; precompute, fit and plot
#                                the default medium; everything into out/
#   tools/quickstart.sh --test   the same set-up, then the whole test suite (ctest)
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(cmake g++ make pkg-config libhdf5-dev libcli11-dev wcslib-dev libhealpix-cxx-dev
          libceres-dev libeigen3-dev libxxhash-dev nlohmann-json3-dev libfmt-dev libopenimageio-dev libembree-dev libopenvdb-dev libboost-iostreams-dev libtoml11-dev libgtest-dev libbenchmark-dev python3-matplotlib python3-h5py
          python3-numpy openmpi-bin libopenmpi-dev pybind11-dev python3-dev python3-healpy)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "quickstart: installing ${missing[*]}" >&2
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release

if [ "${1:-}" = "--test" ]; then
  cmake --build build -j "$(nproc)"
  ctest --test-dir build --output-on-failure -j "$(nproc)"
  exit
fi

# The main job needs the command and the Python module, not the tests and benches (half the
# build): `cmake --build build` builds those too.
cmake --build build -j "$(nproc)" --target stf stf_python

mkdir -p out
# The density grids of data/scenes/cloud.toml and cored_ball.toml (into data/scenes/grids/).
/usr/bin/python3 bench/make_grids.py
build/stf build data/scenes/default.toml --cache out/default-scene.cache -o out/default.stfpack
build/stf report out/default.stfpack -o out/report
build/stf --config data/default_medium.toml precompute -o out/default_healpix.h5
build/stf --config data/default_medium.toml precompute --grid csc:45 -o out/default_csc.h5
build/stf plot out/default_csc.h5 out/default_healpix.h5 --alpha 30 -o out/default_alpha30.png
build/stf fit out/default_healpix.h5 --model vmf:4 --report out/default_vmf4.json -o out/default_vmf4.h5
build/stf plot out/default_healpix.h5 --model out/default_vmf4.h5 --alpha 30 -o out/default_vmf4_alpha30.png
# One pair: Spot in whole milk behind glass (data/scenes/milk_spot.toml) by brute force and in
# strides, at 256 x 256 in colour (the strided render builds its pack first, into the cache:
# 15 spheres, 5 per channel, certified within TV 0.05 to keep this short), side by side with the
# z-map of their difference.
build/stf render data/scenes/milk_spot.toml --spp 24 --seed 1 --method brute -o out/render_brute.h5 \
  --png out/render_brute.png --exr out/render_brute.exr --exposure -0.5
build/stf render data/scenes/milk_spot.toml --spp 24 --seed 2 --method stf --tolerance 0.05 \
  --cache out/render.cache -o out/render_stf.h5 --png out/render_stf.png --exposure -0.5
/usr/bin/python3 tools/render_pair.py out/render_brute.h5 out/render_stf.h5 -o out/render_pair.png
echo "quickstart: in out/: default.stfpack and report/ (report.md, PNGs, JSON)," \
     "render_pair.png (Spot in milk behind glass by brute force and in strides, and the z-map of their difference)," \
     "default_alpha30.png (CSC above, HEALPix below)," \
     "default_vmf4_alpha30.png (table and fitted vmf:4 side by side);" \
     "data/scenes/grids/ (the cloud's and the cored ball's density grids, for data/scenes/cloud.toml and cored_ball.toml);" \
     "Python: PYTHONPATH=build/python /usr/bin/python3 -c 'import stf' (docs/python.md)" >&2
