#!/usr/bin/env bash
# Makes docs/terrain.md's pictures of the shipped DEM
# (samples/dem/jacksboro_fault_dem.tif): normalfit's `shade` and GDAL's
# `gdaldem hillshade` of the same GeoTIFF, and their difference, and
# prints the grey-level differences the page quotes.
#
#   bench/terrain_page.sh            # writes docs/terrain_normalfit.png,
#                                    # docs/terrain_gdaldem.png, docs/terrain_difference.png
#
# The DEM is geographic (3″ pixels); GDAL 3.6's hillshade takes one scale
# for both axes of degrees, so both tools get it as a GIS user would give
# it to them: warped to UTM zone 16 (EPSG 32616) on square 90 m pixels
# (cubic), then cut to the window the warp fills (no empty corners), so
# neither tool meets a hole. Both then light it with the same sun
# (315°, 45°, gdaldem's default) at gain 1 in map units (heights in metres
# over metres of ground).
#
# Needs a Rust toolchain and GDAL with its Python tools
# (apt-get install -y gdal-bin python3-gdal).
set -euo pipefail
cd "$(dirname "$0")/.."
target=${CARGO_TARGET_DIR:-target}
work=bench/.work/terrain_page
mkdir -p "$work"
for tool in gdalwarp gdal_translate gdaldem gdal_calc.py; do
  command -v "$tool" >/dev/null || { echo "$tool is missing: apt-get install -y gdal-bin python3-gdal" >&2; exit 1; }
done
cargo build --release --locked --bin normalfit
bin=$target/release/normalfit
dem=samples/dem/jacksboro_fault_dem.tif

# 1. The DEM in metres on 90 m pixels, cut to the part the warp fills.
gdalwarp -q -overwrite -t_srs EPSG:32616 -tr 90 90 -r cubic -dstnodata -32768 -ot Float32 "$dem" "$work/utm.tif"
gdal_translate -q -srcwin 10 9 324 345 "$work/utm.tif" "$work/dem.tif"

# 2. The two hillshades, same sun, same gain. gdaldem leaves its one-texel
#    edge at 0 (nodata) unless -compute_edges; normalfit fits the edges
#    with clamped borders.
gdaldem hillshade -q "$work/dem.tif" "$work/gdaldem.tif"
"$bin" shade "$work/dem.tif" --units map --border clamp -q -o "$work/normalfit.png"

# 3. The pictures for the page: gdaldem's as an 8-bit PNG, and
#    |normalfit − gdaldem| × 32 (one grey level of difference shows as 32;
#    gdaldem's edge, where it has no value, is left black).
gdal_translate -q -of PNG "$work/gdaldem.tif" "$work/gdaldem.png"
gdal_calc.py --quiet --overwrite -A "$work/normalfit.png" -B "$work/gdaldem.tif" --type Byte --hideNoData \
  --calc "where(B == 0, 0, minimum(abs(A.astype(int16) - B.astype(int16)) * 32, 255))" --outfile "$work/difference.tif"
gdal_translate -q -of PNG "$work/difference.tif" "$work/difference.png"
# Write the page's copies without GDAL's .aux.xml sidecars.
cp "$work/normalfit.png" docs/terrain_normalfit.png
cp "$work/gdaldem.png" docs/terrain_gdaldem.png
cp "$work/difference.png" docs/terrain_difference.png

# 4. The figures: over the texels gdaldem computes (all but its edge).
gdal_calc.py --quiet --overwrite -A "$work/normalfit.png" -B "$work/gdaldem.tif" --type Int16 --NoDataValue -1 \
  --calc "where(B == 0, -1, abs(A.astype(int16) - B.astype(int16)))" --outfile "$work/absdiff.tif"
# GDAL's Python (python3-gdal) is the system's.
/usr/bin/python3 - "$work/absdiff.tif" <<'PY'
import sys
from osgeo import gdal
import numpy as np
d = gdal.Open(sys.argv[1]).ReadAsArray().astype(int)
d = np.sort(d[d >= 0])
at = lambda q: d[round((len(d) - 1) * q)]
print(f"{len(d)} texels: grey-level difference median {at(0.5)}, 99th percentile {at(0.99)}, max {d[-1]}, "
      f"mean {d.mean():.2f}; {np.mean(d <= 1) * 100:.1f} % within one level")
PY
ls -l docs/terrain_normalfit.png docs/terrain_gdaldem.png docs/terrain_difference.png
