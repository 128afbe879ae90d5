//! GeoTIFFs written by GDAL (`gdal_translate`, Debian's `gdal-bin`) read by
//! normalfit: every value, the pixel size, the EPSG code, the model type and
//! the nodata value must be what GDAL wrote (its `gdalinfo -json` says).
//! The fixtures the other tests write with the `tiff` crate are ours; these
//! are a real GIS tool's, with its compressions, predictors, tiling and
//! interleaving. Ignored where GDAL is absent: CI installs `gdal-bin` and
//! runs ignored tests (.ci/run).

use std::path::Path;
use std::process::Command;

use normalfit::io::{ModelType, ReadOptions, read_path};

const W: usize = 37;
const H: usize = 23;
const NODATA: f64 = -9999.0;

/// The heights of the grid: whole numbers in int16's range (negative
/// ones too), or quarters for float types, and one nodata texel.
fn heights(quarters: bool) -> Vec<f64> {
    (0..W * H)
        .map(|i| {
            if i == 40 {
                return NODATA;
            }
            let v = ((i * 7919) % 6000) as f64 - 1000.0;
            if quarters { v + 0.25 * (i % 4) as f64 } else { v }
        })
        .collect()
}

/// An ASCII grid (GDAL's AAIGrid, with its `dx`/`dy` extension for
/// unequal spacing) of `values`, x from 500000, top at 4500000, with
/// `nodata` marking missing texels.
fn write_grid(path: &Path, values: &[f64], (dx, dy): (f64, f64), nodata: f64) {
    let mut text = format!(
        "ncols {W}\nnrows {H}\nxllcorner 500000\nyllcorner {}\ndx {dx}\ndy {dy}\nNODATA_value {nodata}\n",
        4_500_000.0 - H as f64 * dy
    );
    for row in values.chunks(W) {
        text.push_str(&row.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(" "));
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

fn gdal(args: &[&str]) {
    let out = Command::new("gdal_translate").arg("-q").args(args).output().expect("gdal_translate runs");
    assert!(out.status.success(), "gdal_translate {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// What `gdalinfo -json` says: the geotransform, the first band's nodata,
/// the EPSG code.
fn gdalinfo(path: &Path) -> (Vec<f64>, Option<f64>, Option<u64>) {
    let out = Command::new("gdalinfo").args(["-json", path.to_str().unwrap()]).output().expect("gdalinfo runs");
    assert!(out.status.success());
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let transform = info["geoTransform"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    (transform, info["bands"][0]["noDataValue"].as_f64(), info["stac"]["proj:epsg"].as_u64())
}

#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdalinfo); CI installs it"]
fn geotiffs_written_by_gdal_read_as_gdal_wrote_them() {
    let dir = tempfile::tempdir().unwrap();
    let types = [("Int16", false), ("UInt16", false), ("Int32", false), ("Float32", true), ("Float64", true)];
    let layouts: [&[&str]; 5] = [
        &[],
        &["-co", "TILED=YES", "-co", "BLOCKXSIZE=16", "-co", "BLOCKYSIZE=16"],
        &["-co", "COMPRESS=DEFLATE", "-co", "PREDICTOR=2"],
        &["-co", "COMPRESS=LZW", "-co", "TILED=YES", "-co", "BLOCKXSIZE=32", "-co", "BLOCKYSIZE=16"],
        &["-co", "COMPRESS=PACKBITS", "-co", "BLOCKYSIZE=3"],
    ];
    for (ty, quarters) in types {
        let mut values = heights(quarters);
        // No negatives in uint16: heights from 0, and nodata 65535 (GDAL
        // would clamp a -9999 to 0).
        let nodata = if ty == "UInt16" { 65535.0 } else { NODATA };
        if ty == "UInt16" {
            values = values.iter().map(|&v| if v == NODATA { nodata } else { v + 1000.0 }).collect();
        }
        let grid = dir.path().join(format!("{ty}.asc"));
        write_grid(&grid, &values, (30.0, 20.0), nodata);
        for (k, layout) in layouts.iter().enumerate() {
            // Floating-point predictor for floats, where GDAL allows it.
            let mut options: Vec<&str> = layout.to_vec();
            if quarters && options.contains(&"PREDICTOR=2") {
                *options.iter_mut().find(|o| **o == "PREDICTOR=2").unwrap() = "PREDICTOR=3";
            }
            let tif = dir.path().join(format!("{ty}_{k}.tif"));
            let nodata = nodata.to_string();
            let mut args = vec!["-ot", ty, "-a_srs", "EPSG:32633", "-a_nodata", &nodata];
            args.extend(&options);
            args.extend([grid.to_str().unwrap(), tif.to_str().unwrap()]);
            gdal(&args);
            let what = format!("{ty} {options:?}");
            let raster = read_path(&tif, &ReadOptions::default()).unwrap_or_else(|e| panic!("{what}: {e}"));
            let (transform, gdal_nodata, epsg) = gdalinfo(&tif);
            let g = raster.georef.clone().unwrap_or_else(|| panic!("{what}: no georef"));
            assert_eq!(g.pixel_size(), Some((transform[1], transform[5])), "{what}");
            assert_eq!(g.pixel_size(), Some((30.0, -20.0)), "{what}");
            let t = g.affine().unwrap();
            assert_eq!((t.c, t.f), (transform[0], transform[3]), "{what}");
            assert_eq!(g.nodata, gdal_nodata, "{what}");
            assert_eq!(g.epsg.map(u64::from), epsg, "{what}");
            assert_eq!(g.model, Some(ModelType::Projected), "{what}");
            let stored = raster.into_stored_heights(None).unwrap();
            for (i, &want) in values.iter().enumerate() {
                assert_eq!(stored.height(i), Some(want), "{what} texel {i}");
            }
        }
    }
}

#[test]
#[ignore = "needs gdal-bin (gdal_translate, gdalinfo); CI installs it"]
fn gdal_multi_band_files_give_each_band_and_geographic_rasters_their_degrees() {
    let dir = tempfile::tempdir().unwrap();
    let values = heights(false);
    let grid = dir.path().join("g.asc");
    write_grid(&grid, &values, (30.0, 30.0), NODATA);
    // Three bands: the grid, the grid scaled by 2, by -1 (a VRT would do;
    // gdal_translate's -scale per band keeps it one command).
    for interleave in ["PIXEL", "BAND"] {
        for tiled in ["NO", "YES"] {
            let tif = dir.path().join(format!("m_{interleave}_{tiled}.tif"));
            let t = tif.to_str().unwrap();
            gdal(&[
                "-ot",
                "Int32",
                "-a_srs",
                "EPSG:32633",
                "-b",
                "1",
                "-b",
                "1",
                "-b",
                "1",
                "-scale_2",
                "0",
                "1",
                "0",
                "2",
                "-scale_3",
                "0",
                "1",
                "0",
                "-1",
                "-co",
                &format!("INTERLEAVE={interleave}"),
                "-co",
                &format!("TILED={tiled}"),
                "-co",
                "BLOCKXSIZE=16",
                "-co",
                "BLOCKYSIZE=16",
                grid.to_str().unwrap(),
                t,
            ]);
            for (band, factor) in [(1u32, 1.0), (2, 2.0), (3, -1.0)] {
                let r = read_path(&tif, &ReadOptions::default().with_band(band)).unwrap();
                let stored = r.into_stored_heights(None).unwrap();
                for (i, &v) in values.iter().enumerate() {
                    // GDAL's scaling leaves nodata texels nodata.
                    let v = if v == NODATA { NODATA } else { v * factor };
                    assert_eq!(stored.height(i), Some(v), "{interleave} tiled {tiled} band {band} texel {i}");
                }
            }
            let e = read_path(&tif, &ReadOptions::default().with_band(4)).unwrap_err();
            assert_eq!(e.to_string(), "unsupported: band 4 asked for, but the file has 3 bands");
        }
    }
    // Geographic: 10° E to 10.0074° E, 46° N down 23 rows of 1 arc-second.
    let geo = dir.path().join("geo.tif");
    let arc = 1.0 / 3600.0;
    let (east, south) = (10.0 + W as f64 * 2.0 * arc, 46.0 - H as f64 * arc);
    gdal(&[
        "-ot",
        "Float32",
        "-a_srs",
        "EPSG:4326",
        "-a_ullr",
        "10",
        "46",
        &east.to_string(),
        &south.to_string(),
        grid.to_str().unwrap(),
        geo.to_str().unwrap(),
    ]);
    let (transform, _, epsg) = gdalinfo(&geo);
    let g = read_path(&geo, &ReadOptions::default()).unwrap().georef.unwrap();
    assert_eq!(g.model, Some(ModelType::Geographic));
    assert_eq!(g.epsg.map(u64::from), epsg);
    assert_eq!(g.epsg, Some(4326));
    // gdalinfo prints 16 significant digits.
    let (px, py) = g.pixel_size().unwrap();
    assert!((px / transform[1] - 1.0).abs() < 1e-12 && (py / transform[5] - 1.0).abs() < 1e-12, "{px} {py}");
    let (dx, dy) = g.spacing_metres(0.0).unwrap();
    let (per_east, per_north) = normalfit::io::metres_per_degree(46.0 - 0.5 * arc);
    assert!((dx - 2.0 * arc * per_east).abs() < 1e-6 && (dy - arc * per_north).abs() < 1e-6, "{dx} {dy}");
}
