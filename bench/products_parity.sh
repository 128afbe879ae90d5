#!/usr/bin/env bash
# Prints how normalfit's slope, aspect and hillshade maps (`convert
# --product`, docs/products.md) differ from gdaldem's on a real DEM: the
# shipped one (samples/dem/jacksboro_fault_dem.tif, USGS 3″), warped to
# UTM zone 16 on 90 m pixels and cut to the window the warp fills, as
# bench/terrain_page.sh gives it to both tools (no holes). Over the texels
# gdaldem computes (all but its one-texel edge): slope differences in
# degrees, aspect differences in degrees where gdaldem's slope is over 1°,
# hillshade differences in grey levels; for normalfit's N = 3 vertical fit
# (Prewitt's gradient) and its default orthogonal fit, against gdaldem's
# Horn (its default) and Zevenbergen–Thorne.
#
#   bench/products_parity.sh
#
# Needs a Rust toolchain and gdal-bin (gdalwarp, gdal_translate, gdaldem);
# the statistics are Python's standard library, over raw float32 copies.
set -euo pipefail
cd "$(dirname "$0")/.."
target=${CARGO_TARGET_DIR:-target}
work=bench/.work/products_parity
mkdir -p "$work"
for tool in gdalwarp gdal_translate gdaldem; do
  command -v "$tool" >/dev/null || { echo "$tool is missing: apt-get install -y gdal-bin" >&2; exit 1; }
done
cargo build --release --locked --bin normalfit
bin=$target/release/normalfit
gdalwarp -q -overwrite -t_srs EPSG:32616 -tr 90 90 -r cubic -dstnodata -32768 -ot Float32 \
  samples/dem/jacksboro_fault_dem.tif "$work/utm.tif"
gdal_translate -q -srcwin 10 9 324 345 "$work/utm.tif" "$work/dem.tif"

# A raster as raw float32 (ENVI), for the statistics.
raw() { gdal_translate -q -of ENVI -ot Float32 "$1" "$2"; }
for product in slope aspect hillshade; do
  gdaldem "$product" -q "$work/dem.tif" "$work/horn_$product.tif"
  gdaldem "$product" -q -alg ZevenbergenThorne "$work/dem.tif" "$work/zt_$product.tif"
  "$bin" convert "$work/dem.tif" -o "$work/vertical_$product.tif" --product "$product" --units map \
    --border clamp --fit vertical --quiet
  "$bin" convert "$work/dem.tif" -o "$work/orthogonal_$product.tif" --product "$product" --units map \
    --border clamp --quiet
  for who in horn zt vertical orthogonal; do raw "$work/${who}_$product.tif" "$work/${who}_$product.raw"; done
done
python3 - "$work" <<'PY'
import array, sys
work = sys.argv[1]
w, h = 324, 345
def load(name):
    a = array.array("f")
    with open(f"{work}/{name}.raw", "rb") as f:
        a.frombytes(f.read())
    return a
inside = [k for k in range(w * h) if 0 < k % w < w - 1 and 0 < k // w < h - 1]
def spread(d):
    d = sorted(d)
    at = lambda q: d[round((len(d) - 1) * q)]
    return f"median {at(0.5):.4f}, 99th percentile {at(0.99):.4f}, max {d[-1]:.4f}"
def turn(a, b):
    d = (a - b) % 360
    return min(d, 360 - d)
for ours in ["vertical", "orthogonal"]:
    for theirs in ["horn", "zt"]:
        s, t = load(f"{ours}_slope"), load(f"{theirs}_slope")
        print(f"{ours} N 3 vs gdaldem {theirs}: slope |Δ| ° {spread([abs(s[k] - t[k]) for k in inside])}")
        a, b = load(f"{ours}_aspect"), load(f"{theirs}_aspect")
        steep = [k for k in inside if t[k] > 1]
        print(f"  aspect |Δ| ° where the slope > 1° ({len(steep)} of {len(inside)} texels): "
              + spread([turn(a[k], b[k]) for k in steep]))
        g, r = load(f"{ours}_hillshade"), load(f"{theirs}_hillshade")
        d = [abs(round(g[k]) - round(r[k])) for k in inside]
        print(f"  hillshade grey levels {spread(d)}; {100 * d.count(0) / len(d):.1f} % equal, "
              f"{100 * sum(1 for v in d if v <= 1) / len(d):.1f} % within one")
PY
