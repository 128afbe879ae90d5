//! `normalfit height` as users run it: `convert -s S` then `height -s S`
//! gives the heights back; the PNG output's range note re-creates the
//! normals; auto convention and 8-bit precision are said; bad input is one
//! line naming the file, exit 2, and no output; help, man page and
//! completions cover the command.

mod common;

use std::fs;
use std::path::Path;
use std::process::Output;

use common::cli::{run, s};
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
    let line = error_line(&run(&["height", s(&gray), "-o", s(&dir.path().join("out.tif"))]));
    assert!(line.contains("out.tif"), "{line}");
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
