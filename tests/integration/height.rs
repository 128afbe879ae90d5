//! `normalfit::height` against independent answers: single Fourier and
//! cosine modes whose slopes are written here from the fit's definition
//! (SPEC §2), a dense least-squares solve of the same problem written
//! plainly (no code shared with the transforms), round trips through the
//! forward fit, and the properties: flat in → flat out, shifts under wrap,
//! thread counts, texels without a slope, the convention under auto.

use crate::common;

use common::reference::source_index;
use normalfit::height::{ConventionChoice, HeightOptions, Model, heights, heights_with_holes};
use normalfit::{Border, Borders, Convention, Fit, FitRequest, Options, Strength, normals};

/// Σ i² over the N×N patch.
fn a_of(n: usize) -> f64 {
    let r = (n / 2) as i64;
    let mut a = 0.0;
    for i in -r..=r {
        for _ in -r..=r {
            a += (i * i) as f64;
        }
    }
    a
}

/// Σ_i i sin(iω) and Σ_i cos(iω) over i ∈ [−r, r], summed plainly.
fn ramp_and_box(n: usize, omega: f64) -> (f64, f64) {
    let r = (n / 2) as i64;
    let (mut s, mut b) = (0.0, 0.0);
    for i in -r..=r {
        s += i as f64 * (i as f64 * omega).sin();
        b += (i as f64 * omega).cos();
    }
    (s, b)
}

/// The normal of slopes (∂z/∂x, ∂z/∂y) under a convention: n ∝ (−gx, −σ gy, 1).
fn normal_of(gx: f64, gy: f64, convention: Convention) -> [f64; 3] {
    let sigma = if convention == Convention::OpenGl { -1.0 } else { 1.0 };
    let n = [-gx, -sigma * gy, 1.0];
    let len = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
    n.map(|c| c / len)
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

/// The vertical fit of patch `n` with `borders`.
fn vertical(n: usize, borders: Borders) -> Options {
    Options::new().with_fit(Fit::Vertical).with_patch(n).with_borders(borders)
}

fn demean(v: &[f64]) -> Vec<f64> {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    v.iter().map(|x| x - mean).collect()
}

/// Wrap: z = a sin(ωx x + ωy y + φ) has vertical-fit slopes
/// (a/A) S(ωx) B(ωy) cos(θ) and (a/A) B(ωx) S(ωy) cos(θ); the heights found
/// from those normals are z itself (mean 0), to 1e-9.
#[test]
fn a_single_fourier_mode_comes_back_to_1e_9() {
    for (w, h, kx, ky) in [(32, 24, 3, 2), (17, 40, 5, 7), (64, 64, 1, 0), (30, 30, 13, 4)] {
        for n in [3, 5, 9] {
            for convention in [Convention::OpenGl, Convention::DirectX] {
                for scale in [1.0, 7.5] {
                    let (amp, phi) = (0.8, 0.3);
                    let (wx, wy) =
                        (std::f64::consts::TAU * kx as f64 / w as f64, std::f64::consts::TAU * ky as f64 / h as f64);
                    let a = a_of(n);
                    let (sx, bx) = ramp_and_box(n, wx);
                    let (sy, by) = ramp_and_box(n, wy);
                    let mut want = Vec::new();
                    let mut normals = Vec::new();
                    for y in 0..h {
                        for x in 0..w {
                            let theta = wx * x as f64 + wy * y as f64 + phi;
                            // z = S h: heights of amplitude amp, surface of amp · S.
                            let z_amp = amp * scale;
                            let gx = z_amp / a * sx * by * theta.cos();
                            let gy = z_amp / a * bx * sy * theta.cos();
                            normals.push(normal_of(gx, gy, convention));
                            want.push(amp * theta.sin());
                        }
                    }
                    let opts = HeightOptions::from_fit(
                        &Options::new()
                            .with_fit(Fit::Vertical)
                            .with_patch(n)
                            .with_convention(convention)
                            .with_strength(Strength::Scale(scale)),
                    );
                    let got = heights(&normals, w, h, &opts).unwrap();
                    let err = max_diff(&got.values, &demean(&want));
                    assert!(err < 1e-9, "{w}×{h} k ({kx}, {ky}) N {n} {convention:?} S {scale}: {err:e}");
                    assert_eq!(got.report.convention, convention);
                }
            }
        }
    }
}

/// Mirror: z = a cos(ωx x) cos(ωy y), ω = πk/(n − 1), is its own mirrored
/// extension; its slopes are −(a/A) S(ωx) B(ωy) sin(ωx x) cos(ωy y) and
/// −(a/A) B(ωx) S(ωy) cos(ωx x) sin(ωy y).
#[test]
fn a_single_cosine_mode_comes_back_to_1e_9_under_mirror() {
    for (w, h, kx, ky) in [(20, 13, 3, 2), (33, 9, 7, 5), (16, 16, 1, 0)] {
        for n in [3, 5] {
            let pi = std::f64::consts::PI;
            let (wx, wy) = (pi * kx as f64 / (w - 1) as f64, pi * ky as f64 / (h - 1) as f64);
            let a = a_of(n);
            let (sx, bx) = ramp_and_box(n, wx);
            let (sy, by) = ramp_and_box(n, wy);
            let amp = 1.3;
            let mut want = Vec::new();
            let mut normals = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    let (xf, yf) = (x as f64, y as f64);
                    let gx = -amp / a * sx * by * (wx * xf).sin() * (wy * yf).cos();
                    let gy = -amp / a * bx * sy * (wx * xf).cos() * (wy * yf).sin();
                    normals.push(normal_of(gx, gy, Convention::OpenGl));
                    want.push(amp * (wx * xf).cos() * (wy * yf).cos());
                }
            }
            let opts = HeightOptions::from_fit(&vertical(n, Borders::both(Border::Mirror)));
            let got = heights(&normals, w, h, &opts).unwrap();
            let err = max_diff(&got.values, &demean(&want));
            assert!(err < 1e-9, "{w}×{h} k ({kx}, {ky}) N {n}: {err:e}");
        }
    }
}

/// A small deterministic generator (no dependency): values in [−1, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// The dense problem, written from its definition: over one period of the
/// texture as the borders extend it (wrap: the image; mirror: 2(n − 1)
/// texels, a reflected copy's slope along its axis negated; clamp: the
/// image), the squared differences of the vertical fit's slopes of z (the
/// image's texels, read through the reference's border rule) and the given
/// slopes; minimum norm over that period (each texel weighted by how often
/// the period holds it). Solved by the singular value decomposition of the
/// operator itself (one-sided Jacobi), not its normal equations, whose
/// squared conditioning would lose the modes a wide patch sees faintly
/// (singular values 5e-7 of the largest at 2 × 5, N = 41): singular values
/// below 1e-10 of the largest are the null space.
fn dense_solve(gx: &[f64], gy: &[f64], w: usize, h: usize, n: usize, borders: Borders) -> Vec<f64> {
    demean(&dense_least_squares(gx, gy, w, h, n, borders, &vec![false; w * h]).z)
}

/// The dense problem's solution of least W-norm (not demeaned), and its
/// right singular vectors: `modes` holds each one's σ² and its vector in
/// heights (v/√W, so that ⟨a, b⟩_W of two is the Kronecker δ).
struct Dense {
    z: Vec<f64>,
    modes: Vec<(f64, Vec<f64>)>,
    weight: Vec<f64>,
}

impl Dense {
    /// The largest σ².
    fn largest(&self) -> f64 {
        self.modes.iter().fold(0.0f64, |m, (s, _)| m.max(*s))
    }
    /// The W-inner products of `z` (NaN read as 0) with the modes whose σ²
    /// is `above` (true) or at most (false) `cut` times the largest,
    /// summed in squares.
    fn part(&self, z: &[f64], cut: f64, above: bool) -> f64 {
        let largest = self.largest();
        self.modes
            .iter()
            .filter(|(s, _)| (*s > cut * largest) == above)
            .map(|(_, v)| {
                let c: f64 =
                    v.iter().zip(z).zip(&self.weight).map(|((v, z), w)| if z.is_nan() { 0.0 } else { v * z * w }).sum();
                c * c
            })
            .sum()
    }
}

/// The dense problem with holes: the equations of the period texels whose
/// patches hold a hole left out, the holes' heights out of the unknowns
/// (their columns 0, so their heights come out 0).
fn dense_least_squares(
    gx: &[f64],
    gy: &[f64],
    w: usize,
    h: usize,
    n: usize,
    borders: Borders,
    holes: &[bool],
) -> Dense {
    let unknowns = w * h;
    let texels: Vec<PeriodTexel> = period_texels(gx, gy, w, h, n, borders)
        .into_iter()
        .filter(|t| !t.patch.iter().any(|&k| holes[k]))
        .map(|mut t| {
            for k in (0..unknowns).filter(|&k| holes[k]) {
                (t.row_x[k], t.row_y[k]) = (0.0, 0.0);
            }
            t
        })
        .collect();
    // Multiplicities as the period holds the texels, whatever is kept.
    let mut weight = vec![0.0f64; unknowns];
    period_texels(gx, gy, w, h, n, borders).iter().for_each(|t| weight[t.texel] += 1.0);
    // In z' = W^½ z the minimum W-norm is the minimum norm: the operator's
    // columns divided by √W. Columns of M (rows of `columns`), targets g.
    let mut columns = vec![vec![0.0; 2 * texels.len()]; unknowns];
    let mut g = Vec::with_capacity(2 * texels.len());
    for (r, t) in texels.iter().enumerate() {
        for k in 0..unknowns {
            columns[k][2 * r] = t.row_x[k] / weight[k].sqrt();
            columns[k][2 * r + 1] = t.row_y[k] / weight[k].sqrt();
        }
        g.extend([t.target.0, t.target.1]);
    }
    // Rotate pairs of columns until every pair is orthogonal: M V = U Σ,
    // V the product of the rotations.
    let mut v: Vec<Vec<f64>> =
        (0..unknowns).map(|k| (0..unknowns).map(|i| if i == k { 1.0 } else { 0.0 }).collect()).collect();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    for _sweep in 0..60 {
        let mut rotated = false;
        for p in 0..unknowns {
            for q in p + 1..unknowns {
                let (alpha, beta, gamma) =
                    (dot(&columns[p], &columns[p]), dot(&columns[q], &columns[q]), dot(&columns[p], &columns[q]));
                if gamma.abs() <= 1e-15 * (alpha * beta).sqrt() || gamma == 0.0 {
                    continue;
                }
                rotated = true;
                let zeta = (beta - alpha) / (2.0 * gamma);
                let t = zeta.signum() / (zeta.abs() + (1.0 + zeta * zeta).sqrt());
                let t = if zeta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (1.0 + t * t).sqrt();
                let s = c * t;
                for m in [&mut columns, &mut v] {
                    let (left, right) = m.split_at_mut(q);
                    for (a, b) in left[p].iter_mut().zip(right[0].iter_mut()) {
                        let (x, y) = (*a, *b);
                        *a = c * x - s * y;
                        *b = s * x + c * y;
                    }
                }
            }
        }
        if !rotated {
            break;
        }
    }
    // z' = Σ_k v_k (m_k · g) / σ_k², m_k = M v_k = u_k σ_k.
    let sigma2: Vec<f64> = columns.iter().map(|c| dot(c, c)).collect();
    let largest = sigma2.iter().fold(0.0f64, |m, s| m.max(*s));
    let mut z = vec![0.0; unknowns];
    for k in 0..unknowns {
        if sigma2[k] > 1e-20 * largest {
            let f = dot(&columns[k], &g) / sigma2[k];
            for i in 0..unknowns {
                z[i] += f * v[k][i];
            }
        }
    }
    let z: Vec<f64> = z.iter().zip(&weight).map(|(z, w)| z / w.sqrt()).collect();
    let modes =
        (0..unknowns).map(|k| (sigma2[k], v[k].iter().zip(&weight).map(|(v, w)| v / w.sqrt()).collect())).collect();
    Dense { z, modes, weight }
}

/// One texel of the period as the dense problem sees it: the image texel
/// it holds, the rows of the vertical fit's Dx and Dy there (over the
/// image's texels, read through the reference's border rule), and the
/// given slopes it is to match (a reflected copy's slope along its axis
/// negated).
struct PeriodTexel {
    texel: usize,
    /// The image texels its patch reads.
    patch: Vec<usize>,
    row_x: Vec<f64>,
    row_y: Vec<f64>,
    target: (f64, f64),
}

/// Every texel of the period of a `w` × `h` image with `borders`, patch `n`.
fn period_texels(gx: &[f64], gy: &[f64], w: usize, h: usize, n: usize, borders: Borders) -> Vec<PeriodTexel> {
    let period = |len: usize, b: Border| match b {
        Border::Mirror if len > 2 => 2 * (len - 1),
        _ => len,
    };
    let (px, py) = (period(w, borders.x), period(h, borders.y));
    let r = (n / 2) as isize;
    let a = a_of(n);
    let unknowns = w * h;
    let reflected = |p: usize, len: usize, b: Border| b == Border::Mirror && len > 2 && p >= len;
    let map = |k: isize, len: usize, b: Border| source_index(k as i64, len as i64, b) as usize;
    let mut texels = Vec::with_capacity(px * py);
    for qy in 0..py {
        for qx in 0..px {
            let (ix, iy) = (map(qx as isize, w, borders.x), map(qy as isize, h, borders.y));
            let sx = if reflected(qx, w, borders.x) { -1.0 } else { 1.0 };
            let sy = if reflected(qy, h, borders.y) { -1.0 } else { 1.0 };
            let mut row_x = vec![0.0; unknowns];
            let mut row_y = vec![0.0; unknowns];
            let mut patch = Vec::new();
            for j in -r..=r {
                for i in -r..=r {
                    let tx = map(qx as isize + i, w, borders.x);
                    let ty = map(qy as isize + j, h, borders.y);
                    row_x[ty * w + tx] += i as f64 / a;
                    row_y[ty * w + tx] += j as f64 / a;
                    patch.push(ty * w + tx);
                }
            }
            let texel = iy * w + ix;
            texels.push(PeriodTexel { texel, patch, row_x, row_y, target: (sx * gx[texel], sy * gy[texel]) });
        }
    }
    texels
}

/// The dense problem's misfit of heights `z`: Σ over the period of
/// |D z − g|², the vertical fit's slopes as the linear operator gives them.
fn linear_misfit(z: &[f64], gx: &[f64], gy: &[f64], w: usize, h: usize, n: usize, borders: Borders) -> f64 {
    let dot = |row: &[f64]| row.iter().zip(z).map(|(a, b)| a * b).sum::<f64>();
    period_texels(gx, gy, w, h, n, borders)
        .iter()
        .map(|t| (dot(&t.row_x) - t.target.0).powi(2) + (dot(&t.row_y) - t.target.1).powi(2))
        .sum()
}

/// LU factors with partial pivoting: (matrix, pivots).
fn lu_factor(mut a: Vec<f64>, m: usize) -> (Vec<f64>, Vec<usize>) {
    let mut perm: Vec<usize> = (0..m).collect();
    for col in 0..m {
        let pivot = (col..m).max_by(|&p, &q| a[p * m + col].abs().total_cmp(&a[q * m + col].abs())).unwrap();
        if pivot != col {
            for k in 0..m {
                a.swap(col * m + k, pivot * m + k);
            }
            perm.swap(col, pivot);
        }
        let d = a[col * m + col];
        for row in col + 1..m {
            let f = a[row * m + col] / d;
            a[row * m + col] = f;
            if f != 0.0 {
                for k in col + 1..m {
                    a[row * m + k] -= f * a[col * m + k];
                }
            }
        }
    }
    (a, perm)
}

fn lu_solve((a, perm): &(Vec<f64>, Vec<usize>), b: &[f64], m: usize) -> Vec<f64> {
    let mut x: Vec<f64> = perm.iter().map(|&p| b[p]).collect();
    for row in 0..m {
        for k in 0..row {
            x[row] -= a[row * m + k] * x[k];
        }
    }
    for row in (0..m).rev() {
        for k in row + 1..m {
            x[row] -= a[row * m + k] * x[k];
        }
        x[row] /= a[row * m + row];
    }
    x
}

/// Random slopes (not integrable: a foreign map), the fast path against the
/// dense solve, every border, N = 3 and 5, sizes up to 16 texels a side,
/// odd and even. (The dense solve's cost grows with the cube of the texels:
/// with 16×16 the test took 42 s of CI.)
#[test]
fn the_transforms_match_a_dense_least_squares_solve() {
    let mut rng = Lcg(7);
    let modes = [Border::Wrap, Border::Mirror, Border::Clamp];
    for (w, h) in [(16, 8), (9, 12), (15, 7), (2, 5), (1, 6)] {
        for n in [3, 5] {
            for bx in modes {
                for by in modes {
                    let borders = Borders { x: bx, y: by };
                    let len = w * h;
                    let (gx, gy): (Vec<f64>, Vec<f64>) = (0..len).map(|_| (rng.next(), rng.next())).unzip();
                    let normals: Vec<[f64; 3]> =
                        gx.iter().zip(&gy).map(|(&a, &b)| normal_of(a, b, Convention::OpenGl)).collect();
                    let opts = HeightOptions::from_fit(&vertical(n, borders));
                    let got = heights(&normals, w, h, &opts).unwrap();
                    let want = dense_solve(&gx, &gy, w, h, n, borders);
                    let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1.0);
                    let err = max_diff(&got.values, &want) / scale;
                    assert!(err < 1e-7, "{w}×{h} N {n} {borders:?}: {err:e} (iterations {})", got.report.iterations);
                }
            }
        }
    }
}

/// Heights with detail at every scale, in [0, 1]-ish: a few waves and bumps.
fn terrain(w: usize, h: usize, seed: u64) -> Vec<f64> {
    let mut rng = Lcg(seed);
    let waves: Vec<[f64; 4]> =
        (0..12).map(|_| [rng.next() * 0.4, rng.next() * 0.4, rng.next() * 3.0, rng.next() * 0.1]).collect();
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            0.5 + waves.iter().map(|[fx, fy, p, a]| a * (fx * x + fy * y + p).sin()).sum::<f64>()
        })
        .collect()
}

/// A periodic terrain for wrap: waves of whole periods.
fn periodic_terrain(w: usize, h: usize, seed: u64) -> Vec<f64> {
    let mut rng = Lcg(seed);
    let tau = std::f64::consts::TAU;
    let waves: Vec<[f64; 4]> = (0..12)
        .map(|_| [(rng.next() * 6.0).round(), (rng.next() * 6.0).round(), rng.next() * 3.0, rng.next() * 0.1])
        .collect();
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            0.5 + waves
                .iter()
                .map(|[kx, ky, p, a]| a * (tau * (kx * x / w as f64 + ky * y / h as f64) + p).sin())
                .sum::<f64>()
        })
        .collect()
}

/// A terrain for mirror: cosine modes whose mirrored period is smooth.
fn mirror_terrain(w: usize, h: usize, seed: u64) -> Vec<f64> {
    let mut rng = Lcg(seed);
    let pi = std::f64::consts::PI;
    let waves: Vec<[f64; 3]> = (0..12)
        .map(|_| [(rng.next().abs() * 9.0).round(), (rng.next().abs() * 9.0).round(), rng.next() * 0.1])
        .collect();
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            0.5 + waves
                .iter()
                .map(|[kx, ky, a]| a * (pi * kx * x / (w - 1) as f64).cos() * (pi * ky * y / (h - 1) as f64).cos())
                .sum::<f64>()
        })
        .collect()
}

/// The largest error of a round trip, relative to the heights' range, up
/// to a constant.
fn round_trip_error(original: &[f64], back: &[f64]) -> f64 {
    let want = demean(original);
    let (lo, hi) = want.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    max_diff(&want, back) / (hi - lo)
}

/// The same, also up to the heights the fit cannot see: a height that
/// alternates from column to column, row to row, or both (its slopes are 0
/// in every patch), which comes back as 0. The difference's least-squares
/// fit by a constant and those three patterns is removed.
fn visible_round_trip_error(original: &[f64], back: &[f64], w: usize) -> f64 {
    let want = demean(original);
    let (lo, hi) = want.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    let sign = |k: usize| if k.is_multiple_of(2) { 1.0 } else { -1.0 };
    let basis = |k: usize| [1.0, sign(k % w), sign(k / w), sign(k % w) * sign(k / w)];
    let diff: Vec<f64> = want.iter().zip(back).map(|(a, b)| a - b).collect();
    let (mut m, mut v) = (vec![0.0; 16], vec![0.0; 4]);
    for (k, d) in diff.iter().enumerate() {
        let b = basis(k);
        for p in 0..4 {
            v[p] += b[p] * d;
            for q in 0..4 {
                m[p * 4 + q] += b[p] * b[q];
            }
        }
    }
    let c = lu_solve(&lu_factor(m, 4), &v, 4);
    let rest: Vec<f64> =
        diff.iter().enumerate().map(|(k, d)| d - basis(k).iter().zip(&c).map(|(b, c)| b * c).sum::<f64>()).collect();
    rest.iter().fold(0.0f64, |m, v| m.max(v.abs())) / (hi - lo)
}

/// Float normals (f32, as an EXR holds them) from the forward fit, back to
/// heights within 1e-4 of their range: wrap and mirror, N = 3 and 5, both
/// fits, two gains, on terrains smooth over their border's period.
#[test]
fn float_round_trips_are_within_1e_4_of_the_range() {
    let (w, h) = (96, 64);
    for (border, original) in [(Border::Wrap, periodic_terrain(w, h, 3)), (Border::Mirror, mirror_terrain(w, h, 4))] {
        for n in [3, 5] {
            for fit in [Fit::Vertical, Fit::Orthogonal] {
                for scale in [1.0, 20.0] {
                    let opts = Options::new()
                        .with_patch(n)
                        .with_fit(fit)
                        .with_borders(Borders::both(border))
                        .with_strength(Strength::Scale(scale));
                    let n32 = normals(&original, w, h, &opts).unwrap();
                    let back = heights(&n32, w, h, &HeightOptions::from_fit(&opts)).unwrap();
                    let err = round_trip_error(&original, &back.values);
                    assert!(back.report.converged, "{border:?} N {n} {fit:?} S {scale}");
                    assert!(err < 1e-4, "{border:?} N {n} {fit:?} S {scale}: {err:e}");
                }
            }
        }
    }
}

/// Steep relief (S = 40: slopes of several texel widths a texel), where
/// the orthogonal fit's fixed point converges slowly or not at all: the
/// Gauss–Newton refinement brings the heights back within 1e-4 of their
/// range, and says it settled.
#[test]
fn steep_orthogonal_round_trips_are_within_1e_4_of_the_range() {
    let (w, h) = (96, 64);
    for (border, original) in [(Border::Wrap, periodic_terrain(w, h, 3)), (Border::Mirror, mirror_terrain(w, h, 4))] {
        for n in [3, 5] {
            let opts = Options::new()
                .with_patch(n)
                .with_fit(Fit::Orthogonal)
                .with_borders(Borders::both(border))
                .with_strength(Strength::Scale(40.0));
            let n32 = normals(&original, w, h, &opts).unwrap();
            let back = heights(&n32, w, h, &HeightOptions::from_fit(&opts)).unwrap();
            let err = round_trip_error(&original, &back.values);
            println!("{border:?} N {n} S 40: {err:.2e} after {} solves", back.report.iterations);
            assert!(back.report.converged, "{border:?} N {n}");
            assert!(err < 1e-4, "{border:?} N {n}: {err:e}");
        }
    }
}

/// A terrain that is not smooth over the mirrored period holds a little of
/// the alternating heights no fit sees (1.7e-4 of the range here): they
/// come back as 0, and the rest within 1e-4 (vertical fit; the orthogonal
/// fit's λ does see them, through Czz, and the iteration, which solves for
/// the vertical slopes, does not: measured 5e-4 of the range here).
#[test]
fn mirror_round_trips_are_exact_but_for_the_heights_no_fit_sees() {
    let (w, h) = (96, 64);
    let original = terrain(w, h, 4);
    for n in [3, 5] {
        let opts = Options::new().with_patch(n).with_fit(Fit::Vertical).with_borders(Borders::both(Border::Mirror));
        let n32 = normals(&original, w, h, &opts).unwrap();
        let back = heights(&n32, w, h, &HeightOptions::from_fit(&opts)).unwrap();
        let (raw, visible) =
            (round_trip_error(&original, &back.values), visible_round_trip_error(&original, &back.values, w));
        assert!(visible < 1e-4 && raw > visible, "N {n}: {visible:e}, raw {raw:e}");
    }
}

/// Clamp: N = 3 by its transform, N = 5 by conjugate gradients.
#[test]
fn clamp_round_trips_are_within_1e_4_of_the_range() {
    let (w, h) = (40, 32);
    let original = terrain(w, h, 9);
    for n in [3, 5] {
        for fit in [Fit::Vertical, Fit::Orthogonal] {
            let opts = Options::new()
                .with_patch(n)
                .with_fit(fit)
                .with_borders(Borders::both(Border::Clamp))
                .with_strength(Strength::Scale(4.0));
            let n32 = normals(&original, w, h, &opts).unwrap();
            let back = heights(&n32, w, h, &HeightOptions::from_fit(&opts)).unwrap();
            let err = visible_round_trip_error(&original, &back.values, w);
            assert!(err < 1e-4, "N {n} {fit:?}: {err:e}");
        }
    }
}

/// Stored normals: (n + 1)/2 rounded to `bits`, read back as 2c − 1.
fn quantised(normals: &[[f32; 3]], bits: u32) -> Vec<[f64; 3]> {
    let top = f64::from((1u32 << bits) - 1);
    normals.iter().map(|n| n.map(|c| 2.0 * ((f64::from(c) + 1.0) / 2.0 * top).round() / top - 1.0)).collect()
}

/// 16-bit and 8-bit normal maps: the RMS error stays within the stated
/// figures (docs/height.md): 16-bit below 1e-3 of the range, 8-bit below
/// 3e-2, and the report's predicted quantisation error is of the measured
/// error's order.
#[test]
fn quantised_round_trips_stay_within_their_stated_errors() {
    let (w, h) = (128, 128);
    let original = periodic_terrain(w, h, 11);
    let opts = Options::new().with_fit(Fit::Vertical).with_strength(Strength::Scale(8.0));
    let n32 = normals(&original, w, h, &opts).unwrap();
    let want = demean(&original);
    let (lo, hi) = want.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    for (bits, bound) in [(16, 1e-3), (8, 3e-2)] {
        let stored = quantised(&n32, bits);
        let step = 2.0 / f64::from((1u32 << bits) - 1);
        let back = heights(&stored, w, h, &HeightOptions::from_fit(&opts).with_step(step)).unwrap();
        let rms = (want.iter().zip(&back.values).map(|(a, b)| (a - b) * (a - b)).sum::<f64>() / (w * h) as f64).sqrt();
        let relative = rms / (hi - lo);
        assert!(relative < bound, "{bits}-bit: RMS {relative:e} of the range");
        let predicted = back.report.quantisation_error.unwrap();
        assert!(
            predicted > rms / 10.0 && predicted < rms * 10.0,
            "{bits}-bit: predicted {predicted:e}, measured {rms:e}"
        );
    }
}

#[test]
fn flat_in_is_flat_out() {
    for borders in [Borders::both(Border::Wrap), Borders::both(Border::Mirror), Borders::both(Border::Clamp)] {
        for n in [3, 5] {
            for model in [Model::Exact, Model::Generic] {
                let flat = vec![[0.0f32, 0.0, 1.0]; 24 * 10];
                let fit = Options::new().with_borders(borders).with_patch(n);
                let opts = HeightOptions::from_fit(&fit).with_model(model);
                let got = heights(&flat, 24, 10, &opts).unwrap();
                assert!(got.values.iter().all(|&v| v == 0.0), "{borders:?} N {n} {model:?}");
                assert_eq!(got.report.range, (0.0, 0.0));
            }
        }
    }
}

/// Under wrap, shifting the normal map shifts the heights.
#[test]
fn shifting_commutes_with_the_solve_under_wrap() {
    let (w, h) = (48, 36);
    let original = periodic_terrain(w, h, 5);
    for fit in [Fit::Vertical, Fit::Orthogonal] {
        let opts = Options::new().with_fit(fit).with_patch(5).with_strength(Strength::Scale(6.0));
        let n32 = normals(&original, w, h, &opts).unwrap();
        let (dx, dy) = (7, 30);
        let shifted: Vec<[f32; 3]> = (0..w * h).map(|k| n32[((k / w + dy) % h) * w + (k % w + dx) % w]).collect();
        let ho = HeightOptions::from_fit(&opts);
        let (a, b) = (heights(&n32, w, h, &ho).unwrap(), heights(&shifted, w, h, &ho).unwrap());
        let moved: Vec<f64> = (0..w * h).map(|k| a.values[((k / w + dy) % h) * w + (k % w + dx) % w]).collect();
        let err = max_diff(&moved, &b.values);
        assert!(err < 1e-10, "{fit:?}: {err:e}");
    }
}

/// The same bits whatever the number of threads.
#[test]
fn any_thread_count_gives_the_same_bits() {
    let (w, h) = (70, 50);
    let original = terrain(w, h, 6);
    for (fit, borders) in [
        (Fit::Orthogonal, Borders::both(Border::Wrap)),
        (Fit::Vertical, Borders { x: Border::Mirror, y: Border::Clamp }),
        (Fit::Vertical, Borders::both(Border::Clamp)),
    ] {
        let opts = Options::new().with_fit(fit).with_patch(5).with_borders(borders).with_strength(Strength::Scale(3.0));
        let n32 = normals(&original, w, h, &opts).unwrap();
        let ho = HeightOptions::from_fit(&opts).with_convention(ConventionChoice::Auto);
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| heights(&n32, w, h, &ho).unwrap())
        };
        let one = on(1);
        for threads in [2, 3, 8] {
            let other = on(threads);
            let same = one.values.iter().zip(&other.values).all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "{fit:?} {borders:?}: {threads} threads differ");
            assert_eq!(one.report, other.report);
        }
    }
}

/// Texels with nz ≤ 0 or a NaN count, and are taken as flat: the same
/// heights as the map with (0, 0, 1) there.
#[test]
fn texels_without_a_slope_count_as_flat() {
    let (w, h) = (32, 20);
    let original = periodic_terrain(w, h, 8);
    let opts = Options::new().with_fit(Fit::Vertical);
    let good = normals(&original, w, h, &opts).unwrap();
    let mut bad = good.clone();
    let mut flat = good.clone();
    for (k, n) in
        [(5, [0.1, 0.2, 0.0]), (77, [0.3, 0.0, -0.5]), (300, [f32::NAN, 0.0, 1.0]), (301, [0.0, f32::INFINITY, 1.0])]
    {
        bad[k] = n;
        flat[k] = [0.0, 0.0, 1.0];
    }
    let ho = HeightOptions::from_fit(&opts);
    let (a, b) = (heights(&bad, w, h, &ho).unwrap(), heights(&flat, w, h, &ho).unwrap());
    assert_eq!(a.report.bad_texels, 4);
    assert_eq!(b.report.bad_texels, 0);
    assert!(a.values.iter().zip(&b.values).all(|(x, y)| x.to_bits() == y.to_bits()));
    assert!(a.values.iter().all(|v| v.is_finite()));
}

/// Auto picks the convention the map was made with, and says how much
/// curl each has.
#[test]
fn auto_picks_the_convention_the_map_was_made_with() {
    let (w, h) = (64, 48);
    let original = terrain(w, h, 12);
    for convention in [Convention::OpenGl, Convention::DirectX] {
        let opts = Options::new().with_convention(convention).with_strength(Strength::Scale(5.0));
        let n32 = normals(&original, w, h, &opts).unwrap();
        let ho = HeightOptions::from_fit(&opts).with_convention(ConventionChoice::Auto);
        let got = heights(&n32, w, h, &ho).unwrap();
        assert_eq!(got.report.convention, convention);
        let [gl, dx] = got.report.curl.unwrap();
        let (right, wrong) = if convention == Convention::OpenGl { (gl, dx) } else { (dx, gl) };
        assert!(right < 0.25 && wrong > 1.5, "{convention:?}: {gl} {dx}");
        let fixed = heights(&n32, w, h, &HeightOptions::from_fit(&opts)).unwrap();
        assert_eq!(fixed.values, got.values);
    }
}

/// The generic model does not know the fit: on a map normalfit made it is
/// off by far more than the exact inverse.
#[test]
fn the_generic_model_is_worse_on_normalfit_maps() {
    let (w, h) = (128, 96);
    let original = periodic_terrain(w, h, 21);
    let opts = Options::new().with_fit(Fit::Vertical).with_strength(Strength::Scale(10.0));
    let n32 = normals(&original, w, h, &opts).unwrap();
    let exact = heights(&n32, w, h, &HeightOptions::from_fit(&opts)).unwrap();
    let generic = heights(&n32, w, h, &HeightOptions::from_fit(&opts).with_model(Model::Generic)).unwrap();
    let (e, g) = (round_trip_error(&original, &exact.values), round_trip_error(&original, &generic.values));
    assert!(e < 1e-5 && g > 1e-3 && g > 100.0 * e, "exact {e:e}, generic {g:e}");
}

#[test]
fn bad_options_and_buffers_are_errors() {
    let n = vec![[0.0f32, 0.0, 1.0]; 12];
    assert!(heights(&n, 4, 4, &HeightOptions::new()).is_err(), "wrong length");
    assert!(heights(&n, 0, 12, &HeightOptions::new()).is_err(), "zero size");
    assert!(heights(&n, 4, 3, &HeightOptions::from_fit(&Options::new().with_patch(4))).is_err());
    let flat = Options::new().with_strength(Strength::Scale(0.0));
    assert!(heights(&n, 4, 3, &HeightOptions::from_fit(&flat)).is_err());
    assert!(heights(&n, 4, 3, &HeightOptions::new().with_step(f64::NAN)).is_err());
    assert!("frankot-chellappa".parse::<Model>().unwrap() == Model::Generic);
    assert!("auto".parse::<ConventionChoice>().unwrap() == ConventionChoice::Auto);
}

/// Where the orthogonal fit's iteration does not settle (steep, rough
/// patches: N = 5, S = 12 over a wave of nine texels, where λ is most of A
/// and grows with the heights), the guard stops it and returns the heights
/// whose re-fitted normals are closest to the given ones: never farther
/// than the vertical solution's.
#[test]
fn a_steep_rough_map_stops_at_the_closest_heights_found() {
    let (w, h) = (64, 48);
    let tau = std::f64::consts::TAU;
    let original: Vec<f64> = (0..w * h)
        .map(|k| {
            let (u, v) = ((k % w) as f64 / w as f64, (k / w) as f64 / h as f64);
            0.5 + 0.2 * (tau * (2.0 * u + v)).sin() + 0.15 * (tau * 5.0 * v + 1.0).cos() + 0.1 * (tau * 7.0 * u).sin()
        })
        .collect();
    let opts = Options::new().with_patch(5).with_strength(Strength::Scale(12.0));
    let given = normals(&original, w, h, &opts).unwrap();
    let back = heights(&given, w, h, &HeightOptions::from_fit(&opts)).unwrap();
    assert!(back.values.iter().all(|v| v.is_finite()));
    let vertical = heights(&given, w, h, &HeightOptions::from_fit(&opts.clone().with_fit(Fit::Vertical))).unwrap();
    let distance = |hs: &[f64]| {
        let refit = normals(hs, w, h, &opts).unwrap();
        refit.iter().zip(&given).map(|(a, b)| (0..3).map(|c| f64::from(a[c] - b[c]).powi(2)).sum::<f64>()).sum::<f64>()
    };
    let (ours, first) = (distance(&back.values), distance(&vertical.values));
    assert!(ours <= first * (1.0 + 1e-6), "{ours} against the vertical solution's {first}");
    assert!(back.report.iterations > 1);
}

/// A normal map the fit did not make (slopes drawn at random for each
/// texel, stored in 8 bits: no heights give them) is not chased: the
/// Gauss–Newton refinement stops after the few steps that show it gains
/// little, far from its cap of 300 solves, with finite heights.
#[test]
fn a_map_the_fit_did_not_make_is_not_chased() {
    let (w, h) = (96, 64);
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let quantise = |c: f64| ((c + 1.0) / 2.0 * 255.0).round() / 255.0 * 2.0 - 1.0;
    let given: Vec<[f64; 3]> = (0..w * h)
        .map(|_| {
            let (gx, gy) = (0.6 * uniform(), 0.6 * uniform());
            let norm = (1.0 + gx * gx + gy * gy).sqrt();
            [quantise(-gx / norm), quantise(-gy / norm), quantise(1.0 / norm)]
        })
        .collect();
    let opts = HeightOptions::new().with_step(2.0 / 255.0);
    let back = heights(&given, w, h, &opts).unwrap();
    println!("{} solves, settled {}", back.report.iterations, back.report.converged);
    assert!(back.values.iter().all(|v| v.is_finite()));
    assert!(back.report.iterations < 200, "{} solves", back.report.iterations);
}

/// Patches as wide as the image or wider (issue 32: the inverse's time
/// with N): random slopes against the dense solve, every border pair,
/// N = 9 and 15 (the right-hand side by line sums; clamp in dense bases)
/// and 41 (wider than every image here: whole periods, clamp's clipped
/// windows, the responses in closed form). The least squares' misfit, the
/// fit's slopes of the heights found (the test's own linear operator)
/// against the given ones, is never above the dense solve's; and the heights are its
/// own to 1e-7 of their range. A patch this wide can bring the operator
/// near singular (a box over most of a period sums nearly to nothing), with
/// modes it sees faintly but sees: they are part of the answer.
#[test]
fn wide_patches_match_a_dense_least_squares_solve() {
    let mut rng = Lcg(17);
    let modes = [Border::Wrap, Border::Mirror, Border::Clamp];
    let mut worst = 0.0f64;
    for (w, h) in [(9, 12), (15, 7), (1, 6), (2, 5)] {
        for n in [9, 15, 41] {
            for bx in modes {
                for by in modes {
                    let borders = Borders { x: bx, y: by };
                    let len = w * h;
                    let (gx, gy): (Vec<f64>, Vec<f64>) = (0..len).map(|_| (rng.next(), rng.next())).unzip();
                    let normals: Vec<[f64; 3]> =
                        gx.iter().zip(&gy).map(|(&a, &b)| normal_of(a, b, Convention::OpenGl)).collect();
                    let opts = vertical(n, borders);
                    let got = heights(&normals, w, h, &HeightOptions::from_fit(&opts)).unwrap();
                    let want = dense_solve(&gx, &gy, w, h, n, borders);
                    let case = format!("{w}×{h} N {n} {borders:?}");
                    // Σ |D z − g|² over the period, D the fit's linear
                    // operator: heights of a mode the fit barely sees can be
                    // large enough (1e7 from slopes of 1 at 2 × 5, N 41) that
                    // the fit's no-tilt rule reads their patches as flat.
                    let misfit = |z: &[f64]| linear_misfit(z, &gx, &gy, w, h, n, borders);
                    let (ours, theirs) = (misfit(&got.values), misfit(&want));
                    assert!(ours <= theirs * (1.0 + 1e-9) + 1e-12, "{case}: misfit {ours:e} against {theirs:e}");
                    let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1.0);
                    let err = max_diff(&got.values, &want) / scale;
                    worst = worst.max(err);
                    assert!(err < 1e-7, "{case}: {err:e} (iterations {})", got.report.iterations);
                }
            }
        }
    }
    println!("heights within {worst:.1e} of the range of the dense solve's");
}

/// Wide patches, the orthogonal fit, relief S = 4 on terrains smooth over
/// their border's period: the heights found give back the normal map, as
/// the tests' reference fit (`common::reference`, N² loops) computes it:
/// wrap and mirror by the transforms to 1e-6 (and Gauss–Newton where the
/// fixed point leaves the fit's equation off), clamp in dense bases to
/// 1e-5, as the fixed point settles there within 50 times f32's precision
/// of the fit's equation and Gauss–Newton refines only past that
/// (`OFF_BY` in src/height/iterative.rs; 5.7e-6 at N = 9). N = 9 and 15
/// on 40 × 32, 41 (wider than the map) on 24 × 20.
#[test]
fn wide_patch_round_trips_give_back_the_reference_normals() {
    for (n, w, h) in [(9, 40, 32), (15, 40, 32), (41, 24, 20)] {
        for border in [Border::Wrap, Border::Mirror, Border::Clamp] {
            // Smooth over the border's period: no cliff at a seam.
            let original = match border {
                Border::Wrap => periodic_terrain(w, h, 23),
                Border::Mirror => mirror_terrain(w, h, 23),
                _ => terrain(w, h, 23),
            };
            let opts =
                Options::new().with_patch(n).with_borders(Borders::both(border)).with_strength(Strength::Scale(4.0));
            let given = common::reference::normal_map(&original, w, h, &opts);
            let back = heights(&given, w, h, &HeightOptions::from_fit(&opts)).unwrap();
            let again = common::reference::normal_map(&back.values, w, h, &opts);
            let off = again.iter().zip(&given).map(|(a, b)| max_diff(a, b)).fold(0.0f64, f64::max);
            println!("N {n} {border:?}: normals off by {off:.2e} after {} solves", back.report.iterations);
            assert!(back.report.converged, "N {n} {border:?}: not settled");
            let bound = if border == Border::Clamp { 1e-5 } else { 1e-6 };
            assert!(off < bound, "N {n} {border:?}: the normals of the heights found are off by {off:e}");
        }
    }
}

/// A map without a slope is solved at once whatever N, the size and the
/// options: heights 0, no solve, settled; its quantisation figure is the
/// one a solve of the same size and options reports (it depends on them,
/// not on the slopes).
#[test]
fn flat_maps_take_no_solve_whatever_n() {
    let modes = [Border::Wrap, Border::Mirror, Border::Clamp];
    for (w, h) in [(5000, 1), (1, 5000), (24, 10)] {
        for n in [3, 63, 1023] {
            for border in modes {
                for fit in [Fit::Orthogonal, Fit::Vertical] {
                    for model in [Model::Exact, Model::Generic] {
                        let flat = vec![[0.0f32, 0.0, 1.0]; w * h];
                        let opts = Options::new().with_patch(n).with_fit(fit).with_borders(Borders::both(border));
                        let ho = HeightOptions::from_fit(&opts).with_model(model).with_step(2.0 / 65535.0);
                        let got = heights(&flat, w, h, &ho).unwrap();
                        let case = format!("{w}×{h} N {n} {border:?} {fit:?} {model:?}");
                        assert!(got.values.iter().all(|&v| v == 0.0), "{case}");
                        assert_eq!((got.report.iterations, got.report.converged), (0, true), "{case}");
                        assert!(got.report.quantisation_error.is_some_and(f64::is_finite), "{case}");
                    }
                }
            }
        }
    }
    // The same figure as a solve's: a vertical fit's map with slopes.
    let (w, h) = (40, 30);
    for (n, border) in [(3, Border::Wrap), (41, Border::Mirror), (9, Border::Clamp)] {
        let opts = vertical(n, Borders::both(border)).with_strength(Strength::Scale(4.0));
        let ho = HeightOptions::from_fit(&opts).with_step(2.0 / 255.0);
        let tilted = normals(&terrain(w, h, 3), w, h, &opts).unwrap();
        let flat = vec![[0.0f32, 0.0, 1.0]; w * h];
        let (a, b) = (heights(&tilted, w, h, &ho).unwrap(), heights(&flat, w, h, &ho).unwrap());
        let (qa, qb) = (a.report.quantisation_error.unwrap(), b.report.quantisation_error.unwrap());
        assert!((qa - qb).abs() <= 1e-12 * qa, "N {n} {border:?}: {qa:e} solved, {qb:e} flat");
    }
}

/// The same bits whatever the number of threads, with patches wider than
/// the map (line sums over whole periods, Gauss–Newton, clamp's
/// conjugate gradients).
#[test]
fn wide_patches_give_the_same_bits_on_any_thread_count() {
    let (w, h) = (30, 22);
    let original = terrain(w, h, 31);
    for (fit, borders) in [
        (Fit::Orthogonal, Borders::both(Border::Wrap)),
        (Fit::Orthogonal, Borders { x: Border::Mirror, y: Border::Wrap }),
        (Fit::Vertical, Borders { x: Border::Clamp, y: Border::Mirror }),
        (Fit::Orthogonal, Borders::both(Border::Clamp)),
    ] {
        let opts =
            Options::new().with_fit(fit).with_patch(41).with_borders(borders).with_strength(Strength::Scale(20.0));
        let n32 = normals(&original, w, h, &opts).unwrap();
        let ho = HeightOptions::from_fit(&opts);
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| heights(&n32, w, h, &ho).unwrap())
        };
        let one = on(1);
        for threads in [2, 3] {
            let other = on(threads);
            let same = one.values.iter().zip(&other.values).all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "{fit:?} {borders:?}: {threads} threads differ");
            assert_eq!(one.report, other.report);
        }
    }
}

/// The least squares' gradient Dᵀ(Dz − g) of a clamped map, with D the
/// vertical fit's operator written plainly from its definition (each
/// texel's patch read through the reference's border rule, sparse: the
/// dense rows of `period_texels` would not fit past 1024 texels), and
/// Dᵀg's largest value for scale.
fn clamp_gradient(z: &[f64], gx: &[f64], gy: &[f64], w: usize, h: usize, n: usize) -> (Vec<f64>, f64) {
    let (r, a) = ((n / 2) as i64, a_of(n));
    let mut gradient = vec![0.0; w * h];
    let mut scale = vec![0.0f64; w * h];
    for y in 0..h {
        for x in 0..w {
            let taps = |f: &mut dyn FnMut(usize, f64, f64)| {
                for j in -r..=r {
                    for i in -r..=r {
                        let tx = source_index(x as i64 + i, w as i64, Border::Clamp) as usize;
                        let ty = source_index(y as i64 + j, h as i64, Border::Clamp) as usize;
                        f(ty * w + tx, i as f64 / a, j as f64 / a);
                    }
                }
            };
            let (mut dx, mut dy) = (0.0, 0.0);
            taps(&mut |k, cx, cy| {
                dx += cx * z[k];
                dy += cy * z[k];
            });
            let (rx, ry) = (dx - gx[y * w + x], dy - gy[y * w + x]);
            taps(&mut |k, cx, cy| {
                gradient[k] += cx * rx + cy * ry;
                scale[k] += cx * gx[y * w + x] + cy * gy[y * w + x];
            });
        }
    }
    let largest = scale.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    (gradient, largest)
}

/// Clamp with N ≥ 5 past 1024 texels on a side (one dense basis, on the
/// shorter axis, and banded solves along the longer: `banded.rs`),
/// 2048 × 256 and strips either way round (1030 × 3, 2 × 1100,
/// 1100 × 24, 20 × 1040: lengths whose clamped ramp or box is blind to
/// more than the constant, met by a mode of the shorter axis that is
/// blind too), N = 5 and 15, random slopes (a map the fit did not
/// make): the heights are the least squares' solution, their gradient
/// Dᵀ(Dz − g) 0 to 1e-9 of Dᵀg, D written plainly here.
#[test]
fn clamp_past_1024_texels_solves_the_least_squares() {
    let mut rng = Lcg(29);
    for (w, h) in [(2048, 256), (1030, 3), (2, 1100), (1100, 24), (20, 1040)] {
        for n in [5, 15] {
            let len = w * h;
            let (gx, gy): (Vec<f64>, Vec<f64>) = (0..len).map(|_| (0.3 * rng.next(), 0.3 * rng.next())).unzip();
            let normals: Vec<[f64; 3]> =
                gx.iter().zip(&gy).map(|(&a, &b)| normal_of(a, b, Convention::OpenGl)).collect();
            let opts = HeightOptions::from_fit(&vertical(n, Borders::both(Border::Clamp)));
            let got = heights(&normals, w, h, &opts).unwrap();
            let (gradient, scale) = clamp_gradient(&got.values, &gx, &gy, w, h, n);
            let worst = gradient.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(worst <= 1e-9 * scale, "{w}×{h} N {n}: gradient {worst:e} of {scale:e}");
            assert_eq!((got.report.iterations, got.report.converged), (1, true), "{w}×{h} N {n}");
        }
    }
}

/// Clamp past 1024 texels, the forward fit's own maps: both fits, N = 5
/// and 15 on 2048 × 256, back to heights within 1e-4 of their range. (On
/// the strips the fit is blind to much more — 1030 × 3 at N = 15: 3.8e-3
/// of the range lost to its null space — so their least squares are held
/// by the gradient test above.)
#[test]
fn clamp_round_trips_past_1024_texels_are_within_1e_4_of_the_range() {
    for (w, h) in [(2048, 256)] {
        let original = terrain(w, h, 37);
        for n in [5, 15] {
            for fit in [Fit::Vertical, Fit::Orthogonal] {
                let opts = Options::new()
                    .with_patch(n)
                    .with_fit(fit)
                    .with_borders(Borders::both(Border::Clamp))
                    .with_strength(Strength::Scale(4.0));
                let n32 = normals(&original, w, h, &opts).unwrap();
                let back = heights(&n32, w, h, &HeightOptions::from_fit(&opts)).unwrap();
                let err = round_trip_error(&original, &back.values);
                assert!(back.report.converged, "{w}×{h} N {n} {fit:?}: not settled");
                assert!(err < 1e-4, "{w}×{h} N {n} {fit:?}: {err:e} after {} solves", back.report.iterations);
            }
        }
    }
}

/// Clamp with N ≥ 5 where no path solves within the limit of time
/// (`height/cost.rs`: both sides past 1024 texels, so no dense basis):
/// refused in one line naming the estimate and the limit, before any
/// solve; a flat map of that size is still solved at once (heights 0),
/// and N = 3 (a transform) is not refused.
#[test]
fn clamp_past_1024_texels_a_side_is_refused_in_one_line() {
    let (w, h) = (1030, 1025);
    let mut tilted = vec![[0.0f32, 0.0, 1.0]; w * h];
    tilted[w * 7 + 11] = [0.3, 0.0, 0.95];
    let clamp = |n: usize| HeightOptions::from_fit(&vertical(n, Borders::both(Border::Clamp)));
    let message = heights(&tilted, w, h, &clamp(5)).unwrap_err().to_string();
    assert!(message.contains("past the limit of 4.2e9") && message.contains("1030 × 1025"), "{message}");
    assert!(message.contains("--border mirror") && !message.contains('\n'), "{message}");
    let flat = vec![[0.0f32, 0.0, 1.0]; w * h];
    let got = heights(&flat, w, h, &clamp(5)).unwrap();
    assert!(got.values.iter().all(|&v| v == 0.0));
    assert!(heights(&tilted, w, h, &clamp(3)).is_ok());
}

// ---- Holes -------------------------------------------------------------

/// A `w` × `h` mask: a band of holes `band` columns wide from column 4
/// (none when 0), and the texels `extra`.
fn holes_mask(w: usize, h: usize, band: usize, extra: &[(usize, usize)]) -> Vec<bool> {
    let mut holes: Vec<bool> = (0..w * h).map(|k| (4..4 + band).contains(&(k % w))).collect();
    extra.iter().for_each(|&(x, y)| holes[y * w + x] = true);
    holes
}

/// The texels that are not holes but lie in no patch free of holes (the
/// reference's patches, read through its border rule).
fn unseen(w: usize, h: usize, n: usize, borders: Borders, holes: &[bool]) -> Vec<bool> {
    let zeros = vec![0.0; w * h];
    let mut seen = vec![false; w * h];
    for t in period_texels(&zeros, &zeros, w, h, n, borders) {
        if !t.patch.iter().any(|&k| holes[k]) {
            t.patch.iter().for_each(|&k| seen[k] = true);
        }
    }
    (0..w * h).map(|k| !holes[k] && !seen[k]).collect()
}

/// The vertical fit's slopes of `z` (NaN read as 0) at the period texels
/// whose patches hold no hole: what the least squares determine.
fn kept_slopes(z: &[f64], w: usize, h: usize, n: usize, borders: Borders, holes: &[bool]) -> Vec<f64> {
    let zeros = vec![0.0; w * h];
    let z: Vec<f64> = z.iter().map(|&v| if v.is_nan() { 0.0 } else { v }).collect();
    let dot = |row: &[f64]| row.iter().zip(&z).map(|(a, b)| a * b).sum::<f64>();
    period_texels(&zeros, &zeros, w, h, n, borders)
        .iter()
        .filter(|t| !t.patch.iter().any(|&k| holes[k]))
        .flat_map(|t| [dot(&t.row_x), dot(&t.row_y)])
        .collect()
}

/// The fit energy of the map without holes that the inverse with holes
/// minimises among its least-squares solutions (`holes.rs`): the dense
/// matrix (row-major, w h × w h) of Q = Σ over the period of the patch's
/// slope rows' outer products (the reference's border rule, holes or
/// not), plus λ + ε on each texel of the period.
fn whole_map_energy(w: usize, h: usize, n: usize, borders: Borders, lambda_epsilon: f64) -> Vec<f64> {
    let m = w * h;
    let zeros = vec![0.0; m];
    let mut q = vec![0.0; m * m];
    for t in period_texels(&zeros, &zeros, w, h, n, borders) {
        q[t.texel * m + t.texel] += lambda_epsilon;
        for row in [&t.row_x, &t.row_y] {
            let entries: Vec<(usize, f64)> = row.iter().copied().enumerate().filter(|(_, v)| *v != 0.0).collect();
            for &(k, u) in &entries {
                for &(l, v) in &entries {
                    q[k * m + l] += u * v;
                }
            }
        }
    }
    q
}

/// The heights the inverse with holes is to find, densely: among the
/// least-squares solutions of the kept equations (the dense solution of
/// least W-norm plus any null mode, the holes' heights free), the one
/// whose extension over the holes has the least `energy`, uᵀQu: u = z −
/// N (NᵀQN)⁻¹ NᵀQ z, N the null modes.
fn least_energy_solution(dense: &Dense, energy: &[f64]) -> Vec<f64> {
    let m = dense.z.len();
    let cut = 1e-20 * dense.largest();
    let null: Vec<&Vec<f64>> = dense.modes.iter().filter(|(s, _)| *s <= cut).map(|(_, v)| v).collect();
    let q_times = |v: &[f64]| -> Vec<f64> { (0..m).map(|k| (0..m).map(|l| energy[k * m + l] * v[l]).sum()).collect() };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let qn: Vec<Vec<f64>> = null.iter().map(|v| q_times(v)).collect();
    let k = null.len();
    let gram: Vec<f64> = (0..k * k).map(|ij| dot(null[ij / k], &qn[ij % k])).collect();
    let rhs: Vec<f64> = qn.iter().map(|qv| dot(qv, &dense.z)).collect();
    let c = lu_solve(&lu_factor(gram, k), &rhs, k);
    let mut u = dense.z.clone();
    for (v, c) in null.iter().zip(&c) {
        u.iter_mut().zip(v.iter()).for_each(|(u, v)| *u -= c * v);
    }
    u
}

/// Random slopes with holes (a 4-wide band, and scattered holes), every
/// border, N = 3 and 5, against the dense least squares of the kept
/// equations: holes NaN, the unseen texels NaN (and counted), the fitted
/// slopes equal (to 1e-8), and the heights those of the criterion the
/// solve minimises among the least-squares solutions
/// ([`least_energy_solution`] of [`whole_map_energy`], ε = 1e-2 / (w h))
/// on the modes seen and (but clamp with N ≥ 5) on the null modes.
#[test]
fn holes_match_a_dense_least_squares_solve() {
    let mut rng = Lcg(35);
    let wrap = Borders::both(Border::Wrap);
    let cases = [
        wrap,
        Borders::both(Border::Clamp),
        Borders::both(Border::Mirror),
        Borders { x: Border::Clamp, y: Border::Wrap },
    ];
    for (w, h) in [(13, 7), (12, 10)] {
        for n in [3, 5] {
            for borders in cases {
                for (band, extra) in [(4, vec![(0, 0)]), (0, vec![(2, 2), (3, 2), (9, 5), (10, 1), (0, 6)])] {
                    let holes = holes_mask(w, h, band, &extra);
                    let len = w * h;
                    let (gx, gy): (Vec<f64>, Vec<f64>) = (0..len).map(|_| (rng.next(), rng.next())).unzip();
                    let normals: Vec<[f64; 3]> =
                        gx.iter().zip(&gy).map(|(&a, &b)| normal_of(a, b, Convention::OpenGl)).collect();
                    let opts = HeightOptions::from_fit(&vertical(n, borders));
                    let got = heights_with_holes(&normals, w, h, &holes, &opts).unwrap();
                    let case = format!("{w}×{h} N {n} {borders:?} band {band}");
                    assert!(got.report.converged, "{case}");
                    assert_eq!(got.report.regularisation, 0.0, "{case}");
                    let unseen = unseen(w, h, n, borders, &holes);
                    for k in 0..len {
                        assert_eq!(got.values[k].is_nan(), holes[k] || unseen[k], "{case}: texel {k}");
                    }
                    assert_eq!(got.report.holes, holes.iter().filter(|&&v| v).count(), "{case}");
                    assert_eq!(got.report.undetermined, unseen.iter().filter(|&&v| v).count(), "{case}");
                    let dense = dense_least_squares(&gx, &gy, w, h, n, borders, &holes);
                    let want = least_energy_solution(&dense, &whole_map_energy(w, h, n, borders, 1e-2 / len as f64));
                    let (fit_got, fit_want) = (
                        kept_slopes(&got.values, w, h, n, borders, &holes),
                        kept_slopes(&want, w, h, n, borders, &holes),
                    );
                    let size = fit_want.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1.0);
                    let err = max_diff(&fit_got, &fit_want) / size;
                    assert!(err < 1e-8, "{case}: fitted slopes off by {err:e}");
                    // The heights where they are given (the holes and unseen texels
                    // read as the criterion's own), on the modes the kept
                    // equations see well, and on those they do not see at
                    // all: there the criterion alone decides. Clamp with
                    // N ≥ 5 takes its Q from the dense bases, whose ε term
                    // weighs the null modes in the bases' own metric, not
                    // W: there only the modes seen are held.
                    let diff: Vec<f64> =
                        got.values.iter().zip(&want).map(|(g, w)| if g.is_nan() { 0.0 } else { g - w }).collect();
                    let norm = want.iter().map(|v| v * v).sum::<f64>().max(1.0);
                    let seen_part = dense.part(&diff, 1e-12, true);
                    assert!(seen_part < 1e-14 * norm, "{case}: heights off by {seen_part:e} of {norm:e}");
                    let wide_clamp = n >= 5 && (borders.x == Border::Clamp || borders.y == Border::Clamp);
                    let null_part = dense.part(&diff, 1e-20, false);
                    assert!(wide_clamp || null_part < 1e-14 * norm, "{case}: {null_part:e} off on the null modes");
                }
            }
        }
    }
}

/// A terrain with a 4-wide band of holes and a blob, through the forward
/// fit with holes (nodata NaN) and back with the same holes, N = 3 and 5,
/// vertical (gain 8) and orthogonal (gain 1: with holes it has no
/// Gauss–Newton finish, and at gain 8 on these maps its fixed point does
/// not settle), every border: the holes come back NaN (and
/// the texels no patch free of holes holds, as the reference finds them),
/// and
/// the heights' re-fitted normals are the given ones wherever a patch
/// holds no hole (what the least squares determine), to 1e-7 (orthogonal:
/// the fixed point's own 1e-4); at 16 × 12
/// the heights themselves come back up to the modes no kept equation sees
/// (the dense solve's null space: each piece's constant, and at N = 5 the
/// modes along the band's edges).
#[test]
fn round_trips_with_holes_give_the_heights_back_up_to_what_no_patch_sees() {
    for (w, h) in [(16, 12), (41, 33)] {
        for n in [3, 5] {
            for fit in [Fit::Vertical, Fit::Orthogonal] {
                for b in [Border::Wrap, Border::Clamp, Border::Mirror] {
                    let borders = Borders::both(b);
                    let case = format!("{w}×{h} N {n} {fit:?} {b:?}");
                    let holes = holes_mask(w, h, 4, &[(w - 3, h / 2), (w - 2, h / 2), (w - 3, h / 2 + 1)]);
                    let original =
                        if b == Border::Mirror { mirror_terrain(w, h, 3) } else { periodic_terrain(w, h, 3) };
                    let with_holes: Vec<f64> =
                        original.iter().zip(&holes).map(|(&v, &hole)| if hole { f64::NAN } else { v }).collect();
                    let fit_opts = Options::new()
                        .with_fit(fit)
                        .with_patch(n)
                        .with_borders(borders)
                        .with_strength(Strength::Scale(if fit == Fit::Orthogonal { 1.0 } else { 8.0 }));
                    let with_nodata = fit_opts.clone().with_nodata(Some(f64::NAN));
                    let f64_normals = |heights: &[f64]| {
                        let mut out = vec![[0.0f64; 3]; w * h];
                        FitRequest::new(&with_nodata).normals_into(heights, w, h, &mut out).unwrap();
                        out
                    };
                    let given = f64_normals(&with_holes);
                    let back = heights_with_holes(&given, w, h, &holes, &HeightOptions::from_fit(&fit_opts)).unwrap();
                    assert!(back.report.converged, "{case}: {:?}", back.report);
                    // Texels beside the blob at a clamped edge lie in no patch
                    // free of holes: NaN, counted.
                    let unseen = unseen(w, h, n, borders, &holes);
                    assert_eq!(back.report.undetermined, unseen.iter().filter(|&&u| u).count(), "{case}");
                    for k in 0..w * h {
                        assert_eq!(back.values[k].is_nan(), holes[k] || unseen[k], "{case}: texel {k}");
                    }
                    // The re-fit of the heights found, where no patch holds a hole.
                    let again = f64_normals(&back.values);
                    let zeros = vec![0.0; w * h];
                    let mut worst = 0.0f64;
                    for t in period_texels(&zeros, &zeros, w, h, n, borders) {
                        if !t.patch.iter().any(|&k| holes[k]) {
                            for c in 0..3 {
                                worst = worst.max((again[t.texel][c] - given[t.texel][c]).abs());
                            }
                        }
                    }
                    let bound = if fit == Fit::Vertical { 1e-7 } else { 1e-4 };
                    assert!(worst < bound, "{case}: re-fitted normals off by {worst:e}");
                    if w * h <= 200 {
                        let dense = dense_least_squares(&zeros, &zeros, w, h, n, borders, &holes);
                        let diff: Vec<f64> = back
                            .values
                            .iter()
                            .zip(&original)
                            .map(|(b, o)| if b.is_nan() { 0.0 } else { b - o })
                            .collect();
                        let norm = original.iter().map(|v| v * v).sum::<f64>();
                        let seen_part = dense.part(&diff, 1e-12, true);
                        // Orthogonal: the ratios read the whole heights, and the
                        // modes no kept equation sees (N = 5: along the holes'
                        // edges) are the criterion's smooth fill, not 0: the
                        // fixed point settles within its own tolerance of
                        // another point (16 × 12, N = 5, wrap: 3e-6).
                        let bound = if fit == Fit::Vertical { 1e-12 } else { 1e-5 };
                        assert!(seen_part < bound * norm, "{case}: heights off by {seen_part:e} of {norm:e}");
                    }
                }
            }
        }
    }
}

/// Without a hole the mask changes nothing, to the bit; a mask of the wrong
/// size and the generic model with holes are errors.
#[test]
fn an_empty_mask_is_the_inverse_without_holes_and_bad_masks_are_errors() {
    let (w, h) = (24, 20);
    let original = periodic_terrain(w, h, 5);
    let fit = Options::new().with_patch(5).with_borders(Borders::both(Border::Clamp));
    let n = normals(&original, w, h, &fit).unwrap();
    let opts = HeightOptions::from_fit(&fit);
    let plain = heights(&n, w, h, &opts).unwrap();
    let masked = heights_with_holes(&n, w, h, &vec![false; w * h], &opts).unwrap();
    assert!(plain.values.iter().zip(&masked.values).all(|(a, b)| a.to_bits() == b.to_bits()));
    assert!(heights_with_holes(&n, w, h, &[true; 3], &opts).is_err());
    let generic = opts.with_model(Model::Generic);
    let e = heights_with_holes(&n, w, h, &holes_mask(w, h, 2, &[]), &generic).unwrap_err();
    assert!(e.to_string().contains("exact model"), "{e}");
}
