//! The library's conversion API (`normalfit::convert`), its output
//! vocabulary (`io::Encoding`, `io::OutputFormat`), the normal-map reader
//! (`normal_map`) and the lit views and tiling reports of decoded images,
//! called as a Rust program or a binding would: no command line.

use crate::common;

use std::fs;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use common::reference;
use exr::prelude::{AnyChannel, AnyChannels, Encoding as ExrEncoding, FlatSamples, Image, Layer, LayerAttributes};
use exr::prelude::{SmallVec, Vec2, WritableImage};
use normalfit::convert::{
    BorderChoice, BorderChoices, Conversion, Input, Observer, Output, Place, Summary, Warning, read_all,
};
use normalfit::io::{
    Encoding, ExrDepth, ExrOptions, InputFormat, Layout, OutputFormat, PngCompression, PngDepth, PngOptions,
    ReadOptions, SampleType, decode,
};
use normalfit::normal_map::{ImageKind, KindChoice};
use normalfit::shade::{Light, LitOptions, lit_view, shade};
use normalfit::tiling::TilingOptions;
use normalfit::{Border, Borders, Error, Options, Strength, normal_map, normals};

/// A 16-bit gray height map that tiles in x (whole sine periods) and not
/// in y (a ramp); returns its heights in [0, 1].
fn write_height16(path: &Path, w: u32, h: u32) -> Vec<f32> {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
        let v = 0.5
            + 0.2 * (x as f64 * std::f64::consts::TAU * 2.0 / w as f64).sin()
            + 0.25 * y as f64 / h as f64
            + 0.01 * ((x * 7 + y * 3) % 5) as f64;
        image::Luma([(v.clamp(0.0, 1.0) * 65535.0).round() as u16])
    });
    img.save(path).unwrap();
    img.pixels().map(|p| f32::from(p.0[0]) / 65535.0).collect()
}

/// The planes of a decoded file, by name, as f32.
fn plane(bytes: &[u8], name: &str) -> Vec<f32> {
    let r = decode(bytes, &ReadOptions::default()).unwrap();
    r.plane(name).unwrap_or_else(|| panic!("no plane {name}")).data.to_f32().unwrap()
}

/// A float EXR with channels R, G, B of these values.
fn write_exr_rgb(path: &Path, w: usize, h: usize, rgb: &[[f32; 3]]) {
    let channel = |name: &str, c: usize| AnyChannel::new(name, FlatSamples::F32(rgb.iter().map(|t| t[c]).collect()));
    let channels = AnyChannels::sort(SmallVec::from_vec(vec![channel("R", 0), channel("G", 1), channel("B", 2)]));
    let layer = Layer::new(Vec2(w, h), LayerAttributes::default(), ExrEncoding::FAST_LOSSLESS, channels);
    Image::from_layer(layer).write().to_file(path).unwrap();
}

/// Each format and depth, file to file, against the slow reference fit
/// with the encoding written here plainly: PNG c = round(max (n + 1)/2)
/// within one step of the reference; EXR (n + 1)/2, or n signed, within
/// half precision.
#[test]
fn file_to_file_in_each_format_holds_the_reference_normals() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    let (w, h) = (40, 30);
    let heights = write_height16(&input, w as u32, h as u32);
    let fit = Options::new().with_patch(5).with_strength(Strength::Scale(9.0));
    let want = reference::normal_map(&heights, w, h, &fit.clone().with_borders(Borders::both(Border::Clamp)));
    let clamp = BorderChoices::both(BorderChoice::Fixed(Border::Clamp));
    let base = Conversion::new().with_fit(fit).with_borders(clamp);
    let cases: [(&str, Conversion, f64, bool); 6] = [
        ("n8.png", base.clone().with_bits(8), 255.0, false),
        ("n16.png", base.clone(), 65535.0, false),
        ("f.exr", base.clone(), 0.0, false),
        ("half.exr", base.clone().with_bits(16), 0.0, false),
        ("signed.exr", base.clone().with_signed(true), 0.0, true),
        ("no_extension", base.clone().with_format(Some(OutputFormat::Exr)), 0.0, false),
    ];
    for (name, conversion, max, signed) in cases {
        let out = dir.path().join(name);
        let summary = conversion.convert_file(&input, &out).unwrap();
        assert_eq!((summary.width, summary.height), (w, h));
        assert_eq!((summary.input_format.clone(), summary.sample), (InputFormat::Png, SampleType::Int { bits: 16 }));
        let bytes = fs::read(&out).unwrap();
        let r = decode(&bytes, &ReadOptions::default()).unwrap();
        let tolerance = match (max, name) {
            (0.0, "half.exr") => 1e-3,
            (0.0, _) => 1e-5,
            _ => 1.0,
        };
        for (c, ch) in ["R", "G", "B"].iter().enumerate() {
            let got = plane(&bytes, ch);
            for (k, n) in want.iter().enumerate() {
                let (got, expect) = if max > 0.0 {
                    ((f64::from(got[k]) * max).round(), (max * (n[c] + 1.0) / 2.0).round())
                } else if signed {
                    (f64::from(got[k]), n[c])
                } else {
                    (f64::from(got[k]), (n[c] + 1.0) / 2.0)
                };
                assert!((got - expect).abs() <= tolerance, "{name} texel {k} {ch}: {got} vs {expect}");
            }
        }
        let (format, sample) = match max {
            0.0 => (InputFormat::Exr, SampleType::Float),
            255.0 => (InputFormat::Png, SampleType::Int { bits: 8 }),
            _ => (InputFormat::Png, SampleType::Int { bits: 16 }),
        };
        assert_eq!((r.format, r.sample), (format, sample), "{name}");
    }
}

#[test]
fn the_output_format_comes_from_the_name_the_options_then_the_input() {
    let png16 = (&InputFormat::Png, SampleType::Int { bits: 16 });
    let tiff8 = (&InputFormat::Tiff, SampleType::Int { bits: 8 });
    let tiff_float = (&InputFormat::Tiff, SampleType::Float);
    fn p(s: &str) -> Option<&Path> {
        Some(Path::new(s))
    }
    assert_eq!(OutputFormat::choose(p("a.PNG"), None, tiff_float).unwrap(), OutputFormat::Png);
    assert_eq!(OutputFormat::choose(p("a.exr"), None, png16).unwrap(), OutputFormat::Exr);
    assert_eq!(OutputFormat::choose(p("a"), Some(OutputFormat::Exr), png16).unwrap(), OutputFormat::Exr);
    assert_eq!(OutputFormat::choose(None, None, png16).unwrap(), OutputFormat::Png);
    assert_eq!(OutputFormat::choose(None, None, tiff8).unwrap(), OutputFormat::Png);
    assert_eq!(OutputFormat::choose(None, None, tiff_float).unwrap(), OutputFormat::Exr);
    assert_eq!(OutputFormat::choose(None, None, (&InputFormat::Exr, SampleType::Float)).unwrap(), OutputFormat::Exr);
    let e = OutputFormat::choose(p("a.jpg"), None, png16).unwrap_err();
    assert!(
        matches!(&e, Error::Unsupported(m) if m.contains(".jpg") && m.contains(".png, .exr, .tif, .dds or .ktx2")),
        "{e}"
    );
    assert_eq!(OutputFormat::choose(p("a.tif"), None, png16).unwrap(), OutputFormat::Tiff);
    assert_eq!(OutputFormat::choose(p("a.TIFF"), None, png16).unwrap(), OutputFormat::Tiff);
    assert_eq!(OutputFormat::choose(p("a"), Some(OutputFormat::Tiff), png16).unwrap(), OutputFormat::Tiff);
    let e = OutputFormat::choose(p("a.png"), Some(OutputFormat::Exr), png16).unwrap_err();
    assert!(matches!(&e, Error::InvalidOption(m) if m.contains("png") && m.contains("exr")), "{e}");

    let choose =
        |format, bits, signed, input| Encoding::choose(format, bits, signed, Layout::Rgb, PngCompression::Fast, input);
    let int8 = SampleType::Int { bits: 8 };
    let depth = |e: Encoding| match e {
        Encoding::Png(o) => format!("png {:?}", o.depth),
        Encoding::Exr(o) => format!("exr {:?} signed {}", o.depth, o.signed),
        Encoding::Tiff(o) => format!("tiff {:?} signed {}", o.depth, o.signed),
        _ => unreachable!(),
    };
    assert_eq!(depth(choose(OutputFormat::Png, None, false, int8).unwrap()), "png Eight");
    assert_eq!(depth(choose(OutputFormat::Png, None, false, SampleType::Float).unwrap()), "png Sixteen");
    assert_eq!(depth(choose(OutputFormat::Png, Some(16), false, int8).unwrap()), "png Sixteen");
    assert_eq!(depth(choose(OutputFormat::Exr, None, false, int8).unwrap()), "exr Float signed false");
    assert_eq!(depth(choose(OutputFormat::Exr, Some(16), true, int8).unwrap()), "exr Half signed true");
    // TIFF: PNG's integer depths, EXR's float one.
    assert_eq!(depth(choose(OutputFormat::Tiff, None, false, int8).unwrap()), "tiff Eight signed false");
    assert_eq!(depth(choose(OutputFormat::Tiff, None, false, SampleType::Float).unwrap()), "tiff Sixteen signed false");
    assert_eq!(depth(choose(OutputFormat::Tiff, Some(32), true, int8).unwrap()), "tiff Float signed true");
    for (format, bits, signed) in [
        (OutputFormat::Png, Some(32), false),
        (OutputFormat::Exr, Some(8), false),
        (OutputFormat::Png, None, true),
        (OutputFormat::Tiff, Some(12), false),
        (OutputFormat::Tiff, Some(16), true),
    ] {
        let e = choose(format, bits, signed, int8).unwrap_err();
        assert!(matches!(e, Error::Unsupported(_)), "{format:?} {bits:?} {signed}: {e}");
    }
}

#[test]
fn a_refused_output_name_is_an_output_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_height16(&input, 16, 16);
    for (name, conversion) in [
        ("n.jpg", Conversion::new()),
        ("n.png", Conversion::new().with_format(Some(OutputFormat::Exr))),
        ("n.png", Conversion::new().with_bits(32)),
        ("n.exr", Conversion::new().with_bits(8)),
        ("n.png", Conversion::new().with_signed(true)),
    ] {
        let out = dir.path().join(name);
        let e = conversion.convert_file(&input, &out).unwrap_err();
        assert_eq!(e.place, Place::Output, "{name}: {e}");
        assert!(!out.exists(), "{name}");
    }
    let e = Conversion::new().convert_file(&dir.path().join("missing.png"), &dir.path().join("n.png")).unwrap_err();
    assert!(e.place == Place::Input && matches!(e.error, Error::Io(_)), "{e}");
}

/// The input file is never written over, named directly or through a link.
#[test]
fn the_input_is_never_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_height16(&input, 16, 16);
    let before = fs::read(&input).unwrap();
    let link = dir.path().join("link.png");
    fs::hard_link(&input, &link).unwrap();
    for (target, residual) in [(&input, false), (&link, false), (&input, true)] {
        let e = Conversion::new().with_residual(residual).convert_file(&input, target).unwrap_err();
        assert!(e.place == Place::Output && matches!(e.error, Error::InvalidOption(_)), "{e}");
    }
    assert_eq!(fs::read(&input).unwrap(), before);
}

/// Counts what a conversion reports as it goes.
#[derive(Default)]
struct Counter {
    rows: AtomicUsize,
    sizes: AtomicUsize,
    warnings: std::sync::Mutex<Vec<Warning>>,
}

impl Observer for Counter {
    fn size(&self, _: usize, _: usize) {
        self.sizes.fetch_add(1, Ordering::Relaxed);
    }
    fn row(&self) {
        self.rows.fetch_add(1, Ordering::Relaxed);
    }
    fn warning(&self, warning: &Warning) {
        self.warnings.lock().unwrap().push(warning.clone());
    }
}

/// A file that streams and the same bytes read whole give the same
/// normal map: the same EXR bytes; the same PNG pixels (the streamed PNG
/// encoder is not `image`'s, so its bytes differ); to a file or a writer.
#[test]
fn streamed_and_whole_conversions_give_the_same_maps() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    let (w, h) = (70, 150);
    write_height16(&input, w, h);
    let bytes = fs::read(&input).unwrap();
    for borders in [
        BorderChoices::both(BorderChoice::Fixed(Border::Wrap)),
        BorderChoices::both(BorderChoice::Auto),
        BorderChoices { x: BorderChoice::Fixed(Border::Clamp), y: BorderChoice::Fixed(Border::Mirror) },
    ] {
        let conversion = Conversion::new().with_fit(Options::new().with_patch(7)).with_borders(borders);
        for format in [OutputFormat::Png, OutputFormat::Exr] {
            let what = format!("{borders:?} {format:?}");
            let conversion = conversion.clone().with_format(Some(format));
            let file = dir.path().join(format!("n.{}", format.extension()));
            let streamed = conversion.convert_file(&input, &file).unwrap();
            assert!(streamed.streamed, "{what}");
            let streamed_file = fs::read(&file).unwrap();

            let mut to_writer = Vec::new();
            let counter = Counter::default();
            let opened = conversion.open(Input::Path(&input)).unwrap();
            assert!(opened.streams());
            let encoding = opened.encoding(None).unwrap();
            let summary = opened.write(&encoding, Some(Output::Writer(&mut to_writer)), None, &counter).unwrap();
            assert!(summary.streamed, "{what}");
            assert_eq!(counter.rows.load(Ordering::Relaxed) % h as usize, 0, "{what}: every row, once a pass");
            assert!(counter.rows.load(Ordering::Relaxed) >= h as usize, "{what}");
            assert_eq!(counter.sizes.load(Ordering::Relaxed), 1, "{what}");

            let mut whole = Vec::new();
            let read_whole = conversion.convert(Input::Bytes(&bytes), Output::Writer(&mut whole)).unwrap();
            assert!(!read_whole.streamed, "{what}");
            assert_eq!(read_whole.borders, streamed.borders, "{what}");
            assert_eq!(read_whole.warnings, streamed.warnings, "{what}");
            match format {
                OutputFormat::Exr => {
                    assert!(streamed_file == whole, "{what}: EXR bytes");
                    assert!(to_writer == whole, "{what}: EXR bytes to a writer");
                }
                _ => {
                    for ch in ["R", "G", "B"] {
                        let want = plane(&whole, ch);
                        assert!(plane(&streamed_file, ch) == want, "{what} {ch}");
                        assert!(plane(&to_writer, ch) == want, "{what} {ch} to a writer");
                    }
                }
            }
        }
    }
}

/// `auto` borders wrap where the image tiles (x) and mirror where it does
/// not (y); a wrap asked for across a seam is a warning, as data.
#[test]
fn auto_borders_and_seam_warnings_come_back_in_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_height16(&input, 64, 64);
    let auto = Conversion::new().with_borders(BorderChoices::both(BorderChoice::Auto));
    let check = |s: &Summary| {
        let report = s.tiling.expect("the check ran");
        (report.x.seamless, report.y.seamless)
    };
    for residual in [false, true] {
        let out = dir.path().join(format!("a{residual}.exr"));
        let s = auto.clone().with_residual(residual).convert_file(&input, &out).unwrap();
        assert_eq!(s.streamed, !residual);
        assert_eq!(s.borders, Borders { x: Border::Wrap, y: Border::Mirror }, "residual {residual}");
        assert_eq!(check(&s), (true, false));
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        if residual {
            assert!(dir.path().join(format!("a{residual}_residual.exr")).exists());
        }
    }
    let wrap = Conversion::new();
    let s = wrap.convert_file(&input, &dir.path().join("w.png")).unwrap();
    assert_eq!(s.borders, Borders::both(Border::Wrap));
    match s.warnings.as_slice() {
        [Warning::Seams { x: None, y: Some(score) }] => assert!(*score > 1.5, "{score}"),
        other => panic!("{other:?}"),
    }
    let clamp = Conversion::new().with_borders(BorderChoices::both(BorderChoice::Fixed(Border::Clamp)));
    let s = clamp.convert_file(&input, &dir.path().join("c.png")).unwrap();
    assert!(s.tiling.is_none() && s.warnings.is_empty());
}

/// The residual map beside the normal map: its values are the reference
/// residual over the gain, in the format its name says.
#[test]
fn the_residual_goes_where_it_is_asked_in_its_format() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    let (w, h) = (24, 20);
    let heights = write_height16(&input, w as u32, h as u32);
    let fit = Options::new().with_strength(Strength::Scale(5.0)).with_borders(Borders::both(Border::Clamp));
    let conversion = Conversion::new().with_fit(fit.clone()).with_residual(true);
    let opened = conversion.open(Input::Path(&input)).unwrap();
    assert!(!opened.streams(), "a residual is made from the whole image");
    let normals_at = dir.path().join("n.png");
    let residual_at = dir.path().join("r.exr");
    let encoding = opened.encoding(Some(&normals_at)).unwrap();
    let residual = Some((Output::file(&residual_at), OutputFormat::Exr));
    opened.write(&encoding, Some(Output::file(&normals_at)), residual, &()).unwrap();
    let got = plane(&fs::read(&residual_at).unwrap(), "Y");
    for (k, &g) in got.iter().enumerate() {
        let want = reference::residual_at(&heights, w, h, &fit, k % w, k / w) / 5.0;
        assert!((f64::from(g) - want).abs() < 1e-4, "texel {k}: {g} vs {want}");
    }
    // Without `with_residual`, no residual is made.
    let opened = Conversion::new().open(Input::Path(&input)).unwrap();
    let e = opened.write(&encoding, None, Some((Output::file(&residual_at), OutputFormat::Exr)), &()).unwrap_err();
    assert_eq!(e.place, Place::Residual);
}

#[test]
fn read_all_then_bytes_is_the_whole_image_path() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_height16(&input, 20, 10);
    let bytes = read_all(fs::File::open(&input).unwrap()).unwrap();
    let mut out = Vec::new();
    let s = Conversion::new().with_bits(8).convert(Input::Bytes(&bytes), Output::Writer(&mut out)).unwrap();
    assert_eq!((s.width, s.height, s.encoding), (20, 10, Encoding::png8()));
    assert_eq!(decode(&out, &ReadOptions::default()).unwrap().sample, SampleType::Int { bits: 8 });
}

/// Stored colours back to normals, against n = 2c − 1 written here: 8- and
/// 16-bit PNG, float EXR holding (n + 1)/2, and a signed EXR holding n.
#[test]
fn normal_maps_decode_to_two_c_minus_one_or_n_itself() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (5, 3);
    let rgb8: Vec<[u8; 3]> = (0..15).map(|k| [k * 17, 255 - k * 13, 128 + k]).collect();
    let p8 = dir.path().join("n8.png");
    image::RgbImage::from_fn(w, h, |x, y| image::Rgb(rgb8[(y * w + x) as usize])).save(&p8).unwrap();
    let (rw, rh, got) = normal_map::read(&p8, &ReadOptions::default(), false).unwrap();
    assert_eq!((rw, rh), (5, 3));
    for (t, g) in rgb8.iter().zip(&got) {
        for c in 0..3 {
            let want = 2.0 * f64::from(t[c]) / 255.0 - 1.0;
            assert!((f64::from(g[c]) - want).abs() < 1e-6, "{t:?} {g:?}");
        }
    }

    let rgb16: Vec<[u16; 3]> = (0..15).map(|k| [k * 4369, 65535 - k * 3000, 32768 + k]).collect();
    let p16 = dir.path().join("n16.png");
    let flat: Vec<u16> = rgb16.iter().flatten().copied().collect();
    image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(w, h, flat).unwrap().save(&p16).unwrap();
    let (_, _, got) = normal_map::read(&p16, &ReadOptions::default(), false).unwrap();
    for (t, g) in rgb16.iter().zip(&got) {
        for c in 0..3 {
            let want = 2.0 * f64::from(t[c]) / 65535.0 - 1.0;
            assert!((f64::from(g[c]) - want).abs() < 1e-6, "{t:?} {g:?}");
        }
    }

    let n: Vec<[f32; 3]> = (0..15).map(|k| [k as f32 / 15.0 - 0.5, -0.25, 0.75 + k as f32 * 0.01]).collect();
    let unsigned: Vec<[f32; 3]> = n.iter().map(|v| v.map(|c| (c + 1.0) / 2.0)).collect();
    let (pu, ps) = (dir.path().join("u.exr"), dir.path().join("s.exr"));
    write_exr_rgb(&pu, 5, 3, &unsigned);
    write_exr_rgb(&ps, 5, 3, &n);
    let (_, _, from_unsigned) = normal_map::read(&pu, &ReadOptions::default(), false).unwrap();
    let (_, _, from_signed) = normal_map::read(&ps, &ReadOptions::default(), true).unwrap();
    for k in 0..15 {
        for c in 0..3 {
            assert!((from_unsigned[k][c] - n[k][c]).abs() < 1e-6, "{k}");
            assert_eq!(from_signed[k][c], n[k][c], "{k}: n itself");
        }
    }

    let e = normal_map::read(&p8, &ReadOptions::default(), true).unwrap_err();
    assert!(matches!(e, Error::InvalidOption(_)), "signed with integers: {e}");
    let gray = dir.path().join("g.png");
    image::GrayImage::from_pixel(4, 4, image::Luma([9])).save(&gray).unwrap();
    let e = normal_map::read(&gray, &ReadOptions::default(), false).unwrap_err();
    assert!(matches!(e, Error::Unsupported(_)), "no R, G, B: {e}");
}

#[test]
fn the_kind_of_an_image_is_detected_unless_told() {
    let dir = tempfile::tempdir().unwrap();
    let flat_normals = dir.path().join("n.png");
    image::RgbImage::from_fn(32, 32, |x, _| image::Rgb([128 + (x % 3) as u8, 128, 255])).save(&flat_normals).unwrap();
    let heights = dir.path().join("h.png");
    write_height16(&heights, 32, 32);
    let read = |p: &Path| normalfit::io::read_path(p, &ReadOptions::default()).unwrap();
    let (n, h) = (read(&flat_normals), read(&heights));
    assert_eq!(normal_map::kind_of(&n, KindChoice::Auto, None).unwrap(), ImageKind::Normal);
    assert_eq!(normal_map::kind_of(&h, KindChoice::Auto, None).unwrap(), ImageKind::Height);
    let red = normalfit::io::Channel::R;
    assert_eq!(normal_map::kind_of(&n, KindChoice::Auto, Some(&red)).unwrap(), ImageKind::Height, "a channel named");
    assert_eq!(normal_map::kind_of(&n, KindChoice::Height, None).unwrap(), ImageKind::Height);
    assert!(matches!(normal_map::kind_of(&h, KindChoice::Normal, None), Err(Error::Unsupported(_))));

    let report = normalfit::inspect::tiling_report(&n, &TilingOptions::new(), None).unwrap();
    assert_eq!(report.kind, ImageKind::Normal);
    let report = normalfit::inspect::tiling_report(&h, &TilingOptions::new(), None).unwrap();
    assert!(report.kind == ImageKind::Height && report.x.seamless && !report.y.seamless);
}

/// A lit view of a normal map is `shade` of its 2c − 1 normals; of a
/// height map, `shade` of the fit's; tiled, the picture repeats.
#[test]
fn lit_views_shade_the_decoded_or_fitted_normals() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("n.png");
    let rgb: Vec<[u8; 3]> = (0..64).map(|k| [100 + k as u8, 140 - k as u8, 240]).collect();
    image::RgbImage::from_fn(8, 8, |x, y| image::Rgb(rgb[(y * 8 + x) as usize])).save(&path).unwrap();
    let raster = normalfit::io::read_path(&path, &ReadOptions::default()).unwrap();
    let light = Light { azimuth_deg: 30.0, elevation_deg: 50.0 };
    let opts = LitOptions::new().with_light(light).with_kind(KindChoice::Normal);
    let view = lit_view(&raster, &opts).unwrap();
    let decoded: Vec<[f32; 3]> = rgb.iter().map(|t| t.map(|c| (2.0 * f64::from(c) / 255.0 - 1.0) as f32)).collect();
    assert_eq!(view.pixels, shade(&decoded, 8, 8, light, normalfit::Convention::OpenGl).unwrap());
    assert_eq!((view.width, view.height, view.kind), (8, 8, ImageKind::Normal));

    let hpath = dir.path().join("h.png");
    let heights = write_height16(&hpath, 16, 16);
    let raster = normalfit::io::read_path(&hpath, &ReadOptions::default()).unwrap();
    let fit = Options::new().with_strength(Strength::Scale(6.0)).with_borders(Borders::both(Border::Clamp));
    let view = lit_view(&raster, &LitOptions::new().with_fit(fit.clone()).with_tile(true)).unwrap();
    let lit = shade(&normals(&heights, 16, 16, &fit).unwrap(), 16, 16, Light::default(), fit.convention).unwrap();
    assert_eq!((view.width, view.height, view.kind), (32, 32, ImageKind::Height));
    for y in 0..32 {
        assert_eq!(view.pixels[y * 32..][..16], lit[(y % 16) * 16..][..16], "row {y}, left");
        assert_eq!(view.pixels[y * 32 + 16..][..16], lit[(y % 16) * 16..][..16], "row {y}, right");
    }
    let mut png = std::io::Cursor::new(Vec::new());
    view.encode(&mut png).unwrap();
    let back = decode(png.get_ref(), &ReadOptions::default()).unwrap();
    assert_eq!((back.width, back.height, back.planes.len()), (32, 32, 1));
    assert!(lit_view(&raster, &LitOptions::new().with_signed(true)).is_err(), "signed is for normal maps");
}

/// The vocabulary's own values: constructors and defaults.
#[test]
fn encodings_say_what_they_write() {
    assert_eq!(Encoding::png8(), PngOptions::new(PngDepth::Eight).into());
    assert_eq!(Encoding::png16().layout(), Layout::Rgb);
    assert_eq!(Encoding::exr(), ExrOptions::new(ExrDepth::Float).into());
    assert_eq!(Encoding::exr().with_layout(Layout::Rg).layout(), Layout::Rg);
    assert_eq!((Encoding::exr().format(), Encoding::png8().format()), (OutputFormat::Exr, OutputFormat::Png));
    let o = ExrOptions::new(ExrDepth::Half);
    assert_eq!((o.stored(-1.0), o.stored(0.0), o.stored(1.0)), (0.0, 0.5, 1.0));
    assert_eq!(o.with_signed(true).stored(-0.25), -0.25);
}

#[test]
fn border_choices_parse_as_the_command_line_spells_them() {
    use normalfit::convert::{BorderChoice, BorderChoices};
    let fixed = BorderChoice::Fixed;
    assert_eq!("mirror".parse::<BorderChoices>().unwrap(), BorderChoices::both(fixed(Border::Mirror)));
    assert_eq!(
        "wrap, auto".parse::<BorderChoices>().unwrap(),
        BorderChoices { x: fixed(Border::Wrap), y: BorderChoice::Auto }
    );
    assert_eq!("AUTO".parse::<BorderChoices>().unwrap(), BorderChoices::both(BorderChoice::Auto));
    let e = "wrap,tile".parse::<BorderChoices>().unwrap_err();
    assert_eq!(e.to_string(), "invalid option: unknown border mode 'tile': use wrap, clamp, mirror or auto");
    assert!("wrap,clamp,mirror".parse::<BorderChoices>().is_err(), "two axes at most");
}

/// Every option a front end takes by name is parsed by the library, with
/// the same names the command line lists, and the same refusals.
#[test]
fn output_and_check_options_parse_by_the_names_every_front_end_uses() {
    use normalfit::io::{Alpha, OutputChannels};
    assert_eq!("EXR".parse::<OutputFormat>().unwrap(), OutputFormat::Exr);
    assert_eq!(
        OutputFormat::ALL.iter().map(|f| f.to_string()).collect::<Vec<_>>(),
        ["png", "exr", "tiff", "dds", "ktx2"]
    );
    assert_eq!("tif".parse::<OutputFormat>().unwrap(), OutputFormat::Tiff);
    assert_eq!("small".parse::<PngCompression>().unwrap(), PngCompression::Default);
    assert_eq!("fast".parse::<PngCompression>().unwrap(), PngCompression::Fast);
    let e = "best".parse::<PngCompression>().unwrap_err();
    assert_eq!(e.to_string(), "invalid option: unknown compression 'best': use fast or small");
    assert_eq!("normal".parse::<KindChoice>().unwrap(), KindChoice::Normal);
    let e = "depth".parse::<KindChoice>().unwrap_err();
    assert_eq!(e.to_string(), "invalid option: unknown kind 'depth': use auto, height or normal");

    let layout = |c: &str, a: &str| Layout::from_parts(c.parse().unwrap(), a.parse().unwrap());
    assert_eq!(layout("rgb", "none").unwrap(), Layout::Rgb);
    assert_eq!(layout("rgb", "height").unwrap(), Layout::RgbHeight);
    assert_eq!(layout("rgb", "one").unwrap(), Layout::RgbOpaque);
    assert_eq!(layout("rg", "none").unwrap(), Layout::Rg);
    for alpha in [Alpha::Height, Alpha::One] {
        let e = Layout::from_parts(OutputChannels::Rg, alpha).unwrap_err();
        assert!(matches!(e, Error::InvalidOption(_)) && e.to_string().contains("has no alpha"), "{e}");
    }
    assert!("rgba".parse::<OutputChannels>().is_err() && "two".parse::<Alpha>().is_err());

    for bad in [0.0, -1.0, f64::NAN] {
        let e = TilingOptions::new().with_threshold(bad).validate().unwrap_err();
        assert!(e.to_string().contains("threshold must be positive"), "{e}");
    }
    TilingOptions::new().with_threshold(0.1).validate().unwrap();
    assert_eq!(Light::new(135.0, 35.0).unwrap(), Light::default());
    assert!(
        Light::new(0.0, 90.5).is_err() && Light::new(f64::INFINITY, 30.0).is_err() && Light::new(0.0, -1.0).is_err()
    );
    assert!(ReadOptions::default().with_max_texels(0).validate().is_err());
    ReadOptions::default().with_max_texels(1).validate().unwrap();
    assert_eq!(Strength::from_scale_or_relief(None, None).unwrap(), Strength::Scale(1.0));
    assert_eq!(Strength::from_scale_or_relief(Some(4.0), None).unwrap(), Strength::Scale(4.0));
    assert_eq!(Strength::from_scale_or_relief(None, Some(0.1)).unwrap(), Strength::Relief(0.1));
    assert!(Strength::from_scale_or_relief(Some(1.0), Some(0.1)).is_err());
}

/// Heights held in memory settle `auto` as a conversion of the same file
/// does (wrap in x, where it tiles; mirror in y), in every sample type;
/// fixed modes need no check; a wrong length is an error, not a panic.
#[test]
fn auto_borders_of_heights_in_memory_settle_as_a_conversion_does() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    let (w, h) = (64, 64);
    let heights = write_height16(&input, w as u32, h as u32);
    let auto = BorderChoices::both(BorderChoice::Auto);
    let summary = Conversion::new().with_borders(auto).convert_file(&input, &dir.path().join("n.png")).unwrap();
    let want = Borders { x: Border::Wrap, y: Border::Mirror };
    assert_eq!(summary.borders, want);
    let as_u16: Vec<u16> = heights.iter().map(|&v| (v * 65535.0).round() as u16).collect();
    let as_f64: Vec<f64> = heights.iter().map(|&v| f64::from(v)).collect();
    assert_eq!(auto.settle(&as_u16, w, h).unwrap(), want);
    assert_eq!(auto.settle(&heights, w, h).unwrap(), want);
    assert_eq!(auto.settle(&as_f64, w, h).unwrap(), want);
    let half = BorderChoices { x: BorderChoice::Fixed(Border::Clamp), y: BorderChoice::Auto };
    assert_eq!(half.settle(&heights, w, h).unwrap(), Borders { x: Border::Clamp, y: Border::Mirror });
    let fixed = BorderChoices::both(BorderChoice::Fixed(Border::Wrap));
    assert_eq!(fixed.settle(&heights, w, h).unwrap(), Borders::both(Border::Wrap), "as asked, whatever the image");
    assert!(matches!(auto.settle(&heights[..10], w, h), Err(Error::BufferSize { .. })));
}

#[test]
fn fixed_borders_are_the_modes_named_and_auto_names_none() {
    let choices: BorderChoices = "wrap,mirror".parse().unwrap();
    assert_eq!(choices.fixed().unwrap(), Borders { x: Border::Wrap, y: Border::Mirror });
    for auto in ["auto", "clamp,auto", "auto,wrap"] {
        let choices: BorderChoices = auto.parse().unwrap();
        let err = choices.fixed().unwrap_err();
        assert!(matches!(err, Error::InvalidOption(_)), "{auto}: {err}");
        assert!(err.to_string().contains("not auto"), "{auto}: {err}");
    }
}
