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

use super::patch::{Lists, Patch};
use super::solve::SlopeRows as Slopes;
use super::solve::Solver;

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
    solver: &'a Solver,
    slopes: Slopes<'a>,
    w: usize,
    /// Texels in a patch, N².
    n2: f64,
    wx: Vec<f64>,
    wy: Vec<f64>,
    box_xt: Lists,
    ramp_xt: Lists,
    box_yt: Lists,
    ramp_yt: Lists,
    lambda: f64,
}

/// Refines `z` (texel units) towards r(z) = 0; `settle` is how little a
/// step must move the heights for them to count as settled, `precision`
/// the input's step (its rounding sets the cost's floor).
pub(super) fn refine(
    patch: &Patch,
    solver: &Solver,
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
    let mut cost = p.linearise(z, Some((&mut lin, &mut r)));
    let mut trial = plane()?;
    let (mut rhs, mut step) = (plane()?, plane()?);
    let mut work = Work {
        res: plane()?,
        y: plane()?,
        dir: plane()?,
        op: plane()?,
        planes: [plane()?, plane()?, plane()?, plane()?],
    };
    let (mut mu, mut solves, mut converged) = (1e-6, 0, false);
    let mut gains: Vec<f64> = Vec::new();
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
        let trial_cost = p.linearise(&trial, None);
        if trial_cost < cost {
            let moved = step.iter().fold(0.0f64, |m, s| m.max(s.abs()));
            z.copy_from_slice(&trial);
            p.linearise(z, Some((&mut lin, &mut r)));
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
            if slow(&gains) {
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

/// The conjugate gradients' vectors.
struct Work {
    res: Vec<f64>,
    y: Vec<f64>,
    dir: Vec<f64>,
    op: Vec<f64>,
    planes: [Vec<f64>; 4],
}

impl<'a> Problem<'a> {
    fn new(patch: &'a Patch, solver: &'a Solver, slopes: Slopes<'a>, lambda: f64, h: usize) -> Problem<'a> {
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
            box_xt: patch.box_x.transposed(),
            ramp_xt: patch.ramp_x.transposed(),
            box_yt: patch.box_y.transposed(),
            ramp_yt: patch.ramp_y.transposed(),
            lambda,
        }
    }

    /// Row y of J v, and of D v (the damping's).
    fn jacobian_row(&self, z: &[f64], lin: &Linear, v: &[f64], y: usize) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
        let w = self.w;
        let (mut dx, mut dy, mut tmp, mut pv, mut pzv) =
            (vec![0.0; w], vec![0.0; w], vec![0.0; w], vec![0.0; w], vec![0.0; w]);
        self.patch.slopes(v, y, &mut dx, &mut dy);
        self.boxed(v, None, y, &mut tmp, &mut pv);
        self.boxed(v, Some(z), y, &mut tmp, &mut pzv);
        let jv = (0..w)
            .map(|x| {
                let k = y * w + x;
                let (u, ac, m) = (lin.u[k], lin.ac[k], lin.m[k]);
                let e = pzv[x] - lin.mean[k] * pv[x];
                let along = ac[0] * dx[x] + ac[1] * dy[x];
                [dx[x] - u[0] * (along - m * e), dy[x] - u[1] * (along - m * e)]
            })
            .collect();
        (jv, dx.into_iter().zip(dy).map(|(a, b)| [a, b]).collect())
    }

    fn weight(&self, x: usize, y: usize) -> f64 {
        self.wx[x] * self.wy[y]
    }

    /// Row y of the box sums of `a` (times `b` if given) over the patches.
    fn boxed(&self, a: &[f64], b: Option<&[f64]>, y: usize, tmp: &mut [f64], out: &mut [f64]) {
        let w = self.w;
        tmp.fill(0.0);
        for &(i, wgt) in &self.patch.box_y.0[y] {
            let ra = &a[i * w..][..w];
            match b {
                Some(b) => {
                    for ((t, &x), &z) in tmp.iter_mut().zip(ra).zip(&b[i * w..][..w]) {
                        *t += wgt * x * z;
                    }
                }
                None => tmp.iter_mut().zip(ra).for_each(|(t, &x)| *t += wgt * x),
            }
        }
        self.patch.box_x.row(tmp, out);
    }

    /// Σ W |r|² at `z`, and, given `store`, the residual r and the
    /// linearisation there.
    fn linearise(&self, z: &[f64], store: Option<(&mut Linear, &mut [[f64; 2]])>) -> f64 {
        let (w, a) = (self.w, self.patch.a);
        let row_cost = |y: usize, mut out: Option<RowStore<'_>>| {
            let (mut vx, mut vy, mut gx, mut gy) = (vec![0.0; w], vec![0.0; w], vec![0.0; w], vec![0.0; w]);
            let (mut tmp, mut pz, mut pzz) = (vec![0.0; w], vec![0.0; w], vec![0.0; w]);
            self.patch.slopes(z, y, &mut vx, &mut vy);
            (self.slopes)(y, &mut gx, &mut gy);
            self.boxed(z, None, y, &mut tmp, &mut pz);
            self.boxed(z, Some(z), y, &mut tmp, &mut pzz);
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
        let w = self.w;
        {
            let [ax, ay, s, sm] = planes;
            ax.par_chunks_mut(w).zip(ay.par_chunks_mut(w)).zip(s.par_chunks_mut(w)).zip(sm.par_chunks_mut(w)).for_each(
                |(((ax, ay), s), sm)| {
                    let mut t = vec![0.0; w];
                    self.ramp_xt.row(ax, &mut t);
                    ax.copy_from_slice(&t);
                    self.box_xt.row(ay, &mut t);
                    ay.copy_from_slice(&t);
                    self.box_xt.row(s, &mut t);
                    s.copy_from_slice(&t);
                    self.box_xt.row(sm, &mut t);
                    sm.copy_from_slice(&t);
                },
            );
        }
        let [ax, ay, s, sm] = &*planes;
        let a = self.patch.a;
        out.par_chunks_mut(w).enumerate().for_each(|(y, o)| {
            let (mut t1, mut t2, mut t3) = (vec![0.0; w], vec![0.0; w], vec![0.0; w]);
            self.box_yt.column(ax, w, y, o, |v| v);
            self.ramp_yt.column(ay, w, y, &mut t1, |v| v);
            self.box_yt.column(s, w, y, &mut t2, |v| v);
            self.box_yt.column(sm, w, y, &mut t3, |v| v);
            let zr = &z[y * w..][..w];
            for x in 0..w {
                let value = (o[x] + t1[x]) / a + zr[x] * t2[x] - t3[x];
                o[x] = value / self.weight(x, y);
            }
        });
    }

    /// (W⁻¹JᵀWJ + μ(M + ε)) v into `out`.
    fn apply(&self, z: &[f64], lin: &Linear, mu: f64, v: &[f64], out: &mut [f64], planes: &mut [Vec<f64>; 4]) {
        self.back_rows(
            lin,
            planes,
            |y| self.jacobian_row(z, lin, v, y),
            |(jv, dv), x, y| {
                let wt = self.weight(x, y);
                ([wt * jv[x][0], wt * jv[x][1]], [mu * wt * dv[x][0], mu * wt * dv[x][1]])
            },
        );
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
        work: &mut Work,
    ) -> Result<usize> {
        let Work { res, y, dir, op, planes } = work;
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

    fn linear(len: usize) -> Linear {
        Linear { u: vec![[0.0; 2]; len], ac: vec![[0.0; 2]; len], m: vec![0.0; len], mean: vec![0.0; len] }
    }

    /// Against code it does not share: r is (nearly) 0 at heights whose
    /// orthogonal fit (the forward fit, `crate::normals`, f32) gives the
    /// slopes; J matches central differences of r; and the gradient's Jᵀ
    /// is J's adjoint in the period's inner product. Wrap and mirror, N = 3
    /// and 5.
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
        for border in [Border::Wrap, Border::Mirror] {
            for n in [3, 5] {
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
                let solver = Solver::new(w, h, opts.fit.borders, n, Model::Exact).unwrap();
                let p = Problem::new(&patch, &solver, &given, 0.0, h);
                let (mut lin, mut r) = (linear(len), vec![[0.0; 2]; len]);
                let cost = p.linearise(&zs, Some((&mut lin, &mut r)));
                assert!(cost < 1e-10, "{border:?} N {n}: cost {cost:e}");

                let residual = |z: &[f64]| {
                    let (mut l, mut r) = (linear(len), vec![[0.0; 2]; len]);
                    p.linearise(z, Some((&mut l, &mut r)));
                    r
                };
                let t = 1e-6;
                let plus: Vec<f64> = zs.iter().zip(&delta).map(|(z, d)| z + t * d).collect();
                let minus: Vec<f64> = zs.iter().zip(&delta).map(|(z, d)| z - t * d).collect();
                let (rp, rm) = (residual(&plus), residual(&minus));
                let (mut worst, mut size) = (0.0f64, 0.0f64);
                for y in 0..h {
                    let (jv, _) = p.jacobian_row(&zs, &lin, &delta, y);
                    for x in 0..w {
                        for c in 0..2 {
                            let fd = (rp[y * w + x][c] - rm[y * w + x][c]) / (2.0 * t);
                            worst = worst.max((fd - jv[x][c]).abs());
                            size = size.max(jv[x][c].abs());
                        }
                    }
                }
                assert!(worst < 1e-6 * size, "{border:?} N {n}: J off by {worst:e} of {size:e}");

                // ⟨J δ, W r'⟩ = −⟨δ, gradient(r')⟩_W, gradient = −W⁻¹JᵀWr'.
                let mut planes = [vec![0.0; len], vec![0.0; len], vec![0.0; len], vec![0.0; len]];
                let mut back = vec![0.0; len];
                p.gradient(&zs, &lin, &other, &mut back, &mut planes);
                let mut left = 0.0;
                for y in 0..h {
                    let (jv, _) = p.jacobian_row(&zs, &lin, &delta, y);
                    for x in 0..w {
                        let o = other[y * w + x];
                        left += p.weight(x, y) * (jv[x][0] * o[0] + jv[x][1] * o[1]);
                    }
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
