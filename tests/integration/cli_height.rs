//! `normalfit height` as users run it: `convert -s S` then `height -s S`
//! gives the heights back; the PNG output's range note re-creates the
//! normals; auto convention and 8-bit precision are said; bad input is one
//! line naming the file, exit 2, and no output; a folder of normal maps
//! is a batch (one bad file does not stop the others); standard input to
//! standard output as a filter; help, man page and completions cover every
//! option of the command.

use crate::common;

use std::fs;
use std::path::Path;
use std::process::{Output, Stdio};

use common::cli::{bin, listing, run, s, summary_counts};
use normalfit::io::{ReadOptions, read_path};

fn ok(out: &Output) -> String {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The one error line of a failed run; exit code 2.
fn error_line(out: &Output) -> String {
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!err.contains("panicked"), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "want one error line, got {err:?}");
    lines[0].to_string()
}

/// A 16-bit gray height map: waves of whole periods (it tiles).
fn write_heights(path: &Path, w: u32, h: u32) -> Vec<f64> {
    let tau = std::f64::consts::TAU;
    let value = |x: u32, y: u32| {
        let (u, v) = (f64::from(x) / f64::from(w), f64::from(y) / f64::from(h));
        0.5 + 0.2 * (tau * (2.0 * u + v)).sin() + 0.15 * (tau * 5.0 * v + 1.0).cos() + 0.1 * (tau * 7.0 * u).sin()
    };
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
        image::Luma([(value(x, y) * 65535.0).round() as u16])
    });
    img.save(path).unwrap();
    img.into_raw().iter().map(|&v| f64::from(v) / 65535.0).collect()
}

fn plane(path: &Path, name: &str) -> Vec<f64> {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    let p = raster.plane(name).unwrap_or_else(|| panic!("{}: no {name}", path.display()));
    (0..p.data.len()).map(|k| p.data.height(k).unwrap()).collect()
}

fn relative_error(original: &[f64], back: &[f64]) -> f64 {
    let mean = original.iter().sum::<f64>() / original.len() as f64;
    let (lo, hi) = original.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    original.iter().zip(back).fold(0.0f64, |m, (a, b)| m.max((a - mean - b).abs())) / (hi - lo)
}

#[test]
fn convert_then_height_gives_the_heights_back() {
    let dir = tempfile::tempdir().unwrap();
    let (hmap, nmap, back) = (dir.path().join("h.png"), dir.path().join("n.exr"), dir.path().join("back.exr"));
    let original = write_heights(&hmap, 64, 48);
    for (fit, scale) in [("vertical", "12"), ("orthogonal", "4")] {
        ok(&run(&["convert", s(&hmap), "-o", s(&nmap), "-s", scale, "-n", "5", "--fit", fit]));
        let err = ok(&run(&["height", s(&nmap), "-o", s(&back), "-s", scale, "-n", "5", "--fit", fit]));
        assert!(err.is_empty(), "no notes for a float map with a fixed convention: {err}");
        let e = relative_error(&original, &plane(&back, "Y"));
        assert!(e < 1e-4, "{fit}: {e:e}");
    }
}

#[test]
fn the_png_output_says_its_range_and_how_to_make_the_normals_again() {
    let dir = tempfile::tempdir().unwrap();
    let (hmap, nmap) = (dir.path().join("h.png"), dir.path().join("n.exr"));
    write_heights(&hmap, 40, 40);
    ok(&run(&["convert", s(&hmap), "-o", s(&nmap), "-s", "6", "--fit", "vertical"]));
    let out = ok(&run(&["height", s(&nmap), "--fit", "vertical", "-s", "6", "--format", "png"]));
    let png = dir.path().join("n_height.png");
    assert!(png.is_file(), "<stem>_height.png beside the input: {out}");
    let line = out.lines().find(|l| l.contains("re-creates the normals")).unwrap_or_else(|| panic!("{out}"));
    let command = line.split('`').nth(1).unwrap();
    let args: Vec<&str> = command.split(' ').skip(1).collect();
    let again = dir.path().join("again.exr");
    let mut full = args.clone();
    full.extend([s(&png), "-o", s(&again)]);
    ok(&run(&full));
    for c in ["R", "G", "B"] {
        let (a, b) = (plane(&nmap, c), plane(&again, c));
        let worst = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(worst < 2e-3, "{c}: {worst}");
    }
    let stored = plane(&png, "Y");
    let (lo, hi) = stored.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    assert_eq!((lo, hi), (0.0, 1.0));
}

#[test]
fn auto_says_the_convention_and_8_bit_says_the_precision_lost() {
    let dir = tempfile::tempdir().unwrap();
    let (hmap, nmap) = (dir.path().join("h.png"), dir.path().join("n.png"));
    write_heights(&hmap, 48, 32);
    ok(&run(&["convert", s(&hmap), "-o", s(&nmap), "--bits", "8", "-s", "8", "--convention", "directx"]));
    let out = ok(&run(&["height", s(&nmap), "-s", "8", "--convention", "auto"]));
    assert!(out.contains("convention directx (auto: relative curl"), "{out}");
    assert!(out.contains("warning") && out.contains("8-bit normals lose precision"), "{out}");
    assert!(dir.path().join("n_height.exr").is_file());
    let quiet = ok(&run(&["height", s(&nmap), "-s", "8", "--convention", "auto", "--quiet"]));
    assert!(quiet.is_empty(), "{quiet}");
}

#[test]
fn bad_input_is_one_line_naming_the_file_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let junk = dir.path().join("junk.png");
    fs::write(&junk, b"not a png at all").unwrap();
    let line = error_line(&run(&["height", s(&junk), "-o", s(&dir.path().join("out.exr"))]));
    assert!(line.starts_with(&format!("normalfit: {}: ", junk.display())), "{line}");
    let gray = dir.path().join("gray.png");
    write_heights(&gray, 8, 8);
    let line = error_line(&run(&["height", s(&gray), "-o", s(&dir.path().join("out.exr"))]));
    assert!(line.contains(s(&gray)) && line.contains("R, G and B"), "{line}");
    let line = error_line(&run(&["height", s(&gray), "--border", "auto"]));
    assert!(line.contains("--border"), "{line}");
    let line = error_line(&run(&["height", s(&gray), "-o", s(&dir.path().join("out.jpg"))]));
    assert!(line.contains("out.jpg"), "{line}");
    let names: Vec<_> = fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names.len(), 2, "nothing written, no temporary file left: {names:?}");
}

#[test]
fn the_output_is_never_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let (hmap, nmap) = (dir.path().join("h.png"), dir.path().join("n.exr"));
    write_heights(&hmap, 16, 16);
    ok(&run(&["convert", s(&hmap), "-o", s(&nmap)]));
    let before = fs::read(&nmap).unwrap();
    let line = error_line(&run(&["height", s(&nmap), "-o", s(&nmap)]));
    assert!(line.contains("never writes over an input"), "{line}");
    assert_eq!(fs::read(&nmap).unwrap(), before);
}

#[test]
fn a_folder_is_a_batch_and_one_bad_file_does_not_stop_the_others() {
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps");
    fs::create_dir_all(maps.join("sub")).unwrap();
    let hmap = dir.path().join("h.png");
    write_heights(&hmap, 32, 24);
    for (name, scale) in [("a.exr", "4"), ("sub/c.exr", "4")] {
        ok(&run(&["convert", s(&hmap), "-o", s(&maps.join(name)), "-s", scale, "--fit", "vertical"]));
    }
    fs::write(maps.join("b.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let out = dir.path().join("heights");
    let r = run(&["height", s(&maps), "-r", "-o", s(&out), "-s", "4", "--fit", "vertical", "--jobs", "2"]);
    assert_eq!(r.status.code(), Some(2), "{}", String::from_utf8_lossy(&r.stderr));
    let err = String::from_utf8_lossy(&r.stderr).into_owned();
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 2, "one error line and the summary: {err}");
    assert!(lines[0].starts_with(&format!("normalfit: {}: ", maps.join("b.png").display())), "{err}");
    assert_eq!(summary_counts(lines[1]).map(|c| (c.1, c.2, c.3)), Some((2, 0, 1)), "{err}");
    assert_eq!(listing(&out), ["a_height.exr", "sub"]);
    assert_eq!(listing(&out.join("sub")), ["c_height.exr"]);
    // Each is what the file alone gives, and gives the heights back.
    let alone = dir.path().join("alone.exr");
    ok(&run(&["height", s(&maps.join("a.exr")), "-o", s(&alone), "-s", "4", "--fit", "vertical"]));
    assert_eq!(fs::read(&alone).unwrap(), fs::read(out.join("a_height.exr")).unwrap());
    let original = write_heights(&hmap, 32, 24);
    let e = relative_error(&original, &plane(&out.join("sub").join("c_height.exr"), "Y"));
    assert!(e < 1e-4, "{e:e}");
    // Beside the inputs, as PNG; the outputs are not inputs the next time,
    // and --overwrite never skips them.
    let r = run(&["height", s(&maps), "-s", "4", "--fit", "vertical", "--format", "png", "-q"]);
    assert_eq!(r.status.code(), Some(2));
    assert_eq!(listing(&maps), ["a.exr", "a_height.png", "b.png", "sub"]);
    let r = run(&["height", s(&maps), "-s", "4", "--fit", "vertical", "--format", "png", "--overwrite", "never"]);
    let err = String::from_utf8_lossy(&r.stderr).into_owned();
    let last = err.lines().last().unwrap_or_default();
    assert_eq!(summary_counts(last).map(|c| (c.1, c.2, c.3)), Some((0, 1, 1)), "{err}");
}

#[test]
fn standard_input_to_standard_output_is_a_filter() {
    let dir = tempfile::tempdir().unwrap();
    let (hmap, nmap, file_out) = (dir.path().join("h.png"), dir.path().join("n.png"), dir.path().join("f.exr"));
    write_heights(&hmap, 24, 16);
    ok(&run(&["convert", s(&hmap), "-o", s(&nmap), "--bits", "16", "-s", "3"]));
    ok(&run(&["height", s(&nmap), "-o", s(&file_out), "-s", "3"]));
    let piped = bin()
        .args(["height", "-", "-s", "3", "-q"])
        .stdin(fs::File::open(&nmap).unwrap())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert!(piped.status.success(), "{}", String::from_utf8_lossy(&piped.stderr));
    assert_eq!(piped.stdout, fs::read(&file_out).unwrap(), "standard input goes to standard output, as EXR");
    let png = bin()
        .args(["height", "-", "-o", "-", "--format", "png", "-s", "3"])
        .stdin(fs::File::open(&nmap).unwrap())
        .output()
        .unwrap();
    assert!(png.status.success());
    assert_eq!(&png.stdout[..4], b"\x89PNG");
    let err = String::from_utf8_lossy(&png.stderr);
    assert!(err.contains("<standard output>: heights") && err.contains("re-creates the normals"), "{err}");
    // Bad input: one line naming standard input, exit 2, nothing written.
    let bad = bin()
        .args(["height", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .and_then(|mut child| {
            use std::io::Write;
            child.stdin.take().unwrap().write_all(b"junk")?;
            child.wait_with_output()
        })
        .unwrap();
    let line = error_line(&bad);
    assert!(line.starts_with("normalfit: <standard input>: "), "{line}");
    assert!(bad.stdout.is_empty());
    let line = error_line(&run(&["height", "-", "-", "-o", "x.exr"]));
    assert!(line.contains("standard input"), "{line}");
}

#[test]
fn help_man_page_and_completions_cover_height() {
    let help = run(&["height", "--help"]);
    let text = String::from_utf8_lossy(&help.stdout);
    assert!(help.status.success() && text.contains("--model") && text.contains("--convention"), "{text}");
    let top = String::from_utf8_lossy(&run(&["--help"]).stdout).into_owned();
    assert!(top.contains("height"), "{top}");
    let man = String::from_utf8_lossy(&run(&["man"]).stdout).into_owned();
    assert!(man.contains("NORMALFIT HEIGHT") && man.contains("Frankot"), "{}", &man[..man.len().min(400)]);
    let bash = String::from_utf8_lossy(&run(&["completions", "bash"]).stdout).into_owned();
    assert!(bash.contains("normalfit__subcmd__height") && bash.contains("generic"), "bash completions lack height");
}

/// The long options `normalfit height --help` lists.
fn height_options() -> Vec<String> {
    let help = run(&["height", "--help"]);
    assert!(help.status.success());
    let text = String::from_utf8_lossy(&help.stdout).into_owned();
    let mut options: Vec<String> = text
        .lines()
        .filter_map(|l| l.trim_start().split([' ', ',']).find(|w| w.starts_with("--")).map(str::to_owned))
        .filter(|o| o != "--help")
        .collect();
    options.dedup();
    options
}

#[test]
fn help_man_page_and_completions_cover_every_option_of_height() {
    let options = height_options();
    // The options the command reads, each listed by --help.
    for wanted in [
        "--output",
        "--format",
        "--model",
        "--signed",
        "--patch",
        "--scale",
        "--relief",
        "--invert",
        "--fit",
        "--border",
        "--convention",
        "--max-texels",
        "--layer",
        "--recursive",
        "--jobs",
        "--overwrite",
        "--quiet",
    ] {
        assert!(options.iter().any(|o| o == wanted), "--help lacks {wanted}: {options:?}");
    }
    let dir = tempfile::tempdir().unwrap();
    let pages = dir.path().join("man1");
    ok(&run(&["man", "--out", s(&pages)]));
    let page = fs::read_to_string(pages.join("normalfit-height.1")).unwrap();
    let page = page.replace("\\-", "-");
    let bash = String::from_utf8_lossy(&run(&["completions", "bash"]).stdout).into_owned();
    let height_block = bash.split("normalfit__subcmd__height)").nth(1).unwrap_or_else(|| panic!("no height in bash"));
    let height_block = height_block.split("\n        normalfit__").next().unwrap();
    for option in &options {
        assert!(page.contains(option.as_str()), "the man page lacks {option}");
        assert!(height_block.contains(option.as_str()), "bash completion of height lacks {option}");
    }
    let fish = String::from_utf8_lossy(&run(&["completions", "fish"]).stdout).into_owned();
    let zsh = String::from_utf8_lossy(&run(&["completions", "zsh"]).stdout).into_owned();
    let fish: Vec<&str> = fish.lines().filter(|l| l.contains("__fish_normalfit_using_subcommand height\"")).collect();
    for option in &options {
        let name = option.trim_start_matches("--");
        let named = |l: &&str| l.split(' ').collect::<Vec<_>>().windows(2).any(|w| w == ["-l", name]);
        assert!(fish.iter().any(named), "fish completion of height lacks {option}");
        let zsh = zsh.split("(height)").nth(1).and_then(|b| b.split(";;").next()).unwrap_or_default();
        assert!(zsh.contains(&format!("{option}=[")) || zsh.contains(&format!("{option}[")), "zsh lacks {option}");
    }
    let mut models: Vec<String> = {
        let script = dir.path().join("normalfit.bash");
        fs::write(&script, &bash).unwrap();
        let program = format!(
            "source '{}'; COMP_WORDS=(normalfit height --model ''); COMP_CWORD=3; _normalfit normalfit '' --model; \
             printf '%s\\n' \"${{COMPREPLY[@]}}\"",
            script.display()
        );
        let out = std::process::Command::new("bash").args(["--norc", "-c", &program]).output().unwrap();
        String::from_utf8_lossy(&out.stdout).lines().map(str::to_owned).collect()
    };
    models.sort();
    assert!(models.iter().any(|m| m == "exact") && models.iter().any(|m| m == "generic"), "{models:?}");
}

/// A gain so small that the heights leave the float range is an error
/// naming the output, never infinite heights written with exit 0.
#[test]
fn heights_past_the_floats_range_are_an_error_not_infinities() {
    let dir = tempfile::tempdir().unwrap();
    let (hmap, nmap) = (dir.path().join("h.png"), dir.path().join("n.png"));
    write_heights(&hmap, 32, 24);
    ok(&run(&["convert", s(&hmap), "-o", s(&nmap), "-s", "4"]));
    // 1e-40: past f32's ±3.4e38, within f64's; EXR and TIFF hold f32.
    for ext in ["exr", "tif"] {
        let out = dir.path().join(format!("back.{ext}"));
        let line = error_line(&run(&["height", s(&nmap), "-o", s(&out), "-s", "1e-40"]));
        assert!(
            line.starts_with(&format!("normalfit: {}: ", out.display())) && line.contains("larger scale"),
            "{line}"
        );
        assert!(!out.exists());
    }
    // The 16-bit PNG stores the heights scaled to their range: it holds them.
    let png = dir.path().join("back.png");
    ok(&run(&["height", s(&nmap), "-o", s(&png), "-s", "1e-40"]));
    // 1e-320 (subnormal): past f64's range too, whatever the format.
    let line = error_line(&run(&["height", s(&nmap), "-o", s(&dir.path().join("tiny.png")), "-s", "1e-320"]));
    assert!(line.contains("overflow") && line.contains("larger scale"), "{line}");
    assert_eq!(listing(dir.path()), ["back.png", "h.png", "n.png"]);
}

/// Clamp with a patch whose solve would grow with N² (2048 × 4 at
/// N = 255: a band of 254 along the long axis, past the banded path's, and
/// conjugate gradients past the limit of time) is refused before any
/// solve: one line naming the estimate and the limit, exit 2, nothing
/// written; mirror at the same N (a transform) runs.
#[test]
fn clamp_past_the_limit_of_time_is_one_line_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (hmap, nmap, out) = (dir.path().join("h.png"), dir.path().join("n.exr"), dir.path().join("back.exr"));
    write_heights(&hmap, 2048, 4);
    ok(&run(&["convert", s(&hmap), "-o", s(&nmap), "-n", "255", "--border", "clamp"]));
    let line = error_line(&run(&["height", s(&nmap), "-o", s(&out), "-n", "255", "--border", "clamp"]));
    assert!(line.contains("2048 × 4") && line.contains("past the limit of 2.1e9"), "{line}");
    assert!(line.contains("--border mirror or wrap"), "{line}");
    assert!(!out.exists(), "nothing written");
    ok(&run(&["height", s(&nmap), "-o", s(&out), "-n", "255", "--border", "mirror"]));
}

/// Heights with a block of nodata (0) texels at x 10..14, y 8..12.
fn write_heights_with_holes(path: &Path, w: u32, h: u32) -> (Vec<f64>, Vec<bool>) {
    let heights = write_heights(path, w, h);
    let hole = |k: usize| (10..14).contains(&(k % w as usize)) && (8..12).contains(&(k / w as usize));
    let holes: Vec<bool> = (0..heights.len()).map(hole).collect();
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
        let k = (y * w + x) as usize;
        image::Luma([if holes[k] { 0 } else { (heights[k] * 65535.0).round() as u16 }])
    });
    img.save(path).unwrap();
    (heights, holes)
}

/// `convert --nodata` then `height`: the holes convert wrote (its alpha of
/// validity) come back as holes without asking, NaN in EXR and TIFF and
/// alpha 0 in a PNG, the rest up to a constant; `--holes none` reads
/// every texel, and `--holes MASK` takes a mask's.
#[test]
fn holes_convert_wrote_come_back_as_holes() {
    let dir = tempfile::tempdir().unwrap();
    let (hmap, nmap) = (dir.path().join("h.png"), dir.path().join("n.exr"));
    // Odd sides, not multiples of 3: under wrap at N = 3 the constant is
    // then the only height no patch sees (no alternating heights, no zeros
    // of the box), so the rest comes back up to it.
    let (original, holes) = write_heights_with_holes(&hmap, 47, 41);
    ok(&run(&["convert", s(&hmap), "-o", s(&nmap), "-s", "6", "--nodata", "0"]));
    let back = dir.path().join("back.exr");
    let notes = ok(&run(&["height", s(&nmap), "-o", s(&back), "-s", "6"]));
    assert!(notes.contains("16 of 1927 texels are holes"), "{notes}");
    let found = plane(&back, "Y");
    // Missing texels are the holes and, where a patch had fewer than 3
    // points, none here: exactly the holes.
    for (k, v) in found.iter().enumerate() {
        assert_eq!(v.is_nan(), holes[k], "texel {k}");
    }
    let diffs: Vec<f64> = found.iter().zip(&original).filter(|(b, _)| !b.is_nan()).map(|(b, o)| b - o).collect();
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let spread = diffs.iter().fold(0.0f64, |m, d| m.max((d - mean).abs()));
    assert!(spread < 1e-4, "round trip off by {spread:e}");

    let png = dir.path().join("back.png");
    ok(&run(&["height", s(&nmap), "-o", s(&png), "-s", "6"]));
    let alpha = plane(&png, "A");
    for (k, a) in alpha.iter().enumerate() {
        assert_eq!(*a == 0.0, holes[k], "texel {k}");
    }
    let tif = dir.path().join("back.tif");
    ok(&run(&["height", s(&nmap), "-o", s(&tif), "-s", "6"]));
    let stored = plane(&tif, "Y");
    assert!(stored.iter().zip(&holes).all(|(v, &hole)| v.is_nan() == hole));

    let none = dir.path().join("none.exr");
    ok(&run(&["height", s(&nmap), "-o", s(&none), "-s", "6", "--holes", "none"]));
    assert!(plane(&none, "Y").iter().all(|v| v.is_finite()));

    // A mask: the holes and one more column, white on black.
    let mask = dir.path().join("mask.png");
    let marked = |k: usize| holes[k] || k % 47 == 30;
    image::ImageBuffer::<image::Luma<u8>, Vec<u8>>::from_fn(47, 41, |x, y| {
        image::Luma([if marked((y * 47 + x) as usize) { 255 } else { 0 }])
    })
    .save(&mask)
    .unwrap();
    let masked = dir.path().join("masked.exr");
    ok(&run(&["height", s(&nmap), "-o", s(&masked), "-s", "6", "--holes", s(&mask)]));
    for (k, v) in plane(&masked, "Y").iter().enumerate() {
        assert_eq!(v.is_nan(), marked(k), "texel {k}");
    }
}

/// A mask of the wrong size, or that cannot be read: one line naming the
/// mask, exit 2, nothing written.
#[test]
fn a_bad_mask_is_one_line_naming_it_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (hmap, nmap) = (dir.path().join("h.png"), dir.path().join("n.exr"));
    write_heights(&hmap, 24, 16);
    ok(&run(&["convert", s(&hmap), "-o", s(&nmap)]));
    let small = dir.path().join("small.png");
    image::ImageBuffer::<image::Luma<u8>, Vec<u8>>::new(8, 8).save(&small).unwrap();
    let junk = dir.path().join("junk.png");
    fs::write(&junk, b"not a png").unwrap();
    let out = dir.path().join("out.exr");
    for mask in [&small, &junk] {
        let line = error_line(&run(&["height", s(&nmap), "-o", s(&out), "--holes", s(mask)]));
        assert!(line.contains(&format!("holes mask {}", mask.display())), "{line}");
    }
    let line = error_line(&run(&["height", s(&nmap), "-o", s(&out), "--holes", s(&small)]));
    assert!(line.contains("8 × 8 texels, the normal map 24 × 16"), "{line}");
    assert!(!out.exists());
    assert_eq!(listing(dir.path()).len(), 4, "nothing written: {:?}", listing(dir.path()));
}
