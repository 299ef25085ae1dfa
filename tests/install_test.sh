#!/usr/bin/env bash
# Installs stf from the build tree, builds examples/ against the installed package (the way a
# renderer would), and walks paths with a freshly built scene pack.
#   install_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1 source=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/install" > /dev/null
cmake -S "$source/examples" -B "$work/example" -DCMAKE_PREFIX_PATH="$work/install" > /dev/null
cmake --build "$work/example" > /dev/null
# The sampler needs nothing beyond the C++ standard library.
for example in walk_medium render_medium; do
  if ldd "$work/example/$example" | grep -Eiq "ceres|hdf5|healpix|wcs|eigen"; then
    echo "$example links more than the standard library"; exit 1
  fi
done
# A scene of one medium with spheres from tau 2 to 16, built into a pack.
cat > "$work/scene.toml" <<'TOML'
[settings]
paths = 20000
grid = "healpix:4"
alpha_bins = 18
model = "vmf:2"
[[media]]
name = "fog"
sigma_s = 8.0
sigma_a = 0.2
g = 0.6
radius_min = 0.25
radius_max = 2.0
TOML
"$build/stf" build "$work/scene.toml" --quiet -o "$work/scene.stfpack"
out=$("$work/example/walk_medium" "$work/scene.stfpack" fog 8.2 20 200)
echo "$out"
echo "$out" | grep -q "strides per path"
# A medium the pack does not hold (say, a number given where the medium goes) is an error, not a
# silent walk of nothing.
if "$work/example/walk_medium" "$work/scene.stfpack" 8.2 20 200 2>/dev/null; then
  echo "walk_medium accepted a medium the pack does not hold" >&2
  exit 1
fi
# The renderer-side integration: the strided radiance through a sphere of the medium agrees
# with direct tracking within 4.5 combined standard errors.
out=$("$work/example/render_medium" "$work/scene.stfpack" 8.0 0.2 0.6 2.0 40000)
echo "$out"
echo "$out" | awk '/^direct/ {d = $3; sd = $5} /^strided/ {s = $3; ss = $5; n = $6}
  END { z = (s - d) / sqrt(sd * sd + ss * ss); printf "z = %.2f\n", z;
        if (n + 0 <= 0 || z > 4.5 || z < -4.5) exit 1 }'
# The Python module, where the build made one: installed where Debian's python3 finds it.
if ls "$build"/python/stf*.so > /dev/null 2>&1; then
  site=$(ls -d "$work"/install/lib/python3*/dist-packages)
  PYTHONPATH="$site" /usr/bin/python3 -c "import stf, sys; sys.exit(0 if stf.__file__.startswith('$site') else 1)"
  echo "python module installed in $site"
fi
