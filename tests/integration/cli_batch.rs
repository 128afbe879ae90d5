//! `normalfit convert` on batches and for pipelines, as the installed
//! binary runs: folders (recursive, layout kept, outputs and hidden files
//! skipped, link loops harmless), `--suffix`, `--overwrite`, `--jobs`, the
//! progress bar and summary line, `--alpha`, `--channels` and `--residual`.

use crate::common;

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, SystemTime};

use common::cli::{run, s};

fn ok(args: &[&str]) -> String {
    let r = run(args);
    let stderr = String::from_utf8_lossy(&r.stderr).into_owned();
    assert!(r.status.success(), "normalfit {args:?}: {stderr}");
    stderr
}

/// The summary line's counts, from the last line of standard error.
fn summary(stderr: &str) -> (usize, usize, usize) {
    let last = stderr.lines().last().unwrap_or_default();
    let words: Vec<&str> = last.split(' ').collect();
    match words[..] {
        ["normalfit:", c, "converted,", k, "skipped,", f, "failed", "in", t, "s"] => {
            assert!(t.parse::<f64>().is_ok(), "{last}");
            (c.parse().unwrap(), k.parse().unwrap(), f.parse().unwrap())
        }
        _ => panic!("no summary line in {stderr:?}"),
    }
}

/// A small 8-bit gray height map, different for every `seed`.
fn write_gray8(path: &Path, w: u32, h: u32, seed: u32) {
    let img = image::GrayImage::from_fn(w, h, |x, y| image::Luma([((x * 37 + y * 11 + seed * 53) % 256) as u8]));
    img.save(path).unwrap();
}

/// A 16-bit gray height map from stored values.
fn write_gray16(path: &Path, w: u32, h: u32, value: impl Fn(u32, u32) -> u16) -> Vec<u16> {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| image::Luma([value(x, y)]));
    img.save(path).unwrap();
    img.into_raw()
}

/// Every file under `dir`, as sorted relative paths.
fn tree(dir: &Path) -> Vec<String> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
        for e in fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() && !p.is_symlink() {
                walk(root, &p, out);
            } else {
                out.push(p.strip_prefix(root).unwrap().to_string_lossy().into_owned());
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

#[test]
fn a_folder_converts_recursively_keeping_its_layout_and_skipping_outputs_hidden_files_and_link_loops() {
    let dir = tempfile::tempdir().unwrap();
    let tex = dir.path().join("tex");
    fs::create_dir_all(tex.join("sub/deeper")).unwrap();
    fs::create_dir_all(tex.join(".hidden")).unwrap();
    write_gray8(&tex.join("a.png"), 8, 8, 1);
    write_gray8(&tex.join("sub/b.png"), 9, 7, 2);
    write_gray8(&tex.join("sub/deeper/C.PNG"), 6, 6, 3);
    write_gray8(&tex.join(".hidden/x.png"), 4, 4, 4);
    write_gray8(&tex.join(".dot.png"), 4, 4, 5);
    write_gray8(&tex.join("old_normal.png"), 4, 4, 6);
    write_gray8(&tex.join("old_residual.png"), 4, 4, 7);
    fs::write(tex.join("notes.txt"), "not an image").unwrap();
    // A link back up: followed, it would never end.
    std::os::unix::fs::symlink("..", tex.join("sub/loop")).unwrap();

    let out = dir.path().join("out");
    let stderr = ok(&["convert", s(&tex), "-r", "-o", s(&out)]);
    assert_eq!(tree(&out), ["a_normal.png", "sub/b_normal.png", "sub/deeper/C_normal.png"]);
    assert_eq!(summary(&stderr), (3, 0, 0));

    // Without --recursive, the folder's own images only.
    let flat = dir.path().join("flat");
    let stderr = ok(&["convert", s(&tex), "-o", s(&flat)]);
    assert_eq!(tree(&flat), ["a_normal.png"]);
    assert_eq!(summary(&stderr), (1, 0, 0));

    // In place, twice: the outputs of the first run are not inputs of the second.
    for _ in 0..2 {
        let stderr = ok(&["convert", s(&tex), "-r"]);
        assert_eq!(summary(&stderr), (3, 0, 0));
    }
    let made: Vec<String> = tree(&tex).into_iter().filter(|p| p.ends_with("_normal.png")).collect();
    assert_eq!(made, ["a_normal.png", "old_normal.png", "sub/b_normal.png", "sub/deeper/C_normal.png"]);

    // A folder cannot go to standard output, and a folder of no images says so.
    let r = run(&["convert", s(&tex), "-o", "-"]);
    assert_eq!(r.status.code(), Some(2));
    let empty = dir.path().join("empty");
    fs::create_dir(&empty).unwrap();
    let stderr = ok(&["convert", s(&empty), "-o", s(&dir.path().join("none"))]);
    assert!(stderr.contains("empty: holds no image files"), "{stderr}");
    assert_eq!(summary(&stderr), (0, 0, 0));
}

/// Issue 13's case: a folder holding only `h.pgm` was "holds no image
/// files to convert" (exit 0, nothing written), while `convert dir/h.pgm`
/// converted. The folder's search now takes the reader's extensions.
#[test]
fn a_folder_holding_only_a_pgm_converts_it_as_naming_the_file_does() {
    let dir = tempfile::tempdir().unwrap();
    let tex = dir.path().join("tex");
    fs::create_dir(&tex).unwrap();
    // A binary PGM, written by hand: header, then 8-bit gray texels.
    let mut pgm = b"P5\n9 7\n255\n".to_vec();
    pgm.extend((0..9 * 7).map(|i| (i * 37 % 256) as u8));
    fs::write(tex.join("h.pgm"), pgm).unwrap();
    let out = dir.path().join("out");
    let stderr = ok(&["convert", s(&tex), "-o", s(&out)]);
    assert!(!stderr.contains("holds no image files"), "{stderr}");
    assert_eq!(summary(&stderr), (1, 0, 0));
    assert_eq!(tree(&out), ["h_normal.png"]);
    let direct = dir.path().join("direct.png");
    ok(&["convert", s(&tex.join("h.pgm")), "-o", s(&direct)]);
    assert_eq!(fs::read(out.join("h_normal.png")).unwrap(), fs::read(&direct).unwrap());
}

/// A folder gives a file of every extension of every format the library
/// reads (its registry), in any case.
#[test]
fn a_folder_gives_every_extension_the_reader_takes() {
    let dir = tempfile::tempdir().unwrap();
    let tex = dir.path().join("tex");
    fs::create_dir(&tex).unwrap();
    let mut expected = Vec::new();
    for info in normalfit::io::read::formats::FORMATS {
        for (k, ext) in info.extensions.iter().enumerate() {
            let stem = format!("{}_{k}", info.name);
            // Every other file's extension in upper case.
            let ext = if k % 2 == 1 { ext.to_uppercase() } else { ext.to_string() };
            let path = tex.join(format!("{stem}.{ext}"));
            match info.name {
                // A 5 × 5 square at 8 bits, or at 16 (`.r16`, and `.raw`'s
                // length says which).
                "raw" => {
                    let len = if ext.eq_ignore_ascii_case("r8") { 25 } else { 50 };
                    fs::write(&path, vec![100u8; len]).unwrap();
                }
                "exr" => {
                    exr::prelude::write_rgb_file(&path, 6, 5, |x, y| (x as f32 * 0.1, y as f32 * 0.1, 0.5)).unwrap();
                }
                "hdr" => {
                    let img =
                        image::Rgb32FImage::from_fn(6, 5, |x, y| image::Rgb([x as f32 * 0.1, y as f32 * 0.1, 0.5]));
                    img.save_with_format(&path, image::ImageFormat::Hdr).unwrap();
                }
                _ => {
                    let format = image::ImageFormat::from_extension(&ext).unwrap();
                    let img = image::RgbImage::from_fn(6, 5, |x, y| image::Rgb([(x * 40) as u8, (y * 50) as u8, 9]));
                    img.save_with_format(&path, format).unwrap();
                }
            }
            // Float inputs give OpenEXR outputs, the others PNG.
            let out_ext = if matches!(info.name, "exr" | "hdr") { "exr" } else { "png" };
            expected.push(format!("{stem}_normal.{out_ext}"));
        }
    }
    fs::write(tex.join("notes.txt"), "not an image").unwrap();
    let out = dir.path().join("out");
    let stderr = ok(&["convert", s(&tex), "-o", s(&out)]);
    assert_eq!(summary(&stderr), (expected.len(), 0, 0), "{stderr}");
    expected.sort();
    assert_eq!(tree(&out), expected);
}

#[test]
fn a_bad_file_in_a_folder_is_one_line_and_the_others_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let tex = dir.path().join("tex");
    fs::create_dir(&tex).unwrap();
    write_gray8(&tex.join("a.png"), 8, 8, 1);
    fs::write(tex.join("broken.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    write_gray8(&tex.join("c.png"), 8, 8, 2);
    let out = dir.path().join("out");
    let r = run(&["convert", s(&tex), "-o", s(&out)]);
    assert_eq!(r.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&r.stderr);
    let errors: Vec<&str> = stderr.lines().filter(|l| l.contains("broken.png")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    assert_eq!(summary(&stderr), (2, 0, 1));
    assert_eq!(tree(&out), ["a_normal.png", "c_normal.png"]);
}

#[test]
fn the_suffix_names_outputs_and_marks_them_as_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let tex = dir.path().join("tex");
    fs::create_dir(&tex).unwrap();
    write_gray8(&tex.join("rock.png"), 8, 8, 1);
    for _ in 0..2 {
        ok(&["convert", s(&tex), "--suffix", "_n"]);
    }
    assert_eq!(tree(&tex), ["rock.png", "rock_n.png"]);
    // An empty suffix keeps the names, in another folder.
    let out = dir.path().join("out");
    ok(&["convert", s(&tex), "--suffix", "", "-o", s(&out)]);
    assert_eq!(tree(&out), ["rock.png", "rock_n.png"]);
    // Beside the inputs, an empty suffix would write over them: refused, per file.
    let r = run(&["convert", s(&tex.join("rock.png")), "--suffix", ""]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("never writes over an input"));
    let r = run(&["convert", s(&tex), "--suffix", "x/y"]);
    assert_eq!(r.status.code(), Some(2), "a suffix is part of a name");
}

fn set_mtime(path: &Path, t: SystemTime) {
    fs::File::options().write(true).open(path).unwrap().set_modified(t).unwrap();
}

#[test]
fn overwrite_never_and_older_skip_outputs_that_are_there_and_count_them() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    write_gray8(&a, 8, 8, 1);
    write_gray8(&b, 8, 8, 2);
    let out = dir.path().join("out");
    let (na, nb) = (out.join("a_normal.png"), out.join("b_normal.png"));
    let stderr = ok(&["convert", s(&a), s(&b), "-o", s(&out)]);
    assert_eq!(summary(&stderr), (2, 0, 0));

    // Mark the outputs, and date them after their inputs.
    let hour_ago = SystemTime::now() - Duration::from_secs(3600);
    for (input, output) in [(&a, &na), (&b, &nb)] {
        set_mtime(input, hour_ago);
        fs::write(output, b"kept").unwrap();
    }
    let stderr = ok(&["convert", s(&a), s(&b), "-o", s(&out), "--overwrite", "never"]);
    assert_eq!(summary(&stderr), (0, 2, 0));
    assert_eq!(fs::read(&na).unwrap(), b"kept");

    // a changes: only its output is older than its input.
    set_mtime(&a, SystemTime::now() + Duration::from_secs(60));
    let stderr = ok(&["convert", s(&a), s(&b), "-o", s(&out), "--overwrite", "older"]);
    assert_eq!(summary(&stderr), (1, 1, 0));
    assert!(image::open(&na).is_ok(), "a's output was made again");
    assert_eq!(fs::read(&nb).unwrap(), b"kept");

    // The default replaces everything, as before.
    let stderr = ok(&["convert", s(&a), s(&b), "-o", s(&out)]);
    assert_eq!(summary(&stderr), (2, 0, 0));
    assert!(image::open(&nb).is_ok());

    // A missing output is written whatever the policy.
    fs::remove_file(&nb).unwrap();
    let stderr = ok(&["convert", s(&a), s(&b), "-o", s(&out), "--overwrite", "never"]);
    assert_eq!(summary(&stderr), (1, 1, 0));
    assert!(image::open(&nb).is_ok());
}

#[test]
fn files_converted_at_once_give_what_one_at_a_time_gives() {
    let dir = tempfile::tempdir().unwrap();
    let mut inputs: Vec<PathBuf> = Vec::new();
    for k in 0..7 {
        let p = dir.path().join(format!("h{k}.png"));
        if k == 3 {
            fs::write(&p, b"not a png").unwrap();
        } else {
            write_gray8(&p, 30 + k, 20, k);
        }
        inputs.push(p);
    }
    // The same output name twice: a TIFF (read whole, slow to claim) then a
    // PNG (streamed, quick): the first on the command line wins, however
    // many files run at once.
    let tif = dir.path().join("h0.tif");
    image::GrayImage::from_fn(16, 16, |x, y| image::Luma([(x * y) as u8])).save(&tif).unwrap();
    let mut outputs = Vec::new();
    for jobs in ["1", "3"] {
        let out = dir.path().join(format!("out{jobs}"));
        let mut args = vec!["convert", s(&tif)];
        args.extend(inputs.iter().map(|p| s(p)));
        args.extend(["-o", s(&out), "--jobs", jobs]);
        let r = run(&args);
        assert_eq!(r.status.code(), Some(2), "two inputs failed");
        let stderr = String::from_utf8_lossy(&r.stderr).into_owned();
        assert_eq!(summary(&stderr), (6, 0, 2), "{stderr}");
        let conflict: Vec<&str> = stderr.lines().filter(|l| l.contains("earlier input")).collect();
        assert_eq!(conflict.len(), 1, "{stderr}");
        assert!(conflict[0].contains("h0.png is skipped"), "{}", conflict[0]);
        for line in stderr.lines() {
            assert!(line.starts_with("normalfit: "), "whole lines only: {line:?}");
        }
        let files: Vec<(String, Vec<u8>)> =
            tree(&out).into_iter().map(|name| (name.clone(), fs::read(out.join(&name)).unwrap())).collect();
        outputs.push(files);
    }
    assert_eq!(outputs[0].len(), 6);
    assert!(outputs[0] == outputs[1], "--jobs 3 wrote other bytes than --jobs 1");
    let alone = dir.path().join("alone.png");
    ok(&["convert", s(&tif), "-o", s(&alone)]);
    assert!(outputs[1].iter().any(|(name, bytes)| name == "h0_normal.png" && *bytes == fs::read(&alone).unwrap()));
    let r = run(&["convert", s(&tif), "--jobs", "0"]);
    assert_eq!(r.status.code(), Some(2));
}

/// Standard error piped (a log, CI): no progress bar, not a byte of it,
/// only the summary line. On a terminal (`script` gives the run one) the
/// same batch draws the bar, erases it, then prints the summary; `--quiet`
/// prints nothing at all.
#[test]
fn the_progress_bar_stays_silent_when_standard_error_is_not_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let tex = dir.path().join("tex");
    fs::create_dir(&tex).unwrap();
    for k in 0..6 {
        write_gray8(&tex.join(format!("t{k}.png")), 64, 64, k);
    }
    let out = dir.path().join("out");
    let r = run(&["convert", s(&tex), "-o", s(&out), "--border", "clamp"]);
    assert!(r.status.success());
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr:?}");
    assert!(!stderr.contains(['\r', '\x1b', '#']), "{stderr:?}");
    assert_eq!(summary(&stderr), (6, 0, 0));
    // One file: silent on success.
    let r = run(&["convert", s(&tex.join("t0.png")), "-o", s(&dir.path().join("one.png")), "--border", "clamp"]);
    assert!(r.status.success() && r.stderr.is_empty(), "{:?}", String::from_utf8_lossy(&r.stderr));

    let terminal =
        on_a_terminal(&["convert", s(&tex), "-o", s(&dir.path().join("tty")), "--border", "clamp", "--jobs", "1"])
            .expect("the terminal half needs util-linux's `script` command to give the run a terminal");
    assert!(terminal.contains("/6 files"), "a terminal shows the bar: {terminal:?}");
    let (bar, after) = terminal.rsplit_once("\r\x1b[2K").expect("the bar is erased");
    assert!(bar.contains("] ") && bar.contains(" files"), "{bar:?}");
    assert_eq!(summary(after.trim_end()), (6, 0, 0));
    let quiet = on_a_terminal(&["convert", s(&tex), "-o", s(&dir.path().join("q")), "--border", "clamp", "-q"]);
    assert_eq!(quiet.as_deref(), Some(""), "--quiet prints nothing");
}

/// Runs the binary with a terminal as its standard error (through
/// util-linux's `script`), and returns what the terminal got.
fn on_a_terminal(args: &[&str]) -> Option<String> {
    let line: Vec<String> = std::iter::once(env!("CARGO_BIN_EXE_normalfit"))
        .chain(args.iter().copied())
        .map(|a| format!("'{}'", a.replace('\'', r"'\''")))
        .collect();
    // The program's standard output goes to /dev/null: only standard error reaches the terminal.
    let command = format!("{} >/dev/null", line.join(" "));
    let r = Command::new("script").args(["-qec", &command, "/dev/null"]).stdin(Stdio::null()).output().ok()?;
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    Some(String::from_utf8_lossy(&r.stdout).replace("\r\n", "\n"))
}

#[test]
fn alpha_holds_the_input_height_or_one_and_the_colour_is_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    let stored = write_gray16(&input, 37, 300, |x, y| ((x * 1500 + y * 211 + (x * y) % 900) % 65536) as u16);
    let plain = dir.path().join("plain.png");
    ok(&["convert", s(&input), "-o", s(&plain), "-s", "20"]);
    let plain = image::open(&plain).unwrap().into_rgb16();

    let with_height = dir.path().join("height.png");
    ok(&["convert", s(&input), "-o", s(&with_height), "-s", "20", "--alpha", "height"]);
    let rgba = image::open(&with_height).unwrap();
    assert_eq!(rgba.color(), image::ColorType::Rgba16);
    let rgba = rgba.into_rgba16();
    for (k, (p, q)) in rgba.pixels().zip(plain.pixels()).enumerate() {
        assert_eq!(p.0[..3], q.0, "texel {k}: the colour does not change");
        assert_eq!(p.0[3], stored[k], "texel {k}: alpha is the stored height");
    }
    let opaque = dir.path().join("opaque.png");
    ok(&["convert", s(&input), "-o", s(&opaque), "-s", "20", "--alpha", "one", "--bits", "8"]);
    let opaque = image::open(&opaque).unwrap();
    assert_eq!(opaque.color(), image::ColorType::Rgba8);
    assert!(opaque.into_rgba8().pixels().all(|p| p.0[3] == 255));

    // The same heights from a TIFF take the whole-image path: same pixels
    // as the streamed PNG.
    let tif = dir.path().join("h.tif");
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(37, 300, stored.clone()).unwrap().save(&tif).unwrap();
    let from_tif = dir.path().join("from_tif.png");
    ok(&["convert", s(&tif), "-o", s(&from_tif), "-s", "20", "--alpha", "height"]);
    assert_eq!(image::open(&from_tif).unwrap().into_rgba16(), rgba);

    // EXR: an A channel, the heights as read.
    let exr = dir.path().join("height.exr");
    ok(&["convert", s(&input), "-o", s(&exr), "-s", "20", "--alpha", "height"]);
    let raster = normalfit::io::read_path(&exr, &Default::default()).unwrap();
    let alpha = raster.plane("A").expect("an A channel").data.to_f32().unwrap();
    for (k, (&a, &v)) in alpha.iter().zip(&stored).enumerate() {
        assert!((a - f32::from(v) / 65535.0).abs() < 1e-7, "texel {k}");
    }
}

#[test]
fn channels_rg_gives_two_channel_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray16(&input, 40, 25, |x, y| ((x * 900 + y * 1300) % 65536) as u16);
    let plain = dir.path().join("plain.png");
    ok(&["convert", s(&input), "-o", s(&plain), "-s", "9"]);
    let rg = dir.path().join("rg.png");
    ok(&["convert", s(&input), "-o", s(&rg), "-s", "9", "--channels", "rg"]);
    let (plain, two) = (image::open(&plain).unwrap().into_rgb16(), image::open(&rg).unwrap().into_rgb16());
    for (p, q) in two.pixels().zip(plain.pixels()) {
        assert_eq!((p.0[0], p.0[1], p.0[2]), (q.0[0], q.0[1], 0), "R and G kept, B zero");
    }
    let exr = dir.path().join("rg.exr");
    ok(&["convert", s(&input), "-o", s(&exr), "-s", "9", "--channels", "rg", "--signed"]);
    let raster = normalfit::io::read_path(&exr, &Default::default()).unwrap();
    let names: Vec<&str> = raster.planes.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["G", "R"]);
    let r = run(&["convert", s(&input), "-o", s(&rg), "--channels", "rg", "--alpha", "height"]);
    assert_eq!(r.status.code(), Some(2), "two channels have no alpha");
}

/// The residual map: RMS distance from the fitted plane divided by the
/// gain, so in height units. A plane plus a checkerboard of amplitude a
/// (stored units / 65535) gives a·√(1 − 1/N⁴) inside, whatever the gain;
/// the plane alone gives 0.
#[test]
fn the_residual_map_is_in_height_units() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (24u32, 20u32);
    let checker = |x: u32, y: u32| if (x + y).is_multiple_of(2) { 2000i32 } else { -2000 };
    let rough = dir.path().join("rough.png");
    write_gray16(&rough, w, h, |x, y| (20000 + 300 * x as i32 + 100 * y as i32 + checker(x, y)) as u16);
    let flat_rough = dir.path().join("flat_rough.png");
    write_gray16(&flat_rough, w, h, |x, y| (30000 + checker(x, y)) as u16);
    let plane = dir.path().join("plane.png");
    write_gray16(&plane, w, h, |x, y| (20000 + 300 * x + 100 * y) as u16);
    let a = 2000.0 / 65535.0;
    let known = a * (1.0f64 - 1.0 / 81.0).sqrt();
    let interior = |k: usize| {
        let (x, y) = (k as u32 % w, k as u32 / w);
        (1..w - 1).contains(&x) && (1..h - 1).contains(&y)
    };
    for (input, fit, scale, want) in [
        (&rough, "vertical", "8", known),
        (&rough, "vertical", "0.5", known),
        (&flat_rough, "orthogonal", "8", known),
        (&plane, "orthogonal", "8", 0.0),
        (&plane, "vertical", "3", 0.0),
    ] {
        let what = format!("{} {fit} -s {scale}", input.display());
        let normals = dir.path().join("n.png");
        let png = dir.path().join("r.png");
        let args = ["-s", scale, "--fit", fit, "--border", "clamp"];
        let mut full = vec!["convert", s(input), "-o", s(&normals), "--residual", s(&png)];
        full.extend(args);
        ok(&full);
        let map = image::open(&png).unwrap();
        assert_eq!(map.color(), image::ColorType::L16, "{what}");
        let map = map.into_luma16();
        for (k, p) in map.pixels().enumerate().filter(|(k, _)| interior(*k)) {
            let expect = (65535.0 * want).round();
            assert!((f64::from(p.0[0]) - expect).abs() <= 1.0, "{what} texel {k}: {} vs {expect}", p.0[0]);
        }
        let exr = dir.path().join("r.exr");
        let mut full = vec!["convert", s(input), "-o", s(&normals), "--residual", s(&exr)];
        full.extend(args);
        ok(&full);
        let raster = normalfit::io::read_path(&exr, &Default::default()).unwrap();
        let values = raster.plane("Y").expect("channel Y").data.to_f32().unwrap();
        for (k, &v) in values.iter().enumerate().filter(|(k, _)| interior(*k)) {
            assert!((f64::from(v) - want).abs() < 1e-6, "{what} texel {k}: {v} vs {want}");
        }
        // The residual reads the image whole; its normal map is the streamed one.
        let streamed = dir.path().join("streamed.png");
        let mut full = vec!["convert", s(input), "-o", s(&streamed)];
        full.extend(args);
        ok(&full);
        assert_eq!(image::open(&streamed).unwrap().into_rgb16(), image::open(&normals).unwrap().into_rgb16());
    }
}

#[test]
fn residual_maps_of_a_batch_go_into_a_folder_and_never_over_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let tex = dir.path().join("tex");
    fs::create_dir_all(tex.join("sub")).unwrap();
    write_gray8(&tex.join("a.png"), 8, 8, 1);
    write_gray8(&tex.join("sub/b.png"), 8, 8, 2);
    let (out, res) = (dir.path().join("out"), dir.path().join("res"));
    ok(&["convert", s(&tex), "-r", "-o", s(&out), "--residual", s(&res)]);
    assert_eq!(tree(&res), ["a_residual.png", "sub/b_residual.png"]);
    assert_eq!(tree(&out), ["a_normal.png", "sub/b_normal.png"]);
    // --overwrite never keeps both outputs; a missing residual is made alone.
    fs::remove_file(res.join("a_residual.png")).unwrap();
    let before = fs::read(out.join("a_normal.png")).unwrap();
    let stderr = ok(&["convert", s(&tex), "-r", "-o", s(&out), "--residual", s(&res), "--overwrite", "never"]);
    assert_eq!(summary(&stderr), (1, 1, 0));
    assert!(res.join("a_residual.png").exists());
    assert_eq!(fs::read(out.join("a_normal.png")).unwrap(), before);

    let input = tex.join("a.png");
    let original = fs::read(&input).unwrap();
    let r = run(&["convert", s(&input), "-o", s(&dir.path().join("n.png")), "--residual", s(&input)]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("never writes over an input"));
    assert_eq!(fs::read(&input).unwrap(), original);
    let same = dir.path().join("same.png");
    let r = run(&["convert", s(&input), "-o", s(&same), "--residual", s(&same)]);
    assert_eq!(r.status.code(), Some(2));
    assert!(!same.exists());
}
