//! `normalfit blend` and `normalfit check` as users run them: the output
//! equals the library's blend; bad input, sizes that do not divide and
//! an output over an input are one line naming the file, exit 2, no
//! output; `check` exits 0 clean, 1 with a finding, 2 on an error, and
//! its `--json` line has `convention` and `confident`; `--fix` writes the
//! repaired map.

use std::fs;
use std::path::Path;

use crate::common::cli::{run, s};
use normalfit::blend::{BlendOptions, Method, blend};
use normalfit::height::ConventionChoice;
use normalfit::io::{Encoding, ReadOptions, encode_normals};
use normalfit::{Convention, FromNormal, Options, Strength, normal_map, normals};

fn write_map(path: &Path, w: usize, h: usize, k: f64, convention: Convention) -> Vec<[f32; 3]> {
    let tau = std::f64::consts::TAU;
    let heights: Vec<f64> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64 / w as f64, (i / w) as f64 / h as f64);
            0.5 + 0.3 * (tau * k * x).sin() * (tau * (k + 1.0) * y).cos()
        })
        .collect();
    let opts = Options::new().with_convention(convention).with_strength(Strength::Scale(6.0));
    let n = normals(&heights, w, h, &opts).unwrap();
    let texels: Vec<[u16; 3]> = n.iter().map(|v| <[u16; 3]>::from_normal(v.map(f64::from))).collect();
    encode_normals(&texels, None, w, h, &Encoding::png16(), fs::File::create(path).unwrap()).unwrap();
    normal_map::read(path, &ReadOptions::default(), false).unwrap().2
}

fn one_error_line(out: &std::process::Output) -> String {
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(err.lines().count(), 1, "{err}");
    err
}

#[test]
fn cli_blend_writes_the_library_blend_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let (base, detail, dx) = (dir.path().join("base.png"), dir.path().join("detail.png"), dir.path().join("dx.png"));
    let b = write_map(&base, 128, 128, 2.0, Convention::OpenGl);
    let d = write_map(&detail, 64, 64, 5.0, Convention::OpenGl);
    // 128²: enough loops for a confident guess (a 64² map has 3969).
    write_map(&dx, 128, 128, 5.0, Convention::DirectX);
    let out = dir.path().join("out.png");
    let run_ok = run(&["blend", s(&base), s(&detail), "-o", s(&out), "--method", "whiteout"]);
    assert!(run_ok.status.success(), "{}", String::from_utf8_lossy(&run_ok.stderr));
    let opts = BlendOptions::new().with_method(Method::Whiteout).with_convention(ConventionChoice::OpenGl);
    let (want, _) = blend::<f32, [u16; 3]>(&b, (128, 128), &d, (64, 64), &opts).unwrap();
    let raster = normalfit::io::read_path(&out, &ReadOptions::default()).unwrap();
    let got: Vec<f32> = raster.plane("G").unwrap().data.to_f32().unwrap();
    for (k, w) in want.iter().enumerate() {
        assert_eq!((got[k] * 65535.0).round() as u16, w[1], "texel {k}");
    }
    // The DirectX detail is detected and flipped: the same output.
    let out_dx = dir.path().join("out_dx.png");
    let flipped = run(&["blend", s(&base), s(&dx), "-o", s(&out_dx), "--method", "whiteout"]);
    assert!(flipped.status.success());
    assert!(String::from_utf8_lossy(&flipped.stderr).contains("directx map, flipped"));

    // Sizes that do not divide: the detail named, no output.
    let odd = dir.path().join("odd.png");
    write_map(&odd, 48, 64, 3.0, Convention::OpenGl);
    let refused = dir.path().join("refused.png");
    let err = one_error_line(&run(&["blend", s(&base), s(&odd), "-o", s(&refused)]));
    assert!(err.contains("odd.png") && err.contains("must divide"), "{err}");
    assert!(!refused.exists());
    // A broken base, and an output over an input.
    let broken = dir.path().join("broken.png");
    fs::write(&broken, b"not a png").unwrap();
    let err = one_error_line(&run(&["blend", s(&broken), s(&detail), "-o", s(&refused)]));
    assert!(err.contains("broken.png"), "{err}");
    let err = one_error_line(&run(&["blend", s(&base), s(&detail), "-o", s(&detail)]));
    assert!(err.contains("never writes over an input"), "{err}");
    let err = one_error_line(&run(&["blend", s(&base), s(&detail), "-o", s(&refused), "--strength=-1"]));
    assert!(err.contains("strength"), "{err}");
    assert!(!refused.exists());
}

#[test]
fn cli_check_exit_codes_json_and_fix() {
    let dir = tempfile::tempdir().unwrap();
    let (gl, dx) = (dir.path().join("gl.png"), dir.path().join("dx.png"));
    write_map(&gl, 128, 128, 2.0, Convention::OpenGl);
    write_map(&dx, 128, 128, 2.0, Convention::DirectX);
    let clean = run(&["check", s(&gl), s(&dx), "--json"]);
    assert_eq!(clean.status.code(), Some(0), "{}", String::from_utf8_lossy(&clean.stderr));
    let lines: Vec<serde_json::Value> =
        String::from_utf8_lossy(&clean.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines[0]["convention"], "opengl");
    assert_eq!(lines[1]["convention"], "directx");
    assert!(lines.iter().all(|l| l["confident"] == true && l["clean"] == true));
    // Expecting OpenGL: the DirectX map is a finding, exit 1.
    let found = run(&["check", s(&gl), s(&dx), "--convention", "opengl"]);
    assert_eq!(found.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&found.stdout).contains("expected opengl, but its curl says directx"));
    // Repaired to OpenGL: clean under that expectation.
    let fixed = dir.path().join("fixed.png");
    let fix = run(&["check", s(&dx), "--fix", s(&fixed), "--to", "opengl"]);
    assert_eq!(fix.status.code(), Some(0), "{}", String::from_utf8_lossy(&fix.stderr));
    assert_eq!(run(&["check", s(&fixed), "--convention", "opengl"]).status.code(), Some(0));
    // An error outranks a finding.
    let broken = dir.path().join("broken.png");
    fs::write(&broken, b"not a png").unwrap();
    let mixed = run(&["check", s(&broken), s(&dx), "--convention", "opengl"]);
    assert_eq!(mixed.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&mixed.stderr).contains("broken.png"));
}
