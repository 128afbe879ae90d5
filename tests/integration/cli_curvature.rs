//! `normalfit convert --product curvature` as users run it: the float map
//! is the library's, bit for bit; 8- and 16-bit maps by the stated
//! mapping with `--curvature-range`; map units; refusals in one line.

use crate::common;

use std::path::Path;

use common::cli::{run, s};
use normalfit::fit::quadratic::encode;
use normalfit::io::{ReadOptions, read_path};
use normalfit::{Border, Borders, Options, Spacing, Strength, Units, curvature};

fn gray16_png(path: &Path, w: u32, h: u32, values: &[u16]) {
    image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, values.to_vec()).unwrap().save(path).unwrap();
}

/// Bumps and pits on a slope, 16 bits.
fn relief(w: usize, h: usize) -> Vec<u16> {
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            (30000.0 + 900.0 * x + 8000.0 * (x * 0.4).sin() * (y * 0.3).cos()) as u16
        })
        .collect()
}

fn read_values(path: &Path) -> Vec<f32> {
    read_path(path, &ReadOptions::default()).unwrap().heights(None).unwrap()
}

#[test]
fn the_float_map_is_the_librarys_and_the_integer_maps_follow_the_mapping() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (41usize, 29usize);
    let heights = relief(w, h);
    let input = dir.path().join("h.png");
    gray16_png(&input, w as u32, h as u32, &heights);
    let opts =
        Options::new().with_patch(5).with_strength(Strength::Scale(8.0)).with_borders(Borders::both(Border::Mirror));
    let want = curvature(&heights, w, h, &opts).unwrap();
    assert!(want.iter().any(|&k| k > 0.01) && want.iter().any(|&k| k < -0.01), "relief both ways");
    let common = ["--product", "curvature", "-n", "5", "-s", "8", "--border", "mirror", "--quiet"];

    let exr = dir.path().join("k.exr");
    let out = run(&[&["convert", s(&input), "-o", s(&exr)], &common[..]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let got = read_values(&exr);
    assert!(got.iter().zip(&want).all(|(a, b)| a.to_bits() == b.to_bits()), "EXR differs from the library");

    for (bits, max, range) in [("8", 255u32, None), ("16", 65535, Some(0.05))] {
        let png = dir.path().join(format!("k{bits}.png"));
        let mut args = vec!["convert", s(&input), "-o", s(&png), "--bits", bits];
        let r = range.map(|r: f64| r.to_string());
        if let Some(r) = &r {
            args.extend(["--curvature-range", r.as_str()]);
        }
        let out = run(&[&args[..], &common[..]].concat());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let raster = read_path(&png, &ReadOptions::default()).unwrap();
        assert_eq!(raster.planes.len(), 1, "one gray channel");
        let codes: Vec<u32> =
            read_values(&png).iter().map(|&v| (f64::from(v) * f64::from(max)).round() as u32).collect();
        let range = range.unwrap_or(normalfit::fit::quadratic::DEFAULT_RANGE);
        for (k, (&code, &value)) in codes.iter().zip(&want).enumerate() {
            assert_eq!(code, encode(value, range, max), "{bits}-bit texel {k}: curvature {value}");
        }
    }
}

#[test]
fn map_units_take_the_pixel_size() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (20usize, 18usize);
    let heights = relief(w, h);
    let input = dir.path().join("dem.png");
    gray16_png(&input, w as u32, h as u32, &heights);
    let exr = dir.path().join("k.exr");
    let args = ["convert", s(&input), "-o", s(&exr), "--product", "curvature", "--units", "map", "--pixel-size", "30"];
    let out = run(&[&args[..], &["--border", "clamp", "-n", "3", "--quiet"]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let opts = Options::new().with_borders(Borders::both(Border::Clamp)).with_units(Units::Map(Spacing::square(30.0)));
    let want = curvature(&heights, w, h, &opts).unwrap();
    let got = read_values(&exr);
    assert!(got.iter().zip(&want).all(|(a, b)| a.to_bits() == b.to_bits()), "map units differ from the library");
}

#[test]
fn refusals_are_one_line_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    gray16_png(&input, 8, 8, &relief(8, 8));
    let out_path = dir.path().join("k.png");
    for (extra, says) in [
        (&["--product", "curvature", "--curvature-range", "0"][..], "curvature range must be finite and positive"),
        (&["--product", "bumps"][..], "bumps"),
        (&["--product", "curvature", "--mips"][..], "no mip chain"),
        (&["--product", "curvature", "--residual", "r.png"][..], "residual"),
        (&["--product", "curvature", "--detail", "3:1,9:0.5"][..], "not detail at several scales"),
    ] {
        let args = [&["convert", s(&input), "-o", s(&out_path)][..], extra].concat();
        let out = run(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {stderr}");
        // The error is one line (a seam warning may come before it).
        let errors = stderr.lines().filter(|l| !l.starts_with("normalfit: warning:")).count();
        assert!(stderr.contains(says) && errors == 1, "{extra:?}: {stderr}");
        assert!(!out_path.exists(), "{extra:?}: no output");
    }
}

/// Writes a one-channel (`Y`) float EXR.
fn float_exr(path: &Path, w: usize, h: usize, values: &[f32]) {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec, WritableImage,
    };
    let channels = AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new("Y", FlatSamples::F32(values.to_vec()))]));
    let layer = Layer::new((w, h), LayerAttributes::default(), Encoding::SMALL_LOSSLESS, channels);
    Image::from_layer(layer).write().to_file(path).unwrap();
}

#[test]
fn streamed_into_exr_equals_the_whole_image_for_every_border_pair() {
    use normalfit::Product;
    use normalfit::convert::{BorderChoice, BorderChoices, Conversion};
    let dir = tempfile::tempdir().unwrap();
    // Taller than a band (64 rows a thread at N = 5), so the output comes
    // in several bands, and a wrap reads the last rows first.
    let (w, h) = (23usize, 300usize);
    let stored = relief(w, h);
    let floats: Vec<f32> = stored.iter().map(|&v| f32::from(v) / 65535.0 * 3.0 + 7.0).collect();
    let mut holed = floats.clone();
    holed[150 * w + 4] = -1.0;
    let png = dir.path().join("h.png");
    gray16_png(&png, w as u32, h as u32, &stored);
    let exr_in = dir.path().join("h.exr");
    float_exr(&exr_in, w, h, &floats);
    let holed_in = dir.path().join("holed.exr");
    float_exr(&holed_in, w, h, &holed);
    let borders = [Border::Wrap, Border::Clamp, Border::Mirror];
    for bx in borders {
        for by in borders {
            let opts = Options::new().with_patch(5).with_strength(Strength::Scale(2.0));
            let fixed = Borders { x: bx, y: by };
            let conversion = |nodata: Option<f64>| {
                Conversion::new()
                    .with_fit(opts.clone().with_nodata(nodata))
                    .with_borders(BorderChoices { x: BorderChoice::Fixed(bx), y: BorderChoice::Fixed(by) })
                    .with_product(Product::Curvature)
            };
            let library = opts.clone().with_borders(fixed);
            for (input, want, nodata, what) in [
                (&png, curvature(&stored, w, h, &library).unwrap(), None, "16-bit PNG"),
                (&exr_in, curvature(&floats, w, h, &library).unwrap(), None, "float EXR"),
                (
                    &holed_in,
                    curvature(&holed, w, h, &library.clone().with_nodata(Some(-1.0))).unwrap(),
                    Some(-1.0),
                    "holes",
                ),
            ] {
                let out = dir.path().join("k.exr");
                let summary = conversion(nodata).convert_file(input, &out).unwrap();
                assert!(summary.streamed, "{what} {bx},{by}: streamed");
                assert_eq!(summary.missing, want.iter().filter(|v| v.is_nan()).count(), "{what}");
                // The samples as stored: holes are NaN, which heights refuse.
                let raster = read_path(&out, &ReadOptions::default()).unwrap();
                let normalfit::Samples::F32(got) = &raster.planes[0].data else { panic!("{what}: float samples") };
                let differ = got.iter().zip(&want).position(|(a, b)| a.to_bits() != b.to_bits());
                assert_eq!(differ, None, "{what} borders {bx},{by}: streamed differs from the library");
                // The artist's 8- and 16-bit codes, streamed into PNG (the
                // top rows written last).
                for (bits, max) in [(8u8, 255u32), (16, 65535)] {
                    let out = dir.path().join("k.png");
                    let summary = conversion(nodata)
                        .with_bits(bits)
                        .with_curvature_range(0.02)
                        .convert_file(input, &out)
                        .unwrap();
                    assert!(summary.streamed, "{what} {bits}-bit {bx},{by}: streamed");
                    let codes: Vec<u32> =
                        read_values(&out).iter().map(|&v| (f64::from(v) * f64::from(max)).round() as u32).collect();
                    let wanted: Vec<u32> = want.iter().map(|&k| encode(k, 0.02, max)).collect();
                    let differ = codes.iter().zip(&wanted).position(|(a, b)| a != b);
                    assert_eq!(differ, None, "{what} {bits}-bit borders {bx},{by}");
                    assert!(
                        wanted.iter().any(|&c| c > max / 2 + 2) && wanted.iter().any(|&c| c < max / 2 - 2),
                        "{what}: codes both ways"
                    );
                }
            }
        }
    }
}
