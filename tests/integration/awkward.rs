//! Legal but awkward input, each with a defined result, checked exactly
//! where an exact answer exists: 1×1, 1×N and N×1 images, images smaller
//! than the patch, constant images, maximum-contrast checkerboards, a
//! 16-bit ramp of one step per texel, palette and gray+alpha PNGs, EXR
//! with half, float, u32 and mixed channels, several layers, an offset
//! data window, NaN and infinite heights, and finite heights of extreme
//! size. Every file is generated here; every run goes through the binary,
//! and where the path differs, both the streamed reader (a file) and the
//! whole-image one (standard input).

use crate::common;
use crate::corpus;

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use common::reference;
use corpus::*;
use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec, Vec2, WritableImage, f16,
};
use normalfit::io::{ReadOptions, read_path};
use normalfit::{Border, Borders, Fit, FitRequest, Options, Strength, normals};

fn os<S: AsRef<OsStr> + ?Sized>(s: &S) -> &OsStr {
    s.as_ref()
}

/// Runs the binary and expects success.
fn ok(args: &[&OsStr], stdin: Option<&Path>) -> Run {
    let run = run_bin(args, stdin);
    assert_eq!(run.code, Some(0), "normalfit {args:?}: {}", run.stderr);
    run
}

/// Runs the binary and expects exit 2 with one line that says `reason`.
fn refused(args: &[&OsStr], stdin: Option<&Path>, reason: &str) -> String {
    let run = run_bin(args, stdin);
    assert_eq!(run.code, Some(2), "normalfit {args:?}: {}", run.stderr);
    let lines = run.stderr_lines();
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains(reason), "{:?} should say {reason:?}", lines[0]);
    lines[0].to_string()
}

/// A file in `dir` holding `bytes`.
fn file(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The R, G, B planes of an output file.
fn rgb_of(path: &Path) -> (usize, usize, [Vec<f32>; 3]) {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    let plane = |c: &str| raster.plane(c).unwrap_or_else(|| panic!("{path:?} has no {c}")).data.to_f32().unwrap();
    (raster.width, raster.height, [plane("R"), plane("G"), plane("B")])
}

/// An 8-bit PNG output as texels.
fn rgb8_of(path: &Path) -> Vec<[u8; 3]> {
    let (w, h, [r, g, b]) = rgb_of(path);
    (0..w * h).map(|k| [r[k], g[k], b[k]].map(|v| (v * 255.0).round() as u8)).collect()
}

/// A 16-bit PNG output as texels.
fn rgb16_of(path: &Path) -> Vec<[u16; 3]> {
    let (w, h, [r, g, b]) = rgb_of(path);
    (0..w * h).map(|k| [r[k], g[k], b[k]].map(|v| (v * 65535.0).round() as u16)).collect()
}

/// A float EXR output written with `--signed`: the normals themselves.
fn normals_of(path: &Path) -> Vec<[f32; 3]> {
    let (w, h, [r, g, b]) = rgb_of(path);
    (0..w * h).map(|k| [r[k], g[k], b[k]]).collect()
}

/// A one-channel float EXR of these heights.
fn exr_gray(width: usize, height: usize, heights: &[f32]) -> Vec<u8> {
    ExrSpec::gray(width as i32, height as i32).file(&[heights.to_vec()])
}

/// The options as the command line below spells them.
fn options(patch: usize, fit: Fit, borders: Borders) -> Options {
    Options::new().with_patch(patch).with_fit(fit).with_borders(borders)
}

const BORDERS: [Borders; 4] = [
    Borders { x: Border::Wrap, y: Border::Wrap },
    Borders { x: Border::Clamp, y: Border::Clamp },
    Borders { x: Border::Mirror, y: Border::Mirror },
    Borders { x: Border::Wrap, y: Border::Mirror },
];

/// Converts `input` to float normals (`--signed` EXR) with these options
/// and compares every texel with the slow reference of SPEC §2.
fn check_against_reference(input: &Path, heights: &[f32], w: usize, h: usize, opts: &Options, out: &Path) {
    let borders = format!("{},{}", Border::name(opts.borders.x), Border::name(opts.borders.y));
    let patch = opts.patch.to_string();
    let args = [
        os("convert"),
        input.as_os_str(),
        os("-o"),
        out.as_os_str(),
        os("--signed"),
        os("-n"),
        os(&patch),
        os("--fit"),
        os(Fit::name(opts.fit)),
        os("--border"),
        os(&borders),
    ];
    ok(&args, None);
    let got = normals_of(out);
    for y in 0..h {
        for x in 0..w {
            let want = reference::normal_at(heights, w, h, opts, x, y);
            let n = got[y * w + x];
            for c in 0..3 {
                assert!(
                    (f64::from(n[c]) - want[c]).abs() <= 1e-5,
                    "{input:?} {opts:?} texel ({x}, {y}): {n:?}, reference {want:?}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------

#[test]
fn one_by_one_is_the_flat_normal_every_way() {
    let dir = tempfile::tempdir().unwrap();
    let png = file(dir.path(), "one.png", &png_gray8(1, 1, |_, _| 77));
    let exr = file(dir.path(), "one.exr", &exr_gray(1, 1, &[1000.25]));
    let out_png = dir.path().join("out.png");
    let out_exr = dir.path().join("out.exr");
    for borders in BORDERS {
        let borders = format!("{},{}", Border::name(borders.x), Border::name(borders.y));
        for fit in ["orthogonal", "vertical"] {
            for patch in ["3", "9"] {
                let common = [os("-n"), os(patch), os("--fit"), os(fit), os("--border"), os(&borders)];
                let mut args = vec![os("convert"), png.as_os_str(), os("-o"), out_png.as_os_str()];
                args.extend(common);
                ok(&args, None);
                assert_eq!(rgb8_of(&out_png), [[128, 128, 255]], "{args:?}");
                let mut args = vec![os("convert"), exr.as_os_str(), os("-o"), out_exr.as_os_str()];
                args.extend(common);
                ok(&args, None);
                assert_eq!(normals_of(&out_exr), [[0.5, 0.5, 1.0]], "{args:?}");
            }
        }
    }
    // An axis of one texel has no pair to compare: it scores 1, seamless.
    let run = ok(&[os("tiling"), png.as_os_str()], None);
    assert!(run.stdout.contains("tiles (height map; x 1.00 seamless, y 1.00 seamless)"), "{}", run.stdout);
}

#[test]
fn one_by_n_n_by_one_and_images_smaller_than_the_patch_follow_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.exr");
    let shapes: [(usize, usize); 5] = [(1, 9), (9, 1), (2, 3), (3, 2), (4, 4)];
    for (w, h) in shapes {
        let heights: Vec<f32> = (0..w * h).map(|k| ((k * 7919) % 13) as f32 / 13.0 + k as f32 * 0.125).collect();
        let exr = file(dir.path(), &format!("h{w}x{h}.exr"), &exr_gray(w, h, &heights));
        // The same shape as a 16-bit PNG: the streamed PNG reader too.
        let stored: Vec<u16> = (0..w * h).map(|k| ((k * 4099) % 65536) as u16).collect();
        let png = file(dir.path(), &format!("h{w}x{h}.png"), &png_gray16(w as u32, h as u32, |x, y| stored[y * w + x]));
        let png_heights: Vec<f32> = stored.iter().map(|&v| f32::from(v) / 65535.0).collect();
        for borders in BORDERS {
            for fit in [Fit::Orthogonal, Fit::Vertical] {
                for patch in [3, 9, 33] {
                    let opts = options(patch, fit, borders);
                    check_against_reference(&exr, &heights, w, h, &opts, &out);
                    check_against_reference(&png, &png_heights, w, h, &opts, &out);
                }
            }
        }
    }
}

#[test]
fn constant_images_are_exactly_flat() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (17, 13);
    let png8 = file(dir.path(), "c8.png", &png_gray8(17, 13, |_, _| 200));
    let png16 = file(dir.path(), "c16.png", &png_gray16(17, 13, |_, _| 40000));
    let far = file(dir.path(), "far.exr", &exr_gray(w, h, &vec![1000.25; w * h]));
    let huge = file(dir.path(), "huge.exr", &exr_gray(w, h, &vec![-3e38; w * h]));
    let out8 = dir.path().join("o8.png");
    let out16 = dir.path().join("o16.png");
    let out_exr = dir.path().join("o.exr");
    for borders in ["wrap", "clamp", "mirror", "auto"] {
        for patch in ["3", "5", "63"] {
            let opts = [os("--border"), os(borders), os("-n"), os(patch), os("--relief"), os("0.5")];
            let run = |input: &Path, out: &Path, extra: &[&OsStr]| {
                let mut args = vec![os("convert"), input.as_os_str(), os("-o"), out.as_os_str()];
                args.extend(opts);
                args.extend(extra);
                let run = ok(&args, None);
                assert!(run.stderr.is_empty(), "a constant image tiles: no warning; {}", run.stderr);
            };
            run(&png8, &out8, &[]);
            assert!(rgb8_of(&out8).iter().all(|&t| t == [128, 128, 255]));
            run(&png16, &out16, &[]);
            assert!(rgb16_of(&out16).iter().all(|&t| t == [32768, 32768, 65535]));
            for input in [&far, &huge] {
                run(input, &out_exr, &[os("--signed")]);
                assert!(normals_of(&out_exr).iter().all(|&n| n == [0.0, 0.0, 1.0]), "{input:?}");
            }
        }
    }
}

#[test]
fn checkerboards_give_finite_unit_normals_with_their_symmetry() {
    let dir = tempfile::tempdir().unwrap();
    let out_png = dir.path().join("o.png");
    let out_exr = dir.path().join("o.exr");
    // An even checkerboard that wraps: every patch is point-symmetric
    // (z(i, j) = z(−i, −j)), so Cx = Cy = 0 and every normal is flat.
    let even = file(dir.path(), "even.png", &png_gray8(8, 8, |x, y| if (x + y) % 2 == 0 { 0 } else { 255 }));
    for fit in ["orthogonal", "vertical"] {
        for patch in ["3", "5", "7"] {
            for scale in ["1", "1000", "1e30"] {
                let args = [
                    os("convert"),
                    even.as_os_str(),
                    os("-o"),
                    out_png.as_os_str(),
                    os("--fit"),
                    os(fit),
                    os("-n"),
                    os(patch),
                    os("-s"),
                    os(scale),
                ];
                ok(&args, None);
                assert!(rgb8_of(&out_png).iter().all(|&t| t == [128, 128, 255]), "{args:?}");
            }
        }
    }
    // An odd one with clamped borders is symmetric about its middle column
    // and row: n_x(6 − x, y) = −n_x(x, y), n_y(x, 6 − y) = −n_y(x, y).
    let (w, h) = (7, 7);
    for (name, low, high) in [("unit", 0.0f32, 1.0f32), ("extreme", -3e38, 3e38)] {
        let heights: Vec<f32> = (0..w * h).map(|k| if (k % w + k / w) % 2 == 0 { low } else { high }).collect();
        let input = file(dir.path(), &format!("{name}.exr"), &exr_gray(w, h, &heights));
        for fit in ["orthogonal", "vertical"] {
            for patch in ["3", "5"] {
                let args = [
                    os("convert"),
                    input.as_os_str(),
                    os("-o"),
                    out_exr.as_os_str(),
                    os("--signed"),
                    os("--border"),
                    os("clamp"),
                    os("--fit"),
                    os(fit),
                    os("-n"),
                    os(patch),
                ];
                ok(&args, None);
                let n = normals_of(&out_exr);
                for y in 0..h {
                    for x in 0..w {
                        let [nx, ny, nz] = n[y * w + x];
                        let len = (nx * nx + ny * ny + nz * nz).sqrt();
                        assert!(
                            nx.is_finite() && ny.is_finite() && nz >= 0.0,
                            "{name} {args:?}: ({x}, {y}) {:?}",
                            n[y * w + x]
                        );
                        assert!((len - 1.0).abs() < 1e-6, "{name}: ({x}, {y}) has length {len}");
                        let mirrored_x = n[y * w + (w - 1 - x)];
                        let mirrored_y = n[(h - 1 - y) * w + x];
                        assert_eq!(
                            [nx, ny, nz],
                            [-mirrored_x[0], mirrored_x[1], mirrored_x[2]],
                            "{name} {args:?} x symmetry at ({x}, {y})"
                        );
                        assert_eq!(
                            [nx, ny, nz],
                            [mirrored_y[0], -mirrored_y[1], mirrored_y[2]],
                            "{name} {args:?} y symmetry at ({x}, {y})"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn a_16_bit_ramp_of_one_step_per_texel_gives_the_slopes_normal() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (4096usize, 4usize);
    let ramp = file(dir.path(), "ramp.png", &png_gray16(w as u32, h as u32, |x, _| x as u16));
    // The heights as SPEC §1 defines them: value / 65535, in f64.
    let heights: Vec<f64> = (0..w * h).map(|k| (k % w) as f64 / 65535.0).collect();
    let out_exr = dir.path().join("o.exr");
    let out_png = dir.path().join("o.png");
    // One stored step per texel is a slope of 1/65535 in height units, so
    // s = S/65535 in texel units: a plane, whose fitted normal (either fit)
    // is (−s, 0, 1)/√(1 + s²) wherever the patch stays inside (clamp in x
    // bends the first and last columns). The samples reach the fit as the
    // integers they are (no value / 65535 rounded to f32 first, which moved
    // the steep cases by 2e-4), so only the f32 output rounds.
    for (scale, to_plane) in [(1.0f64, 1e-7), (65535.0, 1e-7), (3.0 * 65535.0, 1e-7)] {
        let s = scale / 65535.0;
        let plane = [-s / (1.0 + s * s).sqrt(), 0.0, 1.0 / (1.0 + s * s).sqrt()];
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            for patch in [3usize, 9] {
                let p = patch.to_string();
                let scale_arg = scale.to_string();
                let common = [
                    os("--border"),
                    os("clamp,wrap"),
                    os("--fit"),
                    os(Fit::name(fit)),
                    os("-n"),
                    os(&p),
                    os("-s"),
                    os(&scale_arg),
                ];
                let mut args = vec![os("convert"), ramp.as_os_str(), os("-o"), out_exr.as_os_str(), os("--signed")];
                args.extend(common);
                ok(&args, None);
                let normals = normals_of(&out_exr);
                let opts = options(patch, fit, Borders { x: Border::Clamp, y: Border::Wrap })
                    .with_strength(Strength::Scale(scale));
                for y in 0..h {
                    for x in 0..w {
                        let n = normals[y * w + x].map(f64::from);
                        let reference = reference::normal_at(&heights, w, h, &opts, x, y);
                        let inside = (patch / 2..w - patch / 2).contains(&x);
                        for c in 0..3 {
                            assert!(
                                (n[c] - reference[c]).abs() <= 1e-5,
                                "{args:?} ({x}, {y}): {n:?}, reference {reference:?}"
                            );
                            if inside {
                                assert!(
                                    (n[c] - plane[c]).abs() <= to_plane,
                                    "{args:?} ({x}, {y}): {n:?}, plane {plane:?}"
                                );
                            }
                        }
                    }
                }
                if scale == 1.0 {
                    // 16-bit in gives 16-bit out by default; the plane's
                    // texel, rounded from the closed form.
                    let want = plane.map(|c| (65535.0 * (c + 1.0) / 2.0).round() as u16);
                    let mut args = vec![os("convert"), ramp.as_os_str(), os("-o"), out_png.as_os_str()];
                    args.extend(common);
                    ok(&args, None);
                    let texels = rgb16_of(&out_png);
                    for (k, t) in
                        texels.iter().enumerate().filter(|(k, _)| (patch / 2..w - patch / 2).contains(&(k % w)))
                    {
                        assert_eq!(*t, want, "{args:?} texel {k}");
                    }
                }
            }
        }
    }
}

/// The 8-bit normals of these heights, by the library's fit: what the
/// binary must write when it reads these heights from a file.
fn expected_rgb8(heights: &[f32], w: usize, h: usize) -> Vec<[u8; 3]> {
    let mut out = vec![[0u8; 3]; w * h];
    FitRequest::new(&Options::default()).normals_into(heights, w, h, &mut out).unwrap();
    out
}

/// Converts `input` from its file (streamed when it can) and from
/// standard input (decoded whole), 8-bit PNG out, and checks both.
fn check_both_readers(input: &Path, extra: &[&OsStr], want: &[[u8; 3]], dir: &Path) {
    let out = dir.join("both.png");
    let mut args = vec![os("convert"), input.as_os_str(), os("-o"), out.as_os_str(), os("--bits"), os("8")];
    args.extend(extra);
    ok(&args, None);
    assert_eq!(rgb8_of(&out), want, "from the file: {args:?}");
    let mut args = vec![os("convert"), os("-"), os("-o"), out.as_os_str(), os("--bits"), os("8")];
    args.extend(extra);
    ok(&args, Some(input));
    assert_eq!(rgb8_of(&out), want, "from standard input: {args:?}");
}

#[test]
fn palette_and_gray_alpha_pngs_read_the_documented_channel() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (9usize, 7usize);
    let index = |x: usize, y: usize| ((x * 3 + y * 5) % 4) as u8;
    let palette: [[u8; 3]; 4] = [[250, 10, 30], [20, 240, 90], [60, 70, 200], [128, 128, 128]];
    let alpha: [u8; 4] = [255, 0, 100, 30];
    let raw = scanlines(h, |y| (0..w).map(|x| index(x, y)).collect());
    let plte = png_chunk(b"PLTE", palette.as_flattened());
    let with_alpha = file(
        dir.path(),
        "pal_trns.png",
        &png_file(
            &ihdr(w as u32, h as u32, 8, 3),
            &[plte.clone(), png_chunk(b"tRNS", &alpha)],
            &fdeflate::compress_to_vec(&raw),
        ),
    );
    let opaque = file(
        dir.path(),
        "pal.png",
        &png_file(&ihdr(w as u32, h as u32, 8, 3), &[plte], &fdeflate::compress_to_vec(&raw)),
    );
    let unit = |v: u8| f32::from(v) / 255.0;
    let per_texel =
        |f: &dyn Fn(usize) -> f32| -> Vec<f32> { (0..w * h).map(|k| f(index(k % w, k / w) as usize)).collect() };
    // SPEC §1: luma of the stored values, in f64, rounded to f32 once.
    let luma = per_texel(&|i| {
        let [r, g, b] = palette[i].map(|v| f64::from(unit(v)));
        (0.2126 * r + 0.7152 * g + 0.0722 * b) as f32
    });
    let red = per_texel(&|i| unit(palette[i][0]));
    let blue = per_texel(&|i| unit(palette[i][2]));
    let alphas = per_texel(&|i| unit(alpha[i]));
    for input in [&opaque, &with_alpha] {
        check_both_readers(input, &[], &expected_rgb8(&luma, w, h), dir.path());
        check_both_readers(input, &[os("--channel"), os("luma")], &expected_rgb8(&luma, w, h), dir.path());
        check_both_readers(input, &[os("--channel"), os("r")], &expected_rgb8(&red, w, h), dir.path());
        check_both_readers(input, &[os("--channel"), os("b")], &expected_rgb8(&blue, w, h), dir.path());
    }
    check_both_readers(&with_alpha, &[os("--channel"), os("a")], &expected_rgb8(&alphas, w, h), dir.path());
    let out = dir.path().join("x.png");
    refused(
        &[os("convert"), opaque.as_os_str(), os("-o"), out.as_os_str(), os("--channel"), os("a")],
        None,
        "no alpha channel",
    );

    // Gray + alpha: gray unless alpha is asked for; r, g, b give gray.
    let gray = |x: usize, y: usize| ((x * 29 + y * 41) % 256) as u8;
    let opacity = |x: usize, y: usize| ((x * 7 + y * 90) % 256) as u8;
    let raw = scanlines(h, |y| (0..w).flat_map(|x| [gray(x, y), opacity(x, y)]).collect());
    let gray_alpha =
        file(dir.path(), "ga.png", &png_file(&ihdr(w as u32, h as u32, 8, 4), &[], &fdeflate::compress_to_vec(&raw)));
    let grays: Vec<f32> = (0..w * h).map(|k| unit(gray(k % w, k / w))).collect();
    let opacities: Vec<f32> = (0..w * h).map(|k| unit(opacity(k % w, k / w))).collect();
    for channel in [None, Some("luma"), Some("r"), Some("g"), Some("b")] {
        let extra: Vec<&OsStr> = channel.map(|c| vec![os("--channel"), os(c)]).unwrap_or_default();
        check_both_readers(&gray_alpha, &extra, &expected_rgb8(&grays, w, h), dir.path());
    }
    check_both_readers(&gray_alpha, &[os("--channel"), os("a")], &expected_rgb8(&opacities, w, h), dir.path());
}

/// An EXR written by the `exr` crate: these channels, scan lines, ZIP.
fn exr_with(w: usize, h: usize, channels: Vec<AnyChannel<FlatSamples>>) -> Vec<u8> {
    let channels = AnyChannels::sort(SmallVec::from_vec(channels));
    let layer = Layer::new(Vec2(w, h), LayerAttributes::default(), Encoding::SMALL_LOSSLESS, channels);
    let mut bytes = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut bytes).unwrap();
    bytes.into_inner()
}

#[test]
fn exr_half_float_u32_and_mixed_channels() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (11usize, 6usize);
    let values = |seed: usize| -> Vec<f32> { (0..w * h).map(|k| ((k * seed) % 17) as f32 * 0.37 - 2.0).collect() };
    let halves = |v: &[f32]| -> Vec<f16> { v.iter().map(|&x| f16::from_f32(x)).collect() };
    let as_half = |v: &[f32]| -> Vec<f32> { v.iter().map(|&x| f16::from_f32(x).to_f32()).collect() };
    let (a, b, c) = (values(3), values(5), values(11));
    let ints: Vec<u32> = (0..w * h).map(|k| (k * 13 % 7) as u32).collect();
    let ints_f32: Vec<f32> = ints.iter().map(|&n| n as f32).collect();
    let wide = |v: &[f32]| -> Vec<f64> { v.iter().map(|&x| f64::from(x)).collect() };
    // Luma in f64, not rounded to f32: the heights the fit reads.
    let luma = |r: &[f32], g: &[f32], b: &[f32]| -> Vec<f64> {
        (0..w * h).map(|k| 0.2126 * f64::from(r[k]) + 0.7152 * f64::from(g[k]) + 0.0722 * f64::from(b[k])).collect()
    };
    // Name, channels, the heights they must give.
    type Case<'a> = (&'a str, Vec<AnyChannel<FlatSamples>>, Vec<f64>);
    let cases: Vec<Case> = vec![
        ("half", vec![AnyChannel::new("Y", FlatSamples::F16(halves(&a)))], wide(&as_half(&a))),
        ("float", vec![AnyChannel::new("Y", FlatSamples::F32(a.clone()))], wide(&a)),
        ("u32", vec![AnyChannel::new("Y", FlatSamples::U32(ints.clone()))], wide(&ints_f32)),
        // Y half beside an alpha of floats: Y is the height.
        (
            "y_half_a_float",
            vec![AnyChannel::new("A", FlatSamples::F32(b.clone())), AnyChannel::new("Y", FlatSamples::F16(halves(&a)))],
            wide(&as_half(&a)),
        ),
        // R half, G float, B u32: luma of the three as numbers.
        (
            "rgb_mixed",
            vec![
                AnyChannel::new("R", FlatSamples::F16(halves(&a))),
                AnyChannel::new("G", FlatSamples::F32(c.clone())),
                AnyChannel::new("B", FlatSamples::U32(ints.clone())),
            ],
            luma(&as_half(&a), &c, &ints_f32),
        ),
    ];
    let out = dir.path().join("o.exr");
    for (name, channels, heights) in cases {
        let input = file(dir.path(), &format!("{name}.exr"), &exr_with(w, h, channels));
        let want = normals(&heights, w, h, &Options::default()).unwrap();
        ok(&[os("convert"), input.as_os_str(), os("-o"), out.as_os_str(), os("--signed")], None);
        assert_eq!(normals_of(&out), want, "{name}, from the file");
        ok(&[os("convert"), os("-"), os("-o"), out.as_os_str(), os("--signed")], Some(&input));
        assert_eq!(normals_of(&out), want, "{name}, from standard input");
    }
}

#[test]
fn exr_layers_the_first_part_by_default_and_layer_picks_one() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (10usize, 8usize);
    let wave = |f: f32| -> Vec<f32> { (0..w * h).map(|k| ((k % w) as f32 * f).sin() + (k / w) as f32 * 0.1).collect() };
    let (r, g, b, height) = (wave(0.3), wave(0.7), wave(1.1), wave(0.5));
    let luma: Vec<f64> =
        (0..w * h).map(|k| 0.2126 * f64::from(r[k]) + 0.7152 * f64::from(g[k]) + 0.0722 * f64::from(b[k])).collect();
    let layer = |name: &str, channels: Vec<AnyChannel<FlatSamples>>| {
        let channels = AnyChannels::sort(SmallVec::from_vec(channels));
        Layer::new(Vec2(w, h), LayerAttributes::named(name), Encoding::SMALL_LOSSLESS, channels)
    };
    // Two parts: "albedo" (R, G, B) first, "height" (Y) second.
    let albedo = layer(
        "albedo",
        vec![
            AnyChannel::new("R", FlatSamples::F32(r.clone())),
            AnyChannel::new("G", FlatSamples::F32(g.clone())),
            AnyChannel::new("B", FlatSamples::F32(b.clone())),
        ],
    );
    let heights = layer("height", vec![AnyChannel::new("Y", FlatSamples::F32(height.clone()))]);
    let mut bytes = std::io::Cursor::new(Vec::new());
    let attributes =
        exr::meta::header::ImageAttributes::new(exr::meta::attribute::IntegerBounds::from_dimensions((w, h)));
    Image::from_layers(attributes, vec![albedo, heights]).write().to_buffered(&mut bytes).unwrap();
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes.get_ref()), false).unwrap();
    let names: Vec<String> =
        meta.headers.iter().map(|h| h.own_attributes.layer_name.as_ref().unwrap().to_string()).collect();
    assert_eq!(names, ["albedo", "height"], "the parts in this order");
    let parts = file(dir.path(), "parts.exr", bytes.get_ref());
    let out = dir.path().join("o.exr");
    let opts = Options::default();
    let convert = |input: &Path, extra: &[&str]| -> Vec<[f32; 3]> {
        let mut args = vec![os("convert"), input.as_os_str(), os("-o"), out.as_os_str(), os("--signed")];
        args.extend(extra.iter().map(os));
        ok(&args, None);
        normals_of(&out)
    };
    // Default: the first part, its R, G, B as luma (the `exr` crate's
    // "first valid layer" is the first part of flat samples).
    assert_eq!(convert(&parts, &[]), normals(&luma, w, h, &opts).unwrap());
    assert_eq!(convert(&parts, &["--layer", "albedo"]), normals(&luma, w, h, &opts).unwrap());
    assert_eq!(convert(&parts, &["--layer", "height"]), normals(&height, w, h, &opts).unwrap());
    refused(
        &[os("convert"), parts.as_os_str(), os("-o"), out.as_os_str(), os("--layer"), os("Height")],
        None,
        "has no layer Height (layers: albedo, height)",
    );
    let run = run_bin(&[os("tiling"), parts.as_os_str(), os("--layer"), os("height"), os("--json")], None);
    assert!(matches!(run.code, Some(0 | 1)), "{}", run.stderr);
    assert!(run.stdout.contains("\"width\": 10, \"height\": 8"), "{}", run.stdout);

    // One part whose channels are grouped by name: "bump.Y", "rough.Y".
    let grouped = file(
        dir.path(),
        "grouped.exr",
        &exr_with(
            w,
            h,
            vec![
                AnyChannel::new("bump.Y", FlatSamples::F32(height.clone())),
                AnyChannel::new("rough.Y", FlatSamples::F32(r.clone())),
            ],
        ),
    );
    refused(
        &[os("convert"), grouped.as_os_str(), os("-o"), out.as_os_str()],
        None,
        "every channel is in a layer (bump, rough) and none is at the root",
    );
    assert_eq!(convert(&grouped, &["--layer", "bump"]), normals(&height, w, h, &opts).unwrap());
    assert_eq!(convert(&grouped, &["--layer", "rough"]), normals(&r, w, h, &opts).unwrap());
    ok(
        &[os("convert"), os("-"), os("-o"), out.as_os_str(), os("--signed"), os("--layer"), os("rough")],
        Some(&grouped),
    );
    assert_eq!(normals_of(&out), normals(&r, w, h, &opts).unwrap(), "standard input");
    refused(
        &[os("convert"), grouped.as_os_str(), os("-o"), out.as_os_str(), os("--layer"), os("bum")],
        None,
        "has no layer bum (layers: bump, rough)",
    );
}

#[test]
fn an_offset_data_window_reads_as_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (8usize, 6usize);
    let heights: Vec<f32> = (0..w * h).map(|k| ((k * 37) % 11) as f32 * 0.2).collect();
    let at_origin = file(dir.path(), "origin.exr", &exr_gray(w, h, &heights));
    let window = [-5, 7, 2, 12];
    let offset = ExrSpec { data_window: window, display_window: [0, 0, 7, 5], ..ExrSpec::gray(8, 6) };
    let offset = file(dir.path(), "offset.exr", &offset.file(std::slice::from_ref(&heights)));
    let want = normals(&heights, w, h, &Options::default()).unwrap();
    let out = dir.path().join("o.exr");
    for input in [&at_origin, &offset] {
        for border in ["wrap", "clamp", "auto"] {
            ok(
                &[
                    os("convert"),
                    input.as_os_str(),
                    os("-o"),
                    out.as_os_str(),
                    os("--signed"),
                    os("--border"),
                    os(border),
                ],
                None,
            );
            let opts = Options::default().with_borders(Borders::both(if border == "clamp" {
                Border::Clamp
            } else {
                Border::Wrap
            }));
            if border != "auto" {
                assert_eq!(normals_of(&out), normals(&heights, w, h, &opts).unwrap(), "{input:?} {border}");
            }
        }
        ok(&[os("convert"), os("-"), os("-o"), out.as_os_str(), os("--signed")], Some(input));
        assert_eq!(normals_of(&out), want, "{input:?} from standard input");
    }
    let report = |input: &Path| {
        let run = run_bin(&[os("tiling"), input.as_os_str(), os("--json")], None);
        assert!(matches!(run.code, Some(0 | 1)), "{}", run.stderr);
        (run.code, run.stdout.replace(&input.display().to_string(), ""))
    };
    assert_eq!(report(&offset), report(&at_origin));
}

#[test]
fn nan_and_infinity_name_the_first_bad_texel_in_row_order() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (8usize, 6usize);
    let mut heights: Vec<f32> = (0..w * h).map(|k| k as f32 * 0.01).collect();
    heights[2 * w + 3] = f32::NAN;
    // Also a bad texel in the last row, which a wrap in y reads first
    // (the top rows' patches reach it): row order still names (3, 2).
    heights[5 * w + 1] = f32::INFINITY;
    let input = file(dir.path(), "bad.exr", &exr_gray(w, h, &heights));
    let out = dir.path().join("o.exr");
    let png = dir.path().join("o.png");
    let reason = "height at texel (x 3, y 2) is NaN or infinite";
    for border in ["wrap", "clamp", "auto"] {
        for target in [&out, &png] {
            refused(
                &[os("convert"), input.as_os_str(), os("-o"), target.as_os_str(), os("--border"), os(border)],
                None,
                reason,
            );
            assert!(!target.exists());
        }
    }
    refused(&[os("convert"), os("-"), os("-o"), out.as_os_str()], Some(&input), reason);
    refused(&[os("tiling"), input.as_os_str()], None, reason);
    let mut only_inf = heights.clone();
    only_inf[2 * w + 3] = 0.0;
    only_inf[4 * w + 7] = f32::NEG_INFINITY;
    let input = file(dir.path(), "inf.exr", &exr_gray(w, h, &only_inf));
    refused(&[os("convert"), input.as_os_str(), os("-o"), out.as_os_str()], None, "(x 7, y 4) is NaN or infinite");
}

#[test]
fn heights_of_extreme_size_give_finite_unit_normals() {
    // 4096 wide: a relief of 1e30 is a gain of 4.1e33, past the largest
    // scale accepted.
    let (w, h) = (4096usize, 3usize);
    let patterns: Vec<(&str, Vec<f32>)> = vec![
        ("checkerboard ±3e38", (0..w * h).map(|k| if (k % w + k / w) % 2 == 0 { 3e38 } else { -3e38 }).collect()),
        (
            "ramp −3.4e38 … 3.4e38",
            (0..w * h).map(|k| ((k % w) as f64 / (w - 1) as f64 * 6.8e38 - 3.4e38) as f32).collect(),
        ),
        (
            "f32::MAX beside −f32::MAX and tiny",
            (0..w * h).map(|k| [f32::MAX, -f32::MAX, 1e-38, 0.0][(k * 7) % 4]).collect(),
        ),
    ];
    // Up to the largest gain accepted, and a relief whose gain (F × width)
    // goes past it.
    let strengths = [Strength::Scale(1.0), Strength::Scale(1e10), Strength::Scale(1e30), Strength::Relief(1e30)];
    for (name, heights) in &patterns {
        for strength in strengths {
            for fit in [Fit::Orthogonal, Fit::Vertical] {
                for patch in [3, 63, 255] {
                    for borders in [Borders::both(Border::Wrap), Borders::both(Border::Clamp)] {
                        let opts = options(patch, fit, borders).with_strength(strength);
                        let n = normals(heights, w, h, &opts).unwrap();
                        for (k, v) in n.iter().enumerate() {
                            let len = v.iter().map(|c| f64::from(*c).powi(2)).sum::<f64>().sqrt();
                            assert!(
                                v.iter().all(|c| c.is_finite()) && (len - 1.0).abs() < 1e-6 && v[2] >= 0.0,
                                "{name}, {opts:?}: texel ({}, {}) is {v:?}",
                                k % w,
                                k / w
                            );
                        }
                        if patch == 3 && borders.x == Border::Clamp {
                            for (k, v) in n.iter().enumerate() {
                                let want = reference::normal_at(heights, w, h, &opts, k % w, k / w);
                                for c in 0..3 {
                                    assert!(
                                        (f64::from(v[c]) - want[c]).abs() <= 1e-5,
                                        "{name}, {opts:?}: texel ({}, {}) is {v:?}, reference {want:?}",
                                        k % w,
                                        k / w
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

// Runs the program, which needs the `cli` feature.
#[cfg(feature = "cli")]
#[test]
fn extreme_heights_through_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (16usize, 16usize);
    let board: Vec<f32> = (0..w * h).map(|k| if (k % w + k / w) % 2 == 0 { 3e38 } else { -3e38 }).collect();
    let ramp: Vec<f32> = (0..w * h).map(|k| ((k % w) as f64 / 15.0 * 6e38 - 3e38) as f32).collect();
    let board = file(dir.path(), "board.exr", &exr_gray(w, h, &board));
    let ramp_path = file(dir.path(), "ramp.exr", &exr_gray(w, h, &ramp));
    let out = dir.path().join("o.exr");
    for input in [&board, &ramp_path] {
        for scale in ["1", "1e30"] {
            ok(
                &[
                    os("convert"),
                    input.as_os_str(),
                    os("-o"),
                    out.as_os_str(),
                    os("--signed"),
                    os("-s"),
                    os(scale),
                    os("--border"),
                    os("clamp"),
                ],
                None,
            );
            assert!(normals_of(&out).iter().all(|n| n.iter().all(|c| c.is_finite())), "{input:?} -s {scale}");
        }
    }
}

// Runs the program, which needs the `cli` feature.
#[cfg(feature = "cli")]
#[test]
fn a_wrong_extension_is_refused_and_standard_input_is_read_by_content() {
    let dir = tempfile::tempdir().unwrap();
    let png = png_gray8(8, 8, |x, y| ((x * 30 + y * 3) % 256) as u8);
    let png_named_exr = file(dir.path(), "actually_png.exr", &png);
    let exr_named_png = file(dir.path(), "actually_exr.png", &exr_gray(8, 8, &[0.5; 64]));
    let no_extension = file(dir.path(), "height", &png);
    for (path, message) in [
        (&png_named_exr, "is named .exr but its content is png"),
        (&exr_named_png, "is named .png but its content is exr"),
    ] {
        for command in ["convert", "tiling"] {
            let out = std::process::Command::new(env!("CARGO_BIN_EXE_normalfit"))
                .args([os(command), path.as_os_str()])
                .output()
                .unwrap();
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{command} {path:?}: {stderr}");
            assert!(stderr.contains(message) && stderr.contains(&*path.to_string_lossy()), "{command}: {stderr}");
        }
    }
    // No extension, or standard input: read by content.
    ok(&[os("convert"), no_extension.as_os_str()], None);
    let piped = std::process::Command::new(env!("CARGO_BIN_EXE_normalfit"))
        .args(["convert", "-", "-o", "-"])
        .stdin(std::fs::File::open(&png_named_exr).unwrap())
        .output()
        .unwrap();
    assert_eq!(piped.status.code(), Some(0), "{}", String::from_utf8_lossy(&piped.stderr));
    assert!(piped.stdout.starts_with(b"\x89PNG"));
    assert_eq!(files_in(dir.path()), ["actually_exr.png", "actually_png.exr", "height", "height_normal.png"]);
}
