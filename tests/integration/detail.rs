//! Detail at several scales (`Options::detail`, docs/detail.md): the
//! normal of the weighted sum of the scales' slopes, against that sum made
//! here, in f64, from each scale's own fit; the same bits on any pool,
//! streamed, in windows; one scale of weight 1 is its size's fit.

use crate::common::rng::Rng;

use normalfit::fit::{BandFit, HaloPlan};
use normalfit::{Border, Borders, Detail, Fit, FitRequest, Options, Spacing, Strength, Units};

const BORDERS: [Border; 3] = [Border::Wrap, Border::Clamp, Border::Mirror];

/// Heights with detail at every scale (a slow wave, a faster one, grain),
/// no symmetry, in [0, 1].
fn field(w: usize, h: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed | 1);
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            let v = 0.5 + 0.25 * (x * 0.11 + y * 0.05).sin() + 0.1 * (x * 0.7).cos() * (y * 0.45).sin();
            (v + 0.1 * rng.next()) as f32
        })
        .collect()
}

fn detail(scales: &[(usize, f64)]) -> Detail {
    Detail::new(scales.iter().copied()).unwrap()
}

/// The combination the rule states, made here: each scale fitted alone
/// (the existing API, f64 normals), slopes p = −nx/nz, q = −ny/nz summed
/// with the weights, n ∝ (−Σ w p, −Σ w q, 1).
fn combined(heights: &[f32], (w, h): (usize, usize), opts: &Options, scales: &[(usize, f64)]) -> Vec<[f64; 3]> {
    let mut sums = vec![[0.0f64; 2]; w * h];
    for &(n, weight) in scales {
        let single = opts.clone().with_detail(None).with_patch(n);
        let mut normals = vec![[0.0f64; 3]; w * h];
        FitRequest::new(&single).normals_into(heights, w, h, &mut normals).unwrap();
        for (s, [nx, ny, nz]) in sums.iter_mut().zip(normals) {
            assert!(nz > 0.0, "no plane here is vertical");
            let (p, q) = (-nx / nz, -ny / nz);
            s[0] -= weight * p;
            s[1] -= weight * q;
        }
    }
    sums.iter()
        .map(|&[a, b]| {
            let len = (a * a + b * b + 1.0).sqrt();
            [a / len, b / len, 1.0 / len]
        })
        .collect()
}

fn worst(got: &[[f64; 3]], want: &[[f64; 3]]) -> f64 {
    got.iter().zip(want).flat_map(|(g, w)| (0..3).map(move |c| (g[c] - w[c]).abs())).fold(0.0, f64::max)
}

#[test]
fn the_normal_is_that_of_the_summed_slopes_of_each_scale_s_own_fit_for_every_border_and_fit() {
    let (w, h) = (29, 23);
    let heights = field(w, h, 7);
    // Sizes larger than the image too (patches reaching round it), a
    // negative weight, and an order that is not sorted.
    let scales = [(9, 0.5), (3, 1.0), (5, -0.3), (31, 0.25)];
    for (bx, by) in BORDERS.iter().flat_map(|&x| BORDERS.iter().map(move |&y| (x, y))) {
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            let opts =
                Options::new().with_borders(Borders { x: bx, y: by }).with_fit(fit).with_strength(Strength::Scale(6.0));
            let want = combined(&heights, (w, h), &opts, &scales);
            let multi = opts.clone().with_detail(Some(detail(&scales)));
            let mut got = vec![[0.0f64; 3]; w * h];
            FitRequest::new(&multi).normals_into(&heights, w, h, &mut got).unwrap();
            let what = format!("{bx},{by} {fit}");
            assert!(worst(&got, &want) < 1e-12, "{what}: {}", worst(&got, &want));
            let mut got32 = vec![[0.0f32; 3]; w * h];
            FitRequest::new(&multi).normals_into(&heights, w, h, &mut got32).unwrap();
            let got32: Vec<[f64; 3]> = got32.iter().map(|n| n.map(f64::from)).collect();
            assert!(worst(&got32, &want) < 1e-6, "{what} f32: {}", worst(&got32, &want));
            // Something to see: the scales differ, and the sum is none of them.
            let coarse = combined(&heights, (w, h), &opts, &[(31, 1.0)]);
            assert!(worst(&got, &coarse) > 0.05, "{what}");
        }
    }
}

#[test]
fn integer_heights_and_map_units_combine_the_same_way() {
    let (w, h) = (26, 19);
    let heights: Vec<u16> = field(w, h, 3).iter().map(|&v| (v.clamp(0.0, 1.0) * 65535.0).round() as u16).collect();
    let as_f32: Vec<f32> = heights.iter().map(|&v| v as f32).collect();
    let scales = [(3, 1.0), (7, 0.5)];
    // Map units take the stored values as heights, texels 2 × 3 apart (in
    // units of 10⁴: slopes under 1, so that no scale's plane is vertical).
    let opts = Options::new()
        .with_borders(Borders { x: Border::Mirror, y: Border::Clamp })
        .with_units(Units::Map(Spacing::Uniform { x: 20000.0, y: 30000.0 }));
    let want = combined(&as_f32, (w, h), &opts, &scales);
    let mut got = vec![[0.0f64; 3]; w * h];
    FitRequest::new(&opts.clone().with_detail(Some(detail(&scales)))).normals_into(&heights, w, h, &mut got).unwrap();
    assert!(worst(&got, &want) < 1e-12, "{}", worst(&got, &want));
    // The contract's units: 16-bit samples are v / 65535.
    let opts = Options::new().with_strength(Strength::Scale(20.0));
    let unit: Vec<f32> = heights.iter().map(|&v| (f64::from(v) / 65535.0) as f32).collect();
    let want = combined(&unit, (w, h), &opts, &scales);
    let mut got = vec![[0.0f64; 3]; w * h];
    FitRequest::new(&opts.with_detail(Some(detail(&scales)))).normals_into(&heights, w, h, &mut got).unwrap();
    // The f32 heights round v / 65535; the fit of the samples does not.
    assert!(worst(&got, &want) < 1e-5, "{}", worst(&got, &want));
}

#[test]
fn one_scale_of_weight_one_is_that_size_s_fit_bit_for_bit() {
    let (w, h) = (37, 21);
    let heights = field(w, h, 11);
    for n in [3, 5, 9, 33] {
        let single = Options::new().with_patch(n).with_strength(Strength::Scale(4.0));
        let multi = Options::new().with_strength(Strength::Scale(4.0)).with_detail(Some(detail(&[(n, 1.0)])));
        let mut a = vec![[0u16; 3]; w * h];
        let mut b = vec![[0u16; 3]; w * h];
        FitRequest::new(&single).normals_into(&heights, w, h, &mut a).unwrap();
        FitRequest::new(&multi).normals_into(&heights, w, h, &mut b).unwrap();
        assert_eq!(a, b, "N = {n}");
        let (mut a, mut b) = (vec![[0.0f32; 3]; w * h], vec![[0.0f32; 3]; w * h]);
        FitRequest::new(&single).normals_into(&heights, w, h, &mut a).unwrap();
        FitRequest::new(&multi).normals_into(&heights, w, h, &mut b).unwrap();
        assert_eq!(a, b, "N = {n}");
    }
}

#[test]
fn the_bits_are_the_same_on_any_pool_streamed_and_in_windows() {
    // Tall enough for several bands (a band is at least 2^14 texels).
    let (w, h) = (40, 1300);
    let heights = field(w, h, 5);
    let scales = [(3, 1.0), (9, 0.5), (33, 0.25)];
    for by in BORDERS {
        let opts = Options::new()
            .with_borders(Borders { x: Border::Wrap, y: by })
            .with_strength(Strength::Scale(8.0))
            .with_detail(Some(detail(&scales)));
        let fit = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut out = vec![[0u16; 3]; w * h];
            pool.install(|| FitRequest::new(&opts).normals_into(&heights, w, h, &mut out)).unwrap();
            out
        };
        let whole = fit(1);
        assert_eq!(whole, fit(3), "{by}: 1 and 3 threads");
        // On one thread a band is one block of rows: several bands here.
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let band = one.install(|| BandFit::new(w, h, &opts)).unwrap();
        assert_eq!(band.radius(), 16, "the halo is the largest size's");
        let bands: Vec<_> = band.bands().collect();
        assert!(bands.len() > 2, "{bands:?}");
        let mut streamed = Vec::new();
        for rows in bands {
            let mut out = vec![[0u16; 3]; rows.len() * w];
            band.fit_band(rows, &|y| &heights[y * w..][..w], &mut out).unwrap();
            streamed.extend(out);
        }
        assert_eq!(streamed, whole, "{by}: streamed");
        // A window of rows 500 .. 530, columns 7 .. 30, with the halo planned.
        let window = HaloPlan::new(&opts).unwrap().window((w, h), (7, 500), (23, 30));
        let (hw, hh) = window.held_size();
        // Columns left of 0 are the wrap's, from the right edge.
        let (x0, y0) = (7 - window.halo.left as isize, 500 - window.halo.top);
        let image = &heights;
        let held: Vec<f32> = (y0..y0 + hh)
            .flat_map(|y| (x0..x0 + hw as isize).map(move |x| image[y * w + x.rem_euclid(w as isize) as usize]))
            .collect();
        let mut out = vec![[0u16; 3]; 23 * 30];
        FitRequest::new(&opts).window(window).normals_into(&held, hw, hh, &mut out).unwrap();
        for (k, texel) in out.iter().enumerate() {
            assert_eq!(*texel, whole[(500 + k / 23) * w + 7 + k % 23], "{by}: window texel {k}");
        }
    }
}

#[test]
fn a_texel_is_missing_where_any_scale_misses_it() {
    let (w, h) = (24, 18);
    let mut heights = field(w, h, 9);
    for k in [5 * w + 6, 5 * w + 7, 6 * w + 6, 12 * w + 20] {
        heights[k] = f32::NAN;
    }
    // A 3×3 patch of holes and edges: the centre misses at N = 3 only if
    // too few valid points remain; mark a block to make sure it does.
    for y in 14..18 {
        for x in 0..5 {
            heights[y * w + x] = f32::NAN;
        }
    }
    let scales = [(3, 1.0), (7, 0.5)];
    let opts = Options::new().with_borders(Borders::both(Border::Clamp));
    let mut valid_each = Vec::new();
    let mut normals_each = Vec::new();
    for &(n, _) in &scales {
        let mut normals = vec![[0.0f64; 3]; w * h];
        let mut valid = vec![false; w * h];
        FitRequest::new(&opts.clone().with_patch(n))
            .holes(&mut valid)
            .normals_into(&heights, w, h, &mut normals)
            .unwrap();
        valid_each.push(valid);
        normals_each.push(normals);
    }
    let multi = opts.clone().with_detail(Some(detail(&scales)));
    let mut got = vec![[0.0f64; 3]; w * h];
    let mut valid = vec![false; w * h];
    let missing = FitRequest::new(&multi)
        .holes(&mut valid)
        .missing([f64::NAN; 3])
        .normals_into(&heights, w, h, &mut got)
        .unwrap();
    let want_valid: Vec<bool> = (0..w * h).map(|k| valid_each.iter().all(|v| v[k])).collect();
    assert_eq!(valid, want_valid);
    assert_eq!(missing, want_valid.iter().filter(|&&v| !v).count());
    assert!(missing > 4, "the block misses more than its holes: {missing}");
    for k in 0..w * h {
        if !valid[k] {
            assert!(got[k].iter().all(|c| c.is_nan()), "texel {k}");
            continue;
        }
        let (mut a, mut b) = (0.0, 0.0);
        for (normals, &(_, weight)) in normals_each.iter().zip(&scales) {
            let [nx, ny, nz] = normals[k];
            (a, b) = (a + weight * nx / nz, b + weight * ny / nz);
        }
        let len = (a * a + b * b + 1.0).sqrt();
        let want = [a / len, b / len, 1.0 / len];
        assert!((0..3).all(|c| (got[k][c] - want[c]).abs() < 1e-12), "texel {k}: {:?} {want:?}", got[k]);
    }
}

#[test]
fn what_detail_cannot_do_is_refused_in_one_line() {
    let (w, h) = (8, 8);
    let heights = field(w, h, 1);
    let opts = Options::new().with_detail(Some(detail(&[(3, 1.0), (5, 1.0)])));
    let mut out = vec![[0.0f32; 3]; w * h];
    let mut residual = vec![0.0f32; w * h];
    let e = FitRequest::new(&opts).residual(&mut residual).normals_into(&heights, w, h, &mut out).unwrap_err();
    assert!(e.to_string().contains("detail at several scales has no residual"), "{e}");
    let e = opts.clone().with_patch(5).validate().unwrap_err();
    assert_eq!(e.to_string(), "invalid option: give a patch size (5) or detail at several scales, not both");
    let e = normalfit::height::HeightOptions::from_fit(&opts).validate().unwrap_err();
    assert!(e.to_string().contains("the height inverse undoes one patch size's fit"), "{e}");
    // One scale of weight 1 keeps its residual: it is that size's fit.
    let single = Options::new().with_detail(Some(detail(&[(5, 1.0)])));
    FitRequest::new(&single).residual(&mut residual).normals_into(&heights, w, h, &mut out).unwrap();
}
