//! Curvature (`--product curvature`, `normalfit::curvature`): against the
//! reference's least-squares quadratic (tests/common/reference.rs) for
//! every border pair, against closed forms on quadratic height fields, and
//! the properties: threads and band starts change no bit, flat in → 0
//! out, holes give NaN, the 8/16-bit mapping.

use crate::common;

use common::reference;
use common::rng::Rng;
use normalfit::fit::quadratic::{CurvatureBands, encode, validate_range};
use normalfit::{Border, Borders, Options, Spacing, Strength, Units, curvature};

const BORDERS: [Border; 3] = [Border::Wrap, Border::Clamp, Border::Mirror];

fn random(w: usize, h: usize, seed: u64) -> Vec<f64> {
    let mut rng = Rng(seed);
    (0..w * h).map(|_| rng.next()).collect()
}

/// The largest difference from the reference, relative to the larger of
/// the reference's value and the map's typical curvature `typical`.
fn check(fast: &[f32], slow: &[f64], typical: f64, what: &str) {
    assert_eq!(fast.len(), slow.len());
    for (k, (&f, &s)) in fast.iter().zip(slow).enumerate() {
        if s.is_nan() {
            assert!(f.is_nan(), "{what}: texel {k} should be NaN, got {f}");
            continue;
        }
        let err = (f64::from(f) - s).abs() / s.abs().max(typical);
        assert!(err < 1e-5, "{what}: texel {k}: fast {f} slow {s} (relative error {err:e})");
    }
}

#[test]
fn matches_the_reference_for_every_border_pair() {
    let sizes = [(1, 1), (7, 1), (1, 6), (5, 4), (13, 11), (19, 23)];
    let mut seed = 1;
    for (w, h) in sizes {
        for n in [3, 5, 9] {
            for bx in BORDERS {
                for by in BORDERS {
                    seed += 1;
                    let heights = random(w, h, seed);
                    let opts = Options::new()
                        .with_patch(n)
                        .with_borders(Borders { x: bx, y: by })
                        .with_strength(Strength::Scale(3.0));
                    let what = format!("{w}×{h}, N = {n}, borders {bx},{by}");
                    let slow = reference::curvature_map(&heights, None, w, h, &opts);
                    // Floats: each patch summed outright.
                    check(&curvature(&heights, w, h, &opts).unwrap(), &slow, 1e-3, &format!("f64 {what}"));
                    // 16-bit: the exact running sums.
                    let stored: Vec<u16> = heights.iter().map(|&v| (v * 65535.0).round() as u16).collect();
                    let contract: Vec<f64> = stored.iter().map(|&v| f64::from(v) / 65535.0).collect();
                    let slow = reference::curvature_map(&contract, None, w, h, &opts);
                    check(&curvature(&stored, w, h, &opts).unwrap(), &slow, 1e-3, &format!("u16 {what}"));
                }
            }
        }
    }
}

#[test]
fn map_units_and_gains_match_the_reference() {
    let (w, h) = (17, 12);
    let heights = random(w, h, 99);
    let metres: Vec<f64> = heights.iter().map(|v| 800.0 + 40.0 * v).collect();
    for (units, strength, invert) in [
        (Units::Map(Spacing::Uniform { x: 30.0, y: 20.0 }), Strength::Scale(1.0), false),
        (Units::Map(Spacing::square(2.5)), Strength::Scale(2.0), true),
        (Units::Texels, Strength::Relief(0.05), false),
    ] {
        let opts = Options::new()
            .with_patch(7)
            .with_borders(Borders { x: Border::Mirror, y: Border::Clamp })
            .with_units(units.clone())
            .with_strength(strength)
            .with_invert(invert);
        let slow = reference::curvature_map(&metres, None, w, h, &opts);
        let typical = slow.iter().fold(0.0f64, |m, v| m.max(v.abs())) * 1e-3;
        check(&curvature(&metres, w, h, &opts).unwrap(), &slow, typical, &format!("{units:?} {strength:?}"));
    }
    let rows = Units::Map(Spacing::Rows(vec![[1.0, 1.0]; h].into()));
    let e = curvature(&metres, w, h, &Options::new().with_units(rows)).unwrap_err();
    assert!(e.to_string().contains("one spacing for the whole map"), "{e}");
}

/// The closed form: on z = α·x² + β·xy + γ·y² + δ·x + ε·y + φ the fitted
/// quadratic is the field itself wherever the patch lies inside the image.
fn quadratic_curvature([al, be, ga, de, ep]: [f64; 5], x: f64, y: f64, gain: f64) -> f64 {
    let p = gain * (2.0 * al * x + be * y + de);
    let q = gain * (be * x + 2.0 * ga * y + ep);
    let (r, s, t) = (gain * 2.0 * al, gain * be, gain * 2.0 * ga);
    let g = 1.0 + p * p + q * q;
    -((1.0 + q * q) * r - 2.0 * p * q * s + (1.0 + p * p) * t) / (2.0 * g * g.sqrt())
}

#[test]
fn quadratic_height_fields_give_their_exact_curvature() {
    let (w, h) = (40, 33);
    // Integer coefficients, so 16-bit samples hold the field exactly.
    for (c, phi) in [([3.0, -2.0, 1.0, 5.0, 7.0], 9000.0), ([-4.0, 1.0, -6.0, -3.0, 2.0], 60000.0)] {
        let [al, be, ga, de, ep] = c;
        let field: Vec<f64> = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f64, (k / w) as f64);
                al * x * x + be * x * y + ga * y * y + de * x + ep * y + phi
            })
            .collect();
        let stored: Vec<u16> = field.iter().map(|&v| v as u16).collect();
        assert!(stored.iter().zip(&field).all(|(&s, &f)| f64::from(s) == f), "the field fits 16 bits");
        for n in [3, 9, 21] {
            for border in BORDERS {
                let opts = Options::new()
                    .with_patch(n)
                    .with_borders(Borders::both(border))
                    .with_strength(Strength::Scale(0.5));
                let from_u16 = curvature(&stored, w, h, &opts).unwrap();
                let from_f64 = curvature(&field, w, h, &opts).unwrap();
                let r = n / 2;
                for y in r..h - r {
                    for x in r..w - r {
                        let k = y * w + x;
                        let (xf, yf) = (x as f64, y as f64);
                        let exact_u16 = quadratic_curvature(c, xf, yf, 0.5 / 65535.0);
                        let exact_f64 = quadratic_curvature(c, xf, yf, 0.5);
                        for (got, exact, what) in [(from_u16[k], exact_u16, "u16"), (from_f64[k], exact_f64, "f64")] {
                            let err = (f64::from(got) - exact).abs() / exact.abs();
                            assert!(err < 1e-6, "{what} N = {n} {border} ({x}, {y}): {got} against {exact}");
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn a_dome_is_convex_and_a_bowl_concave() {
    let (w, h) = (15, 15);
    let dome: Vec<f64> = (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64 - 7.0, (k / w) as f64 - 7.0);
            -(x * x + y * y) / 20.0
        })
        .collect();
    let bowl: Vec<f64> = dome.iter().map(|v| -v).collect();
    let opts = Options::new().with_patch(5).with_borders(Borders::both(Border::Clamp));
    let top = curvature(&dome, w, h, &opts).unwrap()[7 * w + 7];
    let bottom = curvature(&bowl, w, h, &opts).unwrap()[7 * w + 7];
    // z = −(x² + y²)/20 at its top: mean curvature 1/10, convex positive.
    assert!((f64::from(top) - 0.1).abs() < 1e-7, "{top}");
    assert_eq!(bottom, -top);
}

#[test]
fn threads_and_band_starts_change_no_bit() {
    // 150 rows: several bands of rows; shifting the image under wrap
    // starts every band's running sums elsewhere in the content.
    let (w, h) = (37, 150);
    let heights = random(w, h, 7);
    let stored: Vec<u16> = heights.iter().map(|&v| (v * 65535.0) as u16).collect();
    let f32s: Vec<f32> = heights.iter().map(|&v| v as f32).collect();
    let (dx, dy) = (5, 41);
    let shift = |k: usize| ((k / w + dy) % h) * w + (k % w + dx) % w;
    for n in [3, 9, 33] {
        let opts = Options::new().with_patch(n).with_strength(Strength::Scale(4.0));
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| (curvature(&stored, w, h, &opts).unwrap(), curvature(&f32s, w, h, &opts).unwrap()))
        };
        let one = on(1);
        for threads in [2, 3, 8] {
            let many = on(threads);
            assert!(one.0.iter().zip(&many.0).all(|(a, b)| a.to_bits() == b.to_bits()), "u16, N = {n}, {threads}");
            assert!(one.1.iter().zip(&many.1).all(|(a, b)| a.to_bits() == b.to_bits()), "f32, N = {n}, {threads}");
        }
        // Shifted content (x + dx, y + dy wrapped): the curvature shifts
        // with it, bit for bit from integers (exact running sums started
        // elsewhere); to rounding from floats, whose blocks are aligned on
        // the image, not on the content.
        let moved: Vec<u16> = (0..w * h).map(|k| stored[shift(k)]).collect();
        let of_moved = curvature(&moved, w, h, &opts).unwrap();
        for (k, v) in of_moved.iter().enumerate() {
            assert_eq!(v.to_bits(), one.0[shift(k)].to_bits(), "u16 N = {n}: texel {k}");
        }
        let moved: Vec<f32> = (0..w * h).map(|k| f32s[shift(k)]).collect();
        let of_moved = curvature(&moved, w, h, &opts).unwrap();
        let typical = one.1.iter().fold(0.0f32, |m, v| m.max(v.abs())) * 1e-3;
        for (k, v) in of_moved.iter().enumerate() {
            let want = one.1[shift(k)];
            assert!((v - want).abs() <= 1e-5 * want.abs().max(typical), "f32 N = {n}: texel {k}: {v} {want}");
        }
    }
}

#[test]
fn flat_in_zero_out() {
    let (w, h) = (23, 70);
    for n in [3, 11, 31] {
        for border in BORDERS {
            let opts =
                Options::new().with_patch(n).with_borders(Borders::both(border)).with_strength(Strength::Scale(7.0));
            let k = curvature(&vec![12345u16; w * h], w, h, &opts).unwrap();
            assert!(k.iter().all(|&v| v == 0.0), "u16 N = {n} {border}");
            let k = curvature(&vec![0.375f32; w * h], w, h, &opts).unwrap();
            assert!(k.iter().all(|&v| v == 0.0), "f32 N = {n} {border}");
            // Planes have no curvature either (exactly, from integers).
            let plane: Vec<u16> = (0..w * h).map(|k| (100 + 3 * (k % w) + 5 * (k / w)) as u16).collect();
            let k = curvature(&plane, w, h, &opts.clone().with_borders(Borders::both(Border::Clamp))).unwrap();
            let r = n / 2;
            for y in r..h - r {
                for x in r..w.saturating_sub(r) {
                    assert_eq!(k[y * w + x], 0.0, "plane N = {n} at ({x}, {y})");
                }
            }
        }
    }
}

#[test]
fn a_patch_with_a_hole_gives_nan_and_the_rest_the_reference() {
    let (w, h) = (21, 16);
    let mut heights: Vec<f32> = random(w, h, 3).iter().map(|&v| v as f32).collect();
    let hole = 5 * w + 8;
    heights[hole] = -9999.0;
    let valid: Vec<bool> = (0..w * h).map(|k| k != hole).collect();
    for n in [3, 5] {
        for bx in BORDERS {
            let opts = Options::new()
                .with_patch(n)
                .with_borders(Borders { x: bx, y: Border::Clamp })
                .with_nodata(Some(-9999.0));
            let fast = curvature(&heights, w, h, &opts).unwrap();
            let slow = reference::curvature_map(&heights, Some(&valid), w, h, &opts);
            assert_eq!(fast.iter().filter(|v| v.is_nan()).count(), n * n, "N = {n}");
            check(&fast, &slow, 1e-3, &format!("holes N = {n} {bx}"));
        }
    }
    // Without a nodata value a NaN height is an error, as for normals.
    heights[hole] = f32::NAN;
    let e = curvature(&heights, w, h, &Options::new()).unwrap_err();
    assert!(e.to_string().contains("(x 8, y 5)"), "{e}");
}

#[test]
fn the_artists_map_is_flat_at_mid_grey_and_convex_above() {
    assert_eq!(encode(0.0, 0.1, 255), 128);
    assert_eq!(encode(0.1, 0.1, 255), 255);
    assert_eq!(encode(-0.1, 0.1, 255), 1);
    assert_eq!(encode(5.0, 0.1, 255), 255);
    assert_eq!(encode(0.05, 0.1, 255), 192);
    assert_eq!(encode(f32::NAN, 0.1, 255), 128);
    assert_eq!(encode(0.0, 2.0, 65535), 32768);
    assert_eq!(encode(2.0, 2.0, 65535), 65535);
    assert_eq!(encode(-2.0, 2.0, 65535), 1);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(validate_range(bad).is_err(), "{bad}");
    }
}

/// Every texel of `fast` on a grid of `step` (the reference at N = 63 is
/// slow) against the reference of `heights` (h − `offset`, the same
/// quadratic but for its constant term, which the reference then solves
/// without cancelling); relative to the larger of the value and `typical`.
fn check_sampled<H: Copy + Into<f64>>(
    fast: &[f32],
    heights: &[H],
    offset: f64,
    size: (usize, usize),
    opts: &Options,
    step: usize,
    what: &str,
) {
    let (w, h) = size;
    let centred: Vec<f64> = heights.iter().map(|&v| v.into() - offset).collect();
    let mut worst = 0.0f64;
    let mut checked = 0;
    for y in (0..h).step_by(step) {
        for x in (0..w).step_by(step) {
            let slow = reference::curvature_at(&centred, None, w, h, opts, x, y).unwrap();
            worst = worst.max(slow.abs());
            let got = f64::from(fast[y * w + x]);
            let err = (got - slow).abs() / slow.abs().max(1e-3 * worst.max(1e-12));
            assert!(err < 2e-5, "{what} ({x}, {y}): fast {got} slow {slow} (relative error {err:e})");
            checked += 1;
        }
    }
    assert!(worst > 0.0 && checked > 20, "{what}: a relief with curvature, {checked} texels");
}

#[test]
fn large_patches_and_heights_far_from_zero_match_the_reference() {
    // Wider and taller than two blocks of the largest N, so windows cross
    // block boundaries along both axes.
    let (w, h) = (130, 140);
    let relief = |x: f64, y: f64| (x * 0.07).sin() * (y * 0.05).cos() + 0.3 * (x * 0.011 + y * 0.019).cos();
    let far: Vec<f32> = (0..w * h).map(|k| 1000.0 + 0.1 * relief((k % w) as f64, (k / w) as f64) as f32).collect();
    let stored: Vec<u16> =
        (0..w * h).map(|k| (40000.0 + 9000.0 * relief((k % w) as f64, (k / w) as f64)).round() as u16).collect();
    let contract: Vec<f64> = stored.iter().map(|&v| f64::from(v) / 65535.0).collect();
    for n in [3, 5, 9, 63] {
        let step = if n == 63 { 23 } else { 9 };
        for (bx, by) in [(Border::Wrap, Border::Mirror), (Border::Clamp, Border::Wrap)] {
            let opts = Options::new()
                .with_patch(n)
                .with_borders(Borders { x: bx, y: by })
                .with_strength(Strength::Scale(40.0));
            let what = format!("N = {n}, borders {bx},{by}");
            let k = curvature(&far, w, h, &opts).unwrap();
            check_sampled(&k, &far, 1000.0, (w, h), &opts, step, &format!("f32 1000 + relief, {what}"));
            let k = curvature(&stored, w, h, &opts).unwrap();
            check_sampled(&k, &contract, 0.0, (w, h), &opts, step, &format!("u16, {what}"));
        }
    }
}

/// The curvature band by band ([`CurvatureBands`]), each band's rows read
/// from `heights`.
fn by_bands<H: normalfit::samples::Sample>(heights: &[H], w: usize, h: usize, opts: &Options) -> Vec<f32> {
    let fit = CurvatureBands::new(w, h, opts).unwrap();
    let mut out = Vec::new();
    let mut rows_seen = 0;
    for rows in fit.bands() {
        assert_eq!(rows.start, rows_seen, "bands in order");
        rows_seen = rows.end;
        let mut band = vec![0.0f32; rows.len() * w];
        fit.fit_band(rows, &|y| &heights[y * w..][..w], &mut band).unwrap();
        out.extend(band);
    }
    assert_eq!(out.len(), w * h);
    out
}

#[test]
fn bands_of_any_height_and_threads_give_the_whole_images_bits() {
    // Bands of 64 rows a thread (N ≤ 32) after the top r rows: with 1, 2,
    // 3 threads they start on different rows, and inside a band the
    // threads' parts start on others again.
    let (w, h) = (29, 211);
    let heights = random(w, h, 17);
    let f32s: Vec<f32> = heights.iter().map(|&v| v as f32).collect();
    let mut stored: Vec<u16> = heights.iter().map(|&v| (v * 65535.0) as u16).collect();
    let mut holed = f32s.clone();
    holed[97 * w + 11] = -5.0;
    stored[150 * w + 3] = 0;
    // Heights far from zero (10⁷ plus a relief of 10⁻³): the f64 sums'
    // rounding reaches the f32 curvature, so only sums made the same way
    // wherever a band starts (blocks aligned on the image) give the same
    // bits.
    let far: Vec<f64> = heights.iter().map(|&v| 1e7 + 1e-3 * v).collect();
    for n in [3, 9, 33] {
        for bx in BORDERS {
            for by in BORDERS {
                let base = Options::new()
                    .with_patch(n)
                    .with_borders(Borders { x: bx, y: by })
                    .with_strength(Strength::Scale(4.0));
                let holes = base.clone().with_nodata(Some(-5.0));
                let u16_holes = base.clone().with_nodata(Some(0.0));
                let whole = (
                    curvature(&f32s, w, h, &base).unwrap(),
                    curvature(&stored, w, h, &base).unwrap(),
                    curvature(&holed, w, h, &holes).unwrap(),
                    curvature(&stored, w, h, &u16_holes).unwrap(),
                );
                assert!(whole.2.iter().any(|v| v.is_nan()) && whole.3.iter().any(|v| v.is_nan()), "holes");
                let far_whole = curvature(&far, w, h, &base).unwrap();
                assert!(far_whole.iter().any(|&v| v != 0.0) && far_whole.iter().all(|v| v.is_finite()), "far");
                for threads in [1, 2, 3] {
                    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                    let banded = pool.install(|| {
                        (
                            by_bands(&f32s, w, h, &base),
                            by_bands(&stored, w, h, &base),
                            by_bands(&holed, w, h, &holes),
                            by_bands(&stored, w, h, &u16_holes),
                        )
                    });
                    let what = format!("N = {n}, borders {bx},{by}, {threads} threads");
                    let far_banded = pool.install(|| by_bands(&far, w, h, &base));
                    for (a, b, kind) in [
                        (&far_whole, &far_banded, "f64 far from zero"),
                        (&whole.0, &banded.0, "f32"),
                        (&whole.1, &banded.1, "u16"),
                        (&whole.2, &banded.2, "f32 holes"),
                        (&whole.3, &banded.3, "u16 holes"),
                    ] {
                        let differ = a.iter().zip(b).position(|(a, b)| a.to_bits() != b.to_bits());
                        assert_eq!(differ, None, "{kind} {what}");
                    }
                }
            }
        }
    }
    // A range that is not a band is refused.
    let fit = CurvatureBands::new(w, h, &Options::new().with_patch(5)).unwrap();
    let mut band = vec![0.0f32; 10 * w];
    let e = fit.fit_band(5..15, &|y| &f32s[y * w..][..w], &mut band).unwrap_err();
    assert!(matches!(e, normalfit::Error::BufferSize { .. }), "{e}");
}
