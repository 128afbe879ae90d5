//! The iterations: the orthogonal fit from the vertical one, and clamp
//! borders with N ≥ 5, which no transform fits, by conjugate gradients
//! with the exact operator.
//!
//! The exact operator here is the patch sums written with the borders'
//! index maps (`patch.rs`): per axis, sparse lists "output texel ← input
//! texels with weights" for the box (weights 1) and the ramp (weights i)
//! of the patch, and their transposes. Every pass is a row (or a combination of
//! rows) at a time, in parallel over rows, in a fixed order per texel:
//! the same bits whatever the thread count.

use crate::error::Result;
use crate::options::{Border, Fit};
use crate::par::prelude::*;
use crate::samples::{try_filled, try_vec};

use super::patch::Patch;
use super::solve::Solver;
use super::{HeightOptions, Model};

use super::solve::SlopeRows as Slopes;

/// The exact model's heights (texel units) into `z`; returns the solves
/// run, whether the iteration converged, and the solve's noise gain.
pub(crate) fn exact(
    slopes: Slopes<'_>,
    w: usize,
    h: usize,
    opts: &HeightOptions,
    lambda: f64,
    z: &mut [f64],
) -> Result<(usize, bool, f64)> {
    let solver = Solver::new(w, h, opts.fit.borders, opts.fit.patch, Model::Exact);
    let patch = Patch::new(w, h, opts);
    let mut iterations = 0;
    // One vertical solve: the transform's, else conjugate gradients.
    let mut vertical = |s: Slopes<'_>, z: &mut [f64]| -> Result<(bool, f64)> {
        iterations += 1;
        match &solver {
            Some(solver) => Ok((true, solver.solve(s, lambda, z)?.noise_gain)),
            None => conjugate_gradients(&patch, s, lambda, opts, z),
        }
    };
    let (mut converged, noise_gain) = vertical(slopes, z)?;
    if opts.fit.fit == Fit::Vertical {
        return Ok((iterations, converged, noise_gain));
    }
    // The orthogonal fit: vertical slopes g · ρ(z), ρ = (A − λ)/A.
    let len = w * h;
    let mut rho = try_filled(len, 1.0)?;
    let mut direction = try_filled(len, 0i8)?;
    // The heights whose re-fitted normals are closest to the given ones so
    // far (the sum of squared differences of unit normals, which steep
    // texels cannot dominate), kept as f32: the vertical solution first.
    let (_, first, mut off) = patch.update_ratios(z, slopes, &mut rho, &mut direction, 1.0)?;
    // The heights closest so far, as f32; `None` while they are the
    // vertical solution, which a solve gives again: most maps converge and
    // never need them, and copying them took 3 % of the time at 4096².
    let mut kept: Option<Vec<f32>> = None;
    let mut best = first;
    let (mut last_change, mut growing, mut damping) = (f64::INFINITY, 0, 1.0);
    // Ratios settled to the input's own precision (its step) are settled:
    // the slopes asked for are known no better.
    let tolerance = opts.tolerance.max(opts.step);
    converged = false;
    for _ in 1..opts.max_iterations {
        let weighted = |y: usize, gx: &mut [f64], gy: &mut [f64]| {
            slopes(y, gx, gy);
            for ((x, y), r) in gx.iter_mut().zip(gy.iter_mut()).zip(&rho[y * w..][..w]) {
                *x *= r;
                *y *= r;
            }
        };
        vertical(&weighted, z)?;
        let (change, mismatch, now_off) = patch.update_ratios(z, slopes, &mut rho, &mut direction, damping)?;
        off = now_off;
        if change <= tolerance {
            converged = true;
            break;
        }
        if mismatch < best {
            best = mismatch;
            let copy = match kept.take() {
                Some(mut k) => {
                    k.par_chunks_mut(w).zip(z.par_chunks(w)).for_each(|(k, z)| {
                        k.iter_mut().zip(z).for_each(|(k, &z)| *k = z as f32);
                    });
                    k
                }
                None => {
                    let mut k = try_vec(len)?;
                    k.par_extend(z.par_iter().map(|&z| z as f32));
                    k
                }
            };
            kept = Some(copy);
        }
        // A change that grows halves the steps (down to 1/64); the guard
        // stops after 8 growths running, or a change that is not a number,
        // and the closest heights found are returned (not converged).
        if change > last_change || !change.is_finite() {
            growing += 1;
            damping = (damping * 0.5f64).max(1.0 / 64.0);
        } else {
            growing = 0;
        }
        last_change = change;
        if growing >= 8 || !change.is_finite() {
            break;
        }
    }
    if !converged {
        match &kept {
            Some(kept) => z.iter_mut().zip(kept).for_each(|(z, &k)| *z = f64::from(k)),
            None => {
                vertical(slopes, z)?;
                z.iter_mut().for_each(|z| *z = f64::from(*z as f32));
            }
        }
    }
    drop((rho, direction, kept));
    // The fixed point solves for vertical slopes, so it keeps the vertical
    // fit's null modes (alternating heights) at 0, but the orthogonal fit
    // sees them through the patches' roughness: where the original held
    // them, and where slopes are steep enough that the fixed point crawls
    // or swings, it settles (or stops) with the fit's equation still off
    // by far more than the input's precision. Gauss–Newton on that
    // equation then finishes the job (`gauss_newton.rs`). On the real
    // sets the fixed point's settled heights were off by at most 22 times
    // the precision where they came back within 6e-6 of the range, and by
    // 194 or more where they did not (docs/height.md). Its heights are
    // kept only where it settles: on a map the fit did not make, no
    // heights give the slopes and it stops early (`gauss_newton.rs`).
    let precision = opts.step.max(f64::from(f32::EPSILON));
    let room = crate::io::check_memory(
        "the orthogonal fit's Gauss–Newton steps",
        super::memory::gauss_newton_bytes(w, h, opts),
    );
    if let (Some(solver), true, Ok(())) = (&solver, !converged || off > OFF_BY * precision, room) {
        let (lo, hi) = z.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
        let mut before: Vec<f64> = try_vec(len)?;
        before.extend_from_slice(z);
        let outcome = super::gauss_newton::refine(&patch, solver, slopes, lambda, SETTLED * (hi - lo), precision, z)?;
        iterations += outcome.solves;
        if outcome.converged {
            converged = true;
        } else {
            // Unsettled, its heights lower the misfit by roughness the map
            // did not draw (on the denim bake: correlation with the set's
            // own heights −0.07 against the fixed point's 0.87): the fixed
            // point's heights stand.
            z.copy_from_slice(&before);
        }
    }
    Ok((iterations, converged, noise_gain))
}

/// How far, in units of the input's precision (its step, at least f32's
/// epsilon) times 1 + |g|², the fit's equation may stay off at the fixed
/// point's heights before Gauss–Newton refines them.
const OFF_BY: f64 = 50.0;

/// Gauss–Newton's heights have settled when a step moves none by more
/// than this fraction of their range.
const SETTLED: f64 = 1e-6;

impl Patch {
    /// The ratios ρ = vertical slope / orthogonal slope per texel that make
    /// the orthogonal fit of `z`'s patches give the slopes `slopes` asks
    /// for, the patches' roughness held.
    ///
    /// A patch is a plane of vertical slope v plus what the vertical fit
    /// leaves, whose squares sum to R = Czz − A|v|². With that R held, the
    /// orthogonal fit's slope is A|v| / (d + q), d = (A − A|v|² − R)/2,
    /// q = √(d² + A²|v|²) (SPEC §2); setting it to g = |g*| gives
    /// s² + s(1 − g²)/g − (1 − R/A) = 0 for s = |v|, whose positive root
    /// makes ρ = s/g. Only R then carries over from the last heights, and
    /// it follows the slopes weakly: the iteration converges in a few
    /// solves. Where no positive root exists (R ≥ A: a patch rougher than
    /// its texels are wide) ρ is the current patch's (A − λ)/A.
    ///
    /// Each texel's ratio moves to its new value, or half way where it
    /// moved the other way on the last step (`direction`): such a texel
    /// oscillates (patches at a mirrored edge, steep ones), and the half
    /// step damps the swing and keeps the fixed point. Returns the largest
    /// change of a ratio asked for, |new − old|, and how far `z`'s
    /// orthogonal fit is from the slopes asked for: Σ |n(o) − n(g)|², the
    /// unit normals of the fitted slopes o and of the given g.
    ///
    /// The patch sums are the forward fit's own sliding sums
    /// ([`crate::fit::BandFit`], O(1) per texel whatever N), a band of rows
    /// at a time, so only a band's sums are held.
    fn update_ratios(
        &self,
        z: &[f64],
        slopes: Slopes<'_>,
        rho: &mut [f64],
        direction: &mut [i8],
        damping: f64,
    ) -> Result<(f64, f64, f64)> {
        let w = self.w;
        let h = z.len() / w;
        let mut fit = self.moments_fit(h)?;
        let bands: Vec<std::ops::Range<usize>> = fit.bands().collect();
        let widest = bands.iter().map(|b| b.len()).max().unwrap_or(0);
        let mut moments: Vec<[f64; 3]> = try_vec(widest * w)?;
        moments.resize(widest * w, [0.0; 3]);
        let (mut largest, mut mismatch, mut worst) = (0.0f64, 0.0, 0.0f64);
        let source = |y: usize| &z[y * w..][..w];
        for rows in bands {
            let band = &mut moments[..rows.len() * w];
            fit.moments(rows.clone(), &source, band)?;
            let (band_rho, band_dir) =
                (&mut rho[rows.start * w..rows.end * w], &mut direction[rows.start * w..rows.end * w]);
            let per_row: Vec<(f64, f64, f64)> = band_rho
                .par_chunks_mut(w)
                .zip(band_dir.par_chunks_mut(w))
                .zip(band.par_chunks(w))
                .enumerate()
                .map(|(k, ((out, dir), m))| {
                    let (mut gx, mut gy) = (vec![0.0; w], vec![0.0; w]);
                    slopes(rows.start + k, &mut gx, &mut gy);
                    ratio_row(self.a, m, &gx, &gy, out, dir, damping)
                })
                .collect();
            for (c, e, o) in per_row {
                largest = largest.max(c);
                mismatch += e;
                worst = worst.max(o);
            }
        }
        Ok((largest, mismatch, worst))
    }

    /// The forward fit's sliding sums for heights in texel units.
    fn moments_fit(&self, h: usize) -> Result<crate::fit::BandFit> {
        let opts = crate::Options::new()
            .with_patch(self.patch)
            .with_fit(Fit::Vertical)
            .with_borders(self.borders)
            .with_strength(crate::Strength::Scale(1.0));
        Ok(crate::fit::BandFit::new(self.w, h, &opts)?.with_unit(1.0))
    }
}

/// One row of [`Patch::update_ratios`]: the patch moments `m` ([Cx, Cy,
/// Czz]) of the current heights, the slopes asked for, the ratios and
/// their last directions to update; returns the largest change asked for
/// and the row's mismatch of unit normals.
///
/// Built for the widest vectors the processor has ([`pulp::Arch`]: AVX2
/// where baseline x86-64 has SSE2's two lanes of f64), chosen at run time:
/// its square roots and divisions took half of each re-fit. They, and the
/// other operations, round alike in every instruction set, and nothing
/// fuses a multiply with an add: the same bits on every processor.
fn ratio_row(
    a: f64,
    m: &[[f64; 3]],
    gx: &[f64],
    gy: &[f64],
    out: &mut [f64],
    dir: &mut [i8],
    damping: f64,
) -> (f64, f64, f64) {
    pulp::Arch::new().dispatch(RatioRow { a, m, gx, gy, out, dir, damping })
}

/// [`ratio_row`]'s arguments, for [`pulp::Arch::dispatch`].
struct RatioRow<'a> {
    a: f64,
    m: &'a [[f64; 3]],
    gx: &'a [f64],
    gy: &'a [f64],
    out: &'a mut [f64],
    dir: &'a mut [i8],
    damping: f64,
}

impl pulp::WithSimd for RatioRow<'_> {
    type Output = (f64, f64, f64);
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> (f64, f64, f64) {
        // Inlined here, so that it is compiled for each instruction set.
        let RatioRow { a, m, gx, gy, out, dir, damping } = self;
        let (mut largest, mut mismatch, mut worst) = (0.0f64, 0.0, 0.0f64);
        // Blocks of texels computed without branches (both sides of every
        // choice, then a select), which the compiler can vectorise; the sums
        // then run over the block in texel order, as one loop would.
        const BLOCK: usize = 8;
        let (mut terms, mut changes, mut offs) = ([0.0f64; BLOCK], [0.0f64; BLOCK], [0.0f64; BLOCK]);
        let mut start = 0;
        while start < out.len() {
            let k = BLOCK.min(out.len() - start);
            let (m, gx, gy) = (&m[start..][..k], &gx[start..][..k], &gy[start..][..k]);
            let (o, d) = (&mut out[start..][..k], &mut dir[start..][..k]);
            for l in 0..k {
                let (term, change, off) = ratio_texel(a, m[l], gx[l], gy[l], &mut o[l], &mut d[l], damping);
                terms[l] = term;
                changes[l] = change;
                offs[l] = off;
            }
            for l in 0..k {
                mismatch += terms[l];
                largest = largest.max(changes[l]);
                worst = worst.max(offs[l]);
            }
            start += k;
        }
        (largest, mismatch, worst)
    }
}

/// One texel of [`ratio_row`]: its mismatch of unit normals and the
/// change of its ratio asked for, |new − old|.
#[inline(always)]
fn ratio_texel(a: f64, m: [f64; 3], gx: f64, gy: f64, out: &mut f64, dir: &mut i8, damping: f64) -> (f64, f64, f64) {
    let unit = |p: f64, q: f64| {
        let inv = 1.0 / (1.0 + p * p + q * q).sqrt();
        [-p * inv, -q * inv, inv]
    };
    let [si, sj, czz] = m;
    let tilt2 = si * si + sj * sj;
    let flat = tilt2 <= 1e-20 * (a + czz) * (a + czz);
    let d = 0.5 * (a - czz);
    let q = (d * d + tilt2).sqrt();
    let (above, below) = (d + q, tilt2 / (q - d));
    let a_minus_lambda = if d >= 0.0 { above } else { below };
    let current = if flat { 1.0 } else { a_minus_lambda / a };
    let fitted = unit(si / (current * a), sj / (current * a));
    let given = unit(gx, gy);
    let term = (fitted[0] - given[0]).powi(2) + (fitted[1] - given[1]).powi(2) + (fitted[2] - given[2]).powi(2);
    let g2 = gx * gx + gy * gy;
    let g = g2.sqrt();
    // The fit's own equation, vertical slopes = g·(A − λ)/A, relative to
    // the precision of a slope g from a normal (its error grows as 1 + g²).
    let (rx, ry) = (si / a - gx * current, sj / a - gy * current);
    let off = (rx * rx + ry * ry).sqrt() / (1.0 + g2);
    let rough = ((czz - tilt2 / a) / a).max(0.0);
    let c = 1.0 - rough;
    let b = (1.0 - g * g) / g;
    let disc = b * b + 4.0 * c;
    let root_disc = disc.sqrt();
    let (positive, other) = (2.0 * c / (b + root_disc), 0.5 * (root_disc - b));
    let root = if b > 0.0 { positive } else { other };
    let solvable = g > 1e-12 && c > 0.0 && disc >= 0.0 && b.is_finite();
    // g → 0: the limit of s/g is c.
    let fallback = if g <= 1e-12 && c > 0.0 { c } else { current };
    let wanted = if solvable { root / g } else { fallback };
    let change = wanted - *out;
    let now: i8 = if change > 0.0 { 1 } else { -1 };
    let step = if now == -*dir { 0.5 * damping } else { damping };
    *dir = now;
    *out += step * change;
    (term, change.abs(), off)
}

/// The conjugate gradients' iterations at most.
const CG_ITERATIONS: usize = 2000;

/// Conjugate gradients on the normal equations (DxᵀDx + DyᵀDy + λ) z =
/// Dxᵀgx + Dyᵀgy with the exact operator, from the nearest transform's
/// solution (clamp as a half-sample reflection), until the residual falls
/// below 1e-12 of the right-hand side's or the iterations run out.
fn conjugate_gradients(
    patch: &Patch,
    slopes: Slopes<'_>,
    lambda: f64,
    opts: &HeightOptions,
    z: &mut [f64],
) -> Result<(bool, f64)> {
    let w = patch.w;
    let len = z.len();
    let h = len / w;
    // The start: clamp read as a half-sample reflection, exact for N = 3.
    let start = Solver::nearest(w, h, opts.fit.borders, opts.fit.patch, Model::Exact)
        .map(|s| s.solve(slopes, lambda, z).map(|st| st.noise_gain))
        .transpose()?
        .unwrap_or(0.0);
    let (box_xt, ramp_xt, box_yt, ramp_yt) =
        (patch.box_x.transposed(), patch.ramp_x.transposed(), patch.box_y.transposed(), patch.ramp_y.transposed());
    let alloc = || -> Result<Vec<f64>> {
        let mut v = try_vec(len)?;
        v.resize(len, 0.0);
        Ok(v)
    };
    let (mut gx, mut gy) = (alloc()?, alloc()?);
    // Dᵀ applied to (gx, gy): Dxᵀ = box_yᵀ ramp_xᵀ / A, Dyᵀ = ramp_yᵀ box_xᵀ / A.
    let adjoint = |gx: &mut [f64], gy: &mut [f64], out: &mut [f64]| {
        gx.par_chunks_mut(w).zip(gy.par_chunks_mut(w)).for_each(|(rx, ry)| {
            let (mut tx, mut ty) = (vec![0.0; w], vec![0.0; w]);
            ramp_xt.row(rx, &mut tx);
            box_xt.row(ry, &mut ty);
            rx.copy_from_slice(&tx);
            ry.copy_from_slice(&ty);
        });
        let (gx, gy) = (&*gx, &*gy);
        out.par_chunks_mut(w).enumerate().for_each(|(y, o)| {
            let mut t = vec![0.0; w];
            box_yt.column(gx, w, y, o, |v| v);
            ramp_yt.column(gy, w, y, &mut t, |v| v);
            o.iter_mut().zip(&t).for_each(|(a, b)| *a = (*a + b) / patch.a);
        });
    };
    // Least squares over the period: a mirrored axis counts its texels but
    // the two edge ones twice (the period holds them twice).
    let multiplicity =
        |n: usize, b: Border, k: usize| if b == Border::Mirror && n > 2 && k != 0 && k != n - 1 { 2.0 } else { 1.0 };
    let wx: Vec<f64> = (0..w).map(|x| multiplicity(w, opts.fit.borders.x, x)).collect();
    let wy: Vec<f64> = (0..h).map(|y| multiplicity(h, opts.fit.borders.y, y)).collect();
    let weigh = |y: usize, rx: &mut [f64], ry: &mut [f64]| {
        for ((gx, gy), m) in rx.iter_mut().zip(ry.iter_mut()).zip(&wx) {
            *gx *= m * wy[y];
            *gy *= m * wy[y];
        }
    };
    let apply = |z: &[f64], gx: &mut [f64], gy: &mut [f64]| {
        gx.par_chunks_mut(w).zip(gy.par_chunks_mut(w)).enumerate().for_each(|(y, (rx, ry))| {
            patch.slopes(z, y, rx, ry);
            weigh(y, rx, ry);
        });
    };
    let dot = |a: &[f64], b: &[f64]| -> f64 {
        let rows: Vec<f64> =
            a.par_chunks(w).zip(b.par_chunks(w)).map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum()).collect();
        rows.iter().sum()
    };
    // b = Dᵀ g.
    let mut rhs = alloc()?;
    gx.par_chunks_mut(w).zip(gy.par_chunks_mut(w)).enumerate().for_each(|(y, (rx, ry))| {
        slopes(y, rx, ry);
        weigh(y, rx, ry);
    });
    adjoint(&mut gx, &mut gy, &mut rhs);
    let normal = |v: &[f64], out: &mut [f64], gx: &mut [f64], gy: &mut [f64]| {
        apply(v, gx, gy);
        adjoint(gx, gy, out);
        out.iter_mut().zip(v).for_each(|(o, v)| *o += lambda * v);
    };
    // Preconditioned by the period's multiplicities W: the steps are then
    // W-orthogonal to the null space, and the solution keeps the start's
    // minimum W-norm there, as the transforms' solutions have it.
    let inverse_weight = |r: &[f64], out: &mut [f64]| {
        out.par_chunks_mut(w).zip(r.par_chunks(w)).enumerate().for_each(|(y, (o, r))| {
            for ((o, r), m) in o.iter_mut().zip(r).zip(&wx) {
                *o = r / (m * wy[y]);
            }
        });
    };
    let mut r = alloc()?;
    normal(z, &mut r, &mut gx, &mut gy);
    r.iter_mut().zip(&rhs).for_each(|(r, b)| *r = b - *r);
    let mut y = alloc()?;
    inverse_weight(&r, &mut y);
    let mut p = y.clone();
    let mut ap = alloc()?;
    let target = 1e-26 * dot(&rhs, &rhs);
    let mut ry = dot(&r, &y);
    let mut converged = dot(&r, &r) <= target;
    for _ in 0..CG_ITERATIONS {
        if converged {
            break;
        }
        normal(&p, &mut ap, &mut gx, &mut gy);
        let pap = dot(&p, &ap);
        if pap <= 0.0 {
            break;
        }
        let alpha = ry / pap;
        z.iter_mut().zip(&p).for_each(|(z, p)| *z += alpha * p);
        r.iter_mut().zip(&ap).for_each(|(r, a)| *r -= alpha * a);
        converged = dot(&r, &r) <= target;
        inverse_weight(&r, &mut y);
        let next = dot(&r, &y);
        let beta = next / ry;
        ry = next;
        p.iter_mut().zip(&y).for_each(|(p, y)| *p = y + beta * *p);
    }
    Ok((converged, start))
}
