//! What normalfit writes from a GeoTIFF, checked by GDAL (Debian's
//! `gdal-bin`): the normal map and the lit view of a GDAL GeoTIFF, PNG
//! with sidecars and GeoTIFF, read back in GDAL (`gdalinfo -json`) with
//! the GeoTIFF's geotransform and EPSG code, PixelIsArea and PixelIsPoint
//! alike; and the lit view's
//! sun matches `gdaldem hillshade` on planes within one grey level.
//! Ignored where GDAL is absent: CI installs `gdal-bin` and runs ignored
//! tests (.ci/run).

use std::path::Path;
use std::process::Command;

use normalfit::convert::{BorderChoices, Conversion, Input, Output};
use normalfit::io::{ReadOptions, read_path};
use normalfit::shade::{LitOptions, Sun, SunChoice, lit_file, lit_view};
use normalfit::{Border, Borders, Options};

const W: usize = 37;
const H: usize = 23;

/// An ASCII grid of `values` (row-major, W × H), texels `cell` wide, x
/// from 500000, top at 4500000.
fn write_grid(path: &Path, values: &[f64], cell: f64) {
    let mut text = format!(
        "ncols {W}\nnrows {H}\nxllcorner 500000\nyllcorner {}\ncellsize {cell}\n",
        4_500_000.0 - H as f64 * cell
    );
    for row in values.chunks(W) {
        text.push_str(&row.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(" "));
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

fn run(tool: &str, args: &[&str]) {
    let out = Command::new(tool).args(args).output().unwrap_or_else(|e| panic!("{tool} runs: {e}"));
    assert!(out.status.success(), "{tool} {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// `gdalinfo -json`'s geotransform and EPSG code.
fn gdalinfo(path: &Path) -> (Vec<f64>, Option<u64>) {
    let out = Command::new("gdalinfo").args(["-json", path.to_str().unwrap()]).output().expect("gdalinfo runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let transform = info["geoTransform"].as_array().expect("a geotransform").iter().map(|v| v.as_f64().unwrap());
    (transform.collect(), info["stac"]["proj:epsg"].as_u64())
}

fn assert_same_transform(a: &[f64], b: &[f64], what: &str) {
    assert_eq!(a.len(), 6, "{what}");
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() <= 1e-9 * x.abs().max(1.0), "{what}: {a:?} against {b:?}");
    }
}

#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdalinfo); CI installs it"]
fn normal_maps_and_lit_views_overlay_the_geotiff_in_gdal() {
    let dir = tempfile::tempdir().unwrap();
    let grid = dir.path().join("dem.asc");
    let values: Vec<f64> = (0..W * H).map(|i| ((i * 7919) % 600) as f64 * 0.25).collect();
    write_grid(&grid, &values, 12.5);
    for (name, extra) in [
        ("area", &[][..]),
        ("point", &["-mo", "AREA_OR_POINT=Point"][..]),
        ("tiled", &["-co", "TILED=YES", "-co", "BLOCKXSIZE=16", "-co", "BLOCKYSIZE=16"][..]),
    ] {
        let tif = dir.path().join(format!("{name}.tif"));
        let mut args = vec!["-q", "-ot", "Float32", "-a_srs", "EPSG:32633"];
        args.extend_from_slice(extra);
        args.extend([grid.to_str().unwrap(), tif.to_str().unwrap()]);
        run("gdal_translate", &args);
        let (source, epsg) = gdalinfo(&tif);
        assert_eq!(epsg, Some(32633));

        let normals = dir.path().join(format!("{name}_normal.png"));
        let summary = Conversion::new().convert_file(&tif, &normals).unwrap();
        assert!(summary.streamed && summary.sidecars.len() == 2, "{name}: {summary:?}");
        let (got, epsg) = gdalinfo(&normals);
        assert_same_transform(&got, &source, &format!("{name}: normal map"));
        assert_eq!(epsg, Some(32633), "{name}: normal map");

        let lit = dir.path().join(format!("{name}_lit.png"));
        let opts = LitOptions::new().with_borders(BorderChoices::from(Borders::both(Border::Clamp)));
        lit_file(Input::Path(&tif), &ReadOptions::default(), &opts, Output::file(&lit))
            .inspect(|done| assert!(done.streamed, "streams"))
            .unwrap();
        let (got, epsg) = gdalinfo(&lit);
        assert_same_transform(&got, &source, &format!("{name}: lit view"));
        assert_eq!(epsg, Some(32633), "{name}: lit view");

        // The whole-image view (a texture-convention light, still placed).
        let whole = dir.path().join(format!("{name}_whole.png"));
        let view = lit_view(&read_path(&tif, &ReadOptions::default()).unwrap(), &opts).unwrap();
        assert_eq!(view.write_file(&whole).unwrap().len(), 2);
        assert_same_transform(&gdalinfo(&whole).0, &source, &format!("{name}: whole lit view"));

        // GeoTIFF outputs hold the georeferencing themselves.
        let normals = dir.path().join(format!("{name}_normal.tif"));
        let summary = Conversion::new().convert_file(&tif, &normals).unwrap();
        assert!(summary.streamed && summary.sidecars.is_empty(), "{name}: {summary:?}");
        let lit = dir.path().join(format!("{name}_lit.tif"));
        lit_file(Input::Path(&tif), &ReadOptions::default(), &opts, Output::file(&lit))
            .inspect(|done| assert!(done.streamed, "streams"))
            .unwrap();
        let whole = dir.path().join(format!("{name}_whole.tif"));
        assert!(view.write_file(&whole).unwrap().is_empty());
        for path in [&normals, &lit, &whole] {
            let what = format!("{name}: {}", path.display());
            let (got, epsg) = gdalinfo(path);
            assert_same_transform(&got, &source, &what);
            assert_eq!(epsg, Some(32633), "{what}");
        }
    }
}

/// The lit view and `gdaldem hillshade` of the plane z = p·x + q·y (x east,
/// y north, in metres) on 1 m texels, so heights in metres at `-s 1` have
/// the geometry gdaldem sees: the largest difference in grey levels over
/// the texels gdaldem computes (not its edges, which it leaves at 0).
fn hillshade_difference(dir: &Path, (p, q): (f64, f64), sun: Option<Sun>) -> (u8, u8) {
    let values: Vec<f64> = (0..W * H)
        .map(|i| {
            let (col, row) = ((i % W) as f64, (i / W) as f64);
            // Rows go south: y = −row.
            100.0 + p * col - q * row
        })
        .collect();
    let grid = dir.join("plane.asc");
    write_grid(&grid, &values, 1.0);
    let tif = dir.join("plane.tif");
    run(
        "gdal_translate",
        &["-q", "-ot", "Float64", "-a_srs", "EPSG:32633", grid.to_str().unwrap(), tif.to_str().unwrap()],
    );
    let theirs = dir.join("hs.tif");
    let mut args =
        vec!["hillshade".to_string(), "-q".into(), tif.to_str().unwrap().into(), theirs.to_str().unwrap().into()];
    let choice = match sun {
        Some(s) => {
            args.extend(["-az".into(), s.azimuth_deg.to_string(), "-alt".into(), s.altitude_deg.to_string()]);
            SunChoice::Always(s)
        }
        None => SunChoice::Georeferenced(Sun::default()),
    };
    run("gdaldem", &args.iter().map(String::as_str).collect::<Vec<_>>());
    let ours = dir.join("ours.png");
    let fit = Options::new().with_borders(Borders::both(Border::Clamp));
    let opts = LitOptions::new().with_fit(fit).with_sun(choice);
    lit_file(Input::Path(&tif), &ReadOptions::default(), &opts, Output::file(&ours))
        .inspect(|done| assert!(done.streamed, "streams"))
        .unwrap();
    let grey = |path: &Path| -> Vec<f32> {
        let raster = read_path(path, &ReadOptions::default()).unwrap();
        raster.planes[0].data.to_f32().unwrap().iter().map(|v| (v * 255.0).round()).collect()
    };
    let (a, b) = (grey(&ours), grey(&theirs));
    let mut worst = 0u8;
    let mut sample = 0u8;
    for y in 1..H - 1 {
        for x in 1..W - 1 {
            let (u, v) = (a[y * W + x], b[y * W + x]);
            worst = worst.max((u - v).abs() as u8);
            sample = v as u8;
        }
    }
    (worst, sample)
}

#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdaldem); CI installs it"]
fn the_sun_matches_gdaldem_hillshade_on_planes_within_one_grey_level() {
    let dir = tempfile::tempdir().unwrap();
    let mut greys = Vec::new();
    for plane in [(0.0, 0.0), (0.3, 0.0), (0.0, -0.7), (-0.4, 0.5), (1.5, 1.2), (-2.0, -0.3)] {
        for sun in [None, Some(Sun::new(200.0, 30.0).unwrap()), Some(Sun::new(90.0, 60.0).unwrap())] {
            let (worst, grey) = hillshade_difference(dir.path(), plane, sun);
            assert!(worst <= 1, "plane {plane:?}, sun {sun:?}: {worst} grey levels from gdaldem");
            greys.push(grey);
        }
    }
    // The planes are lit differently (a test on flat ground alone would
    // pass with the sun in the wrong place).
    greys.sort_unstable();
    greys.dedup();
    assert!(greys.len() > 8, "{greys:?}");
}
