//! Holes through the command line: `--nodata` on a 16-bit PNG, NaN in an
//! EXR, a GeoTIFF's GDAL_NODATA tag; the alpha of validity, the count
//! printed, `shade`'s grey 0, streamed against whole.

use crate::common;

use std::path::Path;

use common::cli::{run, s};
use common::geotiff::{self, GeoTag, Kind, Layout};
use exr::prelude::WritableImage;
use exr::prelude::{AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec, Vec2};
use normalfit::io::{ReadOptions, read_path};
use normalfit::{Border, Borders, FitRequest, Options};

fn gray16_png(path: &Path, w: u32, h: u32, values: &[u16]) {
    image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, values.to_vec()).unwrap().save(path).unwrap();
}

fn exr_gray(w: usize, h: usize, heights: &[f32]) -> Vec<u8> {
    let channel = AnyChannel::new("Y", FlatSamples::F32(heights.to_vec()));
    let layer = Layer::new(
        Vec2(w, h),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    let mut bytes = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut bytes).unwrap();
    bytes.into_inner()
}

/// Heights of a 16-bit PNG with holes (0) in random places and a block.
fn holed_u16(w: usize, h: usize) -> Vec<u16> {
    let mut state = 12345u64;
    (0..w * h)
        .map(|k| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let (x, y) = (k % w, k / w);
            let block = (5..9).contains(&x) && (3..6).contains(&y);
            if (state >> 33).is_multiple_of(10) || block {
                0
            } else {
                1000 + (x * 400 + y * 150) as u16 + ((state >> 40) % 300) as u16
            }
        })
        .collect()
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn nodata_on_a_16_bit_png_gives_an_alpha_of_validity_streamed_and_whole() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37usize, 23usize);
    let heights = holed_u16(w, h);
    let input = dir.path().join("h.png");
    gray16_png(&input, w as u32, h as u32, &heights);
    let opts = Options::new().with_patch(5).with_borders(Borders::both(Border::Clamp)).with_nodata(Some(0.0));
    let mut want = vec![[0u16; 3]; w * h];
    let mut valid = vec![false; w * h];
    let missing = FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, w, h, &mut want).unwrap();
    assert!(missing > w * h / 10 && missing < w * h / 2, "{missing}");

    let streamed = dir.path().join("streamed.png");
    let out = run(&["convert", s(&input), "-o", s(&streamed), "-n", "5", "--border", "clamp", "--nodata", "0"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let line = format!("{missing} of {} texels missing (nodata 0): alpha 0", w * h);
    assert!(stderr(&out).contains(&line), "{}", stderr(&out));
    // A residual map is made from the whole image: the other path.
    let whole = dir.path().join("whole.png");
    let residual = dir.path().join("residual.png");
    let out = run(&[
        "convert",
        s(&input),
        "-o",
        s(&whole),
        "-n",
        "5",
        "--border",
        "clamp",
        "--nodata",
        "0",
        "--residual",
        s(&residual),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains(&line), "{}", stderr(&out));
    let streamed_px = image::open(&streamed).unwrap();
    assert_eq!(streamed_px.color(), image::ColorType::Rgba16);
    let streamed_px = streamed_px.into_rgba16().into_raw();
    let whole_px = image::open(&whole).unwrap().into_rgba16().into_raw();
    assert_eq!(streamed_px, whole_px, "streamed and whole");
    for k in 0..w * h {
        let texel = &streamed_px[4 * k..4 * k + 4];
        assert_eq!(texel[..3], want[k], "texel {k}");
        assert_eq!(texel[3], if valid[k] { 65535 } else { 0 }, "texel {k}");
        if !valid[k] {
            assert_eq!(texel[..3], [32768, 32768, 65535], "a missing texel is flat");
        }
    }
    // Without --nodata the zeros are heights, and the map is RGB.
    let plain = dir.path().join("plain.png");
    let out = run(&["convert", s(&input), "-o", s(&plain), "-n", "5", "--border", "clamp"]);
    assert!(out.status.success());
    assert_eq!(image::open(&plain).unwrap().color(), image::ColorType::Rgb16);
    assert!(!stderr(&out).contains("missing"));
}

#[test]
fn nan_in_an_exr_is_a_hole_with_nodata_nan() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (19usize, 14usize);
    let mut heights: Vec<f32> = (0..w * h).map(|k| 0.02 * (k % w) as f32 + 0.001 * ((k * 7919) % 101) as f32).collect();
    for k in [3, 40, 41, 42, 100, 180, 181, 200, w * h - 1] {
        heights[k] = f32::NAN;
    }
    heights[60] = f32::INFINITY;
    let input = dir.path().join("h.exr");
    std::fs::write(&input, exr_gray(w, h, &heights)).unwrap();
    let output = dir.path().join("n.exr");
    // Without --nodata, the contract's error stands.
    let refused = run(&["convert", s(&input), "-o", s(&output)]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(stderr(&refused).contains("NaN or infinite"));
    for border in ["wrap", "mirror"] {
        let out = run(&["convert", s(&input), "-o", s(&output), "--nodata", "nan", "--border", border, "--signed"]);
        assert!(out.status.success(), "{}", stderr(&out));
        let opts = Options::new().with_borders(Borders::both(border.parse().unwrap())).with_nodata(Some(f64::NAN));
        let mut want = vec![[0.0f32; 3]; w * h];
        let mut valid = vec![false; w * h];
        let missing = FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, w, h, &mut want).unwrap();
        assert!(
            stderr(&out).contains(&format!("{missing} of {} texels missing (nodata NaN)", w * h)),
            "{}",
            stderr(&out)
        );
        let raster = read_path(&output, &ReadOptions::default()).unwrap();
        let plane = |name: &str| raster.plane(name).unwrap().data.to_f32().unwrap();
        let (r, g, b, a) = (plane("R"), plane("G"), plane("B"), plane("A"));
        for k in 0..w * h {
            assert_eq!([r[k], g[k], b[k]], want[k], "{border}: texel {k}");
            assert_eq!(a[k], if valid[k] { 1.0 } else { 0.0 }, "{border}: texel {k}");
        }
        assert!(!valid[3] && !valid[60] && valid[1]);
    }
}

/// A float32 GeoTIFF with GDAL_NODATA −9999, written with the tiff crate.
fn dem_with_nodata(w: usize, h: usize, kind: Kind, nodata: f64) -> (Vec<u8>, Vec<f64>) {
    let mut values = Vec::new();
    for k in 0..w * h {
        let (x, y) = (k % w, k / w);
        let hole = (k * 7919).is_multiple_of(13) || ((10..16).contains(&x) && (4..9).contains(&y));
        values.push(if hole { nodata } else { (300 + 3 * x + 2 * y + (k * 31) % 7) as f64 });
    }
    let layout = Layout::gray(kind);
    let mut tags: Vec<GeoTag> =
        geotiff::utm_tags().into_iter().filter(|t| !matches!(t, GeoTag::Ascii(42113, _))).collect();
    tags.push(GeoTag::Ascii(42113, format!("{nodata}")));
    (geotiff::write(w, h, &layout, std::slice::from_ref(&values), &tags), values)
}

#[test]
fn a_geotiff_nodata_tag_makes_holes_in_convert_and_shade() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (31usize, 22usize);
    for (kind, nodata) in [(Kind::F32, -9999.0), (Kind::I16, -32768.0)] {
        let (bytes, values) = dem_with_nodata(w, h, kind, nodata);
        let input = dir.path().join(format!("dem{kind:?}.tif"));
        std::fs::write(&input, bytes).unwrap();
        let streamed = dir.path().join("streamed.exr");
        let args = ["-n", "3", "--border", "clamp", "--units", "map", "--signed"];
        let out = run(&[&["convert", s(&input), "-o", s(&streamed)][..], &args].concat());
        assert!(out.status.success(), "{}", stderr(&out));
        // The same heights in the library: the DEM's metres, 30 m pixels.
        let heights: Vec<f64> = values.clone();
        let opts = Options::new()
            .with_borders(Borders::both(Border::Clamp))
            .with_units(normalfit::Units::Map(normalfit::Spacing::square(30.0)))
            .with_nodata(Some(nodata));
        let mut want = vec![[0.0f32; 3]; w * h];
        let mut valid = vec![false; w * h];
        let missing = FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, w, h, &mut want).unwrap();
        assert!(stderr(&out).contains(&format!("{missing} of {} texels missing", w * h)), "{}", stderr(&out));
        let raster = read_path(&streamed, &ReadOptions::default()).unwrap();
        let plane = |name: &str| raster.plane(name).unwrap().data.to_f32().unwrap();
        let (r, a) = (plane("R"), plane("A"));
        for k in 0..w * h {
            assert!((r[k] - want[k][0]).abs() < 1e-6, "{kind:?} texel {k}");
            assert_eq!(a[k], if valid[k] { 1.0 } else { 0.0 }, "{kind:?} texel {k}");
        }
        // Texel units, PNG: streamed (the TIFF band) and whole (a residual).
        let (a_png, b_png, res) = (dir.path().join("a.png"), dir.path().join("b.png"), dir.path().join("r.png"));
        let out = run(&["convert", s(&input), "-o", s(&a_png), "--border", "mirror", "-s", "300"]);
        assert!(out.status.success(), "{}", stderr(&out));
        let out =
            run(&["convert", s(&input), "-o", s(&b_png), "--border", "mirror", "-s", "300", "--residual", s(&res)]);
        assert!(out.status.success(), "{}", stderr(&out));
        let pa = image::open(&a_png).unwrap().into_rgba16().into_raw();
        let pb = image::open(&b_png).unwrap().into_rgba16().into_raw();
        assert_eq!(pa, pb, "{kind:?}: streamed and whole");
        let holes = values.iter().filter(|&&v| v == nodata).count();
        let zero_alpha = pa.chunks_exact(4).filter(|t| t[3] == 0).count();
        assert!(zero_alpha >= holes, "{kind:?}: {zero_alpha} < {holes}");

        // shade: grey 0 where missing, at least 1 elsewhere (gdaldem's
        // 1 + 254·cos).
        let lit = dir.path().join("lit.png");
        let out = run(&["shade", s(&input), "-o", s(&lit), "--border", "clamp"]);
        assert!(out.status.success(), "{}", stderr(&out));
        let grey = image::open(&lit).unwrap().into_luma8().into_raw();
        let opts = Options::new().with_borders(Borders::both(Border::Clamp)).with_nodata(Some(nodata));
        let mut normals = vec![[0.0f32; 3]; w * h];
        let missing = FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, w, h, &mut normals).unwrap();
        assert!(stderr(&out).contains(&format!("{missing} of {} texels missing: grey 0", w * h)), "{}", stderr(&out));
        for k in 0..w * h {
            assert_eq!(grey[k] == 0, !valid[k], "{kind:?} texel {k}: grey {}", grey[k]);
        }
    }
}

#[test]
fn an_all_missing_image_converts_to_an_all_transparent_map() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (9usize, 7usize);
    let input = dir.path().join("h.png");
    gray16_png(&input, w as u32, h as u32, &vec![7; w * h]);
    let output = dir.path().join("n.png");
    let out = run(&["convert", s(&input), "-o", s(&output), "--nodata", "7"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(&format!("{0} of {0} texels missing (nodata 7): alpha 0", w * h)),
        "{}",
        stderr(&out)
    );
    let px = image::open(&output).unwrap().into_rgba16().into_raw();
    assert!(px.chunks_exact(4).all(|t| t == [32768, 32768, 65535, 0]));
    let lit = dir.path().join("lit.png");
    let out = run(&["shade", s(&input), "-o", s(&lit), "--nodata", "7"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(image::open(&lit).unwrap().into_luma8().into_raw().iter().all(|&g| g == 0));
}

/// `--nodata none` ignores a GeoTIFF's GDAL_NODATA tag: its value is a
/// height like any other, in `convert` (streamed and whole) and `shade`,
/// and the map has no alpha; the library reads no nodata value either.
#[test]
fn nodata_none_ignores_the_geotiffs_tag() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (31usize, 22usize);
    let (bytes, values) = dem_with_nodata(w, h, Kind::F32, -9999.0);
    let input = dir.path().join("dem.tif");
    std::fs::write(&input, bytes).unwrap();
    let read = ReadOptions::default();
    assert_eq!(read_path(&input, &read).unwrap().georef.unwrap().nodata, Some(-9999.0));
    assert_eq!(read_path(&input, &read.with_nodata_tag(false)).unwrap().georef.unwrap().nodata, None);

    // The plain fit of every value, −9999 included.
    let opts =
        Options::new().with_borders(Borders::both(Border::Clamp)).with_strength(normalfit::Strength::Scale(0.01));
    let mut want = vec![[0.0f32; 3]; w * h];
    FitRequest::new(&opts).normals_into(&values, w, h, &mut want).unwrap();
    let args = ["--border", "clamp", "-s", "0.01", "--signed", "--nodata", "none"];
    let (streamed, whole, res) = (dir.path().join("a.exr"), dir.path().join("b.exr"), dir.path().join("r.exr"));
    for (output, extra) in [(&streamed, &[][..]), (&whole, &["--residual", s(&res)][..])] {
        let out = run(&[&["convert", s(&input), "-o", s(output)][..], &args, extra].concat());
        assert!(out.status.success(), "{}", stderr(&out));
        assert!(!stderr(&out).contains("missing"), "{}", stderr(&out));
        let raster = read_path(output, &ReadOptions::default()).unwrap();
        assert!(raster.plane("A").is_none(), "no alpha without holes");
        let plane = |name: &str| raster.plane(name).unwrap().data.to_f32().unwrap();
        let (r, g, b) = (plane("R"), plane("G"), plane("B"));
        for k in 0..w * h {
            let got = [r[k], g[k], b[k]];
            assert!(got.iter().zip(want[k]).all(|(a, b)| (a - b).abs() < 1e-6), "texel {k}: {got:?} {:?}", want[k]);
        }
    }
    // shade: no texel is missing, so none is grey 0 (gdaldem's 1 + 254·cos).
    let lit = dir.path().join("lit.png");
    let out = run(&["shade", s(&input), "-o", s(&lit), "--border", "clamp", "--nodata", "none"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!stderr(&out).contains("missing"), "{}", stderr(&out));
    assert!(image::open(&lit).unwrap().into_luma8().into_raw().iter().all(|&g| g > 0));
    // Without it, the tag's holes are grey 0.
    let out = run(&["shade", s(&input), "-o", s(&lit), "--border", "clamp"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(image::open(&lit).unwrap().into_luma8().into_raw().contains(&0));
}

#[test]
fn nodata_is_a_number_or_none() {
    let out = run(&["convert", "x.png", "--nodata", "nothing"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("'nothing' is not a number (or nan, or none)"), "{}", stderr(&out));
}

/// An alpha of heights with holes: the height where the texel has a
/// normal, 0 where it is missing (a hole's NaN or nodata value is no
/// height), in EXR and TIFF floats, streamed (a TIFF's bands) and whole
/// (a residual asks for the whole image). In map units the alpha holds
/// the DEM's metres, so integer outputs are refused in one line; so is
/// `--relief`, a gain per image width, which map units have no use for.
#[test]
fn an_alpha_of_heights_is_zero_at_holes_and_metres_need_floats() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (29usize, 19usize);
    let nodata = -9999.0;
    let (_, mut values) = dem_with_nodata(w, h, Kind::F32, nodata);
    // An island: texel (20, 12) alone among holes, a height whose 3 × 3
    // patch holds one valid point, so it has no normal.
    for y in 11..14 {
        for x in 19..22 {
            values[y * w + x] = if (x, y) == (20, 12) { 345.0 } else { nodata };
        }
    }
    let mut tags: Vec<GeoTag> =
        geotiff::utm_tags().into_iter().filter(|t| !matches!(t, GeoTag::Ascii(42113, _))).collect();
    tags.push(GeoTag::Ascii(42113, format!("{nodata}")));
    let input = dir.path().join("dem.tif");
    std::fs::write(&input, geotiff::write(w, h, &Layout::gray(Kind::F32), std::slice::from_ref(&values), &tags))
        .unwrap();
    let opts = Options::new()
        .with_borders(Borders::both(Border::Clamp))
        .with_units(normalfit::Units::Map(normalfit::Spacing::square(30.0)))
        .with_nodata(Some(nodata));
    let mut normals = vec![[0.0f32; 3]; w * h];
    let mut valid = vec![false; w * h];
    let missing = FitRequest::new(&opts).holes(&mut valid).normals_into(&values, w, h, &mut normals).unwrap();
    let holes = values.iter().filter(|&&v| v == nodata).count();
    assert!(missing > holes && holes > 0, "holes {holes}, missing {missing}: both kinds of missing texel");
    let common = ["--units", "map", "--border", "clamp", "--alpha", "height"];
    let residual = dir.path().join("r.exr");
    let residual_args = ["--residual", s(&residual)];
    for (name, extra) in [("s.exr", &[][..]), ("w.exr", &residual_args[..]), ("t.tif", &["--bits", "32"][..])] {
        let output = dir.path().join(name);
        let out = run(&[&["convert", s(&input), "-o", s(&output)][..], &common, extra].concat());
        assert!(out.status.success(), "{name}: {}", stderr(&out));
        let raster = read_path(&output, &ReadOptions::default()).unwrap();
        let alpha = raster.plane("A").unwrap().data.to_f32().unwrap();
        for k in 0..w * h {
            let want = if valid[k] { values[k] as f32 } else { 0.0 };
            assert_eq!(alpha[k].to_bits(), want.to_bits(), "{name}: texel {k} (valid {})", valid[k]);
        }
    }
    for (output, args) in [
        ("n.png", &common[..]),
        ("n16.tif", &common[..]),
        ("relief.exr", &["--units", "map", "--relief", "0.5"][..]),
        ("relief.png", &["--pixel-size", "30", "--relief", "0.5"][..]),
    ] {
        let output = dir.path().join(output);
        let out = run(&[&["convert", s(&input), "-o", s(&output)][..], args].concat());
        let message = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {message}");
        assert_eq!(message.lines().count(), 1, "{message}");
        // The alpha's refusal is the output's; the relief's, the fit's of the input.
        let relief = args.contains(&"--relief");
        let named = if relief { s(&input) } else { s(&output) };
        assert!(message.starts_with(&format!("normalfit: {named}: ")), "{message}");
        let why = if relief { "relief 0.5 (a gain per image width)" } else { "clamp to [0, 1]" };
        assert!(message.contains(why), "{args:?}: {message}");
        assert!(!output.exists(), "{args:?}: no output");
    }
}

#[test]
fn border_auto_skips_the_holes_of_a_dem() {
    // A DEM that tiles along x (periodic noise) and not along y (a crop of
    // its rows), with nodata −9999 in a block inside and at a fifth of
    // the texels of its edges, across both seams. `auto` must pick wrap
    // along x and mirror along y, as for the DEM without holes: read as
    // heights, the −9999 at the edges would be a seam along x too.
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (64usize, 48usize);
    let big = crate::tiling_support::periodic_noise(w, 3 * h, 3, 2, 31);
    let plain: Vec<f64> = big[w * h / 2..][..w * h].iter().map(|&v| 300.0 + 80.0 * f64::from(v)).collect();
    let mut state = 99u64;
    let holed: Vec<f64> = plain
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let (x, y) = (k % w, k / w);
            let edge = x == 0 || y == 0 || x == w - 1 || y == h - 1;
            let block = (20..30).contains(&x) && (10..22).contains(&y);
            if block || (edge && (state >> 33).is_multiple_of(5)) { -9999.0 } else { v }
        })
        .collect();
    let layout = Layout::gray(Kind::F32);
    let mut tags: Vec<GeoTag> =
        geotiff::utm_tags().into_iter().filter(|t| !matches!(t, GeoTag::Ascii(42113, _))).collect();
    tags.push(GeoTag::Ascii(42113, "-9999".into()));
    for (name, values) in [("plain", &plain), ("holed", &holed)] {
        let input = dir.path().join(format!("{name}.tif"));
        std::fs::write(&input, geotiff::write(w, h, &layout, std::slice::from_ref(values), &tags)).unwrap();
        // Streamed (a TIFF's rows), then whole (a residual asks for it).
        for whole in [false, true] {
            let normals = |border: &str| {
                let out = dir.path().join(format!("{name}-{border}-{whole}.png"));
                let residual = dir.path().join("residual.png");
                let mut args = vec!["convert", s(&input), "-o", s(&out), "-n", "5", "--border", border];
                if whole {
                    args.extend(["--residual", s(&residual)]);
                }
                let r = run(&args);
                assert!(r.status.success(), "{name} {border}: {}", stderr(&r));
                image::open(&out).unwrap().into_rgba16().into_raw()
            };
            let auto = normals("auto");
            assert!(auto == normals("wrap,mirror"), "{name}, whole {whole}: auto is not wrap,mirror");
            assert!(auto != normals("mirror"), "{name}, whole {whole}: the borders change nothing");
        }
        // `tiling` reads the tag as `convert` does; `--nodata none` makes
        // the −9999 heights, and a seam along x.
        let verdict = |extra: &[&str]| {
            let r = run(&[&["tiling", s(&input)][..], extra].concat());
            assert_eq!(r.status.code(), Some(1), "{name} {extra:?}: {}", stderr(&r));
            String::from_utf8_lossy(&r.stdout).into_owned()
        };
        let line = verdict(&[]);
        assert!(line.contains(" seamless, y ") && line.trim_end().ends_with("SEAM)"), "{name}: {line}");
        assert_eq!(verdict(&["--nodata", "-9999"]), line, "{name}");
        if name == "holed" {
            let line = verdict(&["--nodata", "none"]);
            assert!(line.contains("SEAM, y "), "{name}, --nodata none: {line}");
        }
    }
}
