//! The orthogonal fit's inverse by Gauss–Newton, where the fixed point of
//! `iterative.rs` converges slowly or not at all (steep slopes, cliffs).
//!
//! Per texel p the orthogonal fit gives the vertical slopes v = Dz times
//! A/m, m = A − λ = d + √(d² + |C|²), d = (A − Czz)/2, C = A·v the ramp
//! sums and Czz the patch's centred sum of squares (SPEC §2). So the
//! heights reproduce the slopes g iff
//!
//! ```text
//! r_p(z) = v_p − g_p · m_p(z) / A = 0
//! ```
//!
//! (the fixed point's own equation: vertical slopes g·ρ, ρ = m/A). Its
//! Jacobian is exact and cheap: with E(δ)_p = Σ_patch (z_k − z̄_p) δ_k
//! (half the change of Czz) and u = g/(A q), q = √(d² + |C|²),
//!
//! ```text
//! J δ = Dδ − u (A C·Dδ − m E(δ)).
//! ```
//!
//! Each step minimises Σ W |r + Jδ|² + μ ⟨δ, (M + ε) δ⟩ (W the period's
//! multiplicities, as the transforms' least squares; M = DᵀD + λ the
//! vertical fit's normal operator, so the damping is in the fit's own
//! metric) by conjugate gradients preconditioned with (M + ε)⁻¹, which is
//! one solve of the transforms. M is J without the roughness terms, so
//! where slopes are moderate few iterations are needed; where they are not
//! the exact J is what makes the step right. ε keeps the vertical fit's
//! null modes (alternating heights) in play: the roughness Czz sees them.
//! Steps that do not lower Σ W|r|² are refused and μ grows
//! (Levenberg–Marquardt): the heights returned are never farther from the
//! slopes, in this measure, than those it started from.
//!
//! Every pass is rows in parallel, each row's sums in a fixed order, and
//! the inner products are sums of per-row sums in row order: the same bits
//! whatever the thread count.

use crate::error::Result;
use crate::par::prelude::*;
use crate::samples::try_vec;

use super::banded::Separable;
use super::line::{Scratch, Work, columns, rows};
use super::patch::Patch;
use super::solve::SlopeRows as Slopes;
use super::solve::Solver;

/// The vertical fit's solve that preconditions the steps: the transforms',
/// or (clamp with N ≥ 5) the dense bases' with the period's multiplicities
/// (per column, per row).
#[derive(Clone, Copy)]
pub(super) enum Vertical<'a> {
    Transform(&'a Solver),
    Dense(&'a Separable, (&'a [f64], &'a [f64])),
}

impl Vertical<'_> {
    /// (DᵀD + λ + ε)⁻¹ b, as [`Solver::inverse`].
    pub(super) fn inverse(&self, b: &[f64], lambda: f64, epsilon: f64, out: &mut [f64]) -> Result<()> {
        match self {
            Vertical::Transform(solver) => solver.inverse(b, lambda, epsilon, out),
            Vertical::Dense(solver, weights) => solver.inverse(b, lambda, epsilon, *weights, out),
        }
    }
}

/// Bytes a texel the refinement holds besides the heights: the heights it
/// started from (1 f64, kept by its caller), the linearisation (6), the
/// residual (2), the trial heights, the right-hand side and the step (3),
/// the conjugate gradients' four vectors and four work planes (8).
pub(super) const BYTES_PER_TEXEL: u64 = 20 * 8;

/// Levenberg–Marquardt steps at most (accepted or refused).
const STEPS: usize = 60;
/// Solves at most, over every step (the steep mirrored test map needs
/// 288).
const SOLVES: usize = 300;
/// The least factor the last `WINDOW` accepted steps together must cut
/// the cost by for the refinement to go on.
const GAIN: f64 = 10.0;
const WINDOW: usize = 3;
/// And the last `SHORT_WINDOW` by `SHORT_GAIN`: a map the fit did not make
/// shows itself in two steps (2.6× and 1.3× on the Bricks061 bake), where
/// the slowest fit-made start measured gained 2.2× and 2.8×.
const SHORT_GAIN: f64 = 4.0;
const SHORT_WINDOW: usize = 2;
/// Conjugate-gradient iterations per step at most: the first step on the
/// real sets' own maps took 16 to 47 at the tolerance below, and a step on
/// a map the fit did not make is paid in full before it shows so.
const CG_ITERATIONS: usize = 30;
/// The conjugate gradients stop when the preconditioned residual has
/// fallen by this factor (squared norms: 1e-4, so 1e-2 in norm): inexact
/// Newton steps. Tighter (down to √(cost / first cost)) took three times
/// the solves per step for the same progress per step on a steep mirrored
/// map, whose tail is set by the weakly seen modes, not by the inner solve.
const CG_TOLERANCE: f64 = 1e-4;
/// ε: the null modes' weight in the preconditioner and the damping.
const EPSILON: f64 = 1e-4;

/// What the refinement did.
pub(super) struct Outcome {
    /// Solves of the transforms run (one per conjugate-gradient iteration).
    pub solves: usize,
    /// Whether the heights settled: the last accepted step moved no height
    /// by more than `settle` (texel units).
    pub converged: bool,
}

/// The linearisation of r at the current heights, per texel.
struct Linear {
    /// u = g / (A q).
    u: Vec<[f64; 2]>,
    /// A·C, C = A·v the ramp sums (∂C = A·Dδ, so C·∂C = A·C·Dδ).
    ac: Vec<[f64; 2]>,
    /// m = A − λ.
    m: Vec<f64>,
    /// The patch's mean height.
    mean: Vec<f64>,
}

/// A row's residual and linearisation to fill: r, u, A·C, m, mean.
type RowStore<'a> = (&'a mut [[f64; 2]], &'a mut [[f64; 2]], &'a mut [[f64; 2]], &'a mut [f64], &'a mut [f64]);

struct Problem<'a> {
    patch: &'a Patch,
    solver: Vertical<'a>,
    slopes: Slopes<'a>,
    w: usize,
    /// Texels in a patch, N².
    n2: f64,
    wx: Vec<f64>,
    wy: Vec<f64>,
    lambda: f64,
}

/// Refines `z` (texel units) towards r(z) = 0; `settle` is how little a
/// step must move the heights for them to count as settled, `precision`
/// the input's step (its rounding sets the cost's floor).
pub(super) fn refine(
    patch: &Patch,
    solver: Vertical<'_>,
    slopes: Slopes<'_>,
    lambda: f64,
    settle: f64,
    precision: f64,
    z: &mut [f64],
) -> Result<Outcome> {
    let len = z.len();
    let p = Problem::new(patch, solver, slopes, lambda, len / patch.w);
    // The cost the input's rounding alone leaves: a residual of its
    // rounding's RMS (step / √12) at every texel of the period.
    let floor = p.wx.iter().sum::<f64>() * p.wy.iter().sum::<f64>() * precision * precision / 12.0;
    let plane = || -> Result<Vec<f64>> {
        let mut v = try_vec(len)?;
        v.resize(len, 0.0);
        Ok(v)
    };
    let pair = || -> Result<Vec<[f64; 2]>> {
        let mut v = try_vec(len)?;
        v.resize(len, [0.0; 2]);
        Ok(v)
    };
    let mut lin = Linear { u: pair()?, ac: pair()?, m: plane()?, mean: plane()? };
    let mut r = pair()?;
    let mut work = Vectors {
        res: plane()?,
        y: plane()?,
        dir: plane()?,
        op: plane()?,
        planes: [plane()?, plane()?, plane()?, plane()?],
    };
    let mut cost = p.linearise(z, Some((&mut lin, &mut r)), &mut work.planes);
    let mut trial = plane()?;
    let (mut rhs, mut step) = (plane()?, plane()?);
    let (mut mu, mut solves, mut converged) = (1e-6, 0, false);
    let mut gains: Vec<f64> = Vec::new();
    let mut accepted: Vec<f64> = Vec::new();
    for _ in 0..STEPS {
        if cost <= floor {
            converged = true;
            break;
        }
        if solves >= SOLVES {
            break;
        }
        // rhs = −W⁻¹ Jᵀ W r.
        p.gradient(z, &lin, &r, &mut rhs, &mut work.planes);
        step.fill(0.0);
        solves += p.conjugate_gradients(z, &lin, mu, CG_TOLERANCE, &rhs, &mut step, &mut work)?;
        trial.iter_mut().zip(z.iter()).zip(&step).for_each(|((t, z), s)| *t = z + s);
        // The trial's cost alone; its linearisation only if it is taken.
        let trial_cost = p.linearise(&trial, None, &mut work.planes);
        if trial_cost < cost {
            let moved = step.iter().fold(0.0f64, |m, s| m.max(s.abs()));
            z.copy_from_slice(&trial);
            p.linearise(z, Some((&mut lin, &mut r)), &mut work.planes);
            let cost_before = cost;
            cost = trial_cost;
            mu = (mu / 10.0).max(1e-12);
            // Settled: the heights move by less than `settle`, or the cost
            // has reached its floor (the input's rounding).
            if moved <= settle || cost <= floor {
                converged = true;
                break;
            }
            // Where the map is the fit's own, the steps cut the cost by
            // orders of magnitude until the input's rounding is all that
            // is left (measured: 90× to 2000× a step on the real sets;
            // from a far start on a steep map 2.2×, 2.8×, 4.5×, then 13×
            // and more). Steps that together gain less than `GAIN` say
            // the rest of the misfit is the map's own (a normal map the
            // fit did not make: 2.6×, 1.3×, 1.5× on the Bricks061 bake)
            // and more steps would only chase it.
            gains.push(cost_before / cost);
            accepted.push(cost_before / cost);
            if slow(&gains) || slow_accepted(&accepted) {
                break;
            }
        } else {
            // A refused step gains nothing: it counts as such.
            gains.push(1.0);
            if slow(&gains) {
                break;
            }
            mu *= 10.0;
            if mu > 1e6 {
                break;
            }
        }
    }
    Ok(Outcome { solves, converged })
}

/// Whether the last `WINDOW` steps together cut the cost by less than
/// `GAIN`.
fn slow(gains: &[f64]) -> bool {
    gains.len() >= WINDOW && gains[gains.len() - WINDOW..].iter().product::<f64>() < GAIN
}

/// Whether the last `SHORT_WINDOW` accepted steps together cut the cost
/// by less than `SHORT_GAIN`.
fn slow_accepted(accepted: &[f64]) -> bool {
    accepted.len() >= SHORT_WINDOW && accepted[accepted.len() - SHORT_WINDOW..].iter().product::<f64>() < SHORT_GAIN
}

/// The conjugate gradients' vectors, and four planes of work (the patch
/// sums' passes).
struct Vectors {
    res: Vec<f64>,
    y: Vec<f64>,
    dir: Vec<f64>,
    op: Vec<f64>,
    planes: [Vec<f64>; 4],
}

impl<'a> Problem<'a> {
    fn new(patch: &'a Patch, solver: Vertical<'a>, slopes: Slopes<'a>, lambda: f64, h: usize) -> Problem<'a> {
        let w = patch.w;
        let multiplicity =
            |n: usize, mirror: bool, k: usize| if mirror && n > 2 && k != 0 && k != n - 1 { 2.0 } else { 1.0 };
        let (mx, my) = (patch.borders.x == crate::Border::Mirror, patch.borders.y == crate::Border::Mirror);
        Problem {
            patch,
            solver,
            slopes,
            w,
            n2: (patch.patch * patch.patch) as f64,
            wx: (0..w).map(|x| multiplicity(w, mx, x)).collect(),
            wy: (0..h).map(|y| multiplicity(h, my, y)).collect(),
            lambda,
        }
    }

    /// J v and D v (the damping's), row by row: the patch sums of v and
    /// z·v down the columns into three of `planes`, then along each row,
    /// where `each(y, jv, dv, rows)` gets row y's and row y of the four
    /// planes to write (their first three rows no longer needed).
    fn jacobian_rows(
        &self,
        z: &[f64],
        lin: &Linear,
        v: &[f64],
        planes: &mut [Vec<f64>; 4],
        each: impl Fn(usize, &[[f64; 2]], &[[f64; 2]], &mut [&mut [f64]]) + Sync,
    ) {
        let (w, a) = (self.w, self.patch.a);
        let [p0, p1, p2, p3] = planes;
        // box_y v, ramp_y v, box_y (z·v).
        columns(w, &[v, z], &mut [&mut p0[..], &mut p1[..], &mut p2[..]], |_, ins, outs, work| {
            let Work { scratch, temps } = work;
            let [boxed, ramped, boxed_zv] = outs else { unreachable!() };
            self.patch.y.apply(ins[0], Some(&mut boxed[..]), Some(&mut ramped[..]), scratch);
            let zv = &mut temps[0];
            zv.iter_mut().zip(ins[0].iter().zip(ins[1])).for_each(|(o, (v, z))| *o = v * z);
            self.patch.y.apply(zv, Some(&mut boxed_zv[..]), None, scratch);
        });
        rows(w, &mut [&mut p0[..], &mut p1[..], &mut p2[..], &mut p3[..]], |y, row, work| {
            let Work { scratch, temps } = work;
            let [dx, pv, dy, pzv] = temps;
            self.patch.x.apply(row[0], Some(&mut pv[..]), Some(&mut dx[..]), scratch);
            self.patch.x.apply(row[1], Some(&mut dy[..]), None, scratch);
            self.patch.x.apply(row[2], Some(&mut pzv[..]), None, scratch);
            let mut jv = vec![[0.0; 2]; w];
            let mut dv = vec![[0.0; 2]; w];
            for x in 0..w {
                let k = y * w + x;
                let (u, ac, m) = (lin.u[k], lin.ac[k], lin.m[k]);
                let (dxv, dyv) = (dx[x] / a, dy[x] / a);
                let e = pzv[x] - lin.mean[k] * pv[x];
                let along = ac[0] * dxv + ac[1] * dyv;
                jv[x] = [dxv - u[0] * (along - m * e), dyv - u[1] * (along - m * e)];
                dv[x] = [dxv, dyv];
            }
            each(y, &jv, &dv, row);
        });
    }

    fn weight(&self, x: usize, y: usize) -> f64 {
        self.wx[x] * self.wy[y]
    }

    /// Σ W |r|² at `z`, and, given `store`, the residual r and the
    /// linearisation there; `planes` is work space.
    fn linearise(&self, z: &[f64], store: Option<(&mut Linear, &mut [[f64; 2]])>, planes: &mut [Vec<f64>; 4]) -> f64 {
        let (w, a) = (self.w, self.patch.a);
        let [p0, p1, p2, _] = planes;
        // box_y z, ramp_y z, box_y z².
        columns(w, &[z], &mut [&mut p0[..], &mut p1[..], &mut p2[..]], |_, ins, outs, work| {
            let Work { scratch, temps } = work;
            let [boxed, ramped, boxed_zz] = outs else { unreachable!() };
            self.patch.y.apply(ins[0], Some(&mut boxed[..]), Some(&mut ramped[..]), scratch);
            let zz = &mut temps[0];
            zz.iter_mut().zip(ins[0]).for_each(|(o, z)| *o = z * z);
            self.patch.y.apply(zz, Some(&mut boxed_zz[..]), None, scratch);
        });
        let (p0, p1, p2) = (&*p0, &*p1, &*p2);
        let row_cost = |y: usize, mut out: Option<RowStore<'_>>| {
            let (mut vx, mut vy, mut gx, mut gy) = (vec![0.0; w], vec![0.0; w], vec![0.0; w], vec![0.0; w]);
            let (mut pz, mut pzz) = (vec![0.0; w], vec![0.0; w]);
            let mut scratch = Scratch::default();
            let (r0, r1, r2) = (&p0[y * w..][..w], &p1[y * w..][..w], &p2[y * w..][..w]);
            self.patch.x.apply(r0, Some(&mut pz), Some(&mut vx), &mut scratch);
            self.patch.x.apply(r1, Some(&mut vy), None, &mut scratch);
            self.patch.x.apply(r2, Some(&mut pzz), None, &mut scratch);
            vx.iter_mut().chain(vy.iter_mut()).for_each(|v| *v /= a);
            (self.slopes)(y, &mut gx, &mut gy);
            let mut sum = 0.0;
            for x in 0..w {
                let mean_x = pz[x] / self.n2;
                let czz = (pzz[x] - pz[x] * mean_x).max(0.0);
                let c = [a * vx[x], a * vy[x]];
                let t = c[0] * c[0] + c[1] * c[1];
                let d = 0.5 * (a - czz);
                let q = (d * d + t).sqrt();
                let mm = if d >= 0.0 { d + q } else { t / (q - d) };
                let g = [gx[x], gy[x]];
                let rx = [vx[x] - g[0] * mm / a, vy[x] - g[1] * mm / a];
                if let Some((r, u, ac, m, mean)) = out.as_mut() {
                    r[x] = rx;
                    u[x] = if q > 0.0 { [g[0] / (a * q), g[1] / (a * q)] } else { [0.0; 2] };
                    ac[x] = [a * c[0], a * c[1]];
                    m[x] = mm;
                    mean[x] = mean_x;
                }
                sum += self.weight(x, y) * (rx[0] * rx[0] + rx[1] * rx[1]);
            }
            sum
        };
        let rows: Vec<f64> = match store {
            Some((lin, r)) => r
                .par_chunks_mut(w)
                .zip(lin.u.par_chunks_mut(w))
                .zip(lin.ac.par_chunks_mut(w))
                .zip(lin.m.par_chunks_mut(w))
                .zip(lin.mean.par_chunks_mut(w))
                .enumerate()
                .map(|(y, ((((r, u), ac), m), mean))| row_cost(y, Some((r, u, ac, m, mean))))
                .collect(),
            None => (0..z.len() / w).into_par_iter().map(|y| row_cost(y, None)).collect(),
        };
        rows.iter().sum()
    }

    /// −W⁻¹ Jᵀ W r into `out`.
    fn gradient(&self, z: &[f64], lin: &Linear, r: &[[f64; 2]], out: &mut [f64], planes: &mut [Vec<f64>; 4]) {
        let w = self.w;
        self.back_rows(
            lin,
            planes,
            |_| (),
            |(), x, y| {
                let (k, wt) = (y * w + x, self.weight(x, y));
                ([wt * r[k][0], wt * r[k][1]], [0.0; 2])
            },
        );
        self.transpose(z, planes, out);
        out.iter_mut().for_each(|o| *o = -*o);
    }

    /// Fills the planes [ax, ay, s, s·mean] that [`Self::transpose`] takes,
    /// rows in parallel: `row(y)` is computed once a row, and `texel(row,
    /// x, y)` gives each texel's weighted residual-like value and damping
    /// for [`Self::back_texel`].
    fn back_rows<R>(
        &self,
        lin: &Linear,
        planes: &mut [Vec<f64>; 4],
        row: impl Fn(usize) -> R + Sync,
        texel: impl Fn(&R, usize, usize) -> ([f64; 2], [f64; 2]) + Sync,
    ) {
        let w = self.w;
        let [ax, ay, s, sm] = planes;
        ax.par_chunks_mut(w)
            .zip(ay.par_chunks_mut(w))
            .zip(s.par_chunks_mut(w))
            .zip(sm.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (((ax, ay), s), sm))| {
                let this_row = row(y);
                for x in 0..w {
                    let (wr, damp) = texel(&this_row, x, y);
                    self.back_texel(lin, y * w + x, wr, damp, (&mut ax[x], &mut ay[x], &mut s[x], &mut sm[x]));
                }
            });
    }

    /// The per-texel part of Jᵀ applied to a weighted residual-like `wr`
    /// (plus `damp`, the damping's W·μ·Dδ): the coefficients of Dᵀ (ax,
    /// ay) and of Eᵀ (s, and s times the patch mean).
    #[inline]
    fn back_texel(
        &self,
        lin: &Linear,
        k: usize,
        wr: [f64; 2],
        damp: [f64; 2],
        out: (&mut f64, &mut f64, &mut f64, &mut f64),
    ) {
        let (u, ac, m) = (lin.u[k], lin.ac[k], lin.m[k]);
        let uw = u[0] * wr[0] + u[1] * wr[1];
        *out.0 = wr[0] - ac[0] * uw + damp[0];
        *out.1 = wr[1] - ac[1] * uw + damp[1];
        *out.2 = m * uw;
        *out.3 = m * uw * lin.mean[k];
    }

    /// out = W⁻¹ (Dᵀ a + Eᵀ s) from the planes [ax, ay, s, s·mean]
    /// (which the row pass overwrites).
    fn transpose(&self, z: &[f64], planes: &mut [Vec<f64>; 4], out: &mut [f64]) {
        let (w, a) = (self.w, self.patch.a);
        let [ax, ay, s, sm] = planes;
        rows(w, &mut [&mut ax[..], &mut ay[..], &mut s[..], &mut sm[..]], |_, row, work| {
            let Work { scratch, temps } = work;
            let t = &mut temps[0];
            for (k, plane) in row.iter_mut().enumerate() {
                let (boxed, ramped) = if k == 0 { (None, Some(&mut t[..])) } else { (Some(&mut t[..]), None) };
                self.patch.x.apply_transposed(plane, boxed, ramped, scratch);
                plane.copy_from_slice(t);
            }
        });
        columns(w, &[ax, ay, s, sm, z], &mut [out], |x, ins, outs, work| {
            let Work { scratch, temps } = work;
            let [o] = outs else { unreachable!() };
            let [t1, t2, t3, _] = temps;
            self.patch.y.apply_transposed(ins[0], Some(&mut o[..]), None, scratch);
            self.patch.y.apply_transposed(ins[1], None, Some(&mut t1[..]), scratch);
            self.patch.y.apply_transposed(ins[2], Some(&mut t2[..]), None, scratch);
            self.patch.y.apply_transposed(ins[3], Some(&mut t3[..]), None, scratch);
            for (y, o) in o.iter_mut().enumerate() {
                let value = (*o + t1[y]) / a + ins[4][y] * t2[y] - t3[y];
                *o = value / self.weight(x, y);
            }
        });
    }

    /// (W⁻¹JᵀWJ + μ(M + ε)) v into `out`.
    fn apply(&self, z: &[f64], lin: &Linear, mu: f64, v: &[f64], out: &mut [f64], planes: &mut [Vec<f64>; 4]) {
        let w = self.w;
        self.jacobian_rows(z, lin, v, planes, |y, jv, dv, row| {
            let [ax, ay, s, sm] = row else { unreachable!() };
            for x in 0..w {
                let wt = self.weight(x, y);
                let wr = [wt * jv[x][0], wt * jv[x][1]];
                let damp = [mu * wt * dv[x][0], mu * wt * dv[x][1]];
                self.back_texel(lin, y * w + x, wr, damp, (&mut ax[x], &mut ay[x], &mut s[x], &mut sm[x]));
            }
        });
        self.transpose(z, planes, out);
        let extra = mu * (self.lambda + EPSILON);
        out.iter_mut().zip(v).for_each(|(o, v)| *o += extra * v);
    }

    /// ⟨a, b⟩ over the period: Σ W a b, per-row sums added in row order.
    fn dot(&self, a: &[f64], b: &[f64]) -> f64 {
        let w = self.w;
        let rows: Vec<f64> = a
            .par_chunks(w)
            .zip(b.par_chunks(w))
            .enumerate()
            .map(|(y, (a, b))| a.iter().zip(b).zip(&self.wx).map(|((a, b), m)| a * b * m).sum::<f64>() * self.wy[y])
            .collect();
        rows.iter().sum()
    }

    /// Preconditioned conjugate gradients for (H + μ(M + ε)) step = rhs
    /// from step = 0, in the W inner product; returns the solves run.
    #[allow(clippy::too_many_arguments)]
    fn conjugate_gradients(
        &self,
        z: &[f64],
        lin: &Linear,
        mu: f64,
        tolerance: f64,
        rhs: &[f64],
        step: &mut [f64],
        work: &mut Vectors,
    ) -> Result<usize> {
        let Vectors { res, y, dir, op, planes } = work;
        res.copy_from_slice(rhs);
        self.solver.inverse(res, self.lambda, EPSILON, y)?;
        let mut solves = 1;
        dir.copy_from_slice(y);
        let mut ry = self.dot(res, y);
        let target = tolerance * ry;
        for _ in 0..CG_ITERATIONS {
            // Also stops on a NaN.
            if ry.partial_cmp(&target) != Some(std::cmp::Ordering::Greater) {
                break;
            }
            self.apply(z, lin, mu, dir, op, planes);
            let curvature = self.dot(dir, op);
            if curvature.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                break;
            }
            let alpha = ry / curvature;
            step.iter_mut().zip(dir.iter()).for_each(|(s, d)| *s += alpha * d);
            res.iter_mut().zip(op.iter()).for_each(|(r, o)| *r -= alpha * o);
            self.solver.inverse(res, self.lambda, EPSILON, y)?;
            solves += 1;
            let next = self.dot(res, y);
            let beta = next / ry;
            ry = next;
            dir.iter_mut().zip(y.iter()).for_each(|(d, y)| *d = y + beta * *d);
        }
        Ok(solves)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::height::{HeightOptions, Model};
    use crate::options::{Border, Borders, Fit};

    impl Problem<'_> {
        /// J v at every texel.
        fn jacobian(&self, z: &[f64], lin: &Linear, v: &[f64]) -> Vec<[f64; 2]> {
            let len = z.len();
            let mut planes = [vec![0.0; len], vec![0.0; len], vec![0.0; len], vec![0.0; len]];
            self.jacobian_rows(z, lin, v, &mut planes, |_, jv, _, row| {
                for (x, j) in jv.iter().enumerate() {
                    (row[0][x], row[1][x]) = (j[0], j[1]);
                }
            });
            planes[0].iter().zip(&planes[1]).map(|(&a, &b)| [a, b]).collect()
        }
    }

    fn linear(len: usize) -> Linear {
        Linear { u: vec![[0.0; 2]; len], ac: vec![[0.0; 2]; len], m: vec![0.0; len], mean: vec![0.0; len] }
    }

    /// Against code it does not share: r is (nearly) 0 at heights whose
    /// orthogonal fit (the forward fit, `crate::normals`, f32) gives the
    /// slopes; J matches central differences of r; and the gradient's Jᵀ
    /// is J's adjoint in the period's inner product. Every border, N = 3
    /// to 31 on a 13 × 11 image (the patch sums added outright, by blocks,
    /// and over patches wider than the image).
    #[test]
    fn residual_jacobian_and_adjoint_match_independent_answers() {
        let (w, h) = (13, 11);
        let len = w * h;
        let z: Vec<f64> = (0..len)
            .map(|k| {
                let (x, y) = ((k % w) as f64, (k / w) as f64);
                0.3 * (0.7 * x).sin() + 0.2 * (0.5 * y + 0.3 * x).cos() + ((k * 7919) % 101) as f64 * 0.002
            })
            .collect();
        let delta: Vec<f64> = (0..len).map(|k| (((k * 3571) % 97) as f64 / 97.0) - 0.5).collect();
        let other: Vec<[f64; 2]> = (0..len)
            .map(|k| [(((k * 1013) % 89) as f64 / 89.0) - 0.5, (((k * 211) % 83) as f64 / 83.0) - 0.5])
            .collect();
        for border in [Border::Wrap, Border::Mirror, Border::Clamp] {
            // Direct sums (N ≤ 7), blocks (9, 15), and patches wider than
            // the image (31: whole periods, clamp's clipped windows).
            for n in [3, 5, 9, 15, 31] {
                let fit = crate::Options::new()
                    .with_patch(n)
                    .with_fit(Fit::Orthogonal)
                    .with_borders(Borders::both(border))
                    .with_strength(crate::Strength::Scale(6.0));
                let opts = HeightOptions::from_fit(&fit);
                let normals = crate::normals(&z, w, h, &fit).unwrap();
                let zs: Vec<f64> = z.iter().map(|v| v * fit.scale_for_width(w)).collect();
                let given = |y: usize, gx: &mut [f64], gy: &mut [f64]| {
                    for x in 0..w {
                        let nv = normals[y * w + x].map(f64::from);
                        gx[x] = -nv[0] / nv[2];
                        gy[x] = -crate::Convention::OpenGl.sigma() * nv[1] / nv[2];
                    }
                };
                let patch = Patch::new(w, h, &opts);
                let solver = Solver::nearest(w, h, opts.fit.borders, n, Model::Exact).unwrap();
                let p = Problem::new(&patch, Vertical::Transform(&solver), &given, 0.0, h);
                let mut planes = [vec![0.0; len], vec![0.0; len], vec![0.0; len], vec![0.0; len]];
                let (mut lin, mut r) = (linear(len), vec![[0.0; 2]; len]);
                let cost = p.linearise(&zs, Some((&mut lin, &mut r)), &mut planes);
                assert!(cost < 1e-10, "{border:?} N {n}: cost {cost:e}");

                let residual = |z: &[f64]| {
                    let (mut l, mut r) = (linear(len), vec![[0.0; 2]; len]);
                    let mut planes = [vec![0.0; len], vec![0.0; len], vec![0.0; len], vec![0.0; len]];
                    p.linearise(z, Some((&mut l, &mut r)), &mut planes);
                    r
                };
                let t = 1e-6;
                let plus: Vec<f64> = zs.iter().zip(&delta).map(|(z, d)| z + t * d).collect();
                let minus: Vec<f64> = zs.iter().zip(&delta).map(|(z, d)| z - t * d).collect();
                let (rp, rm) = (residual(&plus), residual(&minus));
                let (mut worst, mut size) = (0.0f64, 0.0f64);
                let jv = p.jacobian(&zs, &lin, &delta);
                for k in 0..len {
                    for c in 0..2 {
                        let fd = (rp[k][c] - rm[k][c]) / (2.0 * t);
                        worst = worst.max((fd - jv[k][c]).abs());
                        size = size.max(jv[k][c].abs());
                    }
                }
                assert!(worst < 1e-6 * size, "{border:?} N {n}: J off by {worst:e} of {size:e}");

                // ⟨J δ, W r'⟩ = −⟨δ, gradient(r')⟩_W, gradient = −W⁻¹JᵀWr'.
                let mut back = vec![0.0; len];
                p.gradient(&zs, &lin, &other, &mut back, &mut planes);
                let mut left = 0.0;
                for (k, (j, o)) in jv.iter().zip(&other).enumerate() {
                    left += p.weight(k % w, k / w) * (j[0] * o[0] + j[1] * o[1]);
                }
                let right = -p.dot(&delta, &back);
                assert!(
                    (left - right).abs() <= 1e-10 * left.abs().max(1.0),
                    "{border:?} N {n}: {left} against {right}"
                );
            }
        }
    }
}
