//! TIFF output (src/io/tiff/write.rs), read back with the `tiff` crate's own
//! decoder: a normal map in TIFF holds the samples the PNG (8 and 16 bits)
//! or the EXR (float, (n + 1)/2 or n) holds for the same conversion,
//! streamed from a GeoTIFF or fitted whole, for wrapped and clamped
//! borders; holes give a fourth sample, an unassociated alpha of 0; the
//! lit view holds the PNG's greys; the GeoTIFF tags come across as stored;
//! the command line writes TIFF to a file or to standard output and
//! refuses depths TIFF does not take. GDAL's reading of these files is in
//! tests/integration/terrain_gdal_out.rs.

use crate::common;

use std::fs::File;
use std::path::Path;

use common::geotiff::{self, GeoTag, Kind, Layout};
use normalfit::convert::{BorderChoices, Conversion, Input, Output};
use normalfit::io::{ReadOptions, read_path};
use normalfit::shade::{LitOptions, lit_file, lit_view};
use normalfit::{Border, Borders, Options, Strength};
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;

const W: usize = 37;
const H: usize = 23;

/// A projected DEM's tags (UTM 33N, 10 m texels), with a GDAL nodata
/// value if asked for.
fn tags(nodata: Option<&str>) -> Vec<GeoTag> {
    let mut tags = vec![
        GeoTag::Doubles(33550, vec![10.0, 10.0, 0.0]),
        GeoTag::Doubles(33922, vec![0.0, 0.0, 0.0, 500_000.0, 4_500_000.0, 0.0]),
        GeoTag::Shorts(34735, vec![1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32633]),
    ];
    tags.extend(nodata.map(|v| GeoTag::Ascii(42113, v.into())));
    tags
}

/// A float32 GeoTIFF of smooth heights (tiles cut by the edges), with
/// holes of value −9999 at every 11th texel when `holes`.
fn dem(path: &Path, holes: bool) {
    let layout =
        Layout { kind: Kind::F32, bands: 1, planar: false, tile: Some((16, 16)), rows_per_strip: 5, photometric: 1 };
    let values = (0..W * H)
        .map(|i| {
            let (x, y) = ((i % W) as f64, (i / W) as f64);
            if holes && i % 11 == 3 {
                return -9999.0;
            }
            f64::from((200.0 + 40.0 * (x * 0.25).sin() * (y * 0.15).cos() + 3.0 * x) as f32)
        })
        .collect();
    let tags = tags(holes.then_some("-9999"));
    std::fs::write(path, geotiff::write(W, H, &layout, &[values], &tags)).unwrap();
}

/// A TIFF as the `tiff` crate decodes it: size, samples a texel, the
/// samples as f64, and the tags that place it.
struct Decoded {
    size: (u32, u32),
    samples_per_texel: usize,
    samples: Vec<f64>,
    extra_samples: Option<Vec<u16>>,
    pixel_scale: Option<Vec<f64>>,
    tiepoint: Option<Vec<f64>>,
    keys: Option<Vec<u16>>,
    nodata: Option<String>,
}

fn decode(path: &Path) -> Decoded {
    let mut d = Decoder::new(File::open(path).unwrap()).unwrap();
    let size = d.dimensions().unwrap();
    let samples_per_texel = usize::from(d.get_tag_u32(Tag::SamplesPerPixel).unwrap() as u16);
    let mut tag = |code: u16| d.find_tag(Tag::Unknown(code)).unwrap();
    let doubles = |v: Option<tiff::decoder::ifd::Value>| v.map(|v| v.into_f64_vec().unwrap());
    let pixel_scale = doubles(tag(33550));
    let tiepoint = doubles(tag(33922));
    let keys = tag(34735).map(|v| v.into_u16_vec().unwrap());
    let nodata = tag(42113).map(|v| v.into_string().unwrap());
    let extra_samples = d.find_tag(Tag::ExtraSamples).unwrap().map(|v| v.into_u16_vec().unwrap());
    let samples = match d.read_image().unwrap() {
        DecodingResult::U8(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F32(v) => v.into_iter().map(f64::from).collect(),
        other => panic!("{}: unexpected samples {:?}", path.display(), std::mem::discriminant(&other)),
    };
    Decoded { size, samples_per_texel, samples, extra_samples, pixel_scale, tiepoint, keys, nodata }
}

/// A PNG's or EXR's samples, texel after texel, channels R, G, B (, A),
/// as normalfit's reader gives them (PNG's in [0, 1], so scaled back to
/// the stored integers by `max`).
fn samples_of(path: &Path, max: f64) -> Vec<f64> {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    let order = ["Y", "R", "G", "B", "A"];
    let mut planes: Vec<_> = raster.planes.iter().filter(|p| order.contains(&p.name.as_str())).collect();
    planes.sort_by_key(|p| order.iter().position(|&n| n == p.name));
    let planes: Vec<Vec<f32>> = planes.iter().map(|p| p.data.to_f32().unwrap()).collect();
    (0..raster.width * raster.height)
        .flat_map(|i| {
            planes.iter().map(move |p| {
                let v = f64::from(p[i]) * max;
                if max > 1.0 { v.round() } else { v }
            })
        })
        .collect()
}

fn conversion(borders: Borders, bits: Option<u8>, signed: bool, whole: bool) -> Conversion {
    let mut c = Conversion::new()
        .with_fit(Options::new().with_patch(5))
        .with_borders(BorderChoices::from(borders))
        .with_signed(signed)
        .with_residual(whole);
    if let Some(bits) = bits {
        c = c.with_bits(bits);
    }
    c
}

fn assert_placed_as_the_source(d: &Decoded, what: &str) {
    assert_eq!(d.pixel_scale.as_deref(), Some(&[10.0, 10.0, 0.0][..]), "{what}");
    assert_eq!(d.tiepoint.as_deref(), Some(&[0.0, 0.0, 0.0, 500_000.0, 4_500_000.0, 0.0][..]), "{what}");
    let keys = [1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32633];
    assert_eq!(d.keys.as_deref(), Some(&keys[..]), "{what}");
}

#[test]
fn tiff_normal_maps_hold_the_samples_png_and_exr_hold_streamed_or_whole() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dem.tif");
    dem(&input, false);
    let mut compared = 0;
    for borders in [Borders::both(Border::Wrap), Borders { x: Border::Clamp, y: Border::Mirror }] {
        for (bits, signed, ext, max) in
            [(8, false, "png", 255.0), (16, false, "png", 65535.0), (32, false, "exr", 1.0), (32, true, "exr", 1.0)]
        {
            let what = format!("{borders:?}, {bits} bits, signed {signed}");
            let reference = dir.path().join(format!("reference.{ext}"));
            let png_bits = (ext == "png").then_some(bits);
            conversion(borders, png_bits, signed, false).convert_file(&input, &reference).unwrap();
            let expected = samples_of(&reference, max);
            for whole in [false, true] {
                let out = dir.path().join(format!("n{bits}{signed}{whole}.tif"));
                let summary = conversion(borders, Some(bits), signed, whole).convert_file(&input, &out).unwrap();
                assert_eq!(summary.streamed, !whole, "{what}");
                assert!(summary.sidecars.is_empty(), "{what}: a TIFF holds its own georeferencing");
                let d = decode(&out);
                assert_eq!((d.size, d.samples_per_texel), ((W as u32, H as u32), 3), "{what}");
                assert!(d.samples == expected, "{what}, whole {whole}: the TIFF's samples are not the {ext}'s");
                assert_placed_as_the_source(&d, &what);
                assert_eq!(d.nodata, None, "{what}: a normal map's values are not heights");
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 16);
}

#[test]
fn holes_give_a_fourth_sample_an_alpha_of_validity() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("holes.tif");
    dem(&input, true);
    let borders = Borders::both(Border::Clamp);
    let png = dir.path().join("holes.png");
    conversion(borders, Some(8), false, false).convert_file(&input, &png).unwrap();
    let expected = samples_of(&png, 255.0);
    for whole in [false, true] {
        let out = dir.path().join(format!("holes{whole}.tif"));
        let summary = conversion(borders, Some(8), false, whole).convert_file(&input, &out).unwrap();
        assert!(summary.missing > 0, "{summary:?}");
        let d = decode(&out);
        assert_eq!(d.samples_per_texel, 4);
        assert_eq!(d.extra_samples.as_deref(), Some(&[2u16][..]), "an unassociated alpha");
        assert!(d.samples == expected, "whole {whole}: the TIFF's samples are not the PNG's");
        let transparent = d.samples.chunks(4).filter(|t| t[3] == 0.0).count();
        assert_eq!(transparent, summary.missing, "whole {whole}");
    }
}

#[test]
fn the_lit_view_in_tiff_is_the_pngs_grey_for_grey_with_nodata_0() {
    let dir = tempfile::tempdir().unwrap();
    for holes in [false, true] {
        let input = dir.path().join(format!("dem{holes}.tif"));
        dem(&input, holes);
        // A wrap in y: the streamed TIFF reads the last rows first.
        for borders in [Borders::both(Border::Clamp), Borders::both(Border::Wrap)] {
            let what = format!("holes {holes}, {borders:?}");
            let fit = Options::new().with_strength(Strength::Scale(0.1));
            let opts = LitOptions::new().with_fit(fit).with_borders(BorderChoices::from(borders));
            let read = ReadOptions::default();
            let png = dir.path().join("lit.png");
            lit_file(Input::Path(&input), &read, &opts, Output::file(&png))
                .inspect(|done| assert!(done.streamed, "streams"))
                .unwrap();
            let expected = samples_of(&png, 255.0);
            assert!(expected.iter().any(|&g| g != expected[0]), "{what}: a picture, not a flat grey");
            let streamed = dir.path().join("lit.tif");
            let done = lit_file(Input::Path(&input), &read, &opts, Output::file(&streamed))
                .inspect(|done| assert!(done.streamed, "streams"))
                .unwrap();
            assert!(done.sidecars.is_empty(), "{what}");
            let whole = dir.path().join("whole.tif");
            let view = lit_view(&read_path(&input, &read).unwrap(), &opts).unwrap();
            assert!(view.write_file(&whole).unwrap().is_empty(), "{what}");
            for path in [&streamed, &whole] {
                let d = decode(path);
                assert_eq!(d.samples_per_texel, 1, "{what}");
                assert!(d.samples == expected, "{what}: {} is not the PNG's greys", path.display());
                assert_eq!(d.nodata.as_deref(), Some("0"), "{what}");
                assert_placed_as_the_source(&d, &what);
                assert_eq!(d.samples.iter().filter(|&&g| g == 0.0).count() > 0, holes, "{what}: grey 0 is a hole");
            }
        }
    }
}

#[test]
fn the_command_line_writes_tiff_to_files_and_standard_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dem.tif");
    dem(&input, false);
    let file = dir.path().join("n.tif");
    let s = |p: &Path| p.to_str().unwrap().to_owned();
    let args = |extra: &[&str]| {
        let mut a = vec!["convert".to_owned(), s(&input), "-s".into(), "0.1".into(), "--bits".into(), "16".into()];
        a.extend(extra.iter().map(|e| (*e).to_owned()));
        a
    };
    let out = common::cli::bin().args(args(&["-o", &s(&file)])).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let piped = common::cli::bin().args(args(&["-o", "-", "--format", "tiff"])).output().unwrap();
    assert!(piped.status.success(), "{}", String::from_utf8_lossy(&piped.stderr));
    assert!(piped.stdout == std::fs::read(&file).unwrap(), "standard output holds the file's bytes");
    assert_eq!(decode(&file).samples_per_texel, 3);

    // The residual beside it: one float sample, in height units.
    let residual = dir.path().join("r.tif");
    let out = common::cli::bin().args(args(&["-o", &s(&file), "--residual", &s(&residual)])).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let r = decode(&residual);
    assert_eq!(r.samples_per_texel, 1);
    assert!(r.samples.iter().all(|v| v.is_finite() && *v >= 0.0) && r.samples.iter().any(|&v| v > 0.0));

    for (bad, says) in [(&["--bits", "12"][..], "12"), (&["--bits", "8", "--signed"][..], "signed")] {
        let mut a = vec!["convert".to_owned(), s(&input), "-o".into(), s(&dir.path().join("bad.tif"))];
        a.extend(bad.iter().map(|e| (*e).to_owned()));
        let out = common::cli::bin().args(&a).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad:?}: {err}");
        assert!(err.contains(says) && err.lines().count() == 1, "{bad:?}: {err}");
        assert!(!dir.path().join("bad.tif").exists());
    }
    let out = common::cli::bin().args(["shade", &s(&input), "-o", &s(&dir.path().join("lit.jpg"))]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(".tif"), "{err}");
}
