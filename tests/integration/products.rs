//! Slope, aspect and hillshade maps (`convert --product`, issue 35,
//! docs/products.md): each texel's slope and aspect are those of the
//! reference fit's normal (tests/common/reference.rs, gdaldem's formulas
//! in f64) on planes of known slope and aspect, a cone and rough terrain,
//! both fits, every border, holes, projected and geographic DEMs; streamed
//! equals whole; one thread equals many; the program's options and
//! refusals. Against `gdaldem` itself (ignored where gdal-bin is absent;
//! CI installs it): planes, and a small synthetic DEM whose differences
//! (Prewitt's gradient against Horn's) are printed, not held.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::cli::{bin, is_summary, run, s};
use common::geotiff::{self, GeoTag, Kind, Layout};
use common::reference;
use normalfit::convert::{Conversion, Summary};
use normalfit::io::{ReadOptions, read_path};
use normalfit::units::{MapSpacing, map_spacing};
use normalfit::{Border, Borders, Fit, Options, Product, SlopeUnits, Units};

const W: usize = 29;
const H: usize = 23;
/// The projected DEM's pixel (common::geotiff::utm_tags), metres.
const PIXEL: f64 = 30.0;
/// The DEMs' nodata value (utm_tags' GDAL_NODATA).
const HOLE: f64 = -32768.0;

/// A geographic DEM's tags: 3″ pixels from 84.4° W, 36.75° N, WGS 84,
/// nodata −32768.
fn geographic_tags() -> Vec<GeoTag> {
    let step = 1.0 / 1200.0;
    vec![
        GeoTag::Doubles(33550, vec![step, step, 0.0]),
        GeoTag::Doubles(33922, vec![0.0, 0.0, 0.0, -84.4, 36.75, 0.0]),
        GeoTag::Shorts(34735, vec![1, 1, 0, 4, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326, 2054, 0, 1, 9102]),
        GeoTag::Ascii(42113, "-32768".into()),
    ]
}

/// utm_tags' place with row 0 south: a ModelTransformation whose y grows
/// down the rows (e = +30), its first row the north-up raster's last.
fn south_up_tags() -> Vec<GeoTag> {
    let mut tags = geotiff::utm_tags();
    let south = 4_500_000.0 - PIXEL * H as f64;
    let transform = [PIXEL, 0.0, 0.0, 500_000.0, 0.0, PIXEL, 0.0, south, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    tags.retain(|t| !matches!(t, GeoTag::Doubles(33550 | 33922, _)));
    tags.push(GeoTag::Doubles(34264, transform.to_vec()));
    tags
}

/// `values` (W × H) with its rows in the other order.
fn rows_flipped<T: Copy>(values: &[T]) -> Vec<T> {
    values.chunks(W).rev().flatten().copied().collect()
}

/// A float64 GeoTIFF of `values` (W × H) with `tags`.
fn dem(path: &Path, values: &[f64], tags: &[GeoTag]) {
    std::fs::write(path, geotiff::write(W, H, &Layout::gray(Kind::F64), &[values.to_vec()], tags)).unwrap();
}

/// The plane h = 300 + p·east + q·north in metres on 30 m pixels (rows go
/// south: north = −row · 30).
fn plane(p: f64, q: f64) -> Vec<f64> {
    (0..W * H).map(|k| 300.0 + p * (k % W) as f64 * PIXEL - q * (k / W) as f64 * PIXEL).collect()
}

/// A cone: 0.8 m down for every metre from its apex, between texels.
fn cone() -> Vec<f64> {
    let (cx, cy) = (13.3, 10.6);
    (0..W * H).map(|k| 900.0 - 0.8 * PIXEL * ((k % W) as f64 - cx).hypot((k / W) as f64 - cy)).collect()
}

/// Hills with slopes of tens of degrees.
fn terrain() -> Vec<f64> {
    (0..W * H)
        .map(|k| {
            let (x, y) = ((k % W) as f64, (k / W) as f64);
            500.0 + 120.0 * (x * 0.31).sin() * (y * 0.23).cos() + 40.0 * (x * 0.9 + y * 0.7).sin() + 3.0 * x
        })
        .collect()
}

/// The single band of a float output, as stored.
fn values(path: &Path) -> Vec<f32> {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    assert_eq!((raster.width, raster.height, raster.planes.len()), (W, H, 1), "{}", path.display());
    raster.planes[0].data.to_f32().unwrap()
}

/// `product` of the DEM `input` into `output` through the library's
/// conversion, in map units with `fit`.
fn convert(
    input: &Path,
    output: &Path,
    product: Product,
    fit: &Options,
    extra: fn(Conversion) -> Conversion,
) -> Summary {
    let conversion =
        Conversion::new().with_fit(fit.clone()).with_map_units(Some(MapSpacing::FromFile)).with_product(product);
    extra(conversion).convert_file(input, output).unwrap()
}

/// The reference's slope and aspect of every texel of the DEM at `path`
/// (holes: its nodata), fitted with `fit` in the DEM's map units; None
/// where the reference has no plane.
fn reference_of(path: &Path, heights: &[f64], fit: &Options) -> Vec<Option<(f64, Option<f64>)>> {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    let spacing = map_spacing(raster.georef.as_ref(), H).unwrap();
    let opts = fit.clone().with_units(Units::Map(spacing));
    let valid: Vec<bool> = heights.iter().map(|&v| v != HOLE).collect();
    reference::masked_normal_map(heights, Some(&valid), W, H, &opts)
        .into_iter()
        .map(|n| n.map(reference::slope_aspect_gdal))
        .collect()
}

/// Degrees between two compass directions.
fn turn(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

/// Checks a slope map (degrees) and an aspect map against the reference:
/// slope within 1e-4° (f32 rounding of up to 90° is 4e-6°), aspect within
/// 1e-3° where the slope is over 0.01°, −9999 where the reference is flat
/// or has no plane, and in [0, 360) everywhere else.
fn check_against(what: &str, slope: &[f32], aspect: &[f32], want: &[Option<(f64, Option<f64>)>]) {
    for (k, want) in want.iter().enumerate() {
        let (s, a) = (f64::from(slope[k]), f64::from(aspect[k]));
        let at = format!("{what}, texel ({}, {})", k % W, k / W);
        match *want {
            None => assert_eq!((s, a), (-9999.0, -9999.0), "{at}: a hole"),
            Some((ws, wa)) => {
                assert!((s - ws).abs() <= 1e-4, "{at}: slope {s} against {ws}");
                match wa {
                    None => assert_eq!(a, -9999.0, "{at}: flat"),
                    Some(wa) => {
                        assert!((0.0..360.0).contains(&a), "{at}: aspect {a}");
                        assert!(ws <= 0.01 || turn(a, wa) <= 1e-3, "{at}: aspect {a} against {wa}");
                    }
                }
            }
        }
    }
}

/// Planes facing every way, a cone and hills: every texel's slope and
/// aspect are the reference's, both fits, every border; inside (where
/// every border mode sees the plane itself) a plane's are its own, known
/// ones, and the cone's slope is the same all round.
#[test]
fn slope_and_aspect_are_the_references_on_planes_a_cone_and_hills() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dem.tif");
    let (slope_tif, aspect_tif) = (dir.path().join("slope.tif"), dir.path().join("aspect.tif"));
    // (p, q), the plane's known aspect: the way it falls. Each rises 1 in
    // 2 (26.565°).
    let planes = [(0.0, -0.5, 0.0), (-0.5, 0.0, 90.0), (0.0, 0.5, 180.0), (0.5, 0.0, 270.0), (-0.3, -0.4, 36.869_898)];
    let surfaces: Vec<(String, Vec<f64>, Option<f64>)> = planes
        .iter()
        .map(|&(p, q, a)| (format!("plane ({p}, {q})"), plane(p, q), Some(a)))
        .chain([("cone".to_string(), cone(), None), ("hills".to_string(), terrain(), None)])
        .collect();
    let known_slope = 0.5f64.atan().to_degrees();
    let mut aspects_seen = Vec::new();
    for (name, heights, known) in &surfaces {
        dem(&input, heights, &geotiff::utm_tags());
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            for border in [Border::Clamp, Border::Mirror, Border::Wrap] {
                let opts = Options::new().with_fit(fit).with_borders(Borders::both(border));
                let done = convert(&input, &slope_tif, Product::Slope, &opts, |c| c);
                assert!(done.streamed, "a TIFF streams");
                convert(&input, &aspect_tif, Product::Aspect, &opts, |c| c);
                let (slope, aspect) = (values(&slope_tif), values(&aspect_tif));
                let what = format!("{name}, {fit:?}, {border:?}");
                check_against(&what, &slope, &aspect, &reference_of(&input, heights, &opts));
                if let Some(facing) = known {
                    for k in inside() {
                        let (s, a) = (f64::from(slope[k]), f64::from(aspect[k]));
                        assert!((s - known_slope).abs() < 1e-4, "{what} ({k}): slope {s}");
                        assert!(turn(a, *facing) < 1e-3, "{what} ({k}): aspect {a}, facing {facing}");
                    }
                }
                aspects_seen.push(aspect[W * (H / 2) + W / 2 - 3]);
            }
        }
        if name == "cone" {
            // Away from the apex and the borders, every way down is 0.8 in
            // 1 (38.66°) within what the 3×3 plane makes of the cone's
            // curvature.
            let opts = Options::new().with_borders(Borders::both(Border::Clamp));
            convert(&input, &slope_tif, Product::Slope, &opts, |c| c);
            let slope = values(&slope_tif);
            let ring = [(3, 10), (23, 10), (13, 2), (13, 19)];
            for (x, y) in ring {
                let s = f64::from(slope[y * W + x]);
                assert!((s - 0.8f64.atan().to_degrees()).abs() < 0.5, "cone at ({x}, {y}): {s}");
            }
        }
    }
    aspects_seen.sort_by(f32::total_cmp);
    aspects_seen.dedup();
    assert!(aspects_seen.len() >= 6, "the surfaces face many ways: {aspects_seen:?}");
}

/// Flat in, flat out: slope 0 everywhere, aspect −9999 (gdaldem's) or 0
/// with zero_for_flat; percent is 100 · tan of the degrees.
#[test]
fn flat_ground_and_the_units_of_slope() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dem.tif");
    let out = dir.path().join("out.tif");
    let opts = Options::new().with_borders(Borders::both(Border::Clamp));
    dem(&input, &vec![321.5; W * H], &geotiff::utm_tags());
    convert(&input, &out, Product::Slope, &opts, |c| c);
    assert!(values(&out).iter().all(|&v| v == 0.0));
    convert(&input, &out, Product::Aspect, &opts, |c| c);
    assert!(values(&out).iter().all(|&v| v == -9999.0));
    convert(&input, &out, Product::Aspect, &opts, |c| c.with_zero_for_flat(true));
    assert!(values(&out).iter().all(|&v| v == 0.0));

    dem(&input, &terrain(), &geotiff::utm_tags());
    convert(&input, &out, Product::Slope, &opts, |c| c);
    let degrees = values(&out);
    convert(&input, &out, Product::Slope, &opts, |c| c.with_slope_units(SlopeUnits::Percent));
    let percent = values(&out);
    assert!(percent.iter().any(|&p| p > 100.0), "steeper than 45° somewhere");
    for (d, p) in degrees.iter().zip(&percent) {
        let want = 100.0 * f64::from(*d).to_radians().tan();
        assert!((f64::from(*p) - want).abs() <= 1e-5 * want.max(1.0), "{d}° is {want} %, got {p}");
    }
}

/// With holes, on projected and geographic DEMs (metres per row), every
/// border: the streamed TIFF and the whole image's EXR hold the same bits;
/// holes and texels without a plane are −9999, as many as the summary
/// counts; the rest is the reference's. The TIFF keeps the georeferencing
/// and says its nodata, −9999.
#[test]
fn streamed_equals_whole_with_holes_projected_and_geographic() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dem.tif");
    let (tif, exr) = (dir.path().join("p.tif"), dir.path().join("p.exr"));
    let mut heights = terrain();
    for k in [0, 5, W + 6, 3 * W + 17, W * H - 1] {
        heights[k] = HOLE;
    }
    // A block of holes, and a texel whose neighbours are all holes but one
    // line of them (no plane).
    for y in 12..16 {
        for x in 4..9 {
            heights[y * W + x] = HOLE;
        }
    }
    for (place, tags) in [("utm", geotiff::utm_tags()), ("geographic", geographic_tags())] {
        dem(&input, &heights, &tags);
        for border in [Border::Wrap, Border::Clamp, Border::Mirror] {
            let opts = Options::new().with_fit(Fit::Vertical).with_borders(Borders::both(border));
            let want = reference_of(&input, &heights, &opts);
            let missing = want.iter().filter(|w| w.is_none()).count();
            let mut maps = Vec::new();
            for product in [Product::Slope, Product::Aspect] {
                let streamed = convert(&input, &tif, product, &opts, |c| c);
                let whole = convert(&input, &exr, product, &opts, |c| c);
                assert!(streamed.streamed && !whole.streamed, "{place} {border:?}");
                assert_eq!((streamed.missing, whole.missing), (missing, missing), "{place} {border:?}");
                let (a, b) = (values(&tif), values(&exr));
                let what = format!("{place} {border:?} {product}");
                assert!(a.iter().zip(&b).all(|(a, b)| a.to_bits() == b.to_bits()), "{what}: streamed ≠ whole");
                let bytes = std::fs::read(&tif).unwrap();
                assert!(bytes.windows(6).any(|w| w == b"-9999\0"), "{what}: GDAL_NODATA −9999");
                let georef = read_path(&tif, &ReadOptions::default()).unwrap().georef;
                let source = read_path(&input, &ReadOptions::default()).unwrap().georef;
                assert_eq!(
                    georef.as_ref().and_then(|g| g.affine()),
                    source.as_ref().and_then(|g| g.affine()),
                    "{what}"
                );
                maps.push(a);
            }
            check_against(&format!("{place} {border:?}"), &maps[0], &maps[1], &want);
        }
    }
}

/// The program: `--product slope|aspect|hillshade` with its options maps
/// onto the library's conversion (the same bits); one thread or many, the
/// same bits; a hillshade is `shade --units map`'s picture, byte for byte;
/// refusals are one line, exit 2, no output.
#[test]
fn the_program_makes_the_products_and_refuses_what_they_cannot_be() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dem.tif");
    dem(&input, &terrain(), &geotiff::utm_tags());
    let ok = |args: &[&str]| {
        let out = run(args);
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    };
    let cli = dir.path().join("cli.tif");
    let lib = dir.path().join("lib.tif");
    let opts = Options::new().with_borders(Borders::both(Border::Mirror)).with_fit(Fit::Vertical);
    let base = ["--units", "map", "--border", "mirror", "--fit", "vertical", "--quiet"];
    ok(&[&["convert", s(&input), "-o", s(&cli), "--product", "slope", "--slope-units", "percent"][..], &base].concat());
    convert(&input, &lib, Product::Slope, &opts, |c| c.with_slope_units(SlopeUnits::Percent));
    assert_eq!(std::fs::read(&cli).unwrap(), std::fs::read(&lib).unwrap(), "slope in percent");
    ok(&[&["convert", s(&input), "-o", s(&cli), "--product", "aspect", "--zero-for-flat"][..], &base].concat());
    convert(&input, &lib, Product::Aspect, &opts, |c| c.with_zero_for_flat(true));
    assert_eq!(std::fs::read(&cli).unwrap(), std::fs::read(&lib).unwrap(), "aspect");

    // One thread, the same bits.
    let one = dir.path().join("one.tif");
    let args = [&["convert", s(&input), "-o", s(&one), "--product", "aspect", "--zero-for-flat"][..], &base].concat();
    let out = bin().env("RAYON_NUM_THREADS", "1").args(&args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read(&one).unwrap(), std::fs::read(&cli).unwrap(), "one thread");

    // The hillshade is the lit view under the sun, with its options.
    let (hs, lit) = (dir.path().join("hs.tif"), dir.path().join("lit.tif"));
    let sun = ["--azimuth", "200", "--altitude", "30", "--units", "map", "--border", "clamp", "--quiet"];
    ok(&[&["convert", s(&input), "-o", s(&hs), "--product", "hillshade", "-s", "2"][..], &sun].concat());
    ok(&[&["shade", s(&input), "-o", s(&lit), "-s", "2"][..], &sun].concat());
    assert_eq!(std::fs::read(&hs).unwrap(), std::fs::read(&lit).unwrap(), "hillshade");
    let default_sun = dir.path().join("hs315.tif");
    ok(&["convert", s(&input), "-o", s(&default_sun), "--product", "hillshade", "--units", "map", "--quiet"]);
    assert_ne!(std::fs::read(&hs).unwrap(), std::fs::read(&default_sun).unwrap(), "the sun is not lost");

    let refused: [(&[&str], &str); 7] = [
        (&["--product", "slope", "-o", "x.png"], "x.png"),
        (&["--product", "aspect", "-o", "x.tif", "--bits", "16"], "x.tif"),
        (&["--product", "hillshade", "-o", "x.exr"], "x.exr"),
        (&["--product", "hillshade", "-o", "x.tif", "--bits", "32"], "x.tif"),
        (&["--product", "slope", "-o", "x.tif", "--mips"], "x.tif"),
        (&["--product", "slope", "-o", "x.tif", "--alpha", "one"], "x.tif"),
        (&["--product", "hillshade", "-o", "x.tif", "--altitude", "95"], "altitude"),
    ];
    for (extra, named) in refused {
        let out = Command::new(env!("CARGO_BIN_EXE_normalfit"))
            .current_dir(dir.path())
            .args([&["convert", s(&input), "--units", "map"][..], extra].concat())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {stderr}");
        let lines: Vec<&str> =
            stderr.lines().filter(|l| !l.starts_with("normalfit: warning") && !is_summary(l)).collect();
        assert_eq!(lines.len(), 1, "{extra:?}: one line: {stderr}");
        assert!(lines[0].contains(named), "{extra:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        for name in ["x.png", "x.tif", "x.exr"] {
            assert!(!dir.path().join(name).exists(), "{extra:?}: no output");
        }
    }
}

fn tool(name: &str, args: &[&str]) {
    let out = Command::new(name).args(args).output().unwrap_or_else(|e| panic!("{name} runs: {e}"));
    assert!(out.status.success(), "{name} {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// A Float32 GeoTIFF of `values` (W × H) in UTM 33N on 30 m pixels, made
/// by `gdal_translate` from an ASCII grid.
fn gdal_dem(dir: &Path, values: &[f64]) -> PathBuf {
    let grid = dir.join("dem.asc");
    let mut text = format!("ncols {W}\nnrows {H}\nxllcorner 500000\nyllcorner 4000000\ncellsize {PIXEL}\n");
    for row in values.chunks(W) {
        text.push_str(&row.iter().map(|v| format!("{v:.6}")).collect::<Vec<_>>().join(" "));
        text.push('\n');
    }
    std::fs::write(&grid, text).unwrap();
    let tif = dir.join("dem.tif");
    tool("gdal_translate", &["-q", "-ot", "Float32", "-a_srs", "EPSG:32633", s(&grid), s(&tif)]);
    tif
}

/// The texels gdaldem computes (not its one-texel edge).
fn inside() -> impl Iterator<Item = usize> {
    (0..W * H).filter(|k| (1..W - 1).contains(&(k % W)) && (1..H - 1).contains(&(k / W)))
}

/// gdaldem's `product` of `dem` with `extra`, and ours with `ours`
/// (vertical fit, clamp), read back.
fn both(dir: &Path, dem: &Path, product: &str, extra: &[&str], ours: &[&str]) -> (Vec<f32>, Vec<f32>) {
    let theirs = dir.join("gdal.tif");
    tool("gdaldem", &[&[product, "-q", s(dem), s(&theirs)][..], extra].concat());
    let mine = dir.join("ours.tif");
    let args = [&["convert", s(dem), "-o", s(&mine), "--product", product, "--units", "map"][..], ours].concat();
    let out = run(&[&args[..], &["--fit", "vertical", "--border", "clamp", "--quiet"]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    (values(&mine), values(&theirs))
}

/// On planes facing north, east, south, west and between, and flat ground,
/// normalfit's vertical fit is gdaldem's (a plane's Horn and Prewitt
/// gradients are equal): slope within 1e-4° (gdaldem computes in float32),
/// the same in percent within 1e-5 relative, aspect within 1e-3° and −9999
/// (0 with -zero_for_flat) on flat ground, hillshade within one grey
/// level. On a small synthetic DEM the differences are printed: N = 3's
/// unweighted fit is Prewitt's gradient, gdaldem's Horn's.
#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdaldem); CI installs it"]
fn the_products_match_gdaldem_on_planes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let planes = [(0.0, 0.0), (0.0, -0.5), (-0.5, 0.0), (0.0, 0.5), (0.5, 0.0), (-0.3, -0.4), (1.2, -0.7)];
    let mut compared = 0;
    for (p, q) in planes {
        let dem = gdal_dem(d, &plane(p, q));
        let what = format!("plane ({p}, {q})");
        let (ours, theirs) = both(d, &dem, "slope", &[], &[]);
        for k in inside() {
            assert!((ours[k] - theirs[k]).abs() <= 1e-4, "{what} ({k}): slope {} against {}", ours[k], theirs[k]);
        }
        // gdaldem's other options on flat ground and on the diagonal plane
        // alone: each run of either tool costs more than its comparison.
        let others = p == q || p == -0.3;
        if others {
            let (ours, theirs) = both(d, &dem, "slope", &["-p"], &["--slope-units", "percent"]);
            for k in inside() {
                assert!((ours[k] - theirs[k]).abs() <= 1e-5 * theirs[k].max(1.0), "{what} ({k}): {} %", ours[k]);
            }
        }
        let flags: &[(&[&str], &[&str])] =
            if others { &[(&[], &[]), (&["-zero_for_flat"], &["--zero-for-flat"])] } else { &[(&[], &[])] };
        for &(extra, flag) in flags {
            let (ours, theirs) = both(d, &dem, "aspect", extra, flag);
            for k in inside() {
                let (a, b) = (f64::from(ours[k]), f64::from(theirs[k]));
                let flat = p == 0.0 && q == 0.0;
                assert!(
                    if flat { a == b } else { turn(a, b) <= 1e-3 },
                    "{what} {flag:?} ({k}): aspect {a} against {b}"
                );
                compared += 1;
            }
        }
        let suns: &[(&[&str], &[&str])] = if others {
            &[(&[], &[]), (&["-az", "200", "-alt", "30"], &["--azimuth", "200", "--altitude", "30"])]
        } else {
            &[(&[], &[])]
        };
        for &(sun, ours_sun) in suns {
            let (ours, theirs) = both(d, &dem, "hillshade", sun, ours_sun);
            for k in inside() {
                let (a, b) = (ours[k] * 255.0, theirs[k] * 255.0);
                assert!((a - b).abs() <= 1.0 + 1e-3, "{what} {sun:?} ({k}): grey {a} against {b}");
            }
        }
    }
    assert!(compared > 0);

    // A small synthetic DEM: the differences, printed.
    let dem = gdal_dem(d, &terrain());
    let (ours, theirs) = both(d, &dem, "slope", &[], &[]);
    let slope: Vec<f32> = inside().map(|k| (ours[k] - theirs[k]).abs()).collect();
    let (ours_a, theirs_a) = both(d, &dem, "aspect", &[], &[]);
    let aspect: Vec<f64> = inside().map(|k| turn(f64::from(ours_a[k]), f64::from(theirs_a[k]))).collect();
    let (ours_h, theirs_h) = both(d, &dem, "hillshade", &[], &[]);
    let grey: Vec<f32> = inside().map(|k| ((ours_h[k] - theirs_h[k]) * 255.0).abs().round()).collect();
    let max = |v: &[f32]| v.iter().copied().fold(0.0f32, f32::max);
    let within_one = grey.iter().filter(|&&g| g <= 1.0).count() as f64 / grey.len() as f64;
    println!(
        "synthetic DEM, N = 3 vertical (Prewitt) against gdaldem (Horn), {} texels: slope up to {:.3}°, aspect up to {:.3}°, \
         hillshade up to {} grey levels ({:.1} % within one)",
        grey.len(),
        max(&slope),
        aspect.iter().copied().fold(0.0, f64::max),
        max(&grey),
        100.0 * within_one
    );
}

/// With binomial weights, N = 3's vertical fit is Horn's gradient, as
/// gdaldem's: on the synthetic DEM's inside (gdaldem leaves its edge
/// nodata), slope within 0.01°, aspect within 0.2° where the slope is over
/// 1°, hillshade within one grey level (gdaldem 3.6 forms the gradient in
/// float32, which alone makes differences of that order on a DEM far from
/// zero: docs/terrain.md). The share equal to the float32 is printed.
#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdaldem); CI installs it"]
fn binomial_weights_match_gdaldem_on_a_dem() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let dem = gdal_dem(d, &terrain());
    let weights = ["--weights", "binomial"];
    let (ours, theirs) = both(d, &dem, "slope", &[], &weights);
    let (ours_a, theirs_a) = both(d, &dem, "aspect", &[], &weights);
    let (ours_h, theirs_h) = both(d, &dem, "hillshade", &[], &weights);
    let (mut exact, mut aspects) = ([0usize; 3], 0);
    for k in inside() {
        assert!((ours[k] - theirs[k]).abs() <= 0.01, "({k}): slope {} against {}", ours[k], theirs[k]);
        if theirs[k] > 1.0 {
            let (a, b) = (f64::from(ours_a[k]), f64::from(theirs_a[k]));
            assert!(turn(a, b) <= 0.2, "({k}): aspect {a} against {b}");
            aspects += 1;
        }
        let (a, b) = (ours_h[k] * 255.0, theirs_h[k] * 255.0);
        assert!((a - b).abs() <= 1.0 + 1e-3, "({k}): grey {a} against {b}");
        for (e, (x, y)) in exact.iter_mut().zip([(ours[k], theirs[k]), (ours_a[k], theirs_a[k]), (a, b)]) {
            *e += usize::from(x == y);
        }
    }
    let count = inside().count();
    assert!(aspects * 2 > count, "slopes over 1° nearly everywhere: {aspects} of {count}");
    println!(
        "synthetic DEM, N = 3 vertical binomial against gdaldem, {count} texels: equal slope {:.1} %, aspect {:.1} %, \
         hillshade {:.1} %",
        100.0 * exact[0] as f64 / count as f64,
        100.0 * exact[1] as f64 / count as f64,
        100.0 * exact[2] as f64 / count as f64
    );
}

/// The components a sweep of the arctangent takes: zeros of both signs,
/// subnormals, the smallest and largest normals, infinities, and values
/// between.
const SPECIAL: [f64; 14] = [
    0.0,
    -0.0,
    5e-324,
    -5e-324,
    1e-310,
    2.2e-308,
    -1e-300,
    1e-8,
    0.5,
    -1.0,
    3.0,
    1e300,
    f64::INFINITY,
    f64::NEG_INFINITY,
];

/// Degrees between two angles, NaN equal to NaN.
fn apart(a: f64, b: f64) -> f64 {
    if a.is_nan() && b.is_nan() { 0.0 } else { (a - b).abs() }
}

/// `slope_aspect`'s own arctangent against libm's (the reference's
/// `slope_aspect_libm`): over a million directions at radii from 1e-300 to
/// 1e300 in every octant (ratios near 0, 1 and tan(π/8) among them), and
/// the special components in every combination, the aspect within 1e-12°
/// (the products promise 1e-9°), the slope too where e² + n² is a normal
/// f64 (the length of a normal's horizontal part, a unit normal's), flat
/// where libm is flat, and NaN where it is NaN (but a NaN beside an
/// infinity, where libm's hypot is infinite).
#[test]
fn atan2_matches_libm() {
    use normalfit::Convention;
    use normalfit::units::slope_aspect;
    let mut worst: f64 = 0.0;
    let mut check = |n: [f64; 3]| {
        let got = slope_aspect(n, Convention::OpenGl);
        let (slope, aspect) = reference::slope_aspect_libm(n);
        // The slope's horizontal length is √(e² + n²), not libm's hypot:
        // held where e² + n² neither underflows nor overflows (normals are
        // near unit length; components between 1e-154 and 1e154).
        let [e, north, _] = n;
        let h2 = e * e + north * north;
        let representable = (e == 0.0 && north == 0.0)
            || h2.is_normal()
            || e.is_infinite()
            || north.is_infinite()
            || e.is_nan()
            || north.is_nan();
        let ds = if representable { apart(got.slope, slope) } else { 0.0 };
        assert!(ds <= 1e-12, "{n:?}: slope {} against libm's {slope}", got.slope);
        assert_eq!(got.aspect.is_some(), aspect.is_some(), "{n:?}: flat or not");
        if let (Some(a), Some(b)) = (got.aspect, aspect) {
            let da = apart(a, b).min(360.0 - apart(a, b));
            assert!(da <= 1e-12 || (a.is_nan() && b.is_nan()), "{n:?}: aspect {a} against libm's {b}");
            worst = worst.max(da);
        }
        worst = worst.max(ds);
    };
    for k in 0..1_000_000u32 {
        let angle = -std::f64::consts::PI + std::f64::consts::TAU * f64::from(k) / 1e6;
        let r = 10f64.powi((k % 601) as i32 - 300);
        let up = [1.0, 0.3, 1e-9, 0.0, -0.7][(k % 5) as usize];
        check([r * angle.sin(), r * angle.cos(), up]);
    }
    // Ratios right at the reduction's seams: 1 and tan(π/8), and their
    // neighbours in both directions.
    for t in [1.0f64, 0.414_213_562_373_095_03, 2.414_213_562_373_095] {
        for ulps in -3i64..=3 {
            let t = f64::from_bits((t.to_bits() as i64 + ulps) as u64);
            for (e, n) in [(t, 1.0), (1.0, t), (-t, 1.0), (t, -1.0), (-1.0, -t)] {
                check([e, n, 0.5]);
            }
        }
    }
    for e in SPECIAL {
        for n in SPECIAL {
            for up in SPECIAL {
                check([e, n, up]);
            }
        }
    }
    for other in [0.0, -0.0, 1.0, -2.0] {
        check([f64::NAN, other, 1.0]);
        check([other, f64::NAN, 1.0]);
        check([other, 1.0, f64::NAN]);
    }
    eprintln!("atan2_matches_libm: largest difference {worst:e}°");
}

/// The products of heights held in memory (`normalfit::products`, what
/// the Python package calls) are the program's, bit for bit: the slope
/// and aspect against the float TIFF `convert --product` writes (NaN or
/// −9999 at the same holes), the hillshade against its 8-bit one; every
/// border, projected and geographic; in windows of the image (each with
/// the halo the library plans) as whole; on one thread as on four.
#[test]
fn the_products_in_memory_are_the_programs() {
    use normalfit::FitRequest;
    use normalfit::fit::HaloPlan;
    use normalfit::products::{hillshade_into, measure_into};
    use normalfit::shade::Sun;
    use normalfit::units::{Measure, NODATA};
    let dir = tempfile::tempdir().unwrap();
    let (input, tif) = (dir.path().join("dem.tif"), dir.path().join("p.tif"));
    let mut heights = terrain();
    for k in [0, 5, W + 6, 3 * W + 17, W * H - 1] {
        heights[k] = HOLE;
    }
    heights[9 * W + 20] = f64::NAN;
    let measures = [
        (Product::Slope, Measure::Slope(SlopeUnits::Degrees)),
        (Product::Aspect, Measure::Aspect { zero_for_flat: false }),
    ];
    for (place, tags) in
        [("utm", geotiff::utm_tags()), ("geographic", geographic_tags()), ("south-up", south_up_tags())]
    {
        dem(&input, &heights, &tags);
        let georef = read_path(&input, &ReadOptions::default()).unwrap().georef;
        let spacing = map_spacing(georef.as_ref(), H).unwrap();
        let affine = georef.as_ref().and_then(normalfit::io::Georef::affine);
        let affine = affine.as_ref();
        for border in [Border::Wrap, Border::Clamp, Border::Mirror] {
            let fit = Options::new().with_fit(Fit::Vertical).with_borders(Borders::both(border)).with_patch(5);
            let opts = fit.clone().with_units(Units::Map(spacing.clone())).with_nodata(Some(HOLE));
            let what = format!("{place} {border:?}");
            let windows = |size: (usize, usize)| {
                let plan = HaloPlan::new(&opts).unwrap();
                (0..H).step_by(size.1).flat_map(move |y| {
                    (0..W)
                        .step_by(size.0)
                        .map(move |x| plan.window((W, H), (x, y), (size.0.min(W - x), size.1.min(H - y))))
                })
            };
            // The window and its halo, beyond the image's edges what the
            // border gives there.
            let held = |window: &normalfit::fit::Window| -> Vec<f64> {
                let (hw, hh) = window.held_size();
                let x0 = window.origin.0 as isize - window.halo.left as isize;
                let y0 = window.origin.1 as isize - window.halo.top as isize;
                (0..hh as isize)
                    .flat_map(|j| (0..hw as isize).map(move |i| (y0 + j, x0 + i)))
                    .map(|(y, x)| heights[opts.borders.y.map(y, H) * W + opts.borders.x.map(x, W)])
                    .collect()
            };
            for (product, measure) in measures {
                convert(&input, &tif, product, &fit, |c| c);
                let program = values(&tif);
                let mut whole = vec![0.0f32; W * H];
                let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
                let missing = pool
                    .install(|| {
                        measure_into(FitRequest::new(&opts), measure, affine, NODATA, &heights, W, H, &mut whole)
                    })
                    .unwrap();
                assert!(missing >= 6, "{what} {product}: {missing} missing");
                let same = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same(&whole, &program), "{what} {product}: in memory ≠ the program's");
                let mut four = vec![0.0f32; W * H];
                let pool = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
                pool.install(|| {
                    measure_into(FitRequest::new(&opts), measure, affine, f32::NAN, &heights, W, H, &mut four)
                })
                .unwrap();
                let nan_for_nodata: Vec<f32> = whole.iter().map(|&v| if v == NODATA { f32::NAN } else { v }).collect();
                // Aspect's −9999 is a flat texel's too: compare where not.
                let kept: Vec<(f32, f32)> = four
                    .iter()
                    .zip(&nan_for_nodata)
                    .map(|(&a, &b)| if a == NODATA { (b, b) } else { (a, b) })
                    .collect();
                assert!(kept.iter().all(|(a, b)| a.to_bits() == b.to_bits()), "{what} {product}: 4 threads, NaN holes");
                for size in [(7, 5), (11, 23), (29, 4)] {
                    let mut chunked = vec![0.0f32; W * H];
                    for window in windows(size) {
                        let (hw, hh) = window.held_size();
                        let mut out = vec![0.0f32; window.size.0 * window.size.1];
                        measure_into(
                            FitRequest::new(&opts).window(window),
                            measure,
                            affine,
                            NODATA,
                            &held(&window),
                            hw,
                            hh,
                            &mut out,
                        )
                        .unwrap();
                        for (r, row) in out.chunks(window.size.0).enumerate() {
                            let at = (window.origin.1 + r) * W + window.origin.0;
                            chunked[at..at + window.size.0].copy_from_slice(row);
                        }
                    }
                    assert!(same(&chunked, &whole), "{what} {product}: windows of {size:?} ≠ whole");
                }
            }
            convert(&input, &tif, Product::Hillshade, &fit, |c| c);
            let raster = read_path(&tif, &ReadOptions::default()).unwrap();
            // The bytes as stored (to_f32 would give contract units, v / 255).
            let normalfit::Samples::U8(program) = &raster.planes[0].data else { panic!("{what}: an 8-bit hillshade") };
            let mut greys = vec![0u8; W * H];
            hillshade_into(FitRequest::new(&opts), Sun::default(), affine, &heights, W, H, &mut greys).unwrap();
            assert!(greys.contains(&0) && greys.iter().any(|&g| g > 200), "{what}: hillshade");
            assert!(greys == *program, "{what}: hillshade in memory ≠ the program's");
        }
    }
}

/// A south-up raster (row 0 south, the transform's e > 0) is the same map
/// as the north-up one with its rows the other way: its slope, aspect and
/// hillshade are the north-up file's, rows flipped, in both fits and every
/// border (each border is the same read from either end). Read as
/// north-up, its aspect would be mirrored (180° − a), its sun from the
/// south-west.
#[test]
fn a_south_up_raster_is_measured_on_the_map() {
    let dir = tempfile::tempdir().unwrap();
    let (north_up, south_up) = (dir.path().join("n.tif"), dir.path().join("s.tif"));
    let (a, b) = (dir.path().join("a.tif"), dir.path().join("b.tif"));
    let heights = terrain();
    dem(&north_up, &heights, &geotiff::utm_tags());
    dem(&south_up, &rows_flipped(&heights), &south_up_tags());
    for fit in [Fit::Vertical, Fit::Orthogonal] {
        for border in [Border::Wrap, Border::Clamp, Border::Mirror] {
            let opts = Options::new().with_fit(fit).with_borders(Borders::both(border)).with_patch(3);
            let what = format!("{fit:?} {border:?}");
            let mut compared = 0;
            for product in [Product::Slope, Product::Aspect] {
                convert(&north_up, &a, product, &opts, |c| c);
                convert(&south_up, &b, product, &opts, |c| c);
                let (want, got) = (values(&a), rows_flipped(&values(&b)));
                let slope = values(&a);
                for (k, (w, g)) in want.iter().zip(&got).enumerate() {
                    let (w, g) = (f64::from(*w), f64::from(*g));
                    let off = match product {
                        Product::Aspect if slope[k] > 0.1 => {
                            compared += 1;
                            (w - g).abs().min(360.0 - (w - g).abs())
                        }
                        Product::Aspect => continue,
                        _ => (w - g).abs(),
                    };
                    assert!(off < 1e-3, "{what} {product} at {k}: north-up {w}, south-up {g}");
                }
            }
            assert!(compared > W * H / 2, "{what}: {compared} aspects compared");
            convert(&north_up, &a, Product::Hillshade, &opts, |c| c);
            convert(&south_up, &b, Product::Hillshade, &opts, |c| c);
            let greys = |p: &Path| match read_path(p, &ReadOptions::default()).unwrap().planes.remove(0).data {
                normalfit::Samples::U8(g) => g,
                _ => panic!("an 8-bit hillshade"),
            };
            let (want, got) = (greys(&a), rows_flipped(&greys(&b)));
            let worst = want.iter().zip(&got).map(|(w, g)| w.abs_diff(*g)).max().unwrap();
            assert!(worst <= 1, "{what}: hillshade off by {worst} grey levels");
        }
    }
}

/// The aspect and the hillshade made in the fit's loop (from the plane's
/// unnormalised normal, and the grey of the unit normal cast to `f32`) are
/// those of the normals the fit gives: the aspect `Measure::of` of the
/// unit `f64` normal (its north the map's: y, or −y on a south-up
/// raster), the grey `shade_sun` of the `f32` normals; both fits, uniform
/// and binomial weights, both conventions, north-up and south-up.
#[test]
fn the_aspect_and_the_hillshade_are_those_of_the_normals() {
    use normalfit::products::{hillshade_into, measure_into};
    use normalfit::shade::{Sun, shade_sun};
    use normalfit::units::Measure;
    use normalfit::{Convention, FitRequest, Spacing, Weights};
    let heights = terrain();
    let south_up = normalfit::io::Affine { a: PIXEL, b: 0.0, c: 500_000.0, d: 0.0, e: PIXEL, f: 4_000_000.0 };
    let mut sloped = 0;
    for fit in [Fit::Vertical, Fit::Orthogonal] {
        for weights in [Weights::Uniform, Weights::Binomial] {
            for convention in [Convention::OpenGl, Convention::DirectX] {
                let opts = Options::new()
                    .with_fit(fit)
                    .with_weights(weights)
                    .with_convention(convention)
                    .with_borders(Borders::both(Border::Clamp))
                    .with_units(Units::Map(Spacing::Uniform { x: PIXEL, y: PIXEL }));
                let mut unit = vec![[0.0f64; 3]; W * H];
                FitRequest::new(&opts).normals_into(&heights, W, H, &mut unit).unwrap();
                let mut normals = vec![[0.0f32; 3]; W * H];
                FitRequest::new(&opts).normals_into(&heights, W, H, &mut normals).unwrap();
                for (affine, north) in [(None, 1.0), (Some(&south_up), -1.0)] {
                    let what = format!("{fit:?} {weights:?} {convention:?} north {north}");
                    for zero_for_flat in [false, true] {
                        let measure = Measure::Aspect { zero_for_flat };
                        let mut aspect = vec![0.0f32; W * H];
                        measure_into(FitRequest::new(&opts), measure, affine, f32::NAN, &heights, W, H, &mut aspect)
                            .unwrap();
                        for (k, (&got, n)) in aspect.iter().zip(&unit).enumerate() {
                            let y = if convention == Convention::DirectX { -n[1] } else { n[1] };
                            let want = measure.of([n[0], north * y, n[2]], Convention::OpenGl);
                            assert_eq!(got.to_bits(), want.to_bits(), "{what}: aspect at {k}: {got} against {want}");
                            sloped += usize::from(got > 0.0);
                        }
                    }
                    let sun = Sun::default();
                    let mut grey = vec![0u8; W * H];
                    hillshade_into(FitRequest::new(&opts), sun, affine, &heights, W, H, &mut grey).unwrap();
                    let want = shade_sun(&normals, W, H, sun, affine, convention).unwrap();
                    assert_eq!(grey, want, "{what}: hillshade");
                    assert!(grey.iter().any(|&g| g != grey[0]), "{what}: a hillshade of one grey");
                }
            }
        }
    }
    assert!(sloped > 16 * W * H, "the aspects are of sloped ground: {sloped}");
}
