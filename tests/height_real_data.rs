//! `normalfit height` on the real sets of `../shared/data` (CI has them;
//! ignored by a plain `cargo test`, run with `--include-ignored`, where
//! absent data is a failure):
//!
//! * their own height maps through the forward fit and back: the round
//!   trip's error, raw and up to the alternating heights no fit sees;
//! * their own normal maps (baked by their authors, not fitted) integrated
//!   by the exact model and by the generic one (Frankot–Chellappa),
//!   compared with their own height maps: correlation and RMS after the
//!   best gain and offset (the sets' units are their own), and time;
//! * `--convention auto` on the set that ships both conventions.
//!
//! The figures print (`--nocapture`); docs/height.md's tables are them.

use std::path::{Path, PathBuf};
use std::time::Instant;

use normalfit::height::{ConventionChoice, HeightOptions, Model, heights};
use normalfit::io::{ReadOptions, SampleType, read_path};
use normalfit::{Border, Borders, Convention, Fit, Options, Strength, normal_map, normals};

#[path = "common/shared_data.rs"]
mod shared_data;
use shared_data::{correlation, data_dir};

/// (name, height map, OpenGL normal map).
fn sets() -> Vec<(&'static str, PathBuf, PathBuf)> {
    let d = data_dir().join("tileable");
    vec![
        (
            "ambientCG Bricks061 (1024², 8-bit JPEG)",
            d.join("ambientcg_Bricks061/Bricks061_1K-JPG_Displacement.jpg"),
            d.join("ambientcg_Bricks061/Bricks061_1K-JPG_NormalGL.jpg"),
        ),
        (
            "Poly Haven denim_fabric (1024², 16-bit PNG)",
            d.join("polyhaven_denim_fabric/denim_fabric_disp_1k.png"),
            d.join("polyhaven_denim_fabric/denim_fabric_nor_gl_1k.png"),
        ),
        (
            "MaterialX bricks_02 (256², float EXR)",
            d.join("materialx_adsk_bricks_02/bricks_02_height_2k_raw.exr"),
            d.join("materialx_adsk_bricks_02/bricks_02_normal_2k_raw.exr"),
        ),
    ]
}

fn height_map(path: &Path) -> (usize, usize, Vec<f64>) {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    let h = raster.heights(None).unwrap();
    (raster.width, raster.height, h.iter().map(|&v| f64::from(v)).collect())
}

/// The normal map's normals and the step of its storage.
fn normal_map(path: &Path) -> (usize, usize, Vec<[f32; 3]>, f64) {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    let step = match raster.sample {
        SampleType::Int { bits } => 2.0 / f64::from((1u32 << bits) - 1),
        _ => f64::from(f32::EPSILON),
    };
    (raster.width, raster.height, normal_map::decode(&raster, false).unwrap(), step)
}

/// RMS of `want − (a·got + b)` with the least-squares a, b, over want's range.
fn fitted_rms(want: &[f64], got: &[f64]) -> f64 {
    let n = want.len() as f64;
    let (mw, mg) = (want.iter().sum::<f64>() / n, got.iter().sum::<f64>() / n);
    let (mut sgw, mut sgg) = (0.0, 0.0);
    for (w, g) in want.iter().zip(got) {
        sgw += (g - mg) * (w - mw);
        sgg += (g - mg) * (g - mg);
    }
    let a = if sgg > 0.0 { sgw / sgg } else { 0.0 };
    let rms = (want.iter().zip(got).map(|(w, g)| (w - mw - a * (g - mg)).powi(2)).sum::<f64>() / n).sqrt();
    let (lo, hi) = want.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    rms / (hi - lo)
}

fn demean(v: &[f64]) -> Vec<f64> {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    v.iter().map(|x| x - m).collect()
}

/// (largest error, RMS error) over the range, up to a constant; and the
/// largest once the alternating heights no fit sees are removed (the
/// difference's least-squares fit by (−1)^x, (−1)^y, (−1)^(x+y)).
fn round_trip_errors(original: &[f64], back: &[f64], w: usize) -> (f64, f64, f64) {
    let want = demean(original);
    let (lo, hi) = want.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    let diff: Vec<f64> = want.iter().zip(back).map(|(a, b)| a - b).collect();
    let max = diff.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    let rms = (diff.iter().map(|d| d * d).sum::<f64>() / diff.len() as f64).sqrt();
    let sign = |k: usize| if k.is_multiple_of(2) { 1.0 } else { -1.0 };
    // Even sizes: the three patterns are orthogonal to each other and to 1.
    let pattern = |which: usize, k: usize| match which {
        0 => sign(k % w),
        1 => sign(k / w),
        _ => sign(k % w) * sign(k / w),
    };
    let mut rest = diff.clone();
    for which in 0..3 {
        let c = rest.iter().enumerate().map(|(k, d)| d * pattern(which, k)).sum::<f64>() / rest.len() as f64;
        rest.iter_mut().enumerate().for_each(|(k, d)| *d -= c * pattern(which, k));
    }
    let visible = rest.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    (max / (hi - lo), rms / (hi - lo), visible / (hi - lo))
}

/// The gain of the round trips: a height range of 4 texel widths, a
/// relief as steep as these sets' own normal maps draw theirs.
const GAIN: f64 = 4.0;

#[test]
#[ignore = "needs ../shared/data"]
fn real_height_maps_come_back_through_the_fit() {
    println!("| set | N | fit | border | gain S | max error | RMS error | max, alternating removed | solves |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, height_path, _) in sets() {
        let (w, h, original) = height_map(&height_path);
        for (n, fit) in [(3, Fit::Vertical), (3, Fit::Orthogonal), (5, Fit::Vertical), (5, Fit::Orthogonal)] {
            for border in [Border::Wrap, Border::Mirror] {
                let opts = Options::new()
                    .with_patch(n)
                    .with_fit(fit)
                    .with_borders(Borders::both(border))
                    .with_strength(Strength::Scale(GAIN));
                let n32 = normals(&original, w, h, &opts).unwrap();
                let back = heights(&n32, w, h, &HeightOptions::from_fit(&opts)).unwrap();
                let (max, rms, visible) = round_trip_errors(&original, &back.values, w);
                println!(
                    "| {name} | {n} | {fit} | {border} | {:.1} | {max:.2e} | {rms:.2e} | {visible:.2e} | {}{} |",
                    GAIN,
                    back.report.iterations,
                    if back.report.converged { "" } else { " (not settled)" }
                );
                assert!(back.values.iter().all(|v| v.is_finite()));
                if fit == Fit::Vertical && border == Border::Wrap {
                    assert!(visible < 1e-4, "{name} N {n} {border}: {visible:e}");
                }
            }
        }
    }
}

#[test]
#[ignore = "needs ../shared/data"]
fn real_normal_maps_integrate_to_their_own_heights() {
    println!("| set | model | correlation | RMS (best gain) | time |");
    println!("|---|---|---|---|---|");
    let mut weak = Vec::new();
    for (name, height_path, normal_path) in sets() {
        let (w, h, theirs) = height_map(&height_path);
        let (nw, nh, normals, step) = normal_map(&normal_path);
        assert_eq!((w, h), (nw, nh), "{name}");
        for (label, opts) in [
            ("exact, N = 3, vertical", HeightOptions::new().with_fit(Fit::Vertical)),
            ("exact, N = 3, orthogonal", HeightOptions::new()),
            ("generic (Frankot–Chellappa)", HeightOptions::new().with_model(Model::Generic)),
        ] {
            let start = Instant::now();
            let got = heights(&normals, w, h, &opts.with_step(step)).unwrap();
            let seconds = start.elapsed().as_secs_f64();
            let (c, rms) = (correlation(&theirs, &got.values), fitted_rms(&theirs, &got.values));
            println!("| {name} | {label} | {c:.4} | {rms:.4} | {seconds:.3} s |");
            // Their normal maps were baked from their heights: integrated,
            // they follow them.
            if c <= 0.3 {
                weak.push(format!("{name} {label}: correlation {c}"));
            }
        }
    }
    assert!(weak.is_empty(), "{weak:?}");
}

#[test]
#[ignore = "needs ../shared/data"]
fn auto_tells_the_conventions_of_a_set_apart() {
    let d = data_dir().join("tileable/ambientcg_Bricks061");
    for (file, want) in
        [("Bricks061_1K-JPG_NormalGL.jpg", Convention::OpenGl), ("Bricks061_1K-JPG_NormalDX.jpg", Convention::DirectX)]
    {
        let (w, h, normals, step) = normal_map(&d.join(file));
        let opts = HeightOptions::new().with_convention(ConventionChoice::Auto).with_step(step);
        let got = heights(&normals, w, h, &opts).unwrap();
        println!("{file}: {:?}, curl {:?}", got.report.convention, got.report.curl);
        assert_eq!(got.report.convention, want, "{file}");
    }
}
