#!/usr/bin/env bash
# Times normalfit on float32 GeoTIFF DEMs against GDAL's DEM tools, in one
# run: normals (`convert`, to PNG, EXR and GeoTIFF) against `gdaldem
# slope`, and the lit view (`shade`, gdaldem's sun, to PNG and GeoTIFF)
# against `gdaldem hillshade`, which write uncompressed GeoTIFF; then like
# with like: `convert --product slope|aspect|hillshade` against `gdaldem
# slope|aspect|hillshade`, the same products in the same files (float32
# GeoTIFF with nodata −9999; the hillshade 8-bit with nodata 0), with the
# user CPU time beside the wall time. Three
# DEMs of the same heights: projected in strips of one row (as
# gdal_translate writes), projected in 256² tiles (-co TILED=YES), and
# geographic (EPSG:4326, about 10 m texels at 45° N). Each is converted
# the way GIS users call it, `--units map` (the spacing from the file,
# heights in metres); the projected strips also with `-s 0.1` (texel
# units). Each command 5 times, in turn with its GDAL counterpart; the
# best wall time and the highest peak RSS (/usr/bin/time).
# Every output (and sidecar) is removed before each run, for both tools:
# replacing a file makes the file system free the old one's blocks first
# (50 ms for a 201 MB float output on this machine), which is not the
# conversion's work.
# Prints a Markdown table with the ratios and the load average: the
# machine may be shared, so compare ratios from one run.
#
#   bench/terrain.sh          # 4096² (bench/.work/dem4096.tif: the ridged noise
#                             # of examples/heightmap.rs, 0–2000 m, 10 m texels, UTM 33N)
#   bench/terrain.sh 2048     # another size
#   NO_BUILD=1 ONLY=products BASELINE=/path/to/old/normalfit bench/terrain.sh
#                             # the like-with-like table alone, with another
#                             # build's wall time beside (run in turn with
#                             # the others: one load for all three)
#
# Needs a Rust toolchain, GDAL and GNU time (apt-get install -y gdal-bin time).
set -euo pipefail
cd "$(dirname "$0")/.."
size=${1:-4096}
target=${CARGO_TARGET_DIR:-target}
work=bench/.work
mkdir -p "$work"
for tool in gdal_translate gdaldem /usr/bin/time; do
  command -v "$tool" >/dev/null || { echo "$tool is missing: apt-get install -y gdal-bin time" >&2; exit 1; }
done
# NO_BUILD=1: the binary (and the DEMs) are there already.
[ -n "${NO_BUILD:-}" ] || cargo build --release --locked --bin normalfit --example heightmap
bin=$target/release/normalfit
h=$work/h$size.png
dem=$work/dem$size.tif
[ -f "$h" ] || "$target/release/examples/heightmap" "$size" "$h"
# Heights 0 to 2000 m, 10 m texels: gdaldem's geometry is normalfit's at
# -s 0.1 (metres of height per metre of ground, one texel = 10 m).
[ -f "$dem" ] || gdal_translate -q -ot Float32 -scale 0 65535 0 2000 -a_srs EPSG:32633 \
  -a_ullr 500000 5000000 $((500000 + 10 * size)) $((5000000 - 10 * size)) "$h" "$dem"
# The same heights in 256 × 256 tiles.
tiled=$work/dem${size}_tiled.tif
[ -f "$tiled" ] || gdal_translate -q -co TILED=YES "$dem" "$tiled"
# The same heights in degrees: 1/9000° a texel (11.1 m north to south,
# 7.9 m east to west at 45° N).
geo=$work/dem${size}_4326.tif
[ -f "$geo" ] || gdal_translate -q -a_srs EPSG:4326 \
  -a_ullr 10 45.2 "$(python3 -c "print(10 + $size / 9000)")" "$(python3 -c "print(45.2 - $size / 9000)")" "$dem" "$geo"

# best wall time (s), highest peak RSS (MiB) and least user CPU time (s)
# of 5 runs of "$@": a run
# takes about 0.1 s, and one in three may lose 10 to 20 ms to the machine.
# The wall time is bash's clock around the run, to the millisecond
# (/usr/bin/time's is to 10 ms, a tenth of a run); the peak RSS is
# /usr/bin/time's.
measure() {
  local best=999999 peak=0 user=999999 t m u start end
  for _ in 1 2 3 4 5; do
    rm -f "$work"/n.* "$work"/lit.* "$work"/p.* "$work"/slope.tif "$work"/aspect.tif "$work"/hillshade.tif
    start=$EPOCHREALTIME
    /usr/bin/time -f '%M %U' -o "$work/time.txt" "$@" >/dev/null 2>"$work/stderr.txt" || { cat "$work/stderr.txt" >&2; exit 1; }
    end=$EPOCHREALTIME
    read -r m u < "$work/time.txt"
    best=$(python3 -c "print(f'{min($best, $end - $start):.3f}')")
    user=$(python3 -c "print(f'{min($user, $u):.2f}')")
    peak=$(( m > peak ? m : peak ))
  done
  echo "$best $((peak / 1024)) $user"
}

echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg), $(nproc) cores"
baseline=${BASELINE:-}
row() {
  local label=$1 gdal_label=$2 gdal_cmd=$3; shift 3
  read -r t m _ < <(measure "$@")
  # The output's size, from the argument after -o.
  local out="" prev="" arg
  for arg in "$@"; do [ "$prev" = "-o" ] && out=$arg; prev=$arg; done
  local mb
  mb=$(python3 -c "print(f'{$(stat -c %s "$out") / 1e6:.1f} MB')")
  # shellcheck disable=SC2086
  read -r tg mg _ < <(measure $gdal_cmd)
  ratio=$(python3 -c "print(f'{$tg / $t:.2f}×')")
  echo "| $label | $t s | $m MiB | $mb | $gdal_label | $tg s | $mg MiB | $ratio |"
}
# A row of the like-with-like table: the same product from both tools
# (and from the BASELINE build, the same arguments, when given).
product_row() {
  local label=$1 gdal_cmd=$2; shift 2
  read -r t m u < <(measure "$@")
  # shellcheck disable=SC2086
  read -r tg mg ug < <(measure $gdal_cmd)
  local base=""
  if [ -n "$baseline" ]; then
    local tb
    read -r tb _ _ < <(measure "$baseline" "${@:2}")
    base=" $tb s | $(python3 -c "print(f'{$tg / $tb:.2f}×')") |"
  fi
  echo "| $label | $t s | $u s | $m MiB | $tg s | $ug s | $mg MiB | $(python3 -c "print(f'{$tg / $t:.2f}×')") |$base"
}
if [ "${ONLY:-}" != products ]; then
echo
echo "| ${size}² float32 GeoTIFF, 10 m texels | wall (best of 5) | peak RSS | output | GDAL | GDAL wall | GDAL RSS | speed-up |"
echo "|---|---|---|---|---|---|---|---|"
slope="gdaldem slope -q $dem $work/slope.tif"
hillshade="gdaldem hillshade -q $dem $work/hillshade.tif"
# Projected, strips of one row: map units, as GIS users call it.
row "convert --units map --border clamp → 8-bit PNG" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.png" --units map --border clamp --bits 8
row "convert --units map --border clamp → 16-bit PNG (the default for float input)" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.png" --units map --border clamp
row "convert --units map --border clamp → float EXR" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.exr" --units map --border clamp
row "convert --units map --border clamp → float GeoTIFF" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.tif" --units map --border clamp --bits 32
row "convert --units map --border clamp → 8-bit GeoTIFF" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.tif" --units map --border clamp --bits 8
row "convert --units map (wrap, the default) → 8-bit PNG" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.png" --units map --bits 8
row "shade --units map --border clamp (sun 315°, 45°) → PNG" "hillshade" "$hillshade" \
  "$bin" shade "$dem" -o "$work/lit.png" --units map --border clamp
row "shade --units map --border clamp (sun 315°, 45°) → GeoTIFF" "hillshade" "$hillshade" \
  "$bin" shade "$dem" -o "$work/lit.tif" --units map --border clamp
# The same in texel units: -s 0.1 is map units' geometry for 10 m texels.
row "convert -s 0.1 --border clamp → 8-bit PNG" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.png" -s 0.1 --border clamp --bits 8
row "convert -s 0.1 --border clamp → 16-bit PNG" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.png" -s 0.1 --border clamp
row "convert -s 0.1 --border clamp → float EXR" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.exr" -s 0.1 --border clamp
row "convert -s 0.1 --border clamp → float GeoTIFF" "slope" "$slope" \
  "$bin" convert "$dem" -o "$work/n.tif" -s 0.1 --border clamp --bits 32
row "shade -s 0.1 --border clamp (sun 315°, 45°) → PNG" "hillshade" "$hillshade" \
  "$bin" shade "$dem" -o "$work/lit.png" -s 0.1 --border clamp
# Projected, 256² tiles.
slope_t="gdaldem slope -q $tiled $work/slope.tif"
hillshade_t="gdaldem hillshade -q $tiled $work/hillshade.tif"
row "tiled: convert --units map --border clamp → 16-bit PNG" "slope" "$slope_t" \
  "$bin" convert "$tiled" -o "$work/n.png" --units map --border clamp
row "tiled: convert --units map --border clamp → float GeoTIFF" "slope" "$slope_t" \
  "$bin" convert "$tiled" -o "$work/n.tif" --units map --border clamp --bits 32
row "tiled: shade --units map --border clamp → GeoTIFF" "hillshade" "$hillshade_t" \
  "$bin" shade "$tiled" -o "$work/lit.tif" --units map --border clamp
# Geographic: gdaldem takes -s 111120 (metres per degree) for degrees.
slope_g="gdaldem slope -q -s 111120 $geo $work/slope.tif"
hillshade_g="gdaldem hillshade -q -s 111120 $geo $work/hillshade.tif"
row "EPSG:4326: convert --units map --border clamp → 16-bit PNG" "slope -s 111120" "$slope_g" \
  "$bin" convert "$geo" -o "$work/n.png" --units map --border clamp
row "EPSG:4326: convert --units map --border clamp → float GeoTIFF" "slope -s 111120" "$slope_g" \
  "$bin" convert "$geo" -o "$work/n.tif" --units map --border clamp --bits 32
row "EPSG:4326: shade --units map --border clamp → PNG" "hillshade -s 111120" "$hillshade_g" \
  "$bin" shade "$geo" -o "$work/lit.png" --units map --border clamp
fi
echo
echo "| ${size}² float32 GeoTIFF, like with like | wall (best of 5) | user CPU | peak RSS | gdaldem wall | gdaldem user CPU | gdaldem RSS | speed-up (wall) |${baseline:+ baseline wall | baseline speed-up |}"
echo "|---|---|---|---|---|---|---|---|${baseline:+---|---|}"
# gdaldem's N = 3 gradient is a plane's: --fit vertical is its fit.
fit=(--units map --border clamp --fit vertical)
product_row "slope (degrees) → float32 GeoTIFF" "gdaldem slope -q $dem $work/slope.tif" \
  "$bin" convert "$dem" -o "$work/p.tif" --product slope "${fit[@]}"
product_row "slope, orthogonal fit (the default)" "gdaldem slope -q $dem $work/slope.tif" \
  "$bin" convert "$dem" -o "$work/p.tif" --product slope --units map --border clamp
product_row "slope (percent)" "gdaldem slope -q -p $dem $work/slope.tif" \
  "$bin" convert "$dem" -o "$work/p.tif" --product slope --slope-units percent "${fit[@]}"
product_row "aspect → float32 GeoTIFF" "gdaldem aspect -q $dem $work/aspect.tif" \
  "$bin" convert "$dem" -o "$work/p.tif" --product aspect "${fit[@]}"
product_row "hillshade (315°, 45°) → 8-bit GeoTIFF" "gdaldem hillshade -q $dem $work/hillshade.tif" \
  "$bin" convert "$dem" -o "$work/p.tif" --product hillshade "${fit[@]}"
product_row "EPSG:4326: slope (metres per row; gdaldem -s 111120)" "gdaldem slope -q -s 111120 $geo $work/slope.tif" \
  "$bin" convert "$geo" -o "$work/p.tif" --product slope "${fit[@]}"
product_row "EPSG:4326: aspect" "gdaldem aspect -q $geo $work/aspect.tif" \
  "$bin" convert "$geo" -o "$work/p.tif" --product aspect "${fit[@]}"
product_row "EPSG:4326: hillshade" "gdaldem hillshade -q -s 111120 $geo $work/hillshade.tif" \
  "$bin" convert "$geo" -o "$work/p.tif" --product hillshade "${fit[@]}"
echo
# normalfit syncs every output to disk before putting it in place (an
# output appears whole or not at all, after a crash too); gdaldem does
# not. What that costs for a float normal map's bytes, on this disk:
mib=$(( (size * size * 12 + (1 << 20) - 1) >> 20 ))
read -r t _ < <(measure dd if=/dev/zero of="$work/n.dd" bs=1M count=$mib conv=fdatasync)
echo "writing $mib MiB (a ${size}² float normal map's size) and syncing it, dd conv=fdatasync: $t s (best of 5)"
rm -f "$work/n.dd"
echo
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
