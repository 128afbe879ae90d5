//! Slope and aspect in map units against GDAL's `gdaldem slope` and
//! `gdaldem aspect` (Debian's `gdal-bin`): planes of known slope in
//! projected coordinates (EPSG 32633, square and unequal pixels) and in
//! geographic ones (EPSG 4326), and a real DEM (samples/dem/, USGS), whose
//! differences from GDAL's 3×3 methods docs/terrain-accuracy.md reports and
//! explains. Ignored where GDAL is absent: CI installs `gdal-bin` and runs
//! ignored tests (.ci/run).
//!
//! What GDAL 3.6 (Debian 12's, this machine's and CI's) does, and so what
//! is compared:
//! * `slope` divides the x and y differences by the pixel width and height
//!   times `-s`: projected planes match whatever their pixels;
//! * `aspect` takes the raw 3×3 differences and no pixel size: with square
//!   pixels it is the true aspect, with unequal ones it is not (a plane
//!   rising 0.3 east and 0.1 north on 10 × 20 m pixels faces 260.54°,
//!   GDAL says 251.57°). There normalfit is held to the true aspect, and
//!   GDAL's is checked to be either that or its square-pixel value;
//! * geographic rasters take one `-s` for both axes, so only planes along
//!   a meridian or a parallel have a scale at which GDAL is right (metres
//!   per degree of latitude, or of longitude at the row compared); other
//!   planes are held to their known slope and aspect.

use std::path::{Path, PathBuf};
use std::process::Command;

use normalfit::io::{ReadOptions, metres_per_degree, read_path};
use normalfit::units::{map_spacing, slope_aspect};
use normalfit::{Border, Borders, Convention, Fit, FitRequest, Options, Spacing, Units};

fn run(program: &str, args: &[&str]) {
    let out = Command::new(program).args(args).output().unwrap_or_else(|e| panic!("{program} runs: {e}"));
    assert!(out.status.success(), "{program} {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// An ASCII grid (AAIGrid, with GDAL's `dx`/`dy` for unequal spacing)
/// of `values`, lower-left corner (`x0`, `y0`), then a GeoTIFF of it in
/// `srs` with `gdal_translate`.
fn geotiff(
    dir: &Path,
    name: &str,
    (w, h): (usize, usize),
    values: &[f64],
    (x0, y0): (f64, f64),
    (dx, dy): (f64, f64),
    srs: &str,
) -> PathBuf {
    let grid = dir.join(format!("{name}.asc"));
    let mut text = format!("ncols {w}\nnrows {h}\nxllcorner {x0:.12}\nyllcorner {y0:.12}\ndx {dx:.15}\ndy {dy:.15}\n");
    for row in values.chunks(w) {
        text.push_str(&row.iter().map(|v| format!("{v:.12}")).collect::<Vec<_>>().join(" "));
        text.push('\n');
    }
    std::fs::write(&grid, text).unwrap();
    let tif = dir.join(format!("{name}.tif"));
    // The grid read as Float64 (AAIGrid's default for decimals is Float32,
    // whose rounding of heights near 300 m moves slopes by 1e-5°).
    let (grid, tif_path) = (grid.to_str().unwrap(), tif.to_str().unwrap());
    run("gdal_translate", &["-q", "-oo", "DATATYPE=Float64", "-a_srs", srs, "-ot", "Float64", grid, tif_path]);
    tif
}

/// Every value of a one-band raster GDAL wrote, row-major.
fn values(path: &Path) -> Vec<f64> {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    let samples = raster.into_stored_heights(None).unwrap();
    (0..samples.len()).map(|i| samples.height(i).unwrap()).collect()
}

/// `gdaldem slope` and `aspect` of `dem` (Horn's 3×3 unless `alg`), with
/// `-s scale`: (slope°, aspect°) per texel, −9999 where GDAL has none.
fn gdaldem(dir: &Path, dem: &Path, scale: f64, alg: Option<&str>) -> (Vec<f64>, Vec<f64>) {
    let (slope, aspect) = (dir.join("slope.tif"), dir.join("aspect.tif"));
    let alg: Vec<&str> = alg.map(|a| vec!["-alg", a]).unwrap_or_default();
    let s = scale.to_string();
    let mut args = vec!["slope", "-q", dem.to_str().unwrap(), slope.to_str().unwrap(), "-s", &s];
    args.extend(&alg);
    run("gdaldem", &args);
    let mut args = vec!["aspect", "-q", dem.to_str().unwrap(), aspect.to_str().unwrap()];
    args.extend(&alg);
    run("gdaldem", &args);
    (values(&slope), values(&aspect))
}

/// normalfit's slope and aspect of a GeoTIFF in map units (the spacing
/// from its georeferencing, or `spacing` when given).
fn ours(dem: &Path, opts: Options, spacing: Option<Spacing>) -> (usize, usize, Vec<(f64, Option<f64>)>) {
    let raster = read_path(dem, &ReadOptions::default()).unwrap();
    let (w, h) = (raster.width, raster.height);
    let spacing = spacing.unwrap_or_else(|| map_spacing(raster.georef.as_ref(), h).unwrap());
    let heights = raster.into_stored_heights(None).unwrap();
    let opts = opts.with_units(Units::Map(spacing));
    let n: Vec<[f64; 3]> = {
        let mut out = vec![[0.0f64; 3]; w * h];
        FitRequest::new(&opts).normals_into(&heights, w, h, &mut out).unwrap();
        out
    };
    let sa = n.iter().map(|&n| slope_aspect(n, opts.convention)).map(|s| (s.slope, s.aspect)).collect();
    (w, h, sa)
}

/// The smallest difference between two compass angles, in degrees.
fn angle(a: f64, b: f64) -> f64 {
    ((a - b + 540.0).rem_euclid(360.0) - 180.0).abs()
}

fn truth(p: f64, q: f64) -> (f64, Option<f64>) {
    let slope = p.hypot(q).atan().to_degrees();
    let aspect = (p != 0.0 || q != 0.0).then(|| (-p).atan2(-q).to_degrees().rem_euclid(360.0));
    (slope, aspect)
}

fn fit3() -> Options {
    Options::new().with_patch(3).with_fit(Fit::Vertical).with_borders(Borders::both(Border::Clamp))
}

/// Projected planes h = p·east + q·north on square and unequal pixels: the
/// slope matches GDAL's to 1e-3° at every texel GDAL computes (its edges
/// have none), and the aspect matches GDAL's where the pixels are square
/// and the known aspect everywhere; both fits, N = 3 and 5.
#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdaldem); CI installs it"]
fn projected_planes_match_gdaldem() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (12, 9);
    let mut compared = 0;
    // The largest differences from GDAL, printed for docs/terrain-accuracy.md.
    let (mut slope_gap, mut aspect_gap) = (0.0f64, 0.0f64);
    for (dx, dy) in [(10.0, 10.0), (30.0, 20.0), (5.0, 12.5)] {
        for (p, q) in [(0.3, 0.1), (-0.7, 0.25), (0.0, -1.2), (2.0, 0.0), (-0.02, -0.05), (0.0, 0.0)] {
            let (x0, top) = (500_000.0, 4_500_000.0);
            let z: Vec<f64> = (0..w * h)
                .map(|k| {
                    let (east, north) = (x0 + ((k % w) as f64 + 0.5) * dx, top - ((k / w) as f64 + 0.5) * dy);
                    300.0 + p * (east - x0) + q * (north - top + 1000.0)
                })
                .collect();
            let dem = geotiff(dir.path(), "plane", (w, h), &z, (x0, top - h as f64 * dy), (dx, dy), "EPSG:32633");
            let (gdal_slope, gdal_aspect) = gdaldem(dir.path(), &dem, 1.0, None);
            let (want_slope, want_aspect) = truth(p, q);
            for (n, fit) in [(3, Fit::Vertical), (3, Fit::Orthogonal), (5, Fit::Vertical), (5, Fit::Orthogonal)] {
                let (_, _, got) = ours(&dem, fit3().with_patch(n).with_fit(fit), None);
                let r = n / 2;
                for y in r.max(1)..h - r.max(1) {
                    for x in r.max(1)..w - r.max(1) {
                        let k = y * w + x;
                        let what = format!("{dx}×{dy} ({p}, {q}) N {n} {fit:?} ({x}, {y})");
                        let (slope, aspect) = got[k];
                        assert!((slope - gdal_slope[k]).abs() < 1e-3, "{what}: slope {slope}, GDAL {}", gdal_slope[k]);
                        assert!((slope - want_slope).abs() < 1e-6, "{what}: slope {slope}, known {want_slope}");
                        slope_gap = slope_gap.max((slope - gdal_slope[k]).abs());
                        match (aspect, want_aspect) {
                            (None, None) => assert_eq!(gdal_aspect[k], -9999.0, "{what}: GDAL's flat"),
                            (Some(a), Some(want)) => {
                                assert!(angle(a, want) < 1e-6, "{what}: aspect {a}, known {want}");
                                let g = gdal_aspect[k];
                                if dx == dy {
                                    assert!(angle(a, g) < 1e-3, "{what}: aspect {a}, GDAL {g}");
                                    aspect_gap = aspect_gap.max(angle(a, g));
                                } else {
                                    // GDAL 3.6 leaves the pixel size out of its aspect.
                                    let square = truth(p * dx, q * dy).1.unwrap();
                                    assert!(angle(g, want) < 1e-3 || angle(g, square) < 1e-3, "{what}: GDAL {g}");
                                }
                            }
                            other => panic!("{what}: aspect {other:?}"),
                        }
                        compared += 1;
                    }
                }
            }
        }
    }
    assert!(compared > 1000, "{compared}");
    println!("projected planes, {compared} texels: slope within {slope_gap:.2e}° of GDAL, aspect {aspect_gap:.2e}°");
}

/// Geographic planes (EPSG 4326, 1″ pixels near 45° N): a plane along a
/// meridian against GDAL with `-s` = metres per degree of latitude (every
/// row), one along a parallel with `-s` = metres per degree of longitude
/// at the row compared; a plane in any direction against its known slope
/// and aspect at every row (metres per degree at that row's latitude).
#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdaldem); CI installs it"]
fn geographic_planes_match_gdaldem() {
    let dir = tempfile::tempdir().unwrap();
    let (mut slope_gap, mut aspect_gap, mut known_gap) = (0.0f64, 0.0f64, 0.0f64);
    let (w, h) = (11, 9);
    let step = 1.0 / 3600.0;
    let (lon0, top) = (15.0, 45.01);
    let lat_of = |y: usize| top - (y as f64 + 0.5) * step;
    // h = P·(lon − lon0) + Q·(lat − top): P, Q metres per degree.
    for (pp, qq) in [(0.0, 40_000.0), (0.0, -90_000.0), (30_000.0, 0.0), (-70_000.0, 0.0), (25_000.0, 60_000.0)] {
        let z: Vec<f64> =
            (0..w * h).map(|k| 500.0 + pp * ((k % w) as f64 + 0.5) * step + qq * (lat_of(k / w) - top)).collect();
        let dem = geotiff(dir.path(), "geo", (w, h), &z, (lon0, top - h as f64 * step), (step, step), "EPSG:4326");
        for fit in [Fit::Vertical, Fit::Orthogonal] {
            let (_, _, got) = ours(&dem, fit3().with_fit(fit), None);
            for y in 1..h - 1 {
                let (east, north) = metres_per_degree(lat_of(y));
                let (want_slope, want_aspect) = truth(pp / east, qq / north);
                for x in 1..w - 1 {
                    let (slope, aspect) = got[y * w + x];
                    let what = format!("({pp}, {qq}) {fit:?} ({x}, {y})");
                    assert!((slope - want_slope).abs() < 1e-6, "{what}: slope {slope}, known {want_slope}");
                    assert!(angle(aspect.unwrap(), want_aspect.unwrap()) < 1e-6, "{what}: aspect {aspect:?}");
                    known_gap =
                        known_gap.max((slope - want_slope).abs()).max(angle(aspect.unwrap(), want_aspect.unwrap()));
                }
            }
            // GDAL where one scale is right: along a meridian, every row;
            // along a parallel, the middle row at its own scale.
            if pp != 0.0 && qq != 0.0 {
                continue;
            }
            let rows: Vec<usize> = if pp == 0.0 { (1..h - 1).collect() } else { vec![h / 2] };
            let (east, north) = metres_per_degree(lat_of(h / 2));
            let scale = if pp == 0.0 { north } else { east };
            let (gdal_slope, gdal_aspect) = gdaldem(dir.path(), &dem, scale, None);
            for &y in &rows {
                for x in 1..w - 1 {
                    let k = y * w + x;
                    let (slope, aspect) = got[k];
                    let what = format!("({pp}, {qq}) {fit:?} ({x}, {y})");
                    assert!((slope - gdal_slope[k]).abs() < 1e-3, "{what}: slope {slope}, GDAL {}", gdal_slope[k]);
                    assert!(
                        angle(aspect.unwrap(), gdal_aspect[k]) < 1e-3,
                        "{what}: aspect {aspect:?}, GDAL {}",
                        gdal_aspect[k]
                    );
                    slope_gap = slope_gap.max((slope - gdal_slope[k]).abs());
                    aspect_gap = aspect_gap.max(angle(aspect.unwrap(), gdal_aspect[k]));
                }
            }
        }
    }
    println!(
        "geographic planes: slope within {slope_gap:.2e}° of GDAL, aspect {aspect_gap:.2e}°; known slope and aspect within {known_gap:.2e}°"
    );
}

/// Median and 99th percentile of `values` (sorted here).
fn percentiles(mut values: Vec<f64>) -> (f64, f64) {
    values.sort_by(f64::total_cmp);
    let at = |q: f64| values[((values.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.99))
}

/// The real DEM of samples/dem/ (USGS, 3″, around 36.6° N) against GDAL's
/// 3×3 methods, Horn's (the default) and Zevenbergen–Thorne's: the
/// differences in slope and aspect (aspect where GDAL's slope is at least
/// 2°), median and 99th percentile, printed (docs/terrain-accuracy.md has them) and
/// held to bounds a little above what was measured.
///
/// GDAL 3.6 takes one scale for both axes of a geographic raster and no
/// pixel size in its aspect, so both tools get the DEM as GIS users give it
/// to them: warped by `gdalwarp` to UTM zone 16 (EPSG 32616) on square 90 m
/// pixels (cubic), texels whose patch reaches the warp's empty corners left
/// out. What differs then is the stencil. normalfit's own geographic fit
/// (metres per row) is compared with its fit of a copy in metres at the
/// centre latitude.
#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdalwarp, gdaldem); CI installs it"]
fn a_real_dem_against_gdal_3x3_methods() {
    let dem = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/dem/jacksboro_fault_dem.tif");
    let dir = tempfile::tempdir().unwrap();
    let utm = dir.path().join("utm.tif");
    let (dem_path, utm_path) = (dem.to_str().unwrap(), utm.to_str().unwrap());
    run(
        "gdalwarp",
        &["-q", "-t_srs", "EPSG:32616", "-tr", "90", "90", "-r", "cubic", "-dstnodata", "-32768"]
            .into_iter()
            .chain(["-ot", "Float32", dem_path, utm_path])
            .collect::<Vec<_>>(),
    );
    let z = values(&utm);
    let raster = read_path(&utm, &ReadOptions::default()).unwrap();
    let (w, h) = (raster.width, raster.height);
    // Texels whose 3×3 patch holds no empty texel.
    let inner = |k: usize| {
        let (x, y) = (k % w, k / w);
        x > 0 && y > 0 && x + 1 < w && y + 1 < h && (0..9).all(|d| z[(y + d / 3 - 1) * w + x + d % 3 - 1] != -32768.0)
    };
    let texels: Vec<usize> = (0..w * h).filter(|&k| inner(k)).collect();
    assert!(texels.len() > 80_000, "{}", texels.len());
    println!("{} of {} texels have a whole 3×3 patch in the warped DEM", texels.len(), w * h);

    let mut report = Vec::new();
    let mut stats = |name: &str, ours: &[(f64, Option<f64>)], gdal: &(Vec<f64>, Vec<f64>)| {
        let (mut ds, mut da) = (Vec::new(), Vec::new());
        for &k in &texels {
            ds.push((ours[k].0 - gdal.0[k]).abs());
            if gdal.0[k] >= 2.0
                && let Some(a) = ours[k].1
            {
                da.push(angle(a, gdal.1[k]));
            }
        }
        let ((sm, s99), (am, a99)) = (percentiles(ds), percentiles(da));
        report.push(format!("{name}: slope median {sm:.3}°, 99th {s99:.3}°; aspect median {am:.3}°, 99th {a99:.3}°"));
        (sm, s99, am, a99)
    };
    let horn = gdaldem(dir.path(), &utm, 1.0, None);
    let zt = gdaldem(dir.path(), &utm, 1.0, Some("ZevenbergenThorne"));
    let fitted = |fit: Fit| ours(&utm, fit3().with_fit(fit), None).2;
    let (vertical, orthogonal) = (fitted(Fit::Vertical), fitted(Fit::Orthogonal));
    let v_horn = stats("N 3 vertical vs Horn", &vertical, &horn);
    let v_zt = stats("N 3 vertical vs Zevenbergen-Thorne", &vertical, &zt);
    let o_horn = stats("N 3 orthogonal vs Horn", &orthogonal, &horn);
    let o_zt = stats("N 3 orthogonal vs Zevenbergen-Thorne", &orthogonal, &zt);
    let zt_as_ours: Vec<(f64, Option<f64>)> =
        zt.0.iter().zip(&zt.1).map(|(&s, &a)| (s, (a >= 0.0).then_some(a))).collect();
    let z_h = stats("GDAL Zevenbergen-Thorne vs Horn", &zt_as_ours, &horn);

    // normalfit's geographic fit (metres per row) against the centre row's.
    let raster = read_path(&dem, &ReadOptions::default()).unwrap();
    let (gw, gh) = (raster.width, raster.height);
    let rows = match map_spacing(raster.georef.as_ref(), gh).unwrap() {
        Spacing::Rows(rows) => rows,
        other => panic!("a geographic DEM: {other:?}"),
    };
    let [dx, dy] = rows[gh / 2];
    let centre = Spacing::Uniform { x: dx, y: dy };
    let slopes = |spacing: Option<Spacing>| ours(&dem, fit3(), spacing).2;
    let (per_row, centre_row) = (slopes(None), slopes(Some(centre)));
    let (mut ds, mut da) = (Vec::new(), Vec::new());
    for k in 0..gw * gh {
        ds.push((per_row[k].0 - centre_row[k].0).abs());
        if let (Some(a), Some(b)) = (per_row[k].1, centre_row[k].1) {
            da.push(angle(a, b));
        }
    }
    let ((sm, s99), (am, a99)) = (percentiles(ds), percentiles(da));
    report.push(format!(
        "N 3 vertical, metres per row vs centre row: slope median {sm:.4}°, 99th {s99:.4}°; aspect median {am:.4}°, 99th {a99:.4}°"
    ));
    for line in &report {
        println!("{line}");
    }
    // Bounds a little above the measured figures (docs/terrain-accuracy.md).
    for (name, (median, p99)) in [("vertical/Horn", (v_horn.0, v_horn.1)), ("orthogonal/Horn", (o_horn.0, o_horn.1))] {
        assert!(median < 0.3 && p99 < 1.5, "{name}: {median} {p99}");
    }
    assert!(v_zt.0 < 1.2 && v_zt.1 < 6.0 && o_zt.0 < 1.2, "{v_zt:?} {o_zt:?}");
    assert!(s99 < 0.1, "per row: {s99}");
    // The stencils' explanation: each takes the central differences of the
    // three rows (for x; columns for y) weighted 1:1:1 (the N = 3 vertical
    // fit), 1:2:1 (Horn), 0:1:0 (Zevenbergen–Thorne). With T the outer
    // rows' difference minus the middle's, the gradients differ by T/12
    // (fit, Horn), T/4 (Horn, ZT) and T/3 (fit, ZT): slope differences in
    // the ratios 1 : 3 : 4.
    let (horn_zt, fit_zt) = (z_h.0 / v_horn.0, v_zt.0 / v_horn.0);
    assert!((2.6..3.4).contains(&horn_zt) && (3.5..4.5).contains(&fit_zt), "{horn_zt} {fit_zt}");
}

/// The program: `--units map` reads a GeoTIFF's spacing (GDAL's file, 30 ×
/// 20 m pixels): a plane's slope and aspect come out as they are.
#[cfg(feature = "cli")]
#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdaldem); CI installs it"]
fn the_program_fits_a_geotiff_in_map_units() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (8, 6);
    let (p, q) = (0.3, -0.4);
    let z: Vec<f64> = (0..w * h).map(|k| 100.0 + p * (k % w) as f64 * 30.0 - q * (k / w) as f64 * 20.0).collect();
    let dem = geotiff(dir.path(), "dem", (w, h), &z, (500_000.0, 4_000_000.0), (30.0, 20.0), "EPSG:32633");
    let out = dir.path().join("n.exr");
    let bin = env!("CARGO_BIN_EXE_normalfit");
    let status = Command::new(bin)
        .args([
            "convert",
            dem.to_str().unwrap(),
            "--units",
            "map",
            "--border",
            "clamp",
            "--fit",
            "vertical",
            "--signed",
            "-o",
        ])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let raster = read_path(&out, &ReadOptions::default()).unwrap();
    let plane = |name: &str| values_of(&raster, name);
    let (r, g, b) = (plane("R"), plane("G"), plane("B"));
    let k = 2 * w + 3;
    let got = slope_aspect([r[k], g[k], b[k]], Convention::OpenGl);
    let (want, aspect) = truth(p, q);
    assert!((got.slope - want).abs() < 1e-4, "{} against {want}", got.slope);
    assert!(angle(got.aspect.unwrap(), aspect.unwrap()) < 1e-4);
}

#[cfg(feature = "cli")]
fn values_of(raster: &normalfit::io::Raster, name: &str) -> Vec<f64> {
    let plane = raster.plane(name).unwrap_or_else(|| panic!("plane {name}"));
    (0..plane.data.len()).map(|i| plane.data.height(i).unwrap()).collect()
}
