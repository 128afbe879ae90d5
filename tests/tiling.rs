//! The tiling check on the shared real textures, the contract's public
//! cases and generated cases, and its edge cases.

mod tiling_support;

use normalfit::tiling::{ImageKind, KindChoice, TilingOptions, check};
use tiling_support::{Case, generated_cases, real_cases, spec_cases};

/// Checks every case's verdicts and detected kind; prints the scores.
fn assert_cases(cases: &[Case]) {
    let opts = TilingOptions::default();
    let mut wrong = Vec::new();
    for c in cases {
        let r = check(&c.image.refs(), c.image.width, c.image.height, &opts);
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
fn real_tileable_textures_pass_and_photos_fail() {
    let Some(cases) = real_cases() else {
        println!("skipped: ../shared/data is absent");
        return;
    };
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
fn constant_images_tile_with_score_one() {
    for (w, h) in [(1, 1), (2, 5), (3, 3), (7, 4), (64, 64)] {
        for planes in [1, 3, 4] {
            let data = vec![vec![0.25f32; w * h]; planes];
            let refs: Vec<&[f32]> = data.iter().map(Vec::as_slice).collect();
            let r = check(&refs, w, h, &TilingOptions::default());
            assert_eq!((r.x.score, r.y.score), (1.0, 1.0), "{w}×{h}, {planes} planes");
            assert!(r.seamless());
        }
    }
}

#[test]
fn tiny_axes_have_defined_answers() {
    // Width 1: the only pair is a column with itself.
    let col = [0.0f32, 0.5, 1.0, 0.2];
    let r = check(&[&col], 1, 4, &TilingOptions::default());
    assert_eq!(r.x.score, 1.0);
    assert!(r.x.seamless && r.y.score.is_finite());
    // Width 2: the wrap pair equals the interior pair.
    let two = [0.0f32, 1.0, 0.0, 1.0];
    let r = check(&[&two], 2, 2, &TilingOptions::default());
    assert_eq!(r.x.score, 1.0);
    // Width 3, a ramp 0, 0.5, 1: the wrap jumps twice as far as its neighbours.
    let three = [0.0f32, 0.5, 1.0, 0.0, 0.5, 1.0, 0.0, 0.5, 1.0];
    let r = check(&[&three], 3, 3, &TilingOptions::default());
    assert!(r.x.score > 1.9 && !r.x.seamless && r.y.seamless, "{r:?}");
    // Empty images tile.
    let r = check(&[&[]], 0, 5, &TilingOptions::default());
    assert!(r.seamless());
}

#[test]
fn non_finite_texels_give_finite_scores() {
    let mut v = tiling_support::periodic_noise(32, 32, 2, 2, 3);
    v[40] = f32::NAN;
    v[41] = f32::INFINITY;
    let r = check(&[&v], 32, 32, &TilingOptions::default());
    assert!(r.x.score.is_finite() && r.y.score.is_finite());
}

#[test]
fn threshold_and_forced_kind_are_obeyed() {
    let n = 64;
    let ramp: Vec<f32> = (0..n * n).map(|k| (k % n) as f32 / (n - 1) as f32).collect();
    let lax = TilingOptions::default().with_threshold(1e9);
    assert!(check(&[&ramp], n, n, &lax).seamless());
    let strict = TilingOptions::default().with_threshold(0.5);
    let sine = &spec_cases()[0].image;
    assert!(!check(&sine.refs(), sine.width, sine.height, &strict).seamless());
    // The same three planes, judged either way.
    let planes = [ramp.as_slice(), ramp.as_slice(), ramp.as_slice()];
    let h = check(&planes, n, n, &TilingOptions::default().with_kind(KindChoice::Height));
    let m = check(&planes, n, n, &TilingOptions::default().with_kind(KindChoice::Normal));
    assert_eq!((h.kind, m.kind), (ImageKind::Height, ImageKind::Normal));
    assert!(!h.x.seamless && !m.x.seamless);
}

#[test]
fn kind_detection() {
    let n = 32;
    let gray = vec![0.5f32; n * n];
    assert_eq!(ImageKind::detect(&[&gray], n, n), ImageKind::Height);
    // Gray stored as RGB is a height map even where (2c − 1)(1, 1, 1) is unit.
    let g = vec![0.7887f32; n * n];
    assert_eq!(ImageKind::detect(&[&g, &g, &g], n, n), ImageKind::Height);
    // A flat encoded normal map, 8-bit: (128, 128, 255) / 255.
    let (half, one) = (vec![128.0f32 / 255.0; n * n], vec![1.0f32; n * n]);
    assert_eq!(ImageKind::detect(&[&half, &half, &one], n, n), ImageKind::Normal);
    // With alpha too.
    assert_eq!(ImageKind::detect(&[&half, &half, &one, &one], n, n), ImageKind::Normal);
    // A float normal map stored raw, n in [−1, 1].
    let (zero, up) = (vec![0.0f32; n * n], vec![1.0f32; n * n]);
    assert_eq!(ImageKind::detect(&[&zero, &zero, &up], n, n), ImageKind::Normal);
    // Random colours are a photo, a height map.
    let mut rng = tiling_support::Rng(9);
    let rgb: Vec<Vec<f32>> = (0..3).map(|_| (0..n * n).map(|_| rng.next() as f32).collect()).collect();
    assert_eq!(ImageKind::detect(&[&rgb[0], &rgb[1], &rgb[2]], n, n), ImageKind::Height);
}

#[test]
fn a_4096_square_check_is_cheap() {
    // Not a benchmark: a guard against an accidental O(n²) or per-texel
    // allocation. The measured figure is in the module docs.
    let n = 4096;
    let v: Vec<f32> = (0..n * n).map(|k| ((k % n) as f32 * 0.37 + (k / n) as f32 * 0.11).sin()).collect();
    let t = std::time::Instant::now();
    let r = check(&[&v], n, n, &TilingOptions::default());
    let took = t.elapsed();
    println!("4096² check: {took:?}, {r:?}");
    assert!(took.as_secs_f64() < 5.0, "4096² check took {took:?}");
}
