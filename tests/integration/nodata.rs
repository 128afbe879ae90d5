//! Holes stay holes: the masked fit against the slow reference
//! (`tests/common/reference.rs`), texel by texel, with no code shared with
//! the library's sums.

use crate::common;

use common::reference;
use normalfit::fit::BandFit;
use normalfit::{Border, Borders, Fit, FitRequest, Options, Spacing, Strength, Units};

/// A small deterministic generator (xorshift).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn all_borders() -> Vec<Borders> {
    let b = [Border::Wrap, Border::Clamp, Border::Mirror];
    let mut all = Vec::new();
    for x in b {
        for y in b {
            all.push(Borders { x, y });
        }
    }
    all
}

/// Random heights with random holes (NaN, or the nodata value).
fn holed(w: usize, h: usize, density: f64, seed: u64) -> (Vec<f32>, Vec<bool>) {
    let mut rng = Rng(seed);
    let mut heights = Vec::new();
    let mut valid = Vec::new();
    for k in 0..w * h {
        let (x, y) = ((k % w) as f64, (k / w) as f64);
        let z = 0.05 * x - 0.03 * y + 0.2 * rng.next();
        if rng.next() < density {
            heights.push(if rng.next() < 0.5 { f32::NAN } else { -9999.0 });
            valid.push(false);
        } else {
            heights.push(z as f32);
            valid.push(true);
        }
    }
    (heights, valid)
}

fn check(got: &[[f64; 3]], got_valid: &[bool], expected: &[Option<[f64; 3]>], tolerance: f64, what: &str) {
    for (k, (e, (g, v))) in expected.iter().zip(got.iter().zip(got_valid)).enumerate() {
        match e {
            None => {
                assert!(!v, "{what}: texel {k} should be missing, got {g:?}");
                assert_eq!(*g, [0.0, 0.0, 1.0], "{what}: texel {k}: a missing texel is written flat");
            }
            Some(e) => {
                assert!(v, "{what}: texel {k} should be valid ({e:?})");
                for c in 0..3 {
                    assert!((g[c] - e[c]).abs() < tolerance, "{what}: texel {k}: {g:?} against {e:?}");
                }
            }
        }
    }
}

#[test]
fn masked_fits_match_the_reference_with_random_holes() {
    let (w, h) = (23, 19);
    let mut cases = 0;
    for (seed, n) in [(1u64, 3usize), (2, 5), (3, 9), (4, 7)] {
        let density = if n == 9 { 0.35 } else { 0.2 };
        let (heights, valid) = holed(w, h, density, seed);
        let as_f64: Vec<f64> = heights.iter().map(|&v| f64::from(v)).collect();
        for borders in all_borders() {
            for fit in [Fit::Orthogonal, Fit::Vertical] {
                for (units, (sx, sy)) in [
                    (Units::Texels, (1.0, 1.0)),
                    (Units::Map(Spacing::Uniform { x: 0.5, y: 0.5 }), (0.5, 0.5)),
                    (Units::Map(Spacing::Uniform { x: 0.5, y: 1.25 }), (0.5, 1.25)),
                ] {
                    let opts = Options::new()
                        .with_patch(n)
                        .with_fit(fit)
                        .with_borders(borders)
                        .with_strength(Strength::Scale(3.0))
                        .with_units(units)
                        .with_nodata(Some(-9999.0));
                    let mut got = vec![[0.0f64; 3]; w * h];
                    let mut got_valid = vec![false; w * h];
                    let missing =
                        FitRequest::new(&opts).holes(&mut got_valid).normals_into(&heights, w, h, &mut got).unwrap();
                    let expected = reference::masked_normal_map(&as_f64, Some(&valid), w, h, &opts);
                    let what = format!("N {n} {fit:?} {borders:?} spacing {sx},{sy}");
                    check(&got, &got_valid, &expected, 1e-9, &what);
                    assert_eq!(missing, expected.iter().filter(|e| e.is_none()).count(), "{what}");
                    cases += 1;
                }
            }
        }
    }
    assert_eq!(cases, 4 * 9 * 2 * 3);
}

/// Stored 16-bit integers (the running-sum path) with a nodata value.
#[test]
fn sixteen_bit_samples_with_a_nodata_value_match_the_reference() {
    let (w, h) = (31, 17);
    let mut rng = Rng(77);
    let mut heights = Vec::new();
    let mut valid = Vec::new();
    for k in 0..w * h {
        let hole = rng.next() < 0.15;
        let v = (1000.0 + 300.0 * (k % w) as f64 + 5000.0 * rng.next()) as u16;
        heights.push(if hole { 0 } else { v.max(1) });
        valid.push(!hole);
    }
    let as_f64: Vec<f64> = heights.iter().map(|&v| f64::from(v) / 65535.0).collect();
    for n in [3, 5, 9] {
        for borders in all_borders() {
            for fit in [Fit::Orthogonal, Fit::Vertical] {
                let opts = Options::new()
                    .with_patch(n)
                    .with_fit(fit)
                    .with_borders(borders)
                    .with_strength(Strength::Scale(40.0))
                    .with_nodata(Some(0.0));
                let mut got = vec![[0.0f64; 3]; w * h];
                let mut got_valid = vec![false; w * h];
                FitRequest::new(&opts).holes(&mut got_valid).normals_into(&heights, w, h, &mut got).unwrap();
                let expected = reference::masked_normal_map(&as_f64, Some(&valid), w, h, &opts);
                check(&got, &got_valid, &expected, 1e-9, &format!("u16 N {n} {fit:?} {borders:?}"));
            }
        }
    }
}

/// Without a hole the masked fit is the plain one, bit for bit; with a
/// nodata value that no texel holds, too.
#[test]
fn full_patches_keep_their_bits() {
    let (w, h) = (40, 33);
    let (mut heights, _) = holed(w, h, 0.0, 9);
    for n in [3, 5, 9, 11] {
        for borders in all_borders() {
            let opts = Options::new().with_patch(n).with_borders(borders).with_strength(Strength::Scale(2.0));
            let mut plain = vec![[0u16; 3]; w * h];
            FitRequest::new(&opts).normals_into(&heights, w, h, &mut plain).unwrap();
            let mut masked = vec![[0u16; 3]; w * h];
            let mut valid = vec![false; w * h];
            let missing = FitRequest::new(&opts.clone().with_nodata(Some(-1.0)))
                .holes(&mut valid)
                .normals_into(&heights, w, h, &mut masked)
                .unwrap();
            assert_eq!(missing, 0);
            assert!(valid.iter().all(|&v| v));
            assert_eq!(plain, masked, "N {n} {borders:?}");
        }
    }
    // One hole: every texel whose patch misses it keeps its bits.
    let n = 5;
    let opts = Options::new().with_patch(n).with_borders(Borders::both(Border::Clamp));
    let mut plain = vec![[0.0f32; 3]; w * h];
    FitRequest::new(&opts).normals_into(&heights, w, h, &mut plain).unwrap();
    heights[10 * w + 20] = f32::NAN;
    let mut masked = vec![[0.0f32; 3]; w * h];
    let mut valid = vec![false; w * h];
    assert_eq!(FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, w, h, &mut masked).unwrap(), 1);
    for y in 0..h {
        for x in 0..w {
            let near = x.abs_diff(20) <= 2 && y.abs_diff(10) <= 2;
            if !near {
                assert_eq!(plain[y * w + x], masked[y * w + x], "{x},{y}");
            } else if (x, y) != (20, 10) {
                assert!(valid[y * w + x]);
            }
        }
    }
}

#[test]
fn too_few_or_collinear_points_are_missing() {
    // A valid texel whose 3×3 patch has two other valid points: three
    // points, not in a line, give a plane; a valid cross of holes around a
    // texel with only its row valid gives a line: missing.
    let (w, h) = (7, 7);
    let mut heights = vec![f32::NAN; w * h];
    for (x, y) in [(3, 3), (4, 3), (3, 4)] {
        heights[y * w + x] = 0.1 * x as f32;
    }
    let opts = Options::new().with_borders(Borders::both(Border::Clamp));
    let mut normals = vec![[0.0f64; 3]; w * h];
    let mut valid = vec![false; w * h];
    let missing = FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, w, h, &mut normals).unwrap();
    assert!(valid[3 * w + 3] && valid[3 * w + 4] && valid[4 * w + 3], "three points make a plane");
    assert_eq!(missing, w * h - 3);
    let l = (0.01f64 + 1.0).sqrt();
    assert!((normals[3 * w + 3][0] + 0.1 / l).abs() < 1e-6, "{:?}", normals[3 * w + 3]);

    // Two points: too few.
    let mut two = vec![f32::NAN; w * h];
    two[3 * w + 3] = 0.5;
    two[3 * w + 4] = 0.7;
    assert_eq!(FitRequest::new(&opts).holes(&mut valid).normals_into(&two, w, h, &mut normals).unwrap(), w * h);

    // A whole row valid, the rest holes: every patch's points are in a line.
    let mut row = vec![f32::NAN; w * h];
    for x in 0..w {
        row[3 * w + x] = 0.1 * x as f32;
    }
    for fit in [Fit::Orthogonal, Fit::Vertical] {
        let opts = opts.clone().with_fit(fit).with_patch(5);
        assert_eq!(
            FitRequest::new(&opts).holes(&mut valid).normals_into(&row, w, h, &mut normals).unwrap(),
            w * h,
            "{fit:?}"
        );
    }
    // A diagonal line (wrapping: a clamped corner would add points off it).
    let opts = opts.with_borders(Borders::both(Border::Wrap));
    let mut diagonal = vec![f32::NAN; w * h];
    for k in 0..w {
        diagonal[k * w + k] = 0.2 * k as f32;
    }
    assert_eq!(FitRequest::new(&opts).holes(&mut valid).normals_into(&diagonal, w, h, &mut normals).unwrap(), w * h);
}

#[test]
fn an_all_missing_image_is_all_missing() {
    for (w, h) in [(1, 1), (5, 3), (64, 70)] {
        let heights = vec![-32768.0f32; w * h];
        let opts = Options::new().with_nodata(Some(-32768.0));
        let mut normals = vec![[0u8; 3]; w * h];
        let mut valid = vec![true; w * h];
        assert_eq!(FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, w, h, &mut normals).unwrap(), w * h);
        assert!(valid.iter().all(|&v| !v));
        assert!(normals.iter().all(|&n| n == [128, 128, 255]));
        // The plain API with a nodata value: missing texels written flat.
        let mut plain = vec![[0u8; 3]; w * h];
        FitRequest::new(&opts).normals_into(&heights, w, h, &mut plain).unwrap();
        assert_eq!(plain, normals);
    }
}

#[test]
fn flat_heights_with_holes_give_flat_normals() {
    let (w, h) = (30, 20);
    let (mut heights, _) = holed(w, h, 0.25, 5);
    for v in heights.iter_mut().filter(|v| v.is_finite() && **v != -9999.0) {
        *v = 123.25;
    }
    for n in [3, 5, 9] {
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            let opts = Options::new().with_patch(n).with_fit(fit).with_nodata(Some(-9999.0));
            let mut normals = vec![[0u8; 3]; w * h];
            let mut valid = vec![false; w * h];
            FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, w, h, &mut normals).unwrap();
            for (k, normal) in normals.iter().enumerate() {
                assert_eq!(*normal, [128, 128, 255], "N {n} {fit:?} texel {k}");
            }
            assert!(valid.iter().filter(|&&v| v).count() > w * h / 2);
        }
    }
}

#[test]
fn parallel_serial_and_bands_give_the_same_bits() {
    let (w, h) = (700, 300);
    let (heights, _) = holed(w, h, 0.1, 11);
    for n in [3, 9] {
        let opts = Options::new().with_patch(n).with_nodata(Some(-9999.0));
        let mut whole = vec![[0.0f32; 3]; w * h];
        let mut whole_valid = vec![false; w * h];
        let missing = FitRequest::new(&opts).holes(&mut whole_valid).normals_into(&heights, w, h, &mut whole).unwrap();
        let serial = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let mut one = vec![[0.0f32; 3]; w * h];
        let mut one_valid = vec![false; w * h];
        serial.install(|| FitRequest::new(&opts).holes(&mut one_valid).normals_into(&heights, w, h, &mut one).unwrap());
        assert!(whole == one && whole_valid == one_valid, "N {n}: serial");
        let fit = BandFit::new(w, h, &opts).unwrap();
        let (mut banded, mut banded_valid, mut count) = (Vec::new(), Vec::new(), 0);
        for rows in fit.bands() {
            let mut band = vec![[0.0f32; 3]; rows.len() * w];
            let mut valid = vec![false; rows.len() * w];
            count += fit.fit_band_masked(rows, &|y| &heights[y * w..][..w], &mut band, &mut valid).unwrap();
            banded.extend(band);
            banded_valid.extend(valid);
        }
        assert!(whole == banded && whole_valid == banded_valid, "N {n}: bands");
        assert_eq!(count, missing);
    }
}

#[test]
fn without_a_nodata_value_a_nan_is_still_an_error() {
    let mut heights = vec![0.5f32; 16];
    heights[5] = f32::NAN;
    let mut out = vec![[0.0f32; 3]; 16];
    assert!(matches!(
        FitRequest::new(&Options::new()).normals_into(&heights, 4, 4, &mut out),
        Err(normalfit::Error::NonFiniteHeight { x: 1, y: 1 })
    ));
}
