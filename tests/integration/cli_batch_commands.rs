//! The batch driver as `shade` and `tiling` use it (`convert`'s batches are
//! tests/integration/cli_batch.rs): folders searched (recursively, layout kept under
//! `-o DIR`), one bad file among good ones (the others still done, exit 2,
//! one error line naming it), `--jobs 2` giving what `--jobs 1` gives,
//! `--overwrite never`, the summary line and `tiling`'s exit codes and
//! line order.

use crate::common;

use std::f64::consts::TAU;
use std::fs;
use std::path::Path;
use std::process::Output;

use common::cli::{listing, run, s, summary_counts};

/// A 16-bit height map, periodic along x; along y periodic when `tiles_y`,
/// else with a drift that makes the last row unlike the first (a seam).
/// `seed` shifts the phase so that every file differs.
fn write_height(path: &Path, n: u32, tiles_y: bool, seed: u32) {
    let phase = f64::from(seed) * 0.37;
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(n, n, |x, y| {
        let (u, v) = (x as f64 / n as f64, y as f64 / n as f64);
        let mut h = 0.5 + 0.2 * (TAU * (3.0 * u + 2.0 * v) + phase).sin() + 0.1 * (TAU * 5.0 * v).sin();
        if !tiles_y {
            h = 0.3 * h + 0.6 * v;
        }
        image::Luma([(h.clamp(0.0, 1.0) * 65535.0).round() as u16])
    });
    img.save(path).unwrap();
}

/// A file named .png that is not one.
fn write_broken(path: &Path) {
    fs::write(path, b"\x89PNG\r\n\x1a\nnot really").unwrap();
}

/// The error lines of a run: standard error without warnings and the
/// summary line.
fn errors(r: &Output) -> Vec<String> {
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!err.contains("panicked"), "{err}");
    err.lines()
        .filter(|l| !l.starts_with("normalfit: warning: ") && summary_counts(l).is_none())
        .map(str::to_owned)
        .collect()
}

/// The summary line's (verb, done, skipped, failed): the last line.
fn summary(r: &Output) -> (String, usize, usize, usize) {
    let err = String::from_utf8_lossy(&r.stderr);
    let last = err.lines().last().unwrap_or_default();
    let (verb, d, k, f) = summary_counts(last).unwrap_or_else(|| panic!("no summary line in {err:?}"));
    (verb.to_string(), d, k, f)
}

/// A folder `tex` of good height maps (two tiling, one with a seam in
/// `sub/`) and one broken file between them by name.
fn texture_folder(root: &Path) -> std::path::PathBuf {
    let tex = root.join("tex");
    fs::create_dir_all(tex.join("sub")).unwrap();
    write_height(&tex.join("a.png"), 32, true, 1);
    write_broken(&tex.join("b.png"));
    write_height(&tex.join("c.png"), 32, true, 2);
    write_height(&tex.join("sub").join("d.png"), 32, false, 3);
    tex
}

#[test]
fn shade_does_a_folder_and_one_bad_file_is_one_line_while_the_others_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let tex = texture_folder(dir.path());
    let out = dir.path().join("lit");
    let r = run(&["shade", s(&tex), "-r", "-o", s(&out)]);
    assert_eq!(r.status.code(), Some(2), "{}", String::from_utf8_lossy(&r.stderr));
    let errors = errors(&r);
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(errors[0].starts_with(&format!("normalfit: {}: ", tex.join("b.png").display())), "{errors:?}");
    assert_eq!(listing(&out), ["a_lit.png", "c_lit.png", "sub"]);
    assert_eq!(listing(&out.join("sub")), ["d_lit.png"]);
    assert_eq!(summary(&r), ("shaded".into(), 3, 0, 1));
    // Each is what shading the file alone gives.
    let alone = dir.path().join("alone.png");
    assert!(run(&["shade", s(&tex.join("sub").join("d.png")), "-o", s(&alone)]).status.success());
    assert_eq!(fs::read(&alone).unwrap(), fs::read(out.join("sub").join("d_lit.png")).unwrap());

    // Without -r the subfolder is not searched; lit views beside the
    // inputs are outputs, not inputs, the next time.
    let r = run(&["shade", s(&tex), "--quiet"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(tex.join("a_lit.png").exists() && !tex.join("sub").join("d_lit.png").exists());
    let r = run(&["shade", s(&tex)]);
    assert_eq!(summary(&r), ("shaded".into(), 2, 0, 1), "a_lit.png and c_lit.png are not shaded again");
}

#[test]
fn shade_with_two_jobs_writes_what_one_job_writes_and_overwrite_never_skips() {
    let dir = tempfile::tempdir().unwrap();
    let tex = dir.path().join("tex");
    fs::create_dir(&tex).unwrap();
    for k in 0..6 {
        write_height(&tex.join(format!("t{k}.png")), 32, k % 2 == 0, k);
    }
    let mut outputs = Vec::new();
    for jobs in ["1", "2"] {
        let out = dir.path().join(format!("out{jobs}"));
        let r = run(&["shade", s(&tex), "-o", s(&out), "--jobs", jobs, "--border", "clamp"]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        assert_eq!(summary(&r), ("shaded".into(), 6, 0, 0));
        let files: Vec<(String, Vec<u8>)> =
            listing(&out).into_iter().map(|name| (name.clone(), fs::read(out.join(&name)).unwrap())).collect();
        outputs.push(files);
    }
    assert_eq!(outputs[0].len(), 6);
    assert!(outputs[0] == outputs[1], "--jobs 2 wrote other bytes than --jobs 1");

    let out = dir.path().join("out1");
    fs::write(out.join("t3_lit.png"), b"kept").unwrap();
    fs::remove_file(out.join("t4_lit.png")).unwrap();
    let r = run(&["shade", s(&tex), "-o", s(&out), "--overwrite", "never", "--border", "clamp"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(summary(&r), ("shaded".into(), 1, 5, 0));
    assert_eq!(fs::read(out.join("t3_lit.png")).unwrap(), b"kept");
    assert_eq!(fs::read(out.join("t4_lit.png")).unwrap(), outputs[0][4].1);
}

#[test]
fn tiling_checks_a_folder_in_order_and_an_error_outranks_a_seam() {
    let dir = tempfile::tempdir().unwrap();
    let tex = texture_folder(dir.path());
    let r = run(&["tiling", s(&tex), "-r", "--json", "--jobs", "2"]);
    // A seam (sub/d.png) and an error (b.png): the error decides.
    assert_eq!(r.status.code(), Some(2), "{}", String::from_utf8_lossy(&r.stderr));
    let errors = errors(&r);
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(errors[0].starts_with(&format!("normalfit: {}: ", tex.join("b.png").display())), "{errors:?}");
    assert_eq!(summary(&r), ("checked".into(), 3, 0, 1));
    let stdout = String::from_utf8_lossy(&r.stdout);
    let lines: Vec<serde_json::Value> = stdout.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let paths: Vec<&str> = lines.iter().map(|l| l["path"].as_str().unwrap()).collect();
    let want = [tex.join("a.png"), tex.join("c.png"), tex.join("sub").join("d.png")];
    assert_eq!(paths, want.iter().map(|p| s(p)).collect::<Vec<_>>());
    let seamless: Vec<bool> = lines.iter().map(|l| l["seamless"].as_bool().unwrap()).collect();
    assert_eq!(seamless, [true, true, false]);

    // Without the broken file: exit 1 for the seam; without the seam, 0.
    fs::remove_file(tex.join("b.png")).unwrap();
    let r = run(&["tiling", s(&tex), "-r", "--quiet"]);
    assert_eq!(r.status.code(), Some(1), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(r.stderr.is_empty(), "--quiet: no summary line");
    assert_eq!(run(&["tiling", s(&tex)]).status.code(), Some(0), "the seam is in sub/, not searched without -r");
}

#[test]
fn tiling_lines_keep_the_input_order_whatever_the_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let tex = dir.path().join("tex");
    fs::create_dir(&tex).unwrap();
    // A large file first, so that with two jobs the others finish before it.
    for k in 0..8u32 {
        write_height(&tex.join(format!("t{k}.png")), if k == 0 { 512 } else { 16 }, k % 3 != 0, k);
    }
    let one = run(&["tiling", s(&tex), "--json", "--jobs", "1"]);
    let two = run(&["tiling", s(&tex), "--json", "--jobs", "2"]);
    assert_eq!(one.status.code(), Some(1));
    assert_eq!(two.status.code(), Some(1));
    assert_eq!(String::from_utf8_lossy(&one.stdout).lines().count(), 8);
    assert_eq!(String::from_utf8_lossy(&two.stdout), String::from_utf8_lossy(&one.stdout));
}

#[test]
fn tiling_previews_of_a_folder_keep_its_layout_and_overwrite_never_keeps_them() {
    let dir = tempfile::tempdir().unwrap();
    let tex = texture_folder(dir.path());
    fs::remove_file(tex.join("b.png")).unwrap();
    let previews = dir.path().join("previews");
    let r = run(&["tiling", s(&tex), "-r", "--preview", s(&previews)]);
    assert_eq!(r.status.code(), Some(1), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(listing(&previews), ["a_preview.png", "c_preview.png", "sub"]);
    assert_eq!(listing(&previews.join("sub")), ["d_preview.png"]);

    fs::write(previews.join("a_preview.png"), b"kept").unwrap();
    let r = run(&["tiling", s(&tex), "-r", "--preview", s(&previews), "--overwrite", "never"]);
    assert_eq!(r.status.code(), Some(1));
    assert_eq!(fs::read(previews.join("a_preview.png")).unwrap(), b"kept");
    assert_eq!(String::from_utf8_lossy(&r.stdout).lines().count(), 3, "skipping a preview skips no check");
}
