#!/usr/bin/env bash
# Installs stf from the build tree, builds examples/ against the installed package (the way a
# renderer would), and walks a path with a freshly fitted pack.
#   install_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1 source=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/install" > /dev/null
cmake -S "$source/examples" -B "$work/example" -DCMAKE_PREFIX_PATH="$work/install" > /dev/null
cmake --build "$work/example" > /dev/null
# The sampler needs nothing beyond the C++ standard library.
if ldd "$work/example/walk_medium" | grep -Eiq "ceres|hdf5|healpix|wcs|eigen"; then
  echo "walk_medium links more than the standard library"; exit 1
fi
"$build/stf" precompute --sigma-s 8 --sigma-a 0.2 --g 0.6 --alpha-bins 18 --grid healpix:4 --paths 20000 --quiet -o "$work/t.h5"
"$build/stf" fit "$work/t.h5" --model vmf:2 --quiet --pack "$work/m.stfpack" -o "$work/m.h5"
out=$("$work/example/walk_medium" "$work/m.stfpack" 8.2 20 200)
echo "$out"
echo "$out" | grep -q "strides per path"
