#!/usr/bin/env bash
# Times `normalfit convert` of the 4096² float32 GeoTIFF of bench/terrain.sh
# with and without holes (10 % random −9999 texels; one nodata region, a
# 1500 × 1200 block and a disc), against another build of normalfit (the
# program before holes, say) on the same files, in one run: best of N wall
# times and the highest peak RSS (/usr/bin/time), each binary in turn.
#
#   bench/holes.sh OTHER_NORMALFIT [N]
#
# Needs GDAL (gdal_translate), python3 and GNU time.
set -euo pipefail
cd "$(dirname "$0")/.."
old=$(realpath "$1")
n=${2:-5}
target=${CARGO_TARGET_DIR:-target}
work=bench/.work
mkdir -p "$work"
cargo build --release --locked --bin normalfit --example heightmap
new=$(realpath "$target/release/normalfit")
h=$work/h4096.png
dem=$work/dem4096.tif
[ -f "$h" ] || "$target/release/examples/heightmap" 4096 "$h"
[ -f "$dem" ] || gdal_translate -q -ot Float32 -scale 0 65535 0 2000 -a_srs EPSG:32633 \
  -a_ullr 500000 5000000 540960 4959040 "$h" "$dem"
if [ ! -f "$work/region.tif" ]; then
  gdal_translate -q -of ENVI "$dem" "$work/dem.raw"
  python3 - "$work" <<'PY'
import array, random, sys
work = sys.argv[1]
n = 4096
a = array.array('f')
with open(f'{work}/dem.raw', 'rb') as f:
    a.frombytes(f.read())
random.seed(3)
b = array.array('f', a)
for k in random.sample(range(n * n), n * n // 10):
    b[k] = -9999.0
open(f'{work}/holes10.raw', 'wb').write(b.tobytes())
c = array.array('f', a)
for y in range(1000, 2200):
    c[y * n + 1200:y * n + 2700] = array.array('f', [-9999.0] * 1500)
for y in range(3000, 3800):
    for x in range(200, 1000):
        if (x - 600) ** 2 + (y - 3400) ** 2 < 400 ** 2:
            c[y * n + x] = -9999.0
open(f'{work}/region.raw', 'wb').write(c.tobytes())
PY
  for v in holes10 region; do
    cp "$work/dem.hdr" "$work/$v.hdr"
    gdal_translate -q -a_nodata -9999 -of GTiff "$work/$v.raw" "$work/$v.tif"
  done
fi
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg), $(nproc) cores"
echo
echo "| input | other | this | ratio | peak RSS other / this |"
echo "|---|---|---|---|---|"
for input in "$dem" "$work/holes10.tif" "$work/region.tif"; do
  declare -A best=([old]=999 [new]=999) peak=([old]=0 [new]=0)
  for _ in $(seq "$n"); do
    for b in old new; do
      bin=$old; [ $b = new ] && bin=$new
      /usr/bin/time -f '%e %M' -o "$work/time.txt" "$bin" convert "$input" -o "$work/holes_$b.png" \
        -s 0.1 --border clamp --bits 8 --quiet >/dev/null
      read -r t m < "$work/time.txt"
      best[$b]=$(python3 -c "print(min(${best[$b]}, $t))")
      peak[$b]=$(( m > ${peak[$b]} ? m : ${peak[$b]} ))
    done
  done
  ratio=$(python3 -c "print(f'{${best[new]} / ${best[old]}:.2f}×')")
  echo "| $(basename "$input") | ${best[old]} s | ${best[new]} s | $ratio | $((${peak[old]} / 1024)) / $((${peak[new]} / 1024)) MiB |"
done
echo
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
