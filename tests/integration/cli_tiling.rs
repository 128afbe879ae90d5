//! `normalfit tiling` and the tiling-aware parts of `convert`, as run from
//! the command line: verdicts, JSON Lines, exit codes, previews, the wrap
//! warning and `--border auto`.

use crate::common;

use std::f64::consts::TAU;
use std::path::Path;
use std::process::Output;

use common::cli::{run, s};

/// Periodic along x with `px` cycles; along y periodic when `tiles_y`,
/// else a slow drift that makes the last row unlike the first.
fn write_height(path: &Path, n: u32, tiles_y: bool) {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(n, n, |x, y| {
        let (u, v) = (x as f64 / n as f64, y as f64 / n as f64);
        let mut h =
            0.5 + 0.2 * (TAU * (3.0 * u + 2.0 * v)).sin() + 0.1 * (TAU * (7.0 * u)).cos() * (TAU * 5.0 * v).sin();
        if !tiles_y {
            h = 0.3 * h + 0.6 * v;
        }
        image::Luma([(h.clamp(0.0, 1.0) * 65535.0).round() as u16])
    });
    img.save(path).unwrap();
}

fn json(out: &Output) -> Vec<String> {
    String::from_utf8_lossy(&out.stdout).lines().map(str::to_owned).collect()
}

#[test]
fn verdicts_exit_codes_and_json_lines() {
    let dir = tempfile::tempdir().unwrap();
    let (good, half) = (dir.path().join("good.png"), dir.path().join("half.png"));
    write_height(&good, 96, true);
    write_height(&half, 96, false);

    let r = run(&["tiling", "--json", s(&good)]);
    assert_eq!(r.status.code(), Some(0), "{}", String::from_utf8_lossy(&r.stderr));
    let lines = json(&r);
    assert_eq!(lines.len(), 1);
    assert!(lines[0].contains("\"width\": 96") && lines[0].contains("\"seamless\": true"), "{}", lines[0]);

    let r = run(&["tiling", "--json", s(&good), s(&half)]);
    assert_eq!(r.status.code(), Some(1), "one image has a seam");
    let lines = json(&r);
    assert_eq!(lines.len(), 2, "one JSON object per image, per line");
    assert!(lines[1].contains("\"x\": {\"score\":") && lines[1].ends_with("\"seamless\": false}"), "{}", lines[1]);
    assert!(lines[1].contains("\"y\": {\"score\":") && lines[1].contains("\"seamless\": false}, \"seamless\""));

    let text = run(&["tiling", s(&half)]);
    let line = String::from_utf8_lossy(&text.stdout);
    assert!(line.contains("half.png") && line.contains("does not tile") && line.contains("y "), "{line}");

    let missing = dir.path().join("missing.png");
    let r = run(&["tiling", s(&good), s(&missing)]);
    assert_eq!(r.status.code(), Some(2), "an error outranks a seam");
    assert_eq!(json(&r).len(), 1, "the readable image is still reported");
    assert!(String::from_utf8_lossy(&r.stderr).contains("missing.png"));

    // A high enough threshold accepts the seam.
    assert_eq!(run(&["tiling", "--threshold", "1000", s(&half)]).status.code(), Some(0));
    // A threshold that is no positive number is refused by the library's
    // rule, in one line naming it (a negative number is a value, not a flag).
    for bad in ["-1", "0"] {
        let r = run(&["tiling", "--threshold", bad, s(&half)]);
        assert_eq!(r.status.code(), Some(2), "{bad}");
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert!(stderr.contains(&format!("--threshold must be positive, got {bad}")), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
    }
}

/// Every `--json` line is one JSON object (parsed here by a JSON parser,
/// not by matching text) holding the library's verdict: the fields the
/// contract lists, the path as given even with quotes, backslashes and
/// control characters in it, and the scores to four decimals.
#[test]
fn json_lines_parse_and_hold_the_librarys_report() {
    use normalfit::tiling::{TilingOptions, check};
    let dir = tempfile::tempdir().unwrap();
    let (good, odd) = (dir.path().join("good.png"), dir.path().join("we\"ird\\na\tme.png"));
    write_height(&good, 80, true);
    write_height(&odd, 64, false);
    let r = run(&["tiling", "--json", s(&good), s(&odd)]);
    assert_eq!(r.status.code(), Some(1), "{}", String::from_utf8_lossy(&r.stderr));
    let lines = json(&r);
    assert_eq!(lines.len(), 2);
    for (line, path, n) in [(&lines[0], &good, 80), (&lines[1], &odd, 64)] {
        let v: serde_json::Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{e}: {line}"));
        let keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
        let mut want = ["path", "width", "height", "kind", "x", "y", "seamless"];
        want.sort_unstable();
        assert_eq!(keys, want, "{line}");
        assert_eq!(v["path"], s(path), "{line}");
        assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(n), Some(n)), "{line}");
        assert_eq!(v["kind"], "height", "{line}");

        let img = image::open(path).unwrap().into_luma16();
        let heights: Vec<f32> = img.as_raw().iter().map(|&v| f32::from(v) / 65535.0).collect();
        let report = check(&[&heights], n as usize, n as usize, &TilingOptions::default()).unwrap();
        for (axis, want) in [("x", report.x), ("y", report.y)] {
            let score = v[axis]["score"].as_f64().unwrap();
            assert!((score - want.score).abs() <= 0.5e-4, "{axis}: {score} vs {}: {line}", want.score);
            assert_eq!(v[axis]["seamless"], want.seamless, "{axis}: {line}");
        }
        assert_eq!(v["seamless"], report.seamless(), "{line}");
    }
    assert!(
        lines[1].contains(r#""path": "#) && lines[1].contains(r#""score": "#),
        "a space after each colon: {}",
        lines[1]
    );
}

#[test]
fn previews_put_both_seams_in_the_middle() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_height(&input, 64, false);
    let (plain, lit) = (dir.path().join("p.png"), dir.path().join("l.png"));
    let r = run(&["tiling", s(&input), "--preview", s(&plain), "--preview-lit", s(&lit)]);
    assert_eq!(r.status.code(), Some(1));
    let original = image::open(&input).unwrap().to_luma16();
    let preview = image::open(&plain).unwrap().to_rgb8();
    assert_eq!(preview.dimensions(), (64, 64));
    // The preview's top-left is the original's centre, stretched to 8 bits:
    // order is kept, so compare the ranks of a few texels.
    let at = |x, y| original.get_pixel((x + 32) % 64, (y + 32) % 64).0[0];
    for (a, b) in [((0, 0), (10, 40)), ((5, 31), (5, 33)), ((63, 2), (20, 20))] {
        let (pa, pb) = (preview.get_pixel(a.0, a.1).0[0], preview.get_pixel(b.0, b.1).0[0]);
        if at(a.0, a.1) + 600 < at(b.0, b.1) {
            assert!(pa < pb, "{a:?} {b:?}");
        }
    }
    let lit = image::open(&lit).unwrap().to_rgb8();
    assert_eq!(lit.dimensions(), (64, 64));
    // The y seam of a map that drifts upward is a cliff, lit unlike its
    // neighbours: it now runs across the middle row.
    let row_mean = |y: u32| (0..64).map(|x| lit.get_pixel(x, y).0[0] as f64).sum::<f64>() / 64.0;
    let seam = (row_mean(31) - row_mean(32)).abs().max((row_mean(32) - row_mean(33)).abs());
    let inside = (row_mean(10) - row_mean(11)).abs();
    assert!(seam > 3.0 * inside + 1.0, "seam step {seam}, inside step {inside}");
}

#[test]
fn convert_warns_about_wrap_on_a_seam_and_auto_mirrors_there() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_height(&input, 64, false);
    let out = dir.path().join("n.png");
    let r = run(&["convert", s(&input), "-o", s(&out)]);
    assert!(r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("warning") && err.contains("along y") && !err.contains("along x"), "{err}");
    assert!(err.contains("--border clamp") && err.contains("mirror"), "{err}");

    let auto = dir.path().join("auto.png");
    let r = run(&["convert", s(&input), "-o", s(&auto), "--border", "auto"]);
    assert!(r.status.success() && r.stderr.is_empty(), "{}", String::from_utf8_lossy(&r.stderr));
    let explicit = dir.path().join("explicit.png");
    assert!(run(&["convert", s(&input), "-o", s(&explicit), "--border", "wrap,mirror"]).status.success());
    assert_eq!(image::open(&auto).unwrap().to_rgb16(), image::open(&explicit).unwrap().to_rgb16());

    // A map that tiles gets no warning.
    let good = dir.path().join("good.png");
    write_height(&good, 64, true);
    let r = run(&["convert", s(&good), "-o", s(&dir.path().join("g.png"))]);
    assert!(r.status.success() && r.stderr.is_empty(), "{}", String::from_utf8_lossy(&r.stderr));
}

/// A reader that closes the pipe before the reports come (`| head`) stops
/// the run quietly: no panic, no signal, no error line.
#[test]
fn a_closed_standard_output_stops_the_reports_without_a_panic() {
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let inputs: Vec<_> = (0..3).map(|k| dir.path().join(format!("h{k}.png"))).collect();
    for input in &inputs {
        write_height(input, 64, true);
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_normalfit"))
        .arg("tiling")
        .args(&inputs)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Closed before the first report is written.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code().is_some(), "ended by a signal: {:?}", out.status);
    assert!(!stderr.contains("panicked") && !stderr.contains("Broken pipe"), "{stderr}");
}
