//! Terrain inputs on the command line (issue 17): `--band`, `--size`,
//! `--byte-order`, `--decode` in `convert`, `shade` and `tiling`, and their
//! errors (one line naming the file, exit code 2). What they read is the
//! library's, tested in tests/integration/terrain_io.rs; here each input's output must
//! equal the output of the same heights given in a plain format.

use crate::common;

use std::fs;
use std::io::Write;
use std::path::Path;
use std::process::{Output, Stdio};

use common::cli::{bin, is_summary, run, s};
use common::geotiff::{self, Kind, Layout};

fn ok(args: &[&str]) -> Output {
    let r = run(args);
    assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
    r
}

/// A `tiling` run that checked its input: exit code 0 (tiles) or 1 (a
/// seam), not 2 (an error).
fn checked(args: &[&str]) {
    let r = run(args);
    assert!(matches!(r.status.code(), Some(0 | 1)), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
}

/// The pixels of a PNG, to compare outputs written by different paths (a
/// streamed PNG and a whole one have the same pixels, not the same chunks).
fn pixels(path: &Path) -> Vec<u16> {
    image::open(path).unwrap().to_rgb16().into_raw()
}

/// The one error line of a failed run (exit code 2), which must name `file`.
fn fails_naming(args: &[&str], file: &Path) -> String {
    let r = run(args);
    assert_eq!(r.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
    let all = String::from_utf8_lossy(&r.stderr).to_string();
    assert!(!all.contains("panicked"), "{all}");
    let errors: Vec<&str> = all.lines().filter(|l| !l.starts_with("normalfit: warning: ") && !is_summary(l)).collect();
    assert_eq!(errors.len(), 1, "one error line: {all:?}");
    assert!(errors[0].contains(s(file)), "{} should name {}", errors[0], file.display());
    errors[0].to_string()
}

/// A 16-bit gray PNG of `values`.
fn gray16_png(path: &Path, w: u32, h: u32, values: &[u16]) {
    image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, values.to_vec()).unwrap().save(path).unwrap();
}

/// Float heights as a one-band float64 TIFF (the reader keeps them in
/// f64, as it keeps unpacked tiles).
fn f64_tiff(path: &Path, w: usize, h: usize, values: &[f64]) {
    let bytes = geotiff::write(w, h, &Layout::gray(Kind::F64), &[values.to_vec()], &[]);
    fs::write(path, bytes).unwrap();
}

#[test]
fn a_band_of_a_planar_tiled_dem_converts_as_that_band_alone() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37, 23);
    let layout =
        Layout { kind: Kind::I16, bands: 3, planar: true, tile: Some((16, 16)), rows_per_strip: 5, photometric: 1 };
    let values = geotiff::band_values(&layout, w, h);
    let multi = dir.path().join("multi.tif");
    fs::write(&multi, geotiff::write(w, h, &layout, &values, &geotiff::utm_tags())).unwrap();
    let single = dir.path().join("single.tif");
    // The same tags: the GDAL_NODATA tag (−32768) makes holes of both.
    let tags = geotiff::utm_tags();
    fs::write(&single, geotiff::write(w, h, &Layout::gray(Kind::I16), &[values[1].clone()], &tags)).unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    ok(&["convert", s(&multi), "--band", "2", "-o", s(&a), "-s", "300"]);
    ok(&["convert", s(&single), "-o", s(&b), "-s", "300"]);
    assert_eq!(fs::read(&a).unwrap(), fs::read(&b).unwrap());
    // Without --band, the first.
    let first = dir.path().join("first.tif");
    fs::write(&first, geotiff::write(w, h, &Layout::gray(Kind::I16), &[values[0].clone()], &tags)).unwrap();
    let (c, d) = (dir.path().join("c.png"), dir.path().join("d.png"));
    ok(&["convert", s(&multi), "-o", s(&c)]);
    ok(&["convert", s(&first), "-o", s(&d)]);
    assert_eq!(fs::read(&c).unwrap(), fs::read(&d).unwrap());
    // shade and tiling take the band too.
    let lit = dir.path().join("lit.png");
    ok(&["shade", s(&multi), "--band", "3", "-o", s(&lit)]);
    assert!(lit.exists());
    checked(&["tiling", s(&multi), "--band", "3", "--json"]);

    let e = fails_naming(&["convert", s(&multi), "--band", "4", "-o", s(&a)], &multi);
    assert!(e.ends_with("band 4 asked for, but the file has 3 bands"), "{e}");
    let png = dir.path().join("h.png");
    gray16_png(&png, 2, 2, &[1, 2, 3, 4]);
    let e = fails_naming(&["convert", s(&png), "--band", "1"], &png);
    assert!(e.ends_with("band 1 asked for, but png files have no bands (only TIFF has)"), "{e}");
    // A band of 0 is refused by the option's parser: a usage error.
    let r = run(&["convert", s(&multi), "--band", "0"]);
    assert_eq!(r.status.code(), Some(2));
}

#[test]
fn a_raw_heightmap_converts_as_the_same_16_bit_png() {
    let dir = tempfile::tempdir().unwrap();
    let n = 33u32;
    let values: Vec<u16> = (0..n * n).map(|i| ((i * 977) % 4000 + 20_000) as u16).collect();
    let png = dir.path().join("same.png");
    gray16_png(&png, n, n, &values);
    let r16 = dir.path().join("terrain.r16");
    fs::write(&r16, values.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
    let mac = dir.path().join("mac.raw");
    fs::write(&mac, values.iter().flat_map(|v| v.to_be_bytes()).collect::<Vec<u8>>()).unwrap();
    let want = dir.path().join("want.png");
    ok(&["convert", s(&png), "-o", s(&want), "-s", "50"]);
    // Beside the input, named as usual, 16-bit like the input.
    ok(&["convert", s(&r16), "-s", "50"]);
    assert_eq!(pixels(&dir.path().join("terrain_normal.png")), pixels(&want));
    let out = dir.path().join("mac.png");
    ok(&["convert", s(&mac), "--byte-order", "big", "-o", s(&out), "-s", "50"]);
    assert_eq!(pixels(&out), pixels(&want));

    // From standard input with its size given.
    let mut child = bin()
        .args(["convert", "-", "--size", &format!("{n}x{n}"), "-o", "-", "--format", "png", "-s", "50"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || stdin.write_all(&bytes));
    let r = child.wait_with_output().unwrap();
    writer.join().unwrap().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let piped = dir.path().join("piped.png");
    fs::write(&piped, &r.stdout).unwrap();
    assert_eq!(pixels(&piped), pixels(&want));

    // A folder takes RAW files by their extension.
    let folder = dir.path().join("tiles");
    fs::create_dir(&folder).unwrap();
    fs::copy(&r16, folder.join("a.r16")).unwrap();
    fs::write(folder.join("b.r8"), vec![9u8; 16]).unwrap();
    let outs = dir.path().join("outs");
    ok(&["convert", s(&folder), "-o", s(&outs)]);
    assert!(outs.join("a_normal.png").exists() && outs.join("b_normal.png").exists());
    ok(&["shade", s(&r16), "-o", s(&dir.path().join("lit.png"))]);
    checked(&["tiling", s(&r16)]);
}

#[test]
fn raw_errors_name_the_file_and_the_length() {
    let dir = tempfile::tempdir().unwrap();
    let odd = dir.path().join("odd.raw");
    fs::write(&odd, vec![0u8; 10]).unwrap();
    let e = fails_naming(&["convert", s(&odd)], &odd);
    assert!(e.contains("RAW heightmap of 10 bytes is not a square of 8- or 16-bit samples"), "{e}");
    let sized = dir.path().join("sized.r16");
    fs::write(&sized, vec![0u8; 2 * 64 * 32 - 2]).unwrap();
    let e = fails_naming(&["convert", s(&sized), "--size", "64x32"], &sized);
    assert!(e.contains("does not hold 64×32 16-bit samples (that takes 4096 bytes at 16 bits)"), "{e}");
    // Sizes and byte orders the parser refuses: usage errors, exit 2.
    for bad in [["--size", "64"], ["--size", "0x4"], ["--byte-order", "middle"]] {
        let r = run(&["convert", s(&sized), bad[0], bad[1]]);
        assert_eq!(r.status.code(), Some(2), "{bad:?}");
        assert!(String::from_utf8_lossy(&r.stderr).contains(bad[1]), "{bad:?}");
    }
    // In a batch, the bad file is reported and skipped, the good one written.
    let good = dir.path().join("good.r8");
    fs::write(&good, vec![3u8; 9]).unwrap();
    let r = run(&["convert", s(&odd), s(&good), "-o", s(&dir.path().join("out"))]);
    assert_eq!(r.status.code(), Some(2));
    assert!(dir.path().join("out/good_normal.png").exists());
}

#[test]
fn packed_tiles_convert_as_their_metres_in_a_float_tiff() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (24u32, 16u32);
    let px: Vec<[u8; 3]> =
        (0..w * h).map(|i| [1 + (i % 3) as u8, (i * 37 % 256) as u8, (i * 91 % 256) as u8]).collect();
    let tile = dir.path().join("tile.png");
    let flat: Vec<u8> = px.iter().flatten().copied().collect();
    image::RgbImage::from_raw(w, h, flat).unwrap().save(&tile).unwrap();
    for (name, metres) in [
        (
            "terrain-rgb",
            px.iter()
                .map(|p| -10_000.0 + (f64::from(p[0]) * 65536.0 + f64::from(p[1]) * 256.0 + f64::from(p[2])) * 0.1)
                .collect::<Vec<f64>>(),
        ),
        (
            "terrarium",
            px.iter().map(|p| f64::from(p[0]) * 256.0 + f64::from(p[1]) + f64::from(p[2]) / 256.0 - 32768.0).collect(),
        ),
    ] {
        let tif = dir.path().join(format!("{name}.tif"));
        f64_tiff(&tif, w as usize, h as usize, &metres);
        let (a, b) = (dir.path().join(format!("{name}_a.png")), dir.path().join(format!("{name}_b.png")));
        ok(&["convert", s(&tile), "--decode", name, "-o", s(&a), "-s", "0.05"]);
        ok(&["convert", s(&tif), "-o", s(&b), "-s", "0.05"]);
        // The same texels; not the same bytes: the float TIFF streams, and
        // the streamed PNG stores its top rows apart (docs/terrain-outputs.md).
        let pixels = |p: &std::path::Path| image::open(p).unwrap().into_rgb16().into_raw();
        assert_eq!(pixels(&a), pixels(&b), "{name}");
        let img = image::open(&a).unwrap();
        assert_eq!(img.color(), image::ColorType::Rgb16, "float heights: a 16-bit PNG by default");
    }
    ok(&["shade", s(&tile), "--decode", "terrarium", "-o", s(&dir.path().join("lit.png"))]);
    // A gray PNG is no tile.
    let gray = dir.path().join("gray.png");
    gray16_png(&gray, 2, 2, &[1, 2, 3, 4]);
    let e = fails_naming(&["convert", s(&gray), "--decode", "terrarium"], &gray);
    // The sample type in words, not a Rust value ("Int { bits: 16 }").
    assert!(e.ends_with("terrarium tiles hold 8-bit RGB; this one has 16-bit integer samples"), "{e}");
    let r = run(&["convert", s(&tile), "--decode", "lerc"]);
    assert_eq!(r.status.code(), Some(2));
}

/// A lossy WebP: the 1×1 VP8 image browsers are probed with (a lossy
/// keyframe, `RIFF…WEBPVP8 `), which `image` decodes to RGB.
const LOSSY_WEBP: &[u8] = &[
    0x52, 0x49, 0x46, 0x46, 0x22, 0x00, 0x00, 0x00, 0x57, 0x45, 0x42, 0x50, 0x56, 0x50, 0x38, 0x20, 0x16, 0x00, 0x00,
    0x00, 0x30, 0x01, 0x00, 0x9d, 0x01, 0x2a, 0x01, 0x00, 0x01, 0x00, 0x0e, 0xc0, 0xfe, 0x25, 0xa4, 0x00, 0x03, 0x70,
    0x00, 0x00, 0x00, 0x00,
];

#[test]
fn packed_tiles_are_read_from_lossless_webp_only() {
    let dir = tempfile::tempdir().unwrap();
    let lossy = dir.path().join("lossy.webp");
    fs::write(&lossy, LOSSY_WEBP).unwrap();
    // It is an image: read as one without --decode.
    ok(&["convert", s(&lossy), "-o", s(&dir.path().join("picture.png"))]);
    // Its bytes are not the ones packed: every packing refuses it, in
    // every command that unpacks, from a file and from standard input.
    for packing in ["terrarium", "terrain-rgb"] {
        for command in ["convert", "shade"] {
            let out = dir.path().join(format!("{packing}_{command}.png"));
            let e = fails_naming(&[command, s(&lossy), "--decode", packing, "-o", s(&out)], &lossy);
            assert!(
                e.ends_with("lossless WebP tiles only: this one is lossy (VP8), which changes the packed bytes"),
                "{e}"
            );
            assert!(!out.exists());
        }
    }
    let r = bin()
        .args(["convert", "-", "--decode", "terrarium", "-o", s(&dir.path().join("stdin.png"))])
        .stdin(fs::File::open(&lossy).unwrap())
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("this one is lossy"), "{}", String::from_utf8_lossy(&r.stderr));
    // A lossless WebP tile unpacks as its PNG twin does.
    let (w, h) = (6u32, 4u32);
    let rgb: Vec<u8> = (0..w * h * 3).map(|k| (k * 29 % 256) as u8).collect();
    let (webp, png) = (dir.path().join("tile.webp"), dir.path().join("tile.png"));
    let mut bytes = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::webp::WebPEncoder::new_lossless(&mut bytes),
        &rgb,
        w,
        h,
        image::ExtendedColorType::Rgb8,
    )
    .unwrap();
    fs::write(&webp, bytes).unwrap();
    image::RgbImage::from_raw(w, h, rgb).unwrap().save(&png).unwrap();
    let (a, b) = (dir.path().join("a.exr"), dir.path().join("b.exr"));
    ok(&["convert", s(&webp), "--decode", "terrarium", "-o", s(&a)]);
    ok(&["convert", s(&png), "--decode", "terrarium", "-o", s(&b)]);
    assert_eq!(fs::read(&a).unwrap(), fs::read(&b).unwrap());
}

#[test]
fn a_raw_size_past_2_pow_64_bytes_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("small.raw");
    fs::write(&raw, [0u8; 16]).unwrap();
    // (2^32 − 1)(2^32 + 1) = 2^64 − 1 texels: 2^64 − 1 bytes at 8 bits, and
    // at 16 more than a u64 counts, said so rather than saturated.
    let e = fails_naming(&["convert", s(&raw), "--size", "4294967295x4294967297"], &raw);
    assert!(e.ends_with("(that takes 18446744073709551615 bytes at 8 bits or 2^64 bytes or more at 16 bits)"), "{e}");
    let e = fails_naming(&["convert", s(&raw), "--size", "4294967296x4294967296"], &raw);
    assert!(e.ends_with("too large: 4294967296 × 4294967296 is 2^64 texels or more"), "{e}");
}

#[test]
fn bad_geotiffs_are_one_line_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (20, 12);
    let layout = Layout::gray(Kind::F32);
    let bytes = geotiff::write(w, h, &layout, &geotiff::band_values(&layout, w, h), &geotiff::utm_tags());
    let cut = dir.path().join("cut.tif");
    fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    fails_naming(&["convert", s(&cut)], &cut);
    let bad_nodata = dir.path().join("nodata.tif");
    let tags = vec![geotiff::GeoTag::Ascii(42113, "none".into())];
    fs::write(&bad_nodata, geotiff::write(w, h, &layout, &geotiff::band_values(&layout, w, h), &tags)).unwrap();
    let e = fails_naming(&["convert", s(&bad_nodata)], &bad_nodata);
    assert!(e.ends_with("GDAL_NODATA tag (42113) holds 'none', not a number"), "{e}");
    // A pixel scale that is finite and not 0, but too large to fit by:
    // the number as written (1e308, not its 309 digits), and the file's
    // tags at fault, not an option.
    let huge = dir.path().join("huge.tif");
    let tags = vec![
        geotiff::GeoTag::Doubles(33550, vec![1e308, 1e308, 0.0]),
        geotiff::GeoTag::Doubles(33922, vec![0.0, 0.0, 0.0, 500_000.0, 4_000_000.0, 0.0]),
    ];
    fs::write(&huge, geotiff::write(w, h, &layout, &geotiff::band_values(&layout, w, h), &tags)).unwrap();
    for command in ["convert", "shade"] {
        let out = dir.path().join(format!("huge_{command}.png"));
        let e = fails_naming(&[command, s(&huge), "--units", "map", "-o", s(&out)], &huge);
        assert!(
            e.ends_with(
                "unsupported: the file's georeferencing: texel spacing 1e308 × 1e308 is out of range: each \
                 side within 1e-30 to 1e30, one at most 1e6 times the other"
            ),
            "{e}"
        );
        assert!(!out.exists());
    }
}

#[test]
fn help_man_page_and_completions_know_the_terrain_options() {
    let text = |args: &[&str]| String::from_utf8(ok(args).stdout).unwrap();
    for command in ["convert", "shade", "tiling"] {
        let help = text(&[command, "--help"]);
        for option in ["--band", "--size", "--byte-order", "--decode"] {
            assert!(help.contains(option), "{command} --help lacks {option}");
        }
        assert!(help.contains("Terrain:"), "{command} --help has a Terrain heading");
    }
    let help = text(&["convert", "--help"]);
    for value in ["terrain-rgb", "terrarium", "little", "big"] {
        assert!(help.contains(value), "convert --help lacks {value}");
    }
    let man = text(&["man"]);
    let bash = text(&["completions", "bash"]);
    for option in ["band", "size", "byte-order", "decode"] {
        // roff escapes the hyphens: \-\-byte\-order.
        assert!(man.contains(&format!("\\-\\-{}", option.replace('-', "\\-"))), "man page lacks --{option}");
        assert!(bash.contains(&format!("--{option}")), "bash completion lacks --{option}");
    }
    // The registry's extensions are in the inputs' help.
    assert!(help.contains("RAW heightmap"), "{help}");
}
