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

use super::banded::Separable;
use super::cost::CG_ITERATIONS;
use super::gauss_newton::Vertical;
use super::line::{Work, columns_in_place, rows};
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
    let (borders, n) = (opts.fit.borders, opts.fit.patch);
    // Refused before any work where no path solves it within the limit
    // of time (`cost.rs`).
    super::cost::check(w, h, opts)?;
    let solver = Solver::new(w, h, borders, n, Model::Exact);
    let patch = Patch::new(w, h, opts);
    // Clamp with N ≥ 5: conjugate gradients, preconditioned by (and, the
    // first time, started from) the nearest transform's solve, within one
    // budget of iterations for the whole inverse; the later solves start
    // from the last one's heights.
    let nearest = if solver.is_none() { Solver::nearest(w, h, borders, n, Model::Exact) } else { None };
    // The exact solve in dense bases where the axes are short enough, or
    // in one dense basis and banded solves (`banded.rs`).
    let dense = if solver.is_none() { Separable::within_limit(&patch, h, opts)? } else { None };
    // The dense solves' null threshold: the fixed point's own first, the
    // exact least squares once it has settled (see below).
    let mut null = if opts.fit.fit == Fit::Vertical { super::dense::NULL } else { super::dense::ORTHOGONAL_NULL };
    let mut budget = CG_ITERATIONS;
    let mut iterations = 0;
    // One vertical solve: the transform's, else the dense bases', else
    // conjugate gradients; whether it met its tolerance, its noise gain.
    let mut vertical = |s: Slopes<'_>, z: &mut [f64], warm: bool, null: f64| -> Result<(bool, f64)> {
        iterations += 1;
        match (&solver, &dense) {
            (Some(solver), _) => Ok((true, solver.solve(s, lambda, z)?.noise_gain)),
            (None, Some(dense)) => {
                dense_solve(&patch, dense, s, lambda, null, z)?;
                Ok((true, nearest.as_ref().map_or(0.0, |n| n.noise_gain(lambda).noise_gain)))
            }
            (None, None) => conjugate_gradients(&patch, nearest.as_ref(), s, lambda, z, warm, &mut budget),
        }
    };
    let (mut converged, noise_gain) = vertical(slopes, z, false, null)?;
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
    let (_, first, mut off) = patch.update_ratios(z, slopes, None, &mut rho, &mut direction, 1.0)?;
    // The heights closest so far, as f32; `None` while they are the
    // vertical solution, which a solve gives again: most maps converge and
    // never need them, and copying them took 3 % of the time at 4096².
    let mut kept: Option<Vec<f32>> = None;
    if solver.is_none() && dense.is_none() {
        // Conjugate gradients cannot promise the vertical solution again
        // within their budget: kept from the start.
        let mut k = try_vec(len)?;
        k.par_extend(z.par_iter().map(|&z| z as f32));
        kept = Some(k);
    }
    let mut best = first;
    let (mut last_change, mut growing, mut damping) = (f64::INFINITY, 0, 1.0);
    // Ratios settled to the input's own precision (its step) are settled:
    // the slopes asked for are known no better.
    let tolerance = opts.tolerance.max(opts.step);
    converged = false;
    let mut settled_without_faint_modes = false;
    // The closest mismatch after each step, for the stall rule below.
    let mut bests: Vec<f64> = vec![best];
    for _ in 1..opts.max_iterations {
        let weighted = |y: usize, gx: &mut [f64], gy: &mut [f64]| {
            slopes(y, gx, gy);
            for ((x, y), r) in gx.iter_mut().zip(gy.iter_mut()).zip(&rho[y * w..][..w]) {
                *x *= r;
                *y *= r;
            }
        };
        if !vertical(&weighted, z, true, null)?.0 {
            // Conjugate gradients that did not meet their tolerance (their
            // budget spent): the iteration stops, unsettled.
            break;
        }
        let (change, mismatch, now_off) = patch.update_ratios(z, slopes, None, &mut rho, &mut direction, damping)?;
        off = now_off;
        if change <= tolerance {
            if dense.is_some() && null != super::dense::NULL {
                // Settled without the modes the vertical fit barely sees:
                // the slopes asked for are now some heights' slopes, and
                // the exact solves go on from here to give those modes
                // back (a step that makes the fit worse is not kept: the
                // closest heights found are).
                settled_without_faint_modes = true;
                null = super::dense::NULL;
                (last_change, growing) = (f64::INFINITY, 0);
                continue;
            }
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
        // A mismatch that no longer falls: the closest heights found have
        // not come closer by STALL_FALL in STALL_STEPS steps. On a map the
        // fit did not make (a bake) that is the map's own non-integrable
        // part, which more steps only chase (the Bricks061 bake: its
        // vertical solution stayed the closest through 100 steps); where
        // the map is the fit's own and the fixed point crawls, each step
        // comes closer by some per cent (10 % a step on Bricks061, N = 5,
        // mirror). Gauss–Newton then takes over as after any unsettled
        // end (the closest heights kept).
        // (Not once settled without the faint modes: those steps are
        // bounded by the iterations alone, as before.)
        bests.push(best);
        let stalled = bests.len() > STALL_STEPS && best > (1.0 - STALL_FALL) * bests[bests.len() - 1 - STALL_STEPS];
        if stalled && !settled_without_faint_modes {
            break;
        }
    }
    if !converged && settled_without_faint_modes {
        // The exact solves did not settle again: the closest heights kept
        // stand, settled as the fixed point was.
        match &kept {
            Some(kept) => z.iter_mut().zip(kept).for_each(|(z, &k)| *z = f64::from(k)),
            None => drop(vertical(slopes, z, false, super::dense::ORTHOGONAL_NULL)?),
        }
        converged = true;
    } else if !converged {
        match &kept {
            Some(kept) => z.iter_mut().zip(kept).for_each(|(z, &k)| *z = f64::from(k)),
            None => {
                vertical(slopes, z, false, null)?;
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
    let weights = multiplicities(&patch, h);
    let preconditioner = match (&solver, &dense) {
        (Some(solver), _) => Some(Vertical::Transform(solver)),
        (None, Some(dense)) => Some(Vertical::Dense(dense, (&weights.0, &weights.1))),
        (None, None) => None,
    };
    if let (Some(preconditioner), true, Ok(())) = (preconditioner, !converged || off > OFF_BY * precision, room) {
        let (lo, hi) = z.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
        let mut before: Vec<f64> = try_vec(len)?;
        before.extend_from_slice(z);
        let settle = SETTLED * (hi - lo);
        let outcome = super::gauss_newton::refine(&patch, preconditioner, slopes, lambda, settle, precision, z)?;
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

/// The fixed point stops, unsettled, when its closest mismatch has not
/// fallen by `STALL_FALL` of itself in `STALL_STEPS` steps.
const STALL_STEPS: usize = 10;
const STALL_FALL: f64 = 0.01;

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
    pub(super) fn update_ratios(
        &self,
        z: &[f64],
        slopes: Slopes<'_>,
        kept: Option<&[bool]>,
        rho: &mut [f64],
        direction: &mut [i8],
        damping: f64,
    ) -> Result<(f64, f64, f64)> {
        let w = self.w;
        let h = z.len() / w;
        if self.refit_by_lines(h) {
            return self.update_ratios_by_lines(z, slopes, kept, rho, direction, damping);
        }
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
                    let kept = kept.map(|kept| &kept[(rows.start + k) * w..][..w]);
                    ratio_row(self.a, m, &gx, &gy, kept, out, dir, damping)
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

    /// Whether the re-fit takes its patch sums from the line sums of
    /// `line.rs` rather than the forward fit's: where the image is less
    /// than 8N texels wide or tall. The forward fit starts each tile of at
    /// least 8N rows and strip of at least 8N columns with 2N rows of sums,
    /// each as long as the strip plus N, and its blocks' sums of N values
    /// per row sum (O(N²) a strip): on an image that small that setup is
    /// no longer shared by enough texels, and grows with N (a re-fit of a
    /// 512² image took 60 ms at N = 1023 by it). The line sums take a few
    /// operations a texel whatever N, and three planes.
    pub(super) fn refit_by_lines(&self, h: usize) -> bool {
        super::line::refit_by_lines(self.w, h, self.patch)
    }

    /// [`Self::update_ratios`] with the patch sums from the line sums:
    /// along the rows the ramp and box of z and the box of z², down the
    /// columns Σiz, Σjz, Σz and Σz², then each row's ratios.
    fn update_ratios_by_lines(
        &self,
        z: &[f64],
        slopes: Slopes<'_>,
        kept: Option<&[bool]>,
        rho: &mut [f64],
        direction: &mut [i8],
        damping: f64,
    ) -> Result<(f64, f64, f64)> {
        let w = self.w;
        let len = z.len();
        let (mut si, mut sj, mut czz) = (try_filled(len, 0.0)?, try_filled(len, 0.0)?, try_filled(len, 0.0)?);
        rows(w, &mut [&mut si, &mut sj, &mut czz], |y, row, work| {
            let Work { scratch, temps } = work;
            let [ramped, boxed, boxed_zz] = row else { unreachable!() };
            let zr = &z[y * w..][..w];
            self.x.apply(zr, Some(&mut boxed[..]), Some(&mut ramped[..]), scratch);
            let zz = &mut temps[0];
            zz.iter_mut().zip(zr).for_each(|(o, z)| *o = z * z);
            self.x.apply(zz, Some(&mut boxed_zz[..]), None, scratch);
        });
        let n2 = (self.patch * self.patch) as f64;
        columns_in_place(w, &mut [&mut si, &mut sj, &mut czz], |_, cols, work| {
            let Work { scratch, temps } = work;
            let [ramped, boxed, boxed_zz] = cols else { unreachable!() };
            let [t_si, t_s0, t_sj, t_szz] = temps;
            self.y.apply(ramped, Some(&mut t_si[..]), None, scratch);
            self.y.apply(boxed, Some(&mut t_s0[..]), Some(&mut t_sj[..]), scratch);
            self.y.apply(boxed_zz, Some(&mut t_szz[..]), None, scratch);
            ramped.copy_from_slice(t_si);
            boxed.copy_from_slice(t_sj);
            // Czz as the forward fit forms it: (N² Σz² − (Σz)²) / N².
            for ((c, &s0), &szz) in boxed_zz.iter_mut().zip(t_s0.iter()).zip(t_szz.iter()) {
                *c = ((n2 * szz - s0 * s0) / n2).max(0.0);
            }
        });
        let per_row: Vec<(f64, f64, f64)> = rho
            .par_chunks_mut(w)
            .zip(direction.par_chunks_mut(w))
            .enumerate()
            .map(|(y, (out, dir))| {
                let (mut gx, mut gy) = (vec![0.0; w], vec![0.0; w]);
                slopes(y, &mut gx, &mut gy);
                let at = y * w..(y + 1) * w;
                let m: Vec<[f64; 3]> =
                    si[at.clone()].iter().zip(&sj[at.clone()]).zip(&czz[at]).map(|((&a, &b), &c)| [a, b, c]).collect();
                let kept = kept.map(|kept| &kept[y * w..][..w]);
                ratio_row(self.a, &m, &gx, &gy, kept, out, dir, damping)
            })
            .collect();
        let (mut largest, mut mismatch, mut worst) = (0.0f64, 0.0, 0.0f64);
        for (c, e, o) in per_row {
            largest = largest.max(c);
            mismatch += e;
            worst = worst.max(o);
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
#[allow(clippy::too_many_arguments)]
fn ratio_row(
    a: f64,
    m: &[[f64; 3]],
    gx: &[f64],
    gy: &[f64],
    kept: Option<&[bool]>,
    out: &mut [f64],
    dir: &mut [i8],
    damping: f64,
) -> (f64, f64, f64) {
    pulp::Arch::new().dispatch(RatioRow { a, m, gx, gy, kept, out, dir, damping })
}

/// [`ratio_row`]'s arguments, for [`pulp::Arch::dispatch`].
struct RatioRow<'a> {
    a: f64,
    m: &'a [[f64; 3]],
    gx: &'a [f64],
    gy: &'a [f64],
    /// The texels whose equations count (the solve with holes keeps
    /// some): the others' ratios are updated but left out of the sums.
    kept: Option<&'a [bool]>,
    out: &'a mut [f64],
    dir: &'a mut [i8],
    damping: f64,
}

impl pulp::WithSimd for RatioRow<'_> {
    type Output = (f64, f64, f64);
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> (f64, f64, f64) {
        // Inlined here, so that it is compiled for each instruction set.
        let RatioRow { a, m, gx, gy, kept, out, dir, damping } = self;
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
                if kept.is_none_or(|kept| kept[start + l]) {
                    mismatch += terms[l];
                    largest = largest.max(changes[l]);
                    worst = worst.max(offs[l]);
                }
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

/// The period's multiplicities of `patch`'s axes (a mirrored axis holds
/// its texels but the two edge ones twice), per column and per row.
pub(super) fn multiplicities(patch: &Patch, h: usize) -> (Vec<f64>, Vec<f64>) {
    let multiplicity =
        |n: usize, b: Border, k: usize| if b == Border::Mirror && n > 2 && k != 0 && k != n - 1 { 2.0 } else { 1.0 };
    let w = patch.w;
    (
        (0..w).map(|x| multiplicity(w, patch.borders.x, x)).collect(),
        (0..h).map(|y| multiplicity(h, patch.borders.y, y)).collect(),
    )
}

/// The vertical solve of `slopes` in `dense`'s bases, into `z`.
fn dense_solve(
    patch: &Patch,
    dense: &Separable,
    slopes: Slopes<'_>,
    lambda: f64,
    null: f64,
    z: &mut [f64],
) -> Result<()> {
    let len = z.len();
    let (wx, wy) = multiplicities(patch, len / patch.w);
    let (mut gx, mut gy, mut b) = (try_filled(len, 0.0)?, try_filled(len, 0.0)?, try_filled(len, 0.0)?);
    super::dense::DenseSolver::right_hand_side(patch, slopes, (&wx, &wy), (&mut gx, &mut gy), &mut b);
    drop((gx, gy));
    dense.solve(&mut b, lambda, null, (&wx, &wy), z)
}

/// ε of the conjugate gradients' preconditioner: the weight of the
/// transform's null modes, which the exact operator sees where patches
/// reach past a clamped edge.
const PRECONDITIONER_EPSILON: f64 = 1e-4;

/// The conjugate gradients stop when the normal equations' residual has
/// fallen to this fraction of the right-hand side (in norm): the round
/// trips and the dense solves of `tests/integration/height.rs` hold at 1e-8 as at
/// 1e-13, and each decade costs some 50 iterations on a 128² map.
const CG_TOLERANCE: f64 = 1e-10;

/// Conjugate gradients on the normal equations (DxᵀWDx + DyᵀWDy + λ) z =
/// DxᵀWgx + DyᵀWgy with the exact operator, preconditioned by the nearest
/// transform's solve `nearest` (clamp as a half-sample reflection, exact for
/// N = 3), from its solution or (`warm`) from `z`, until the residual falls
/// below [`CG_TOLERANCE`] of the right-hand side's or `budget` (the
/// iterations left) runs out. Returns whether it met the tolerance, and
/// the nearest solve's noise gain (0 when `warm`).
fn conjugate_gradients(
    patch: &Patch,
    nearest: Option<&Solver>,
    slopes: Slopes<'_>,
    lambda: f64,
    z: &mut [f64],
    warm: bool,
    budget: &mut usize,
) -> Result<(bool, f64)> {
    let w = patch.w;
    let len = z.len();
    let h = len / w;
    // The start: clamp read as a half-sample reflection, exact for N = 3.
    let start = match nearest {
        Some(s) if !warm => s.solve(slopes, lambda, z)?.noise_gain,
        _ => 0.0,
    };
    let alloc = || -> Result<Vec<f64>> {
        let mut v = try_vec(len)?;
        v.resize(len, 0.0);
        Ok(v)
    };
    let (mut gx, mut gy) = (alloc()?, alloc()?);
    // Dᵀ applied to (gx, gy), which it overwrites.
    let adjoint = |gx: &mut [f64], gy: &mut [f64], out: &mut [f64]| patch.adjoint(gx, gy, out);
    // Least squares over the period: a mirrored axis counts its texels but
    // the two edge ones twice (the period holds them twice).
    let (wx, wy) = multiplicities(patch, h);
    let weigh = |y: usize, rx: &mut [f64], ry: &mut [f64]| {
        for ((gx, gy), m) in rx.iter_mut().zip(ry.iter_mut()).zip(&wx) {
            *gx *= m * wy[y];
            *gy *= m * wy[y];
        }
    };
    let apply = |z: &[f64], gx: &mut [f64], gy: &mut [f64]| {
        patch.slopes(z, gx, gy);
        gx.par_chunks_mut(w).zip(gy.par_chunks_mut(w)).enumerate().for_each(|(y, (rx, ry))| weigh(y, rx, ry));
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
    // Preconditioned by the nearest transform's solve M = (DₙᵀWDₙ + λ + ε)⁻¹
    // (`Solver::inverse`, which takes its right-hand side times W⁻¹): the
    // exact operator differs from it only where a patch reaches past a
    // clamped edge, so few iterations are needed whatever N and the size,
    // where the period's multiplicities W alone needed more than the
    // conditioning (P² at the lowest frequencies, and the box's near zeros
    // of a wide patch) and ran to the cap. M is symmetric, and the null
    // modes the exact operator shares with the transform (the constant, and
    // along a wrapped or mirrored axis its alternating and box-zero modes)
    // are its eigenvectors: the steps stay orthogonal to them, and the
    // solution keeps the start's minimum norm there, as the transforms'
    // solutions have it.
    let mut weighted = alloc()?;
    let precondition = |r: &[f64], out: &mut [f64]| -> Result<()> {
        weighted.par_chunks_mut(w).zip(r.par_chunks(w)).enumerate().for_each(|(y, (o, r))| {
            for ((o, r), m) in o.iter_mut().zip(r).zip(&wx) {
                *o = r / (m * wy[y]);
            }
        });
        match nearest {
            Some(solver) => solver.inverse(&weighted, lambda, PRECONDITIONER_EPSILON, out),
            None => {
                out.copy_from_slice(&weighted);
                Ok(())
            }
        }
    };
    let converged = preconditioned_cg(z, &rhs, (w, CG_TOLERANCE), normal, precondition, (&mut gx, &mut gy), budget)?;
    Ok((converged, start))
}

/// Σ a·b, row by row in parallel, the rows' sums added in order: the same
/// bits whatever the thread count.
pub(super) fn dot(a: &[f64], b: &[f64], w: usize) -> f64 {
    let rows: Vec<f64> =
        a.par_chunks(w).zip(b.par_chunks(w)).map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum()).collect();
    rows.iter().sum()
}

/// Preconditioned conjugate gradients on `normal` z = `rhs` (`normal(v,
/// out, gx, gy)` applies the normal equations' operator to v, with gx, gy
/// as its scratch planes), from `z`, until the residual falls below
/// `tolerance` of the right-hand side's or `budget` (iterations left) runs
/// out; image rows of `w`. Returns whether it met the tolerance.
pub(super) fn preconditioned_cg(
    z: &mut [f64],
    rhs: &[f64],
    (w, tolerance): (usize, f64),
    normal: impl Fn(&[f64], &mut [f64], &mut [f64], &mut [f64]),
    mut precondition: impl FnMut(&[f64], &mut [f64]) -> Result<()>,
    (gx, gy): (&mut [f64], &mut [f64]),
    budget: &mut usize,
) -> Result<bool> {
    let plane = || try_filled(z.len(), 0.0);
    let mut r = plane()?;
    normal(z, &mut r, gx, gy);
    r.par_iter_mut().zip(rhs).for_each(|(r, b)| *r = b - *r);
    let mut y = plane()?;
    precondition(&r, &mut y)?;
    let mut p = y.clone();
    let mut ap = plane()?;
    let target = tolerance * tolerance * dot(rhs, rhs, w);
    let mut ry = dot(&r, &y, w);
    let mut converged = dot(&r, &r, w) <= target;
    while !converged && *budget > 0 {
        *budget -= 1;
        normal(&p, &mut ap, gx, gy);
        let pap = dot(&p, &ap, w);
        if pap <= 0.0 {
            break;
        }
        let alpha = ry / pap;
        z.par_iter_mut().zip(&p).for_each(|(z, p)| *z += alpha * p);
        r.par_iter_mut().zip(&ap).for_each(|(r, a)| *r -= alpha * a);
        converged = dot(&r, &r, w) <= target;
        if converged {
            break;
        }
        precondition(&r, &mut y)?;
        let next = dot(&r, &y, w);
        let beta = next / ry;
        ry = next;
        p.par_iter_mut().zip(&y).for_each(|(p, y)| *p = y + beta * *p);
    }
    Ok(converged)
}
