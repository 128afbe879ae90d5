//! Binomial weights (`--weights binomial`, `weights="binomial"`): the fast
//! weighted fit against the slow reference's weighted least squares
//! (`tests/common/reference.rs`), Horn's formula at N = 3, and the
//! properties every fit holds (flat in → flat out, wrap commutes with
//! shifting, one thread = many, bands = whole, windows = whole).

use std::sync::Arc;

use crate::common;

use common::reference;
use normalfit::fit::{BandFit, HaloPlan};
use normalfit::{Border, Borders, Fit, FitRequest, Options, Spacing, Strength, Units, Weights, normals};

const BORDERS: [Border; 3] = [Border::Wrap, Border::Clamp, Border::Mirror];

/// A DEM-like field: heights near 400 (metres) with hills, a ridge and
/// small-scale roughness, so that every patch has a known non-zero tilt.
fn dem(w: usize, h: usize) -> Vec<f64> {
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            let rough = (((k as u64).wrapping_mul(2_654_435_761) % 1009) as f64 / 1009.0 - 0.5) * 0.3;
            400.0 + 3.0 * (0.21 * x).sin() * (0.17 * y).cos() + 0.4 * x - 0.25 * y
                + 2.0 * (-(x - y).abs() / 6.0).exp()
                + rough
        })
        .collect()
}

fn binomial(n: usize, fit: Fit, borders: Borders) -> Options {
    Options::new().with_patch(n).with_fit(fit).with_borders(borders).with_weights(Weights::Binomial)
}

fn all_borders() -> impl Iterator<Item = Borders> {
    BORDERS.into_iter().flat_map(|x| BORDERS.into_iter().map(move |y| Borders { x, y }))
}

fn worst(fast: &[[f64; 3]], slow: &[[f64; 3]]) -> (f64, usize) {
    let mut worst = (0.0, 0);
    for (k, (f, s)) in fast.iter().zip(slow).enumerate() {
        for c in 0..3 {
            let e = (f[c] - s[c]).abs();
            if e > worst.0 {
                worst = (e, k);
            }
        }
    }
    worst
}

fn fitted(z: &[f64], w: usize, h: usize, opts: &Options) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0f64; 3]; w * h];
    FitRequest::new(opts).normals_into(z, w, h, &mut out).unwrap();
    out
}

/// Every border pair, both fits, N = 3, 5, 9 and 33, in texel units with
/// a gain and in map units with unequal spacing and a spacing a row.
#[test]
fn the_weighted_fit_is_the_references_weighted_least_squares() {
    let mut cases = 0;
    for (n, (w, h)) in [(3, (19, 13)), (5, (17, 15)), (9, (21, 18)), (33, (35, 20))] {
        let z = dem(w, h);
        let rows: Arc<[[f64; 2]]> = (0..h).map(|y| [2.0 + 0.05 * y as f64, 3.0]).collect();
        // N = 33's reference costs N² a texel: three border pairs (each
        // mode on each axis) keep the test to a few seconds.
        let pairs: Vec<Borders> = if n < 33 {
            all_borders().collect()
        } else {
            vec![
                Borders { x: Border::Wrap, y: Border::Clamp },
                Borders { x: Border::Clamp, y: Border::Mirror },
                Borders { x: Border::Mirror, y: Border::Wrap },
            ]
        };
        for borders in pairs {
            for fit in [Fit::Orthogonal, Fit::Vertical] {
                for units in [
                    Units::Texels,
                    Units::Map(Spacing::Uniform { x: 2.0, y: 3.0 }),
                    Units::Map(Spacing::Rows(rows.clone())),
                ] {
                    let map = !matches!(units, Units::Texels);
                    // In texel units the gain makes the slopes steep
                    // enough for the orthogonal fit to differ.
                    let opts = binomial(n, fit, borders).with_units(units).with_strength(Strength::Scale(if map {
                        1.0
                    } else {
                        0.7
                    }));
                    let fast = fitted(&z, w, h, &opts);
                    let slow = reference::normal_map(&z, w, h, &opts);
                    let (err, at) = worst(&fast, &slow);
                    assert!(
                        err < 1e-9,
                        "N {n} {fit:?} {borders:?} map {map}: {err:e} at {at}: {:?} {:?}",
                        fast[at],
                        slow[at]
                    );
                    // And not the unweighted fit's: the weights change the answer.
                    if n < 33 {
                        let uniform = reference::normal_map(&z, w, h, &opts.clone().with_weights(Weights::Uniform));
                        assert!(worst(&fast, &uniform).0 > 1e-4, "N {n} {fit:?}: the weights made no difference");
                    }
                    cases += 1;
                }
            }
        }
    }
    assert_eq!(cases, (3 * 9 + 3) * 2 * 3);
}

/// Holes: every patch fitted to its valid points with their weights, as
/// the reference's weighted least squares over the points it keeps.
#[test]
fn holes_are_fitted_with_the_valid_points_weights() {
    let (w, h) = (23, 19);
    let mut z = dem(w, h);
    let mut valid = vec![true; w * h];
    for k in 0..w * h {
        // About a fifth of the texels, and a block of nine.
        if (k * 7919) % 100 < 20 || ((k % w) / 3 == 2 && (k / w) / 3 == 2) {
            z[k] = if k % 2 == 0 { f64::NAN } else { -9999.0 };
            valid[k] = false;
        }
    }
    let mut cases = 0;
    for n in [3, 5, 9] {
        for borders in all_borders() {
            for fit in [Fit::Orthogonal, Fit::Vertical] {
                for units in [Units::Texels, Units::Map(Spacing::Uniform { x: 0.5, y: 1.25 })] {
                    let opts = binomial(n, fit, borders).with_units(units).with_nodata(Some(-9999.0));
                    let mut got = vec![[0.0f64; 3]; w * h];
                    let mut got_valid = vec![false; w * h];
                    let missing =
                        FitRequest::new(&opts).holes(&mut got_valid).normals_into(&z, w, h, &mut got).unwrap();
                    let expected = reference::masked_normal_map(&z, Some(&valid), w, h, &opts);
                    let what = format!("N {n} {fit:?} {borders:?}");
                    for (k, e) in expected.iter().enumerate() {
                        match e {
                            None => assert!(!got_valid[k], "{what}: texel {k} should be missing"),
                            Some(e) => {
                                assert!(got_valid[k], "{what}: texel {k} should be valid");
                                // Heights near 400 in texel units: the centred
                                // moments W·Σwz² − (Σwz)² of steep patches keep
                                // about 1e-9 of the normal (the spec asks 1e-5).
                                let err = (0..3).map(|c| (got[k][c] - e[c]).abs()).fold(0.0, f64::max);
                                assert!(err < 1e-7, "{what}: texel {k}: {:?} against {e:?}", got[k]);
                            }
                        }
                    }
                    assert_eq!(missing, expected.iter().filter(|e| e.is_none()).count(), "{what}");
                    assert!(missing > 0 && missing < w * h / 2, "{what}: {missing}");
                    cases += 1;
                }
            }
        }
    }
    assert_eq!(cases, 3 * 9 * 2 * 2);
}

/// Horn's gradient (gdaldem's), written out: at N = 3 with the vertical
/// fit, binomial weights give its slope and aspect, on a projected map of
/// unequal spacing.
#[test]
fn at_n_3_the_vertical_fit_is_horns_gradient() {
    let (w, h) = (40, 30);
    let z = dem(w, h);
    for (sx, sy) in [(1.0, 1.0), (2.0, 3.0), (30.0, 20.0)] {
        let opts = binomial(3, Fit::Vertical, Borders::both(Border::Clamp))
            .with_units(Units::Map(Spacing::Uniform { x: sx, y: sy }));
        let fast = fitted(&z, w, h, &opts);
        let (mut checked, mut aspects) = (0, 0);
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                // a b c / d e f / g h i, rows down the image (south).
                let at = |i: isize, j: isize| z[(y as isize + j) as usize * w + (x as isize + i) as usize];
                let (a, b, c) = (at(-1, -1), at(0, -1), at(1, -1));
                let (d, f) = (at(-1, 0), at(1, 0));
                let (g, hh, i) = (at(-1, 1), at(0, 1), at(1, 1));
                let dzdx = ((c + 2.0 * f + i) - (a + 2.0 * d + g)) / (8.0 * sx);
                let dzdy = ((g + 2.0 * hh + i) - (a + 2.0 * b + c)) / (8.0 * sy);
                let slope = (dzdx * dzdx + dzdy * dzdy).sqrt().atan().to_degrees();
                let aspect = {
                    let a = dzdy.atan2(-dzdx).to_degrees();
                    if a > 90.0 { 450.0 - a } else { 90.0 - a }
                };
                let (got_slope, got_aspect) = reference::slope_aspect_gdal(fast[y * w + x]);
                assert!((got_slope - slope).abs() < 1e-5, "{sx}×{sy} ({x}, {y}): slope {got_slope} against {slope}");
                if slope > 0.1 {
                    let diff = (got_aspect.unwrap() - aspect).rem_euclid(360.0);
                    let diff = diff.min(360.0 - diff);
                    assert!(diff < 1e-3, "{sx}×{sy} ({x}, {y}): aspect {got_aspect:?} against {aspect}");
                    aspects += 1;
                }
                checked += 1;
            }
        }
        assert_eq!(checked, (w - 2) * (h - 2));
        // Known non-zero answers: nearly every texel has a slope and an aspect.
        assert!(aspects * 10 > checked * 9, "{sx}×{sy}: {aspects} of {checked}");
    }
}

/// Flat in → flat out, exactly, at every N, whatever the level.
#[test]
fn flat_heights_give_flat_normals() {
    for n in [3, 9, 15, 33, 63, 255] {
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            for level in [0.0f32, 0.37, 412.5] {
                let (w, h) = (40, 37);
                let opts = binomial(n, fit, Borders::both(Border::Mirror));
                let got = normals(&vec![level; w * h], w, h, &opts).unwrap();
                assert!(got.iter().all(|&v| v == [0.0, 0.0, 1.0]), "N {n} {fit:?} at {level}");
            }
        }
    }
}

/// With wrap, the fit of a shifted image is the shifted fit, bit for bit.
#[test]
fn wrap_commutes_with_shifting() {
    let (w, h) = (29, 23);
    let z = dem(w, h);
    // 41 by blocks: the shift moves texels across blocks, which round
    // differently (about 1e-12 of a normal), hence 1e-10, not bits.
    for n in [3, 9, 41] {
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            let opts = binomial(n, fit, Borders::both(Border::Wrap)).with_strength(Strength::Scale(0.5));
            let base = fitted(&z, w, h, &opts);
            let (dx, dy) = (5, 3);
            let shifted: Vec<f64> = (0..w * h).map(|k| z[((k / w + dy) % h) * w + (k % w + dx) % w]).collect();
            let got = fitted(&shifted, w, h, &opts);
            for k in 0..w * h {
                let expected = base[((k / w + dy) % h) * w + (k % w + dx) % w];
                let close = (0..3).all(|c| (got[k][c] - expected[c]).abs() < 1e-10);
                assert!(close, "N {n} {fit:?}: texel {k}: {:?} against {expected:?}", got[k]);
            }
        }
    }
}

/// One thread and many, bands (as a stream fits them) and the whole image,
/// windows of any cut: the same bits, holes included.
#[test]
fn threads_bands_and_windows_give_the_whole_image_bits() {
    let (w, h) = (1100, 90);
    let mut z: Vec<f32> = dem(w, h).into_iter().map(|v| v as f32).collect();
    for k in (0..w * h).step_by(37) {
        z[k] = -9999.0;
    }
    // 41 and 65 by blocks of 88 and 192 columns and rows.
    for n in [3, 9, 41, 65] {
        for nodata in [None, Some(-9999.0)] {
            let heights: Vec<f32> = match nodata {
                None => z.iter().map(|&v| if v == -9999.0 { 400.0 } else { v }).collect(),
                Some(_) => z.clone(),
            };
            let opts = binomial(n, Fit::Orthogonal, Borders { x: Border::Mirror, y: Border::Wrap })
                .with_units(Units::Map(Spacing::Uniform { x: 1.0, y: 1.5 }))
                .with_nodata(nodata);
            let run = |threads: Option<usize>| {
                let mut out = vec![[0.0f32; 3]; w * h];
                let mut valid = vec![false; w * h];
                let mut fit =
                    || FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, w, h, &mut out).unwrap();
                match threads {
                    None => fit(),
                    Some(t) => rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap().install(fit),
                };
                (out, valid)
            };
            let (whole, whole_valid) = run(None);
            let what = format!("N {n} nodata {nodata:?}");
            assert!(run(Some(1)) == (whole.clone(), whole_valid.clone()), "{what}: one thread");
            let fit = BandFit::new(w, h, &opts).unwrap();
            let mut banded = Vec::new();
            for rows in fit.bands() {
                let mut band = vec![[0.0f32; 3]; rows.len() * w];
                let mut valid = vec![false; rows.len() * w];
                fit.fit_band_masked(rows, &|y| &heights[y * w..][..w], &mut band, &mut valid).unwrap();
                banded.extend(band);
            }
            assert!(banded == whole, "{what}: bands");
            // Windows of a few cuts, each fitted from its own held texels.
            let plan = HaloPlan::new(&opts).unwrap();
            for (xs, ys) in [(0..300, 0..40), (300..777, 40..90), (777..1100, 7..61), (50..51, 20..21)] {
                let window = plan.window((w, h), (xs.start, ys.start), (xs.len(), ys.len()));
                let (hw, hh) = window.held_size();
                let (x0, y0) =
                    (xs.start as isize - window.halo.left as isize, ys.start as isize - window.halo.top as isize);
                let held: Vec<f32> = (0..hh as isize)
                    .flat_map(|j| {
                        let row = opts.borders.y.map(y0 + j, h);
                        (0..hw as isize).map(move |i| (row, opts.borders.x.map(x0 + i, w)))
                    })
                    .map(|(row, col)| heights[row * w + col])
                    .collect();
                let mut out = vec![[0.0f32; 3]; xs.len() * ys.len()];
                let mut valid = vec![false; xs.len() * ys.len()];
                FitRequest::new(&opts).window(window).holes(&mut valid).normals_into(&held, hw, hh, &mut out).unwrap();
                for (k, y) in ys.clone().enumerate() {
                    assert!(
                        out[k * xs.len()..][..xs.len()] == whole[y * w + xs.start..y * w + xs.end],
                        "{what}: window {xs:?} × {ys:?}, row {y}"
                    );
                }
            }
        }
    }
}

/// Past the crossover (sums by FFT in blocks): the reference's weighted
/// least squares with holes, each border mode on each axis, both fits, on
/// an image of two blocks across and two down (N = 37: blocks of 92
/// columns from 0; rows 0..18, then 92 from row 18), holes in some blocks
/// only (those rows' blocks summed directly, the others by FFT). The
/// reference costs N² a texel: three pairs keep it to a few seconds (the
/// bits of the other pairs are the whole fit's in the window tests).
#[test]
fn by_blocks_the_fit_is_the_references_with_holes() {
    let (n, w, h) = (37, 94, 22);
    let mut z = dem(w, h);
    let mut valid = vec![true; w * h];
    for k in (0..w * h).filter(|k| (k * 7919) % 500 < 3 || (k / w == 12 && (k % w) / 4 == 3)) {
        z[k] = -9999.0;
        valid[k] = false;
    }
    let pairs = [
        (Borders { x: Border::Wrap, y: Border::Clamp }, Fit::Orthogonal),
        (Borders { x: Border::Clamp, y: Border::Mirror }, Fit::Vertical),
        (Borders { x: Border::Mirror, y: Border::Wrap }, Fit::Orthogonal),
    ];
    for (borders, fit) in pairs {
        let opts = binomial(n, fit, borders)
            .with_units(Units::Map(Spacing::Uniform { x: 1.5, y: 1.0 }))
            .with_nodata(Some(-9999.0));
        let mut got = vec![[0.0f64; 3]; w * h];
        let mut got_valid = vec![false; w * h];
        FitRequest::new(&opts).holes(&mut got_valid).normals_into(&z, w, h, &mut got).unwrap();
        let expected = reference::masked_normal_map(&z, Some(&valid), w, h, &opts);
        let what = format!("N {n} {fit:?} {borders:?}");
        let (mut worst, mut fitted) = (0.0f64, 0);
        for (k, e) in expected.iter().enumerate() {
            match e {
                None => assert!(!got_valid[k], "{what}: texel {k} should be missing"),
                Some(e) => {
                    assert!(got_valid[k], "{what}: texel {k} should be valid");
                    worst = worst.max((0..3).map(|c| (got[k][c] - e[c]).abs()).fold(0.0, f64::max));
                    fitted += 1;
                }
            }
        }
        assert!(fitted * 10 > w * h * 9, "{what}: {fitted} fitted");
        // Heights near 400 m: the transforms' rounding scales with the
        // relief within a block (about 1e-12 of a normal here, the direct
        // sums' about 1e-13); the spec asks 1e-5.
        assert!(worst < 1e-9, "{what}: {worst:e}");
    }
}

/// By blocks a window's halo holds its blocks' inputs: the plan says so,
/// and a window holding only r texels around it is refused in one line.
#[test]
fn by_blocks_a_halo_too_small_for_the_blocks_is_refused() {
    let (w, h) = (300, 200);
    let z = dem(w, h);
    let opts = binomial(41, Fit::Vertical, Borders::both(Border::Wrap));
    let plan = HaloPlan::new(&opts).unwrap();
    // r = 20 and blocks of 88: columns from 0, rows from 20.
    assert_eq!((plan.radius(), plan.reach()), (20, 20 + 87));
    let window = plan.window((w, h), (100, 120), (10, 10));
    let halo = normalfit::fit::Halo {
        left: 100 - 88 + 20,
        right: 176 - 110 + 20,
        top: 120 - 108 + 20,
        bottom: 196 - 130 + 20,
    };
    assert_eq!(window.halo, halo);
    // Below N = 37 the halo stays r.
    assert_eq!(HaloPlan::new(&binomial(35, Fit::Vertical, Borders::both(Border::Wrap))).unwrap().reach(), 17);
    let small = normalfit::fit::Window { halo: normalfit::fit::Halo::uniform(20), ..window };
    let (hw, hh) = small.held_size();
    let held: Vec<f64> = (0..hw * hh).map(|k| z[((120 - 20 + k / hw) % h) * w + (100 - 20 + k % hw) % w]).collect();
    let mut out = vec![[0.0f64; 3]; 100];
    let e = FitRequest::new(&opts).window(small).normals_into(&held, hw, hh, &mut out).unwrap_err();
    let e = e.to_string();
    assert!(e.contains("the window's patches read column 68") && e.contains("HaloPlan") && !e.contains('\n'), "{e}");
    // The planned halo fits, and gives the whole image's bits.
    let (hw, hh) = window.held_size();
    let (x0, y0) = (100 - window.halo.left, 120 - window.halo.top);
    let held: Vec<f64> = (0..hw * hh).map(|k| z[((y0 + k / hw) % h) * w + (x0 + k % hw) % w]).collect();
    FitRequest::new(&opts).window(window).normals_into(&held, hw, hh, &mut out).unwrap();
    let whole = fitted(&z, w, h, &opts);
    for (k, got) in out.iter().enumerate() {
        assert_eq!(*got, whole[(120 + k / 10) * w + 100 + k % 10], "texel {k}");
    }
}

/// What the weighted fit does not define yet is refused in one line.
#[test]
fn undefined_combinations_are_refused_with_the_reason() {
    let opts = Options::new().with_weights(Weights::Binomial);
    let z = vec![0.5f32; 64];
    let mut out = vec![[0.0f32; 3]; 64];
    let mut residual = vec![0.0f32; 64];
    let e = FitRequest::new(&opts).residual(&mut residual).normals_into(&z, 8, 8, &mut out).unwrap_err();
    assert!(e.to_string().contains("residual") && !e.to_string().contains('\n'), "{e}");
    let e = normalfit::curvature(&z, 8, 8, &opts).unwrap_err();
    assert!(e.to_string().contains("curvature map fits an unweighted quadratic"), "{e}");
    let detail = opts.clone().with_detail(Some("3:1,9:0.5".parse().unwrap()));
    assert!(detail.validate().unwrap_err().to_string().contains("fit one patch size"));
    let e = normalfit::height::HeightOptions::from_fit(&opts).validate().unwrap_err();
    assert!(e.to_string().contains("height inverse"), "{e}");
}
