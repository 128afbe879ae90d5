//! The tiling check on the shared real textures, the contract's public
//! cases and generated cases, and its edge cases.

use crate::common::reference;
use crate::tiling_support;

use normalfit::normal_map::{ImageKind, KindChoice};
use normalfit::tiling::{HeightSeams, TilingOptions, TilingReport, check, shift_half};
use normalfit::{Error, Samples};
use tiling_support::{Case, Rng, generated_cases, hard_photo_cases, real_cases, spec_cases, structured_cases};

/// Checks every case's verdicts and detected kind; prints the scores.
fn assert_cases(cases: &[Case]) {
    let opts = TilingOptions::default();
    let mut wrong = Vec::new();
    for c in cases {
        let r = check(&c.image.refs(), c.image.width, c.image.height, &opts).unwrap();
        println!("{:45} {:?} x {:7.2} y {:7.2}", c.name, r.kind, r.x.score, r.y.score);
        if (r.x.seamless, r.y.seamless) != c.expect || r.kind != c.kind {
            wrong.push(format!("{}: {r:?}, expected {:?} {:?}", c.name, c.expect, c.kind));
        }
        assert!(r.x.score.is_finite() && r.y.score.is_finite() && r.x.score > 0.0 && r.y.score > 0.0);
        assert_eq!(r.seamless(), r.x.seamless && r.y.seamless);
    }
    assert!(wrong.is_empty(), "wrong verdicts:\n{}", wrong.join("\n"));
}

#[test]
#[ignore = "needs ../shared/data (the shared real textures); CI runs it with --include-ignored"]
fn real_tileable_textures_pass_and_photos_fail() {
    let cases = real_cases().expect("../shared/data is absent: the real-texture tests need it beside the clone");
    assert_cases(&cases);
}

#[test]
fn spec_sine_tiles_and_ramp_tiles_only_along_y() {
    assert_cases(&spec_cases());
}

#[test]
fn generated_noise_crops_creases_and_normal_maps() {
    for n in [64, 256] {
        assert_cases(&generated_cases(n));
    }
}

#[test]
fn generated_cases_keep_their_verdicts_at_odd_sizes() {
    assert_cases(&generated_cases(96));
    assert_cases(&generated_cases(160));
}

#[test]
fn structured_photos_fail_and_periodic_structures_tile() {
    // Photos at angles (lines hitting the borders at positions that do not
    // match), and the same scenes exactly periodic, rotated and sheared.
    assert_cases(&structured_cases(256));
    assert_cases(&structured_cases(160));
}

#[test]
fn rough_planks_photos_fail_on_both_axes() {
    // Their broken plank gaps are no larger, texel by texel, than the
    // wood's grain: level 0 alone passed them.
    assert_cases(&hard_photo_cases());
}

/// Stripes at 30° from the y axis under heavy texel noise, `w` × `h`:
/// `period` texels apart along x, so they continue across the x wrap
/// exactly when `period` divides W. The noise, drawn per texel, tiles on
/// its own.
fn noisy_stripes(w: usize, h: usize, period: f64, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let slope = 30f64.to_radians().tan();
    let v: Vec<f64> = (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            let phase = (x + y * slope) / period;
            let stripe = if phase - phase.floor() < 0.25 { 0.3 } else { 0.0 };
            stripe + 0.6 * rng.next()
        })
        .collect();
    tiling_support::quantize(&tiling_support::normalize(&v), 16)
}

#[test]
fn stripes_that_do_not_continue_are_found_under_noise() {
    // The stripes' jump at a broken wrap is small beside the noise's jumps
    // between any two columns, so texel by texel the seam looks ordinary;
    // summed in runs along the seam the noise averages out and the broken
    // stripes remain. The same stripes continuing across the wrap tile.
    let (w, h) = (256, 256);
    let opts = TilingOptions::default();
    // 256 / 32: continues; 256 / 40 leaves a 16-texel part-stripe at the
    // wrap, the stripes 10 wide.
    let continuing = noisy_stripes(w, h, 32.0, 1);
    let r = check(&[&continuing], w, h, &opts).unwrap();
    assert!(r.x.seamless, "{r:?}");
    let broken = noisy_stripes(w, h, 40.0, 1);
    let r = check(&[&broken], w, h, &opts).unwrap();
    println!("broken stripes: {r:?}");
    assert!(!r.x.seamless && r.x.score > 1.8, "{r:?}");
    // Streaming finds the same.
    let streamed = stream(&broken, w, h, &opts);
    assert_eq!(streamed.x.score.to_bits(), r.x.score.to_bits(), "{streamed:?} vs {r:?}");
}

#[test]
fn constant_images_tile_with_score_one() {
    for (w, h) in [(1, 1), (2, 5), (3, 3), (7, 4), (64, 64)] {
        for planes in [1, 3, 4] {
            let data = vec![vec![0.25f32; w * h]; planes];
            let refs: Vec<&[f32]> = data.iter().map(Vec::as_slice).collect();
            let r = check(&refs, w, h, &TilingOptions::default()).unwrap();
            assert_eq!((r.x.score, r.y.score), (1.0, 1.0), "{w}×{h}, {planes} planes");
            assert!(r.seamless());
        }
    }
}

#[test]
fn tiny_axes_have_defined_answers() {
    // Width 1: the only pair is a column with itself.
    let col = [0.0f32, 0.5, 1.0, 0.2];
    let r = check(&[&col], 1, 4, &TilingOptions::default()).unwrap();
    assert_eq!(r.x.score, 1.0);
    assert!(r.x.seamless && r.y.score.is_finite());
    // Width 2: the wrap pair equals the interior pair.
    let two = [0.0f32, 1.0, 0.0, 1.0];
    let r = check(&[&two], 2, 2, &TilingOptions::default()).unwrap();
    assert_eq!(r.x.score, 1.0);
    // Width 3, a ramp 0, 0.5, 1: the wrap jumps twice as far as its neighbours.
    let three = [0.0f32, 0.5, 1.0, 0.0, 0.5, 1.0, 0.0, 0.5, 1.0];
    let r = check(&[&three], 3, 3, &TilingOptions::default()).unwrap();
    assert!(r.x.score > 1.9 && !r.x.seamless && r.y.seamless, "{r:?}");
    // An image without texels has no seams to judge: refused, as the fit
    // refuses it (and as no decoder gives one), never "seamless".
    for (w, h) in [(0, 5), (5, 0), (0, 0)] {
        let e = check(&[&[]], w, h, &TilingOptions::default()).unwrap_err();
        assert_eq!(e.to_string(), format!("invalid option: image is {w}×{h}: both sides must be at least 1"));
    }
}

#[test]
fn non_finite_heights_and_normals_are_refused() {
    let mut v = tiling_support::periodic_noise(32, 32, 2, 2, 3);
    v[41] = f32::NAN;
    v[42] = f32::INFINITY;
    // A height map: the first non-finite height in row order, gray or the
    // luma of R, G and B (one of which is NaN), judged by choice or
    // detected (issue 32: a NaN map was "seamless").
    let clean = tiling_support::periodic_noise(32, 32, 2, 2, 3);
    for planes in [vec![v.as_slice()], vec![clean.as_slice(), clean.as_slice(), v.as_slice()]] {
        for kind in [KindChoice::Auto, KindChoice::Height] {
            let e = check(&planes, 32, 32, &TilingOptions::default().with_kind(kind)).unwrap_err();
            assert!(matches!(e, Error::NonFiniteHeight { x: 9, y: 1 }), "{e}");
        }
    }
    let e = check(&[&clean, &v], 32, 32, &TilingOptions::default());
    assert!(e.is_ok(), "a second plane is alpha, not judged: {e:?}");
    // A normal map's components: a normal with a non-finite one is no
    // normal, refused naming the texel (the fuzzers' python_entry case).
    let planes = [v.as_slice(), clean.as_slice(), clean.as_slice()];
    let e = check(&planes, 32, 32, &TilingOptions::default().with_kind(KindChoice::Normal)).unwrap_err();
    assert!(matches!(e, Error::NonFiniteNormal { x: 9, y: 1 }), "{e}");
    // Finite everywhere, the same map scores finite.
    let planes = [clean.as_slice(), clean.as_slice(), clean.as_slice()];
    let r = check(&planes, 32, 32, &TilingOptions::default().with_kind(KindChoice::Normal)).unwrap();
    assert!(r.x.score.is_finite() && r.y.score.is_finite());
}

#[test]
fn threshold_and_forced_kind_are_obeyed() {
    let n = 64;
    let ramp: Vec<f32> = (0..n * n).map(|k| (k % n) as f32 / (n - 1) as f32).collect();
    let lax = TilingOptions::default().with_threshold(1e9);
    assert!(check(&[&ramp], n, n, &lax).unwrap().seamless());
    let strict = TilingOptions::default().with_threshold(0.5);
    let sine = &spec_cases()[0].image;
    assert!(!check(&sine.refs(), sine.width, sine.height, &strict).unwrap().seamless());
    // The same three planes, judged either way.
    let planes = [ramp.as_slice(), ramp.as_slice(), ramp.as_slice()];
    let h = check(&planes, n, n, &TilingOptions::default().with_kind(KindChoice::Height)).unwrap();
    let m = check(&planes, n, n, &TilingOptions::default().with_kind(KindChoice::Normal)).unwrap();
    assert_eq!((h.kind, m.kind), (ImageKind::Height, ImageKind::Normal));
    assert!(!h.x.seamless && !m.x.seamless);
}

#[test]
fn kind_detection() {
    let n = 32;
    let gray = vec![0.5f32; n * n];
    assert_eq!(ImageKind::detect(&[&gray], n, n).unwrap(), ImageKind::Height);
    // Gray stored as RGB is a height map even where (2c − 1)(1, 1, 1) is unit.
    let g = vec![0.7887f32; n * n];
    assert_eq!(ImageKind::detect(&[&g, &g, &g], n, n).unwrap(), ImageKind::Height);
    // A flat encoded normal map, 8-bit: (128, 128, 255) / 255.
    let (half, one) = (vec![128.0f32 / 255.0; n * n], vec![1.0f32; n * n]);
    assert_eq!(ImageKind::detect(&[&half, &half, &one], n, n).unwrap(), ImageKind::Normal);
    // With alpha too.
    assert_eq!(ImageKind::detect(&[&half, &half, &one, &one], n, n).unwrap(), ImageKind::Normal);
    // A float normal map stored raw, n in [−1, 1].
    let (zero, up) = (vec![0.0f32; n * n], vec![1.0f32; n * n]);
    assert_eq!(ImageKind::detect(&[&zero, &zero, &up], n, n).unwrap(), ImageKind::Normal);
    // Random colours are a photo, a height map.
    let mut rng = tiling_support::Rng(9);
    let rgb: Vec<Vec<f32>> = (0..3).map(|_| (0..n * n).map(|_| rng.next() as f32).collect()).collect();
    assert_eq!(ImageKind::detect(&[&rgb[0], &rgb[1], &rgb[2]], n, n).unwrap(), ImageKind::Height);
}

/// The streaming check of `v` (`w` × `h`), fed row by row.
fn stream(v: &[f32], w: usize, h: usize, opts: &TilingOptions) -> TilingReport {
    let mut seams = HeightSeams::new(w, h).unwrap();
    for y in 0..h {
        seams.push_row(&v[y * w..][..w]).unwrap();
    }
    assert_eq!(seams.rows(), h);
    seams.finish(opts).unwrap()
}

/// Asserts that streaming `v` gives `check`'s report as a height map under
/// `threshold`: same kind and verdicts, scores within 1e-9 relative.
/// Returns the larger relative score difference of the two axes.
fn assert_stream_matches(v: &[f32], w: usize, h: usize, threshold: f64, label: &str) -> f64 {
    let opts = TilingOptions::new().with_kind(KindChoice::Height).with_threshold(threshold);
    let whole = check(&[v], w, h, &opts).unwrap();
    let streamed = stream(v, w, h, &opts);
    let rel = |a: f64, b: f64| if a == b { 0.0 } else { (a - b).abs() / a.abs().max(b.abs()) };
    let diff = rel(whole.x.score, streamed.x.score).max(rel(whole.y.score, streamed.y.score));
    assert!(diff <= 1e-9, "{label} {w}×{h}: check {whole:?}, streamed {streamed:?}");
    assert_eq!(streamed.kind, ImageKind::Height, "{label} {w}×{h}");
    assert_eq!(
        (streamed.x.seamless, streamed.y.seamless),
        (whole.x.seamless, whole.y.seamless),
        "{label} {w}×{h}: check {whole:?}, streamed {streamed:?}"
    );
    diff
}

/// The luma `check` judges a colour height map by, or the one plane.
fn luma(planes: &[&[f32]]) -> Vec<f32> {
    match planes {
        [r, g, b, ..] => r.iter().zip(*g).zip(*b).map(|((r, g), b)| 0.2126 * r + 0.7152 * g + 0.0722 * b).collect(),
        _ => planes[0].to_vec(),
    }
}

/// Sizes around every special case: axes of 1 to 6 (no interior crease, the
/// wrap stencils overlapping), and heights around the 32-row blocks.
const SIZES_W: [usize; 11] = [1, 2, 3, 4, 5, 7, 8, 9, 17, 33, 64];
const SIZES_H: [usize; 14] = [1, 2, 3, 4, 5, 6, 7, 31, 32, 33, 63, 64, 65, 97];

#[test]
fn streaming_equals_check_on_random_heights_of_many_sizes() {
    let mut worst = 0.0f64;
    for &w in &SIZES_W {
        for &h in &SIZES_H {
            for seed in 0..3u64 {
                let mut rng = Rng(seed * 1000 + (w * 131 + h) as u64);
                // Unit range, and a large offset and range for f32 rounding.
                let (lo, span) = if seed == 2 { (1000.0, 500.0) } else { (0.0, 1.0) };
                let v: Vec<f32> = (0..w * h).map(|_| (lo + span * rng.next()) as f32).collect();
                for t in [0.8, 1.5] {
                    worst = worst.max(assert_stream_matches(&v, w, h, t, &format!("random seed {seed}")));
                }
            }
        }
    }
    println!("largest relative score difference: {worst:e}");
}

/// Slope creases at a wrap: a profile along the axis whose ends meet in
/// value, not in slope, plus some noise, as a 16-bit file would hold it.
fn crease_image(w: usize, h: usize, along_y: bool, seed: u64) -> Vec<f32> {
    let base = tiling_support::periodic_noise(w, h, 2, 2, seed);
    let v: Vec<f64> = (0..w * h)
        .map(|k| {
            let t = if along_y { (k / w) as f64 / h as f64 } else { (k % w) as f64 / w as f64 };
            0.5 * (std::f64::consts::PI * t).sin() + 0.5 * f64::from(base[k])
        })
        .collect();
    tiling_support::quantize(&tiling_support::normalize(&v), 16)
}

#[test]
fn streaming_equals_check_on_noise_crops_creases_and_ramps() {
    let mut worst = 0.0f64;
    let mut same = |v: &[f32], w: usize, h: usize, label: &str| {
        worst = worst.max(assert_stream_matches(v, w, h, 1.5, label));
    };
    // The generated gray cases (tileable noise, crops, noise periodic in x
    // only, creases at the x wrap) and the contract's sine, ramp, constant.
    for n in [64, 96] {
        for c in generated_cases(n).iter().filter(|c| c.image.planes.len() == 1) {
            same(&c.image.planes[0], c.image.width, c.image.height, &c.name);
        }
    }
    for c in spec_cases() {
        same(&c.image.planes[0], c.image.width, c.image.height, &c.name);
    }
    // The structured photos and textures (luma rows for the RGB ones, as
    // `check` takes them); 160 and 96 are not multiples of the 32-row
    // blocks, nor of the longest runs along the seams.
    for n in [96, 160] {
        for c in structured_cases(n) {
            let (w, h) = (c.image.width, c.image.height);
            let v = luma(&c.image.refs());
            same(&v, w, h, &c.name);
            let as_planes = check(&c.image.refs(), w, h, &TilingOptions::new().with_kind(KindChoice::Height)).unwrap();
            let streamed = stream(&v, w, h, &TilingOptions::new());
            let rel = |a: f64, b: f64| (a - b).abs() / a.max(b);
            assert!(rel(as_planes.x.score, streamed.x.score) < 1e-5, "{}: {as_planes:?} {streamed:?}", c.name);
            assert!(rel(as_planes.y.score, streamed.y.score) < 1e-5, "{}: {as_planes:?} {streamed:?}", c.name);
        }
    }
    // Non-square and not a multiple of the 32-row blocks.
    for (w, h) in [(80, 45), (45, 80), (7, 100), (100, 7), (257, 1000)] {
        let t = tiling_support::periodic_noise(w, h, 3, 2, (w * h) as u64);
        same(&t, w, h, "tileable noise");
        let big = tiling_support::periodic_noise(3 * w, 3 * h, 9, 2, 7);
        same(&tiling_support::crop(&big, 3 * w, w / 3 + 5, h / 2 + 7, w, h), w, h, "crop of noise");
        let ramp_x: Vec<f32> = (0..w * h).map(|k| (k % w) as f32 / w as f32).collect();
        same(&ramp_x, w, h, "ramp along x");
        let ramp_y: Vec<f32> = (0..w * h).map(|k| (k / w) as f32 / h as f32).collect();
        same(&ramp_y, w, h, "ramp along y");
    }
    // A slope crease at each wrap: the streamed y wrap (pairs H − 1 → 0 and
    // the creases across it) must find the seam `check` finds.
    for (w, h) in [(64, 64), (48, 97)] {
        for along_y in [false, true] {
            let v = crease_image(w, h, along_y, 77);
            same(&v, w, h, if along_y { "crease at the y wrap" } else { "crease at the x wrap" });
            let r = stream(&v, w, h, &TilingOptions::new());
            let seam = if along_y { r.y } else { r.x };
            let other = if along_y { r.x } else { r.y };
            assert!(!seam.seamless && seam.score > 3.0 && other.seamless, "{w}×{h} along_y {along_y}: {r:?}");
        }
    }
    println!("largest relative score difference: {worst:e}");
}

#[test]
fn streaming_judges_the_crease_not_only_the_value_at_the_y_wrap() {
    // A parabola along y meets itself in value at the wrap (h(0) = h(H)),
    // so the value pair H − 1 → 0 is ordinary: the verdict rests on the
    // creases across the wrap, which only `finish` can compute.
    let (w, h) = (32, 64);
    let v: Vec<f32> = (0..w * h)
        .map(|k| {
            let t = (k / w) as f64 / h as f64;
            (4.0 * t * (1.0 - t) + 0.01 * ((k % w) as f64 * 0.7).sin()) as f32
        })
        .collect();
    let r = stream(&v, w, h, &TilingOptions::new());
    let whole = check(&[&v], w, h, &TilingOptions::new().with_kind(KindChoice::Height)).unwrap();
    assert!(!r.y.seamless && r.y.score > 3.0, "{r:?}");
    assert_eq!(r.y.score.to_bits(), whole.y.score.to_bits(), "{r:?} vs {whole:?}");
    // The same image judged as a normal map, by value only, tiles along y:
    // the crease is what fails it.
    let as_normal = check(&[&v], w, h, &TilingOptions::new().with_kind(KindChoice::Normal)).unwrap();
    assert!(as_normal.y.seamless, "{as_normal:?}");
}

#[test]
fn streaming_constant_images_tile_with_score_one() {
    for (w, h) in [(1, 1), (1, 7), (7, 1), (2, 5), (3, 3), (7, 4), (64, 64), (5, 33)] {
        let r = stream(&vec![0.25f32; w * h], w, h, &TilingOptions::new());
        assert_eq!((r.x.score, r.y.score), (1.0, 1.0), "{w}×{h}");
        assert!(r.seamless() && r.kind == ImageKind::Height);
    }
}

#[test]
fn streaming_non_finite_values_are_holes() {
    for (w, h) in [(32, 32), (5, 4), (3, 2), (1, 6), (40, 70)] {
        let mut v = tiling_support::periodic_noise(w, h, 2, 2, 3);
        // In the first rows, the last rows, the first and last columns.
        let spots = [0, w - 1, w * h / 2, w * (h - 1), w * h - 1, w.min(w * h - 1), (w * (h - 1)).saturating_sub(1)];
        let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        for (i, &k) in spots.iter().enumerate() {
            v[k] = bad[i % 3];
        }
        // The streamed check (which settles the borders of maps with
        // holes) skips them, as the whole check does when told there are
        // holes; without being told, the whole check refuses them.
        let opts = TilingOptions::new().with_kind(KindChoice::Height);
        let holes = opts.with_nodata(Some(f64::NAN));
        let (a, b) = (stream(&v, w, h, &opts), check(&[&v], w, h, &holes).unwrap());
        assert_eq!((a.x.seamless, a.y.seamless), (b.x.seamless, b.y.seamless), "{w}×{h}: {a:?} {b:?}");
        for (s, t) in [(a.x.score, b.x.score), (a.y.score, b.y.score)] {
            assert!(!s.is_nan() && (s == t || (s - t).abs() <= 1e-9 * s.abs()), "{w}×{h}: {a:?} {b:?}");
        }
        let e = check(&[&v], w, h, &opts).unwrap_err();
        assert!(matches!(e, Error::NonFiniteHeight { x: 0, y: 0 }), "{e}");
    }
}

/// `v` (`w` × `h`) with holes: a block of `nodata` inside, NaN at random
/// texels (1 in 12), and `nodata` at some texels of the first and last
/// columns and rows, across both seams.
fn with_holes(v: &[f32], w: usize, h: usize, nodata: f32, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let mut out = v.to_vec();
    for (k, t) in out.iter_mut().enumerate() {
        let (x, y) = (k % w, k / w);
        let block = (w / 3..w / 3 + w / 5).contains(&x) && (h / 2..h / 2 + h / 4).contains(&y);
        let edge = (x == 0 || x == w - 1 || y == 0 || y == h - 1) && rng.next() < 0.2;
        if block || edge {
            *t = nodata;
        } else if rng.next() < 1.0 / 12.0 {
            *t = f32::NAN;
        }
    }
    out
}

/// The plain reference's scores of `v` with holes at `nodata` and NaN.
fn reference_scores(v: &[f32], w: usize, h: usize, nodata: f32) -> (f64, f64) {
    let heights: Vec<f64> = v.iter().map(|&t| f64::from(t)).collect();
    reference::seam_scores(&heights, w, h, |t| t.is_nan() || t == f64::from(nodata))
}

#[test]
fn holes_are_skipped_as_the_plain_reference_skips_them() {
    // Tileable noise, a crop of it that does not tile, and a ramp along
    // x: known scores far from 0 and 1, every level judged up to 64 lines.
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    for (w, h) in [(48, 40), (70, 33), (9, 64)] {
        let tiles = tiling_support::periodic_noise(w, h, 3, 2, 11);
        let big = tiling_support::periodic_noise(2 * w, 2 * h, 5, 2, 12);
        let crop = tiling_support::crop(&big, 2 * w, w / 3, h / 4, w, h);
        let ramp: Vec<f32> = (0..w * h).map(|k| (k % w) as f32 * 0.3 + (k / w % 5) as f32 * 0.01).collect();
        for (name, v) in [("tiles", tiles), ("crop", crop), ("ramp", ramp)] {
            let holed = with_holes(&v, w, h, -9999.0, (w * h) as u64);
            let opts = TilingOptions::new().with_kind(KindChoice::Height).with_nodata(Some(-9999.0));
            let got = check(&[&holed], w, h, &opts).unwrap();
            let want = reference_scores(&holed, w, h, -9999.0);
            let label = format!("{name} {w}×{h}: {got:?}, reference {want:?}");
            assert!(rel(got.x.score, want.0) < 1e-5 && rel(got.y.score, want.1) < 1e-5, "{label}");
            // Without holes, the same reference gives the scores as ever.
            let plain = check(&[&v], w, h, &opts.with_nodata(None)).unwrap();
            let want = reference_scores(&v, w, h, f32::NAN);
            assert!(rel(plain.x.score, want.0) < 1e-5 && rel(plain.y.score, want.1) < 1e-5, "{name} {plain:?}");
            // The streamed check: the same, within the f64 order of sums.
            let mut seams = HeightSeams::new(w, h).unwrap().with_nodata(Some(-9999.0));
            seams.push_heights(&holed).unwrap();
            let streamed = seams.finish(&opts).unwrap();
            assert!(rel(streamed.x.score, got.x.score) <= 1e-12, "{label}: streamed {streamed:?}");
            assert!(rel(streamed.y.score, got.y.score) <= 1e-12, "{label}: streamed {streamed:?}");
            assert_eq!((streamed.x.seamless, streamed.y.seamless), (got.x.seamless, got.y.seamless), "{label}");
        }
    }
}

#[test]
fn holes_keep_the_verdict_of_a_texture_that_tiles_and_of_one_that_does_not() {
    let (w, h) = (96, 80);
    let opts = TilingOptions::new().with_kind(KindChoice::Height).with_nodata(Some(-9999.0));
    let tiles = tiling_support::periodic_noise(w, h, 4, 3, 21);
    let big = tiling_support::periodic_noise(3 * w, 3 * h, 9, 3, 22);
    let crop = tiling_support::crop(&big, 3 * w, 37, 29, w, h);
    for (v, expect) in [(&tiles, true), (&crop, false)] {
        let before = check(&[v], w, h, &opts).unwrap();
        assert_eq!((before.x.seamless, before.y.seamless), (expect, expect), "{before:?}");
        let holed = with_holes(v, w, h, -9999.0, 5);
        let after = check(&[&holed], w, h, &opts).unwrap();
        assert_eq!((after.x.seamless, after.y.seamless), (expect, expect), "before {before:?}, after {after:?}");
        // Read as heights, the −9999 at the seams would be a seam.
        let as_heights: Vec<f32> = holed.iter().map(|&t| if t.is_nan() { 0.5 } else { t }).collect();
        let wrong = check(&[&as_heights], w, h, &opts.with_nodata(None)).unwrap();
        assert!(!wrong.x.seamless && !wrong.y.seamless, "{wrong:?}");
    }
}

#[test]
fn streamed_equals_whole_with_holes_at_many_sizes() {
    for &w in &SIZES_W {
        for &h in &SIZES_H {
            let v = tiling_support::periodic_noise(w, h, 2, 2, (w * 131 + h) as u64);
            let holed = with_holes(&v, w, h, -9999.0, (w * 7 + h) as u64);
            let opts = TilingOptions::new().with_kind(KindChoice::Height).with_nodata(Some(-9999.0));
            let whole = check(&[&holed], w, h, &opts).unwrap();
            let mut seams = HeightSeams::new(w, h).unwrap().with_nodata(Some(-9999.0));
            for row in holed.chunks_exact(w) {
                seams.push_row(row).unwrap();
            }
            let streamed = seams.finish(&opts).unwrap();
            for (a, b) in [(whole.x, streamed.x), (whole.y, streamed.y)] {
                assert!(!a.score.is_nan() && a.score > 0.0, "{w}×{h}: {whole:?}");
                let same = a.score == b.score || (a.score - b.score).abs() <= 1e-12 * a.score;
                assert!(same && a.seamless == b.seamless, "{w}×{h}: whole {whole:?}, streamed {streamed:?}");
            }
        }
    }
}

#[test]
fn an_edge_of_holes_alone_is_judged_not_to_tile_and_no_score_is_nan() {
    let (w, h) = (40, 36);
    let opts = TilingOptions::new().with_kind(KindChoice::Height).with_nodata(Some(-9999.0));
    let mut v = tiling_support::periodic_noise(w, h, 2, 2, 4);
    // The last column all holes: no pair across the x seam is valid.
    for y in 0..h {
        v[y * w + w - 1] = -9999.0;
    }
    let r = check(&[&v], w, h, &opts).unwrap();
    assert!(r.x.score == f64::INFINITY && !r.x.seamless, "{r:?}");
    assert!(r.y.score.is_finite() && r.y.seamless, "{r:?}");
    assert_eq!(r.suggested_borders(), normalfit::Borders { x: normalfit::Border::Mirror, y: normalfit::Border::Wrap });
    let streamed = stream(&v.iter().map(|&t| if t == -9999.0 { f32::NAN } else { t }).collect::<Vec<_>>(), w, h, &opts);
    assert!(streamed.x.score == f64::INFINITY && streamed.y.seamless, "{streamed:?}");
    // Holes alone: neither axis can be judged.
    let r = check(&[&vec![f32::NAN; w * h]], w, h, &opts).unwrap();
    assert!(r.x.score == f64::INFINITY && r.y.score == f64::INFINITY && !r.seamless(), "{r:?}");
}

#[test]
fn streaming_with_rows_missing_is_refused_with_the_count() {
    let (w, h) = (24, 70);
    let v = tiling_support::periodic_noise(w, h, 3, 2, 11);
    for pushed in [0, 1, 33, 69] {
        let mut seams = HeightSeams::new(w, h).unwrap();
        for row in v.chunks_exact(w).take(pushed) {
            seams.push_row(row).unwrap();
        }
        assert_eq!(seams.rows(), pushed);
        let err = seams.finish(&TilingOptions::new()).unwrap_err();
        assert!(matches!(err, Error::InvalidOption(_)), "{err}");
        assert_eq!(err.to_string(), format!("invalid option: the tiling check has {pushed} of its 70 rows"));
    }
}

#[test]
fn streaming_empty_images_and_kind() {
    // Refused as `check` refuses them.
    for (w, h) in [(0, 5), (5, 0)] {
        let e = HeightSeams::new(w, h).expect_err("an image without texels is refused");
        assert_eq!(e.to_string(), format!("invalid option: image is {w}×{h}: both sides must be at least 1"));
    }
    // A forced Normal kind does not apply: the rows are heights.
    let v = vec![0.5f32; 16];
    let r = stream(&v, 4, 4, &TilingOptions::new().with_kind(KindChoice::Normal));
    assert_eq!(r.kind, ImageKind::Height);
}

#[test]
fn streaming_refuses_a_row_too_many_and_keeps_its_report() {
    let mut seams = HeightSeams::new(2, 1).unwrap();
    seams.push_row(&[0.0, 1.0]).unwrap();
    let err = seams.push_row(&[5.0, 9.0]).unwrap_err();
    assert!(matches!(err, Error::InvalidOption(_)), "{err}");
    assert!(err.to_string().contains("rows of the tiling check are in already"), "{err}");
    assert_eq!(seams.rows(), 1);
    let whole = check(&[&[0.0, 1.0]], 2, 1, &TilingOptions::new().with_kind(KindChoice::Height)).unwrap();
    assert_eq!(seams.finish(&TilingOptions::new()).unwrap(), whole, "the refused row left no trace");
}

#[test]
fn streaming_refuses_a_row_of_the_wrong_width() {
    let err = HeightSeams::new(2, 2).unwrap().push_row(&[0.0, 1.0, 2.0]).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 2, actual: 3 }), "{err}");
}

#[test]
fn streaming_refuses_samples_that_are_not_whole_rows_or_too_many() {
    let mut seams = HeightSeams::new(3, 2).unwrap();
    let err = seams.push_samples(&Samples::U8(vec![1; 4])).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 6, actual: 4 }), "{err}");
    let err = seams.push_samples(&Samples::U8(vec![1; 9])).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 6, actual: 9 }), "{err}");
    assert_eq!(seams.rows(), 0, "nothing pushed");
    seams.push_samples(&Samples::U8(vec![1; 6])).unwrap();
    assert_eq!(seams.rows(), 2);
}

/// A caller's slice of any sample type gives the report its samples give,
/// and that of the whole-image check of its heights, bit for bit.
#[test]
fn heights_pushed_from_a_slice_report_as_their_samples_do() {
    let (w, h) = (37, 23);
    let mut rng = Rng(7);
    let values: Vec<u16> = (0..w * h).map(|_| (rng.next() * 65535.0) as u16).collect();
    let opts = TilingOptions::new().with_kind(KindChoice::Height);
    let mut from_slice = HeightSeams::new(w, h).unwrap();
    from_slice.push_heights(&values[..w * 10]).unwrap();
    from_slice.push_heights(&values[w * 10..]).unwrap();
    let mut from_samples = HeightSeams::new(w, h).unwrap();
    from_samples.push_samples(&Samples::U16(values.clone())).unwrap();
    let heights = Samples::U16(values.clone()).to_f32().unwrap();
    let whole = check(&[&heights], w, h, &opts).unwrap();
    let (a, b) = (from_slice.finish(&opts).unwrap(), from_samples.finish(&opts).unwrap());
    assert_eq!(a, b);
    assert_eq!(a, whole);
    let mut seams = HeightSeams::new(w, h).unwrap();
    assert!(matches!(seams.push_heights(&values[..w + 1]), Err(Error::BufferSize { .. })));
}

#[test]
fn bad_arguments_are_errors_not_panics() {
    let opts = TilingOptions::new();
    let err = check(&[], 2, 2, &opts).unwrap_err();
    assert!(matches!(err, Error::InvalidOption(_)), "{err}");
    let short = [0.5f32; 3];
    let err = check(&[&short], 2, 2, &opts).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 4, actual: 3 }), "{err}");
    let four = [0.5f32; 4];
    let err = check(&[&four, &four, &short], 2, 2, &opts).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 4, actual: 3 }), "a short third plane: {err}");
    let err = check(&[&four], usize::MAX, 2, &opts).unwrap_err();
    assert!(matches!(err, Error::InvalidOption(_)), "{err}");
    let err = ImageKind::detect(&[&four, &four, &short], 2, 2).unwrap_err();
    assert!(matches!(err, Error::BufferSize { .. }), "{err}");
    let err = shift_half(&[1u8, 2, 3], 2, 2).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 4, actual: 3 }), "{err}");
    let err = shift_half(&[1u8, 2, 3, 4, 5], 2, 2).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 4, actual: 5 }), "{err}");
    assert!(HeightSeams::new(usize::MAX, 2).is_err());
}

/// With the `serde` feature the reports serialise with their fields' names
/// and the kind in lower case, as `normalfit tiling --json` prints them.
#[cfg(feature = "serde")]
#[test]
fn reports_serialise_with_their_field_names() {
    // A ramp along x: a height map with a seam in x only.
    let (w, h) = (64, 32);
    let ramp: Vec<f32> = (0..w * h).map(|k| (k % w) as f32 / (w - 1) as f32).collect();
    let report = check(&[&ramp], w, h, &TilingOptions::new()).unwrap();
    let json: serde_json::Value = serde_json::to_value(report).unwrap();
    assert_eq!(json["kind"], "height");
    for (axis, want) in [("x", report.x), ("y", report.y)] {
        assert_eq!(json[axis]["score"].as_f64(), Some(want.score), "{axis}");
        assert_eq!(json[axis]["seamless"].as_bool(), Some(want.seamless), "{axis}");
    }
    assert_eq!(json.as_object().map(|o| o.len()), Some(3), "kind, x and y: {json}");
    assert_eq!(serde_json::to_string(&ImageKind::Normal).unwrap(), r#""normal""#);
}

/// The scores of a height map written plainly from the module docs, in
/// f64, sharing nothing with the library: per level l the texels summed in
/// runs of 2^l along each line, the value and crease sums of every pair of
/// neighbouring lines, the seam against the k-th largest of the interior
/// pairs (those whose stencil lies within the first or the last 256 lines
/// of an axis longer than 512, all of them otherwise), ε from the mean
/// |Δ| over the pairs so judged and the seams.
fn plain_scores(v: &[f32], w: usize, h: usize) -> (f64, f64) {
    const EDGE: usize = 256;
    let at = |x: usize, y: usize| f64::from(v[y * w + x]);
    // Lines of the x axis are columns (h texels); of the y axis, rows.
    let x_lines: Vec<Vec<f64>> = (0..w).map(|x| (0..h).map(|y| at(x, y)).collect()).collect();
    let y_lines: Vec<Vec<f64>> = (0..h).map(|y| (0..w).map(|x| at(x, y)).collect()).collect();
    // Whether lines a ..= b (no wrap) lie in one kept strip.
    let kept = |n: usize, a: usize, b: usize| n <= 2 * EDGE || b < EDGE || a >= n - EDGE;
    let judged_value = |n: usize, k: usize| k == n - 1 || kept(n, k, k + 1);
    let mut total = 0.0;
    let mut count = 0usize;
    for (lines, n) in [(&x_lines, w), (&y_lines, h)] {
        for k in (0..n).filter(|&k| judged_value(n, k)) {
            let (a, b) = (&lines[k], &lines[(k + 1) % n]);
            total += a.iter().zip(b).map(|(a, b)| (b - a).abs()).sum::<f64>();
            count += a.len();
        }
    }
    let mean = total / count as f64;
    let score = |lines: &[Vec<f64>]| -> f64 {
        let (n, len) = (lines.len(), lines[0].len());
        let eps = 1e-3 * mean * len as f64 + 1e-30;
        let ratio = |seam: f64, mut interior: Vec<f64>| -> f64 {
            let k = 4.max((interior.len() as f64 * 0.01).ceil() as usize).min(interior.len().div_ceil(2)).max(1);
            interior.sort_by(f64::total_cmp);
            (seam + eps) / (interior[interior.len() - k] + eps)
        };
        let mut best = 0.0f64;
        for level in 0..6 {
            if level > 0 && len < 8 << level {
                continue;
            }
            let runs: Vec<Vec<f64>> =
                lines.iter().map(|line| line.chunks(1 << level).map(|run| run.iter().sum()).collect()).collect();
            let line = |k: usize| &runs[k % n];
            let value = |k: usize| line(k).iter().zip(line(k + 1)).map(|(a, b)| (b - a).abs()).sum::<f64>();
            let crease = |k: usize| -> f64 {
                let (a, b, c, d) = (line(k + n - 1), line(k), line(k + 1), line(k + 2));
                (0..a.len()).map(|i| ((d[i] - c[i]) - (b[i] - a[i])).abs()).sum()
            };
            let values = (0..n - 1).filter(|&k| kept(n, k, k + 1)).map(value).collect();
            best = best.max(ratio(value(n - 1), values));
            if n >= 4 {
                let creases = (1..n - 2).filter(|&k| kept(n, k - 1, k + 2)).map(crease).collect();
                best = best.max(ratio(crease(n - 1), creases));
            }
        }
        best
    };
    (score(&x_lines), score(&y_lines))
}

/// Heights with structure at every scale and a different character in the
/// middle of the image than within 256 lines of its edges, so that a reference taken over
/// the whole axis gives other scores than one near the seam.
fn two_part_heights(w: usize, h: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let noise = tiling_support::periodic_noise(w, h, 5, 2, seed);
    (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            // Strong stripes in the lines more than 256 from either edge
            // only: interior pairs that only a whole-axis reference sees.
            let middle = (x >= 256 && x + 256 < w) || (y >= 256 && y + 256 < h);
            let stripes = if middle && (x / 5 + y / 7) % 2 == 0 { 3.0 } else { 0.0 };
            noise[k] + stripes + 0.02 * rng.next() as f32 + x as f32 * 1e-3
        })
        .collect()
}

/// Sizes around the cut: axes of 512 (every line kept) and just above it,
/// and long axes against short ones.
const CUT_SIZES: [(usize, usize); 7] = [(512, 40), (513, 40), (514, 37), (40, 515), (600, 530), (1100, 33), (70, 1030)];

#[test]
fn scores_are_the_plain_formulas_with_the_reference_near_the_seam() {
    for (w, h) in CUT_SIZES {
        let v = two_part_heights(w, h, (w * 7 + h) as u64);
        let r = check(&[&v], w, h, &TilingOptions::new().with_kind(KindChoice::Height)).unwrap();
        let (px, py) = plain_scores(&v, w, h);
        let rel = |a: f64, b: f64| (a - b).abs() / b;
        // The library sums in f32 blocks, the plain sums in f64.
        assert!(rel(r.x.score, px) < 1e-4 && rel(r.y.score, py) < 1e-4, "{w}×{h}: {r:?} against {px}, {py}");
    }
}

/// Every row's edge columns and the edge rows, pushed as a caller holding
/// the image in pieces would.
fn stream_edges(v: &[f32], w: usize, h: usize, opts: &TilingOptions, rows_first: bool) -> TilingReport {
    let mut seams = HeightSeams::new(w, h).unwrap();
    let cols = seams.edge_columns();
    let rows = seams.edge_rows();
    let push_rows = |seams: &mut HeightSeams| {
        for r in rows.clone() {
            // In two pieces each, as a row of chunks would bring them.
            let mid = r.start + r.len() / 2;
            seams.push_edge_rows(&v[r.start * w..mid * w]).unwrap();
            seams.push_edge_rows(&v[mid * w..r.end * w]).unwrap();
        }
    };
    if rows_first {
        push_rows(&mut seams);
    }
    let kept: Vec<f64> = v
        .chunks_exact(w)
        .flat_map(|row| cols.iter().flat_map(|c| row[c.clone()].iter().map(|&t| f64::from(t))))
        .collect();
    seams.push_edge_columns(&kept).unwrap();
    if !rows_first {
        push_rows(&mut seams);
    }
    seams.finish(opts).unwrap()
}

#[test]
fn the_edge_strips_alone_give_the_whole_images_report() {
    let opts = TilingOptions::new().with_kind(KindChoice::Height);
    for (w, h) in CUT_SIZES {
        let v = two_part_heights(w, h, (w + h) as u64);
        let whole_rows = stream(&v, w, h, &opts);
        for rows_first in [false, true] {
            assert_eq!(stream_edges(&v, w, h, &opts, rows_first), whole_rows, "{w}×{h}, edge rows first {rows_first}");
        }
        assert_stream_matches(&v, w, h, 1.5, "two-part heights");
        // What the strips hold is what the check reads: the columns and
        // rows (of a long axis) outside them change nothing.
        let seams = HeightSeams::new(w, h).unwrap();
        let (cols, rows) = (seams.edge_columns(), seams.edge_rows());
        // Edge rows are none when the edge columns are whole rows.
        let no_edge_rows = rows.iter().all(|r| r.is_empty());
        let mut changed = v.clone();
        for (k, t) in changed.iter_mut().enumerate() {
            let (x, y) = (k % w, k / w);
            let in_cols = cols.iter().any(|c| c.contains(&x));
            let in_rows = no_edge_rows || rows.iter().any(|r| r.contains(&y));
            if !in_cols && !in_rows {
                *t = 1e3 * ((x * 31 + y * 17) % 13) as f32;
            }
        }
        let report = check(&[&v], w, h, &opts).unwrap();
        assert_eq!(check(&[&changed], w, h, &opts).unwrap(), report, "{w}×{h}: the middle was read");
        assert_eq!(changed != v, w > 512 && h > 512, "{w}×{h}: texels outside the strips");
        // Along an axis of 512 or less every line counts.
        let count = |r: &[std::ops::Range<usize>; 2]| r.iter().map(|r| r.len()).sum::<usize>();
        assert_eq!(count(&cols), w.min(512), "{w}×{h}");
        assert_eq!(count(&rows), if w <= 512 { 0 } else { h.min(512) }, "{w}×{h}");
    }
}

#[test]
fn edge_rows_mixed_with_whole_rows_or_too_many_are_refused() {
    let (w, h) = (600, 530);
    let v = two_part_heights(w, h, 3);
    let mut seams = HeightSeams::new(w, h).unwrap();
    assert_eq!(seams.edge_columns(), [0..256, 344..600]);
    assert_eq!(seams.edge_rows(), [0..256, 274..530]);
    seams.push_edge_rows(&v[..w]).unwrap();
    let err = seams.push_row(&v[w..2 * w]).unwrap_err();
    assert!(err.to_string().contains("edge rows and whole rows"), "{err}");
    let err = seams.push_edge_rows(&vec![0.0f32; 512 * w]).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected, actual } if expected == 511 * w && actual == 512 * w), "{err}");
    let err = seams.push_edge_columns(&[0.0f32; 511]).unwrap_err();
    assert!(matches!(err, Error::BufferSize { .. }), "{err}");
    let err = seams.clone().finish(&TilingOptions::new()).unwrap_err();
    assert_eq!(err.to_string(), "invalid option: the tiling check has 0 of its 530 rows");
    // A narrow image: the edge columns are whole rows, which serve both
    // axes; no edge rows are taken.
    let seams = HeightSeams::new(300, 900).unwrap();
    assert_eq!(seams.edge_columns(), [0..300, 300..300]);
    assert_eq!(seams.edge_rows(), [0..0, 0..0]);
}

/// `HeightSeams::refusing_non_finite` (Python's `normalfit.dask.check_tiling`)
/// refuses a NaN or infinite height among the lines the check reads,
/// naming its texel in the image, whichever way the lines come; heights it
/// does not read are not judged, and without it they count as 0.
#[test]
fn streamed_check_refusing_non_finite_names_the_texel_it_reads() {
    let (w, h) = (600, 600);
    let clean = tiling_support::periodic_noise(w, h, 2, 2, 5);
    let with = |holes: &[(usize, usize)]| {
        let mut v = clean.clone();
        holes.iter().for_each(|&(x, y)| v[y * w + x] = f32::NAN);
        v
    };
    let refusing = || HeightSeams::new(w, h).unwrap().refusing_non_finite();
    // Whole rows: the first in row order.
    let v = with(&[(300, 300), (590, 10)]);
    let e = refusing().push_heights(&v).unwrap_err();
    assert!(matches!(e, Error::NonFiniteHeight { x: 590, y: 10 }), "{e}");
    // Edge columns, then edge rows: each names the image's texel.
    let feed = |v: &[f32]| -> normalfit::Result<()> {
        let mut seams = refusing();
        let cols = seams.edge_columns();
        let strip: Vec<f32> =
            v.chunks_exact(w).flat_map(|row| cols.iter().flat_map(|c| row[c.clone()].to_vec())).collect();
        seams.push_edge_columns(&strip)?;
        for r in seams.edge_rows() {
            seams.push_edge_rows(&v[r.start * w..r.end * w])?;
        }
        seams.finish(&TilingOptions::new()).map(|_| ())
    };
    let e = feed(&with(&[(590, 10)])).unwrap_err();
    assert!(matches!(e, Error::NonFiniteHeight { x: 590, y: 10 }), "{e}");
    let e = feed(&with(&[(300, 595)])).unwrap_err();
    assert!(matches!(e, Error::NonFiniteHeight { x: 300, y: 595 }), "{e}");
    // A height the check does not read is not judged.
    assert!(feed(&with(&[(300, 300)])).is_ok());
    // Without the refusal, non-finite heights count as 0.
    let mut seams = HeightSeams::new(w, h).unwrap();
    seams.push_heights(&with(&[(590, 10)])).unwrap();
    assert!(seams.finish(&TilingOptions::new()).is_ok());
}
