//! `--detail N:W,…` as users run it: streamed files equal the library's
//! whole-image fit for every border (and `auto`), one scale of weight 1 is
//! `-n N` byte for byte, and what it cannot do is refused in one line.

use crate::common;

use std::path::Path;

use common::cli::{run, s};
use common::rng::Rng;
use normalfit::convert::{BorderChoices, Conversion};
use normalfit::{Borders, Detail, FitRequest, Options};

/// Heights with detail at several scales, as 16-bit samples.
fn field(w: usize, h: usize) -> Vec<u16> {
    let mut rng = Rng(99);
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            let v = 0.5 + 0.2 * (x * 0.09 + y * 0.04).sin() + 0.1 * (x * 0.8).cos() * (y * 0.5).sin();
            ((v + 0.1 * rng.next()).clamp(0.0, 1.0) * 65535.0).round() as u16
        })
        .collect()
}

fn gray16_png(path: &Path, w: usize, h: usize, values: &[u16]) {
    image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w as u32, h as u32, values.to_vec())
        .unwrap()
        .save(path)
        .unwrap();
}

fn rgb16(path: &Path) -> Vec<[u16; 3]> {
    let image = image::open(path).unwrap().to_rgb16();
    image.pixels().map(|p| p.0).collect()
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

const SCALES: &str = "3:1,9:0.5,33:0.25";

#[test]
fn a_streamed_file_is_the_library_s_whole_image_fit_for_every_border() {
    let dir = tempfile::tempdir().unwrap();
    // Several bands of rows: a band holds at least 2^14 texels.
    let (w, h) = (45, 800);
    let heights = field(w, h);
    let input = dir.path().join("h.png");
    gray16_png(&input, w, h, &heights);
    let detail: Detail = SCALES.parse().unwrap();
    for border in ["wrap", "clamp", "mirror", "wrap,mirror", "clamp,wrap", "auto"] {
        let output = dir.path().join("n.png");
        let conversion = Conversion::new()
            .with_fit(Options::new().with_strength(normalfit::Strength::Scale(10.0)).with_detail(Some(detail.clone())))
            .with_borders(border.parse::<BorderChoices>().unwrap())
            .with_bits(16);
        let summary = conversion.convert_file(&input, &output).unwrap();
        assert!(summary.streamed, "{border}");
        let opts = Options::new()
            .with_strength(normalfit::Strength::Scale(10.0))
            .with_borders(summary.borders)
            .with_detail(Some(detail.clone()));
        let mut want = vec![[0u16; 3]; w * h];
        FitRequest::new(&opts).normals_into(&heights, w, h, &mut want).unwrap();
        assert_eq!(rgb16(&output), want, "{border} ({})", summary.borders);
        if border != "auto" {
            let cli = dir.path().join("cli.png");
            let out = run(&[
                "convert",
                s(&input),
                "-o",
                s(&cli),
                "--detail",
                SCALES,
                "-s",
                "10",
                "--border",
                border,
                "--bits",
                "16",
            ]);
            assert!(out.status.success(), "{}", stderr(&out));
            assert_eq!(rgb16(&cli), want, "{border}: the command line");
        }
    }
    // The sizes' sum is not any one size's map.
    let mut single = vec![[0u16; 3]; w * h];
    let one = Options::new().with_strength(normalfit::Strength::Scale(10.0)).with_borders(Borders::default());
    FitRequest::new(&one).normals_into(&heights, w, h, &mut single).unwrap();
    assert_ne!(rgb16(&dir.path().join("cli.png")), single);
}

#[test]
fn one_scale_of_weight_one_is_dash_n_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (33, 27);
    let input = dir.path().join("h.png");
    gray16_png(&input, w, h, &field(w, h));
    let (a, b) = (dir.path().join("a.exr"), dir.path().join("b.exr"));
    let out = run(&["convert", s(&input), "-o", s(&a), "-n", "5", "--border", "mirror"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = run(&["convert", s(&input), "-o", s(&b), "--detail", "5:1", "--border", "mirror"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn what_detail_cannot_do_is_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    gray16_png(&input, 16, 16, &field(16, 16));
    let output = dir.path().join("n.png");
    let refused = |args: &[&str], says: &str| {
        let mut all = vec!["convert", s(&input), "-o", s(&output)];
        all.extend_from_slice(args);
        let out = run(&all);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        let err = stderr(&out);
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!output.exists(), "{args:?} left an output");
    };
    refused(&["--detail", "4:1"], "detail patch size must be odd, at least 3 and at most 1023, got 4");
    refused(&["--detail", "3:1,3:2"], "detail gives patch size 3 twice");
    refused(&["--detail", "3:nan"], "detail weight must be finite");
    refused(&["-n", "5", "--detail", "3:1,9:1"], "cannot be used with");
    let residual = dir.path().join("r.png");
    refused(&["--detail", "3:1,9:1", "--residual", s(&residual)], "detail at several scales has no residual");
    assert!(!residual.exists());
}
