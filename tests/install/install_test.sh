#!/usr/bin/env bash
# Installs a build into a temporary prefix and uses it as a program outside this tree would: the C example
# (examples/c) built once with pkg-config and once with CMake's find_package(egopd), run on the built-in tiny model
# for two clips, their taxels compared with the installed egopd command's taxels.csv for the same inputs and seed
# (the output folders byte for byte, the arrays value for value); then the Python module's tests (python/tests)
# and the Python example, with Debian's python3 and the module installed by `cmake --install`.
# usage: tests/install/install_test.sh BUILD_DIR WORK_DIR
set -euo pipefail
src=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "$1" && pwd)
work=$2
rm -rf "$work"
mkdir -p "$work"
work=$(cd "$work" && pwd)
prefix=$work/prefix
export XDG_CACHE_HOME=$work/cache OMP_WAIT_POLICY=passive EGOPD_THREADS=2
python=/usr/bin/python3
fail() { echo "install test FAILED: $*" >&2; exit 1; }

echo "-- cmake --install $build --prefix $prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log"
lib=$(find "$prefix" -name libegopd.so.0 | head -n 1)
[ -n "$lib" ] || fail "no libegopd.so.0 installed"
libdir=$(dirname "$lib")
for f in include/egopd.h bin/egopd bin/egopd-convert share/egopd/templates/synthetic_right_hand.json \
         share/egopd/tokenizer/vocab.json; do
  [ -e "$prefix/$f" ] || fail "$f not installed"
done
[ -e "$libdir/pkgconfig/egopd.pc" ] || fail "egopd.pc not installed"
[ -e "$libdir/cmake/egopd/egopdConfig.cmake" ] || fail "CMake package not installed"
readelf -d "$lib" | grep -q 'SONAME.*\[libegopd\.so\.0\]' || fail "SONAME is not libegopd.so.0"
others=$(nm -D --defined-only "$lib" | awk '{print $3}' | grep -v -e '^egopd_' -e '^EGOPD_0$' || true)
[ -z "$others" ] || fail "libegopd.so exports more than the C API: $(echo "$others" | head -n 3 | tr '\n' ' ')"

echo "-- the C example with pkg-config and with find_package(egopd)"
mkdir -p "$work/pc"
PKG_CONFIG_PATH=$libdir/pkgconfig make -s -C "$work/pc" -f "$src/examples/c/Makefile" VPATH="$src/examples/c" \
  CFLAGS="-O2 -Wall -Wextra -Werror -std=c99"
cmake -S "$src/examples/c" -B "$work/cm" -G Ninja -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_C_FLAGS="-Wall -Werror" \
  >"$work/cmake.log" || { cat "$work/cmake.log"; fail "find_package(egopd) configure"; }
cmake --build "$work/cm" >>"$work/cmake.log" || { cat "$work/cmake.log"; fail "find_package(egopd) build"; }

# References from the installed command: the built-in clip, and the same clip as an MP4 video.
egopd=$prefix/bin/egopd
args=(--frames 3 --size 64 --seed 5)
"$egopd" predict "${args[@]}" --out "$work/cli1" 2>"$work/cli1.log" || { cat "$work/cli1.log"; fail "egopd predict"; }
cp "$work/cli1/sample_clip.mp4" "$work/clip.mp4"
"$egopd" predict "${args[@]}" --video "$work/clip.mp4" --out "$work/cli2" 2>"$work/cli2.log" \
  || { cat "$work/cli2.log"; fail "egopd predict --video"; }

# The arrays as "%.17g" and taxels.csv's shortest round-trip decimals must be the same doubles.
same_values() {
  "$python" - "$1" "$2" <<'PY'
import sys
def rows(p):
    with open(p) as f:
        return [[float(v) for v in line.split(",")] for line in f.read().splitlines()[1:]]
a, b = rows(sys.argv[1]), rows(sys.argv[2])
sys.exit(0 if a == b and len(a) > 0 else 1)
PY
}
for ex in "$work/pc/predict_two_clips" "$work/cm/predict_two_clips"; do
  name=$(basename "$(dirname "$ex")")
  "$ex" "${args[@]}" --out "$work/ex_$name" --csv "$work/ex_$name/array" - "$work/clip.mp4" \
    >"$work/ex_$name.out" 2>"$work/ex_$name.log" || { cat "$work/ex_$name.log"; fail "$ex"; }
  grep -q "frame  2:" "$work/ex_$name.out" || fail "$name: no per-frame forces printed"
  for k in 1 2; do
    cmp "$work/ex_$name/clip$k/taxels.csv" "$work/cli$k/taxels.csv" || fail "$name clip $k: taxels.csv differs"
    same_values "$work/ex_$name/array$k.csv" "$work/cli$k/taxels.csv" || fail "$name clip $k: taxel array differs"
  done
  echo "   $name: clip 1 and clip 2 taxels identical to egopd predict"
done

echo "-- Python module (installed by cmake --install) and its tests"
pydir=$(dirname "$(find "$prefix" -type d -path '*dist-packages/egopd' | head -n 1)")
[ -d "$pydir/egopd" ] || fail "Python module not installed"
(cd "$work" && PYTHONPATH=$pydir EGOPD_CLI=$egopd PYTHONDONTWRITEBYTECODE=1 "$python" -m pytest -q -p no:cacheprovider \
   "$src/python/tests")

echo "-- pip install ./python (no index, no downloads)"
cp -r "$src/python" "$work/python-src"  # setuptools builds in the project folder: not in the source tree
"$python" -m pip install -q --no-index --no-deps --no-build-isolation --target "$work/pip" "$work/python-src" \
  >"$work/pip.log" 2>&1 || { cat "$work/pip.log"; fail "pip install ./python"; }
PYTHONPATH=$work/pip EGOPD_LIBRARY=$lib "$python" -c 'import egopd; print("   pip-installed module: egopd", egopd.version())'

echo "-- Python example: counterfactual weight sweep"
(cd "$work" && PYTHONPATH=$pydir PYTHONDONTWRITEBYTECODE=1 "$python" "$src/examples/python/weight_sweep.py" --frames 3 --size 64 \
   --weights 1,1000,omit --out "$work/sweep" 2>"$work/sweep.log") || { cat "$work/sweep.log"; fail "weight_sweep.py"; }
[ -s "$work/sweep/force_per_frame.csv" ] || fail "weight_sweep.py wrote no CSV"
if "$python" -c 'import matplotlib' 2>/dev/null; then
  [ -s "$work/sweep/force_per_frame.png" ] || fail "weight_sweep.py wrote no plot"
fi
echo "install test passed"
