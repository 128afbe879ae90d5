//! The `normalfit` binary as users and pipelines run it: outputs, exit
//! codes, one-line errors, batches, and files that are never lost.

use crate::common;

use std::fs;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};

use common::cli::{bin, is_summary, listing, run, s};
use common::reference;
use normalfit::{Border, Borders, Convention, Fit, Options, Strength};

/// A 16-bit gray height map with real detail: a bump on a slope.
fn write_gray16(path: &Path, w: u32, h: u32) -> Vec<f32> {
    let mut img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(w, h);
    for (x, y, p) in img.enumerate_pixels_mut() {
        let (dx, dy) = (x as f64 - w as f64 / 2.0, y as f64 - h as f64 / 3.0);
        let v = 0.3 * x as f64 / w as f64
            + 0.5 * (-(dx * dx + dy * dy) / 40.0).exp()
            + 0.1 * ((x * 7 + y * 3) % 5) as f64 / 5.0;
        p.0[0] = (v.min(1.0) * 65535.0).round() as u16;
    }
    img.save(path).unwrap();
    img.pixels().map(|p| p.0[0] as f32 / 65535.0).collect()
}

fn write_gray8(path: &Path, w: u32, h: u32) {
    let img = image::GrayImage::from_fn(w, h, |x, y| image::Luma([((x * 37 + y * 11) % 256) as u8]));
    img.save(path).unwrap();
}

/// The one error line on standard error. Warnings (the wrap-seam hint) may
/// precede it, each on its own line, and a batch's summary line follow it.
fn one_line_error(out: &Output) -> String {
    let all = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!all.contains("panicked"), "{all}");
    let errors: Vec<&str> = all.lines().filter(|l| !l.starts_with("normalfit: warning: ") && !is_summary(l)).collect();
    assert_eq!(errors.len(), 1, "want one error line on stderr, got {all:?}");
    errors[0].to_string()
}

#[test]
fn converts_a_16_bit_map_exactly_as_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    let heights = write_gray16(&input, 37, 23);
    let out = dir.path().join("n.png");
    let args = [
        "convert",
        s(&input),
        "-o",
        s(&out),
        "-n",
        "5",
        "--fit",
        "vertical",
        "--border",
        "clamp,mirror",
        "--convention",
        "dx",
        "--scale",
        "12",
    ];
    let r = run(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let got = image::open(&out).unwrap();
    assert_eq!(got.color(), image::ColorType::Rgb16, "16-bit input gives 16-bit output by default");
    let got = got.to_rgb16();
    let opts = Options::new()
        .with_patch(5)
        .with_fit(Fit::Vertical)
        .with_borders(Borders { x: Border::Clamp, y: Border::Mirror })
        .with_convention(Convention::DirectX)
        .with_strength(Strength::Scale(12.0));
    let want = reference::normal_map(&heights, 37, 23, &opts);
    assert_eq!(got.pixels().len(), want.len());
    for (k, p) in got.pixels().enumerate() {
        for (c, (&got, &w)) in p.0.iter().zip(&want[k]).enumerate() {
            let expect = (65535.0 * (w + 1.0) / 2.0).round();
            assert!((got as f64 - expect).abs() <= 1.0, "texel {k} channel {c}: {got} vs {expect}");
        }
    }
}

#[test]
fn default_output_sits_beside_the_input_and_is_8_bit_for_8_bit_input() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("stone.png");
    write_gray8(&input, 16, 16);
    let r = run(&["convert", s(&input)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let out = image::open(dir.path().join("stone_normal.png")).unwrap();
    assert_eq!(out.color(), image::ColorType::Rgb8);
    let mode = fs::metadata(dir.path().join("stone_normal.png")).unwrap().permissions().mode() & 0o777;
    assert_ne!(mode, 0o600, "the output has an ordinary file's permissions");
    assert_eq!(listing(dir.path()), ["stone.png", "stone_normal.png"], "no temporary files left");
}

#[test]
fn bad_arguments_exit_2_with_one_line_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 8, 8);
    let out = dir.path().join("o.png");
    for bad in [
        &["--patch", "4"][..],
        &["--patch", "1"],
        &["--scale", "abc"],
        &["--border", "tile"],
        &["--fit", "cubic"],
        &["--bits", "32"],
        &["--signed"],
        &["--scale", "2", "--relief", "0.1"],
    ] {
        let mut args = vec!["convert", s(&input), "-o", s(&out)];
        args.extend_from_slice(bad);
        let r = run(&args);
        assert_eq!(r.status.code(), Some(2), "{bad:?}");
        one_line_error(&r);
        assert!(!out.exists(), "{bad:?} left an output");
    }
    assert_eq!(listing(dir.path()), ["h.png"]);
}

#[test]
fn unreadable_inputs_are_named_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("notes.png");
    fs::write(&text, "this is not an image\n").unwrap();
    let empty = dir.path().join("empty.exr");
    fs::write(&empty, "").unwrap();
    let out = dir.path().join("o.png");
    for (input, name) in
        [(text.clone(), "notes.png"), (empty.clone(), "empty.exr"), (dir.path().join("missing.png"), "missing.png")]
    {
        let r = run(&["convert", s(&input), "-o", s(&out)]);
        assert_eq!(r.status.code(), Some(2));
        let err = one_line_error(&r);
        assert!(err.contains(name), "{err}");
        assert!(!out.exists());
    }
    assert_eq!(listing(dir.path()), ["empty.exr", "notes.png"], "no output, no temporary file");
}

#[test]
fn a_bad_file_in_a_batch_does_not_stop_the_others() {
    let dir = tempfile::tempdir().unwrap();
    let (a, bad, b) = (dir.path().join("a.png"), dir.path().join("bad.png"), dir.path().join("b.png"));
    write_gray8(&a, 9, 7);
    fs::write(&bad, [0x89, b'P', b'N', b'G', 1, 2, 3]).unwrap();
    write_gray16(&b, 12, 5);
    let outdir = dir.path().join("out");
    let r = run(&["convert", s(&a), s(&bad), s(&b), "-o", s(&outdir)]);
    assert_eq!(r.status.code(), Some(2), "one input failed");
    let err = one_line_error(&r);
    assert!(err.contains("bad.png"), "{err}");
    assert_eq!(listing(&outdir), ["a_normal.png", "b_normal.png"]);
    assert_eq!(image::open(outdir.join("b_normal.png")).unwrap().color(), image::ColorType::Rgb16);
}

#[test]
fn inputs_are_never_written_over_even_through_links() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 8, 8);
    let before = fs::read(&input).unwrap();
    let hard = dir.path().join("hard.png");
    fs::hard_link(&input, &hard).unwrap();
    let soft = dir.path().join("soft.png");
    std::os::unix::fs::symlink(&input, &soft).unwrap();
    for target in [&input, &hard, &soft] {
        let r = run(&["convert", s(&input), "-o", s(target)]);
        assert_eq!(r.status.code(), Some(2), "writing over {target:?}");
        let err = one_line_error(&r);
        assert!(err.contains("input"), "{err}");
        assert_eq!(fs::read(&input).unwrap(), before);
    }
    // In a batch, one input's default output may be another input.
    let other = dir.path().join("h_normal.png");
    write_gray8(&other, 4, 4);
    let other_before = fs::read(&other).unwrap();
    let r = run(&["convert", s(&input), s(&other)]);
    assert_eq!(r.status.code(), Some(2));
    assert_eq!(fs::read(&other).unwrap(), other_before, "an input is never replaced");
    assert!(dir.path().join("h_normal_normal.png").exists(), "the other input was still converted");
}

#[test]
fn a_failed_write_keeps_the_old_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 8, 8);
    let out = dir.path().join("o.png");
    fs::write(&out, b"old").unwrap();
    // Writing an 8-bit EXR is refused after the image is read: the old
    // output must survive untouched.
    let r = run(&["convert", s(&input), "-o", s(&out), "--format", "exr"]);
    assert_eq!(r.status.code(), Some(2));
    one_line_error(&r);
    assert_eq!(fs::read(&out).unwrap(), b"old");
    let missing_dir = dir.path().join("nope").join("o.png");
    let r = run(&["convert", s(&input), "-o", s(&missing_dir)]);
    assert_eq!(r.status.code(), Some(2));
    assert!(one_line_error(&r).contains("nope"));
    assert_eq!(listing(dir.path()), ["h.png", "o.png"]);
}

#[test]
fn standard_input_to_standard_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 10, 6);
    let file_out = dir.path().join("f.png");
    assert!(run(&["convert", s(&input), "-o", s(&file_out)]).status.success());
    let child = bin()
        .args(["convert", "-", "-o", "-"])
        .stdin(fs::File::open(&input).unwrap())
        .stdout(Stdio::piped())
        .output()
        .unwrap();
    assert!(child.status.success(), "{}", String::from_utf8_lossy(&child.stderr));
    let piped = image::load_from_memory(&child.stdout).unwrap().to_rgb8();
    assert_eq!(piped, image::open(&file_out).unwrap().to_rgb8());
    let exr = bin()
        .args(["convert", "-", "-o", "-", "--format", "exr", "--signed"])
        .stdin(fs::File::open(&input).unwrap())
        .output()
        .unwrap();
    assert!(exr.status.success());
    assert_eq!(&exr.stdout[..4], &[0x76, 0x2f, 0x31, 0x01], "EXR magic");
}

#[test]
fn exr_output_holds_the_normal_in_float() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    let heights = write_gray16(&input, 20, 14);
    for (bits, signed, tol) in [("32", false, 1e-6), ("16", false, 1e-3), ("32", true, 1e-6)] {
        let out = dir.path().join(format!("n{bits}{signed}.exr"));
        let mut args = vec!["convert", s(&input), "-o", s(&out), "--bits", bits];
        if signed {
            args.push("--signed");
        }
        let r = run(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let raster = normalfit::io::read_path(&out, &Default::default()).unwrap();
        let want = reference::normal_map(&heights, 20, 14, &Options::new());
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let plane = raster.plane(name).unwrap();
            assert_eq!(plane.data.len(), want.len());
            for (k, (&got, w)) in plane.data.to_f32().unwrap().iter().zip(&want).enumerate() {
                let expect = if signed { w[c] } else { (w[c] + 1.0) / 2.0 };
                assert!((got as f64 - expect).abs() < tol, "{bits} {signed} {name}[{k}]");
            }
        }
    }
}

/// A 32-bit float gray TIFF as terrain tools export it: heights in metres,
/// far from zero.
fn write_float_tiff(path: &Path, w: u32, h: u32) -> Vec<f32> {
    let heights: Vec<f32> = (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                let (dx, dy) = (x as f64 - w as f64 / 2.0, y as f64 - h as f64 / 3.0);
                (812.5 + 3.0 * x as f64 / w as f64 + 6.0 * (-(dx * dx + dy * dy) / 30.0).exp()
                    - 0.5 * ((x * 5 + y * 3) % 4) as f64) as f32
            })
        })
        .collect();
    let file = fs::File::create(path).unwrap();
    tiff::encoder::TiffEncoder::new(file)
        .unwrap()
        .write_image::<tiff::encoder::colortype::Gray32Float>(w, h, &heights)
        .unwrap();
    heights
}

#[test]
fn a_float_tiff_becomes_a_float_exr_by_default_as_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("terrain.tif");
    let heights = write_float_tiff(&input, 29, 17);
    let r = run(&["convert", s(&input), "--scale", "0.5", "--border", "clamp"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(listing(dir.path()), ["terrain.tif", "terrain_normal.exr"], "float input gives EXR output");
    let raster = normalfit::io::read_path(&dir.path().join("terrain_normal.exr"), &Default::default()).unwrap();
    assert_eq!(raster.sample, normalfit::io::SampleType::Float);
    let opts =
        Options::new().with_borders(Borders { x: Border::Clamp, y: Border::Clamp }).with_strength(Strength::Scale(0.5));
    let want = reference::normal_map(&heights, 29, 17, &opts);
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        let plane = raster.plane(name).unwrap();
        assert_eq!(plane.data.len(), want.len());
        for (k, (&got, w)) in plane.data.to_f32().unwrap().iter().zip(&want).enumerate() {
            let expect = (w[c] + 1.0) / 2.0;
            assert!((got as f64 - expect).abs() < 1e-5, "{name}[{k}]: {got} vs {expect}");
        }
    }
}

#[test]
fn a_signed_16_bit_tiff_gives_a_16_bit_png_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dem.tif");
    let (w, h) = (13u32, 9u32);
    let stored: Vec<i16> = (0..w * h).map(|i| ((i * 977) % 2000) as i16 - 1000).collect();
    tiff::encoder::TiffEncoder::new(fs::File::create(&input).unwrap())
        .unwrap()
        .write_image::<tiff::encoder::colortype::GrayI16>(w, h, &stored)
        .unwrap();
    let r = run(&["convert", s(&input), "--border", "mirror", "--scale", "40"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let got = image::open(dir.path().join("dem_normal.png")).unwrap();
    assert_eq!(got.color(), image::ColorType::Rgb16, "a 16-bit integer input gives 16-bit PNG output");
    let heights: Vec<f32> = stored.iter().map(|&v| f32::from(v) / 65535.0).collect();
    let opts = Options::new()
        .with_borders(Borders { x: Border::Mirror, y: Border::Mirror })
        .with_strength(Strength::Scale(40.0));
    let want = reference::normal_map(&heights, w as usize, h as usize, &opts);
    for (k, p) in got.to_rgb16().pixels().enumerate() {
        for (c, (&got, &wc)) in p.0.iter().zip(&want[k]).enumerate() {
            let expect = (65535.0 * (wc + 1.0) / 2.0).round();
            assert!((got as f64 - expect).abs() <= 1.0, "texel {k} channel {c}: {got} vs {expect}");
        }
    }
}

#[test]
fn many_inputs_go_into_the_output_folder() {
    let dir = tempfile::tempdir().unwrap();
    let inputs: Vec<PathBuf> = (0..3).map(|k| dir.path().join(format!("t{k}.png"))).collect();
    for p in &inputs {
        write_gray8(p, 6, 6);
    }
    let outdir = dir.path().join("normals");
    let mut args = vec!["convert"];
    args.extend(inputs.iter().map(|p| s(p)));
    args.extend(["-o", s(&outdir)]);
    let r = run(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(listing(&outdir), ["t0_normal.png", "t1_normal.png", "t2_normal.png"]);
    let r = run(&["convert", s(&inputs[0]), s(&inputs[1]), "-o", "-"]);
    assert_eq!(r.status.code(), Some(2), "many images cannot share standard output");
}

/// A PNG whose pixel data stops half way fails while its rows stream
/// through: the error names the input, and no output or temporary file is
/// left, whatever the border (a wrap in y reads the file twice).
#[test]
fn a_png_truncated_in_its_pixels_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cut.png");
    write_gray16(&input, 300, 700);
    let bytes = fs::read(&input).unwrap();
    fs::write(&input, &bytes[..bytes.len() / 2]).unwrap();
    for border in ["wrap", "clamp"] {
        let out = dir.path().join("out.png");
        let r = run(&["convert", s(&input), "-o", s(&out), "--border", border]);
        assert_eq!(r.status.code(), Some(2), "{border}");
        let err = one_line_error(&r);
        assert!(err.contains("cut.png"), "{err}");
        assert_eq!(listing(dir.path()), vec!["cut.png".to_string()], "{border}");
    }
}

/// PNG to PNG streams rows to standard output too, identical to a file.
#[test]
fn a_png_streams_to_standard_output_as_to_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray16(&input, 90, 530);
    let file = dir.path().join("n.png");
    assert!(run(&["convert", s(&input), "-o", s(&file), "-n", "5"]).status.success());
    let piped = run(&["convert", s(&input), "-o", "-", "--format", "png", "-n", "5"]);
    assert!(piped.status.success(), "{}", String::from_utf8_lossy(&piped.stderr));
    let a = image::load_from_memory(&piped.stdout).unwrap().to_rgb16();
    let b = image::open(&file).unwrap().to_rgb16();
    assert_eq!(a, b);
}

/// A reader of standard output that stops early (`| head -c4`) closes the
/// pipe: the output it did not want is no error, as for ripgrep and fd.
/// Exit 0 and not a word, whether the image was read whole (standard input)
/// or streamed, and whatever the output format.
#[test]
fn a_closed_standard_output_ends_the_conversion_quietly() {
    use std::io::{Read, Write};
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("noise.png");
    // Noise does not compress, so every output is far larger than a pipe
    // holds; and it tiles, so no warning is due.
    let noise = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(512, 512, |x, y| {
        let k = (y * 512 + x).wrapping_mul(2_654_435_761);
        image::Luma([(k >> 16) as u16])
    });
    noise.save(&input).unwrap();
    let bytes = fs::read(&input).unwrap();
    let cases: [(&str, &[&str]); 5] = [
        ("standard input to EXR", &["convert", "-", "--format", "exr"]),
        ("standard input to PNG", &["convert", "-", "--format", "png"]),
        ("streamed to EXR", &["convert", s(&input), "-o", "-", "--format", "exr"]),
        ("streamed to PNG", &["convert", s(&input), "-o", "-", "--format", "png", "--border", "wrap"]),
        ("shade", &["shade", s(&input), "-o", "-"]),
    ];
    for (what, args) in cases {
        let mut child =
            bin().args(args).stdin(Stdio::piped()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
        let mut stdin = child.stdin.take().unwrap();
        let feed = std::thread::spawn({
            let bytes = bytes.clone();
            move || {
                // The streamed runs do not read it: a closed pipe is fine.
                let _ = stdin.write_all(&bytes);
            }
        });
        let mut head = [0u8; 4];
        child.stdout.as_mut().unwrap().read_exact(&mut head).unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        feed.join().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(head == *b"\x89PNG" || head == [0x76, 0x2f, 0x31, 0x01], "{what}: {head:?}");
        assert_eq!(out.status.code(), Some(0), "{what}: {stderr}");
        assert!(stderr.is_empty(), "{what}: {stderr}");
    }
}
