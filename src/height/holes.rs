//! The inverse with holes: heights where the caller marks none, solved in
//! least squares from the equations whose patches hold no hole.
//!
//! A texel's equation (its two slopes, Dx z = gx and Dy z = gy) is kept
//! when no texel of its N×N patch, read through the borders' index maps,
//! is a hole: there the forward fit's normal is the full patch's, so the
//! operator is exactly the one of the inverse without holes (`patch.rs`);
//! elsewhere the forward fit saw a part of the patch (docs/terrain.md,
//! "Holes"), or nothing. The unknowns are the heights of the texels that
//! are not holes. With K the kept equations, P the texels that are not
//! holes and W the period's multiplicities (mirror), the heights solve
//!
//! ```text
//! min ‖W^½ K (D P z − g)‖² + λ ‖P z‖²
//! ```
//!
//! by conjugate gradients on the normal equations, from 0, preconditioned
//! by the inverse without holes restricted to the texels that are not
//! holes (a fictitious domain): B = P Q⁻¹ P, Q = DₙᵀWDₙ + (λ + ε)W the
//! operator of the map without holes, ε = [`EPSILON`] / (w h), solved as
//! the inverse without holes solves it: the transform where one is exact
//! (Dₙ = D), else for clamp with N ≥ 5 the dense bases or banded solves
//! within the limit of time (Dₙ = D, but ε's W taken in each basis
//! vector's own measure, so ε settles the null modes otherwise: the dense
//! test holds them only elsewhere), else the nearest transform (Dₙ reads
//! clamp as a half-sample reflection; its edge modes then cost hundreds
//! of iterations). Q sees every frequency of the map and the
//! dropped equations change it only around the holes, so a lake or a
//! river takes some tens of iterations whatever the size, where W⁻¹
//! alone needed a multiple of the side (the lowest frequency's condition
//! grows as the side squared). Many small holes take more: each is an
//! edge where Q and the kept equations differ (10 % scattered, N = 3:
//! some hundreds, growing with the side).
//!
//! Which solution: the steps lie in B times the range of the operator, so
//! from 0 the iteration ends on the least-squares solution of least
//! B⁻¹-norm, and B⁻¹ (the Schur complement of Q on the holes) is
//!
//! ```text
//! ‖z‖²_B⁻¹ = min over the holes' heights u of [z; u]ᵀ Q [z; u]:
//! ```
//!
//! among the heights that fit the kept equations best, those whose
//! extension over the holes, chosen as smoothly as the patches allow, has
//! the least fit energy ‖W^½ Dₙ ·‖² + (λ + ε)‖W^½ ·‖² over the whole map.
//! The freedom the holes leave (each connected piece's constant, and at
//! N ≥ 5 the modes along holes' edges that no kept equation sees) is
//! spent making the heights across a hole agree as the patches would see
//! them: the two banks of a river get heights consistent with a smooth
//! fill, not each its own mean 0. ε (tiny against the lowest frequency's
//! energy) only settles what no patch sees at all: the map's constant
//! (mean about 0) and the transform's own null modes. λ > 0 (quantised
//! input) adds its λ‖Pz‖²; the modes it alone pins lie below the
//! stopping tolerance, so in practice the criterion above decides them too.
//!
//! Texels that are not holes but that no kept equation sees are
//! undetermined: they come back NaN, counted in
//! [`HeightReport::undetermined`](super::HeightReport::undetermined).
//!
//! The orthogonal fit runs the same fixed point as without holes (slopes
//! g · (A − λ)/A asked of the vertical solve, `iterative.rs`), each solve
//! started from the last heights (the steps stay in B times the same
//! range, so the least B⁻¹-norm holds), without the Gauss–Newton finish.

use crate::error::Result;
use crate::options::Fit;
use crate::par::prelude::*;
use crate::samples::try_filled;

use super::HeightOptions;
use super::Model;
use super::banded::Separable;
use super::gauss_newton::Vertical;
use super::iterative::preconditioned_cg;
use super::line::{Work, columns_in_place, rows};
use super::patch::Patch;
use super::solve::SlopeRows as Slopes;
use super::solve::Solver;

/// The conjugate gradients stop when the normal equations' residual has
/// fallen to this fraction of the right-hand side (in norm), as without
/// holes.
const TOLERANCE: f64 = 1e-10;

/// ε of the preconditioner Q, times the texels: the weight of the modes
/// no patch of the map sees (its constant, the transform's null modes).
/// Against the lowest frequency's energy, some (2π)² / (w h) a texel, it is
/// 1/4000, so it leaves the conditioning alone; it is far enough from 0
/// that the rounding of the residual's constant, amplified by 1/ε, stays
/// below 1e-10 of the steps even at 4096².
pub(crate) const EPSILON: f64 = 1e-2;

/// The iterations the whole inverse may take (each one transform solve):
/// the holes' own conditioning, not the size, sets the count.
const BUDGET: usize = 5_000;

/// Which equations and heights the holes leave.
pub(super) struct Support {
    /// Per texel: its equations are kept (its patch holds no hole).
    pub(super) kept: Vec<bool>,
    /// Per texel: not a hole, and in some kept equation's patch.
    pub(super) seen: Vec<bool>,
    /// Per texel: a hole.
    holes: Vec<bool>,
}

impl Support {
    /// The kept equations and seen texels of `holes` (row-major, `w` × `h`)
    /// under `patch`: the box of the holes' indicator through the borders
    /// (0 where the patch holds none), then the transposed box of the kept
    /// equations' (positive where one sees the texel). The sums are of 0
    /// and 1, exact in f64.
    pub(super) fn new(patch: &Patch, h: usize, holes: &[bool]) -> Result<Support> {
        let w = patch.w;
        let mut count = try_filled(holes.len(), 0.0)?;
        let indicator = |plane: &mut [f64], marks: &[bool]| {
            plane.par_iter_mut().zip(marks).for_each(|(c, &m)| *c = if m { 1.0 } else { 0.0 });
        };
        let boxed = |plane: &mut [f64], transposed: bool| {
            rows(w, &mut [&mut *plane], |_, row, work| {
                let Work { scratch, temps } = work;
                let t = &mut temps[0];
                if transposed {
                    patch.x.apply_transposed(&*row[0], Some(&mut t[..]), None, scratch);
                } else {
                    patch.x.apply(&*row[0], Some(&mut t[..]), None, scratch);
                }
                row[0].copy_from_slice(t);
            });
            columns_in_place(w, &mut [&mut *plane], |_, col, work| {
                let Work { scratch, temps } = work;
                let t = &mut temps[0];
                if transposed {
                    patch.y.apply_transposed(&*col[0], Some(&mut t[..]), None, scratch);
                } else {
                    patch.y.apply(&*col[0], Some(&mut t[..]), None, scratch);
                }
                col[0].copy_from_slice(t);
            });
        };
        indicator(&mut count, holes);
        boxed(&mut count, false);
        let kept: Vec<bool> = count.par_iter().map(|&c| c < 0.5).collect();
        indicator(&mut count, &kept);
        boxed(&mut count, true);
        let seen = count.par_iter().zip(holes).map(|(&c, &hole)| !hole && c > 0.5).collect();
        debug_assert!(h * w == holes.len());
        Ok(Support { kept, seen, holes: holes.to_vec() })
    }
}

/// The heights (texel units) of the texels `support` leaves into `z`
/// (0 elsewhere); returns the solves run and whether the iteration met its
/// tolerance.
pub(super) fn solve(
    slopes: Slopes<'_>,
    w: usize,
    h: usize,
    opts: &HeightOptions,
    lambda: f64,
    support: &Support,
    z: &mut [f64],
) -> Result<(usize, bool)> {
    let patch = Patch::new(w, h, opts);
    let weights = super::iterative::multiplicities(&patch, h);
    let (borders, n) = (opts.fit.borders, opts.fit.patch);
    // Q as the module comment says.
    let transform = Solver::new(w, h, borders, n, Model::Exact);
    // A separable solve that cannot be made (its pins failing, say) leaves
    // the nearest transform: slower, never wrong.
    let dense = if transform.is_none() { Separable::within_limit(&patch, h, opts).unwrap_or(None) } else { None };
    let nearest =
        if transform.is_none() && dense.is_none() { Solver::nearest(w, h, borders, n, Model::Exact) } else { None };
    let vertical = match (&transform, &dense, &nearest) {
        (Some(solver), _, _) | (None, None, Some(solver)) => Vertical::Transform(solver),
        (None, Some(dense), _) => Vertical::Dense(dense, (&weights.0, &weights.1)),
        (None, None, None) => {
            return Err(crate::error::Error::InvalidOption(format!("no solve for a {w} × {h} map with {borders:?}")));
        }
    };
    let precondition = Preconditioner { vertical, lambda, epsilon: EPSILON / (w as f64 * h as f64) };
    // The slopes of the kept equations; 0 where an equation is dropped.
    // There a ratio scales nothing, and it follows the fill across the
    // holes: it is left out of the fixed point's settling (a 1024² lake
    // did not settle in 100 solves with it in).
    let kept = |y: usize, gx: &mut [f64], gy: &mut [f64]| {
        slopes(y, gx, gy);
        for ((gx, gy), &k) in gx.iter_mut().zip(gy.iter_mut()).zip(&support.kept[y * w..][..w]) {
            if !k {
                (*gx, *gy) = (0.0, 0.0);
            }
        }
    };
    z.iter_mut().for_each(|z| *z = 0.0);
    let mut budget = BUDGET;
    let mut iterations = 1;
    let mut converged = conjugate_gradients(&patch, support, &weights, &precondition, &kept, z, &mut budget)?;
    if opts.fit.fit == Fit::Vertical {
        return Ok((iterations, converged));
    }
    let len = w * h;
    let mut rho = try_filled(len, 1.0)?;
    let mut direction = try_filled(len, 0i8)?;
    patch.update_ratios(z, &kept, Some(&support.kept), &mut rho, &mut direction, 1.0)?;
    let tolerance = opts.tolerance.max(opts.step);
    let (mut last_change, mut growing, mut damping) = (f64::INFINITY, 0, 1.0);
    converged = false;
    for _ in 1..opts.max_iterations {
        let weighted = |y: usize, gx: &mut [f64], gy: &mut [f64]| {
            kept(y, gx, gy);
            for ((x, y), r) in gx.iter_mut().zip(gy.iter_mut()).zip(&rho[y * w..][..w]) {
                *x *= r;
                *y *= r;
            }
        };
        iterations += 1;
        if !conjugate_gradients(&patch, support, &weights, &precondition, &weighted, z, &mut budget)? {
            break;
        }
        let (change, _, _) = patch.update_ratios(z, &kept, Some(&support.kept), &mut rho, &mut direction, damping)?;
        if change <= tolerance {
            converged = true;
            break;
        }
        // As without holes: a change that grows halves the steps, and
        // eight growths running (or a change that is not a number) stop.
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
    Ok((iterations, converged))
}

/// The preconditioner B = P Q⁻¹ P of the module comment.
struct Preconditioner<'a> {
    vertical: Vertical<'a>,
    lambda: f64,
    epsilon: f64,
}

/// Conjugate gradients on P(DᵀKWD + λ)P z = PDᵀKW g, preconditioned by
/// `b`, from `z` (0 at the holes), until the residual falls below
/// [`TOLERANCE`] of the right-hand side's or `budget` runs out. Returns
/// whether it met the tolerance.
fn conjugate_gradients(
    patch: &Patch,
    support: &Support,
    (wx, wy): &(Vec<f64>, Vec<f64>),
    b: &Preconditioner<'_>,
    slopes: Slopes<'_>,
    z: &mut [f64],
    budget: &mut usize,
) -> Result<bool> {
    let lambda = b.lambda;
    let w = patch.w;
    let len = z.len();
    let plane = || try_filled(len, 0.0);
    let (mut gx, mut gy) = (plane()?, plane()?);
    // K W on the slopes' planes.
    let weigh = |gx: &mut [f64], gy: &mut [f64]| {
        gx.par_chunks_mut(w).zip(gy.par_chunks_mut(w)).enumerate().for_each(|(y, (rx, ry))| {
            let kept = &support.kept[y * w..][..w];
            for (((gx, gy), m), &k) in rx.iter_mut().zip(ry.iter_mut()).zip(wx).zip(kept) {
                let weight = if k { m * wy[y] } else { 0.0 };
                *gx *= weight;
                *gy *= weight;
            }
        });
    };
    let holes = &support.holes;
    let normal = |v: &[f64], out: &mut [f64], gx: &mut [f64], gy: &mut [f64]| {
        patch.slopes(v, gx, gy);
        weigh(gx, gy);
        patch.adjoint(gx, gy, out);
        out.par_iter_mut().zip(v).zip(holes).for_each(|((o, v), &hole)| *o = if hole { 0.0 } else { *o + lambda * v });
    };
    // Q⁻¹ r = Solver::inverse(W⁻¹ r): the transform solves on the period,
    // which holds each texel W times. r is 0 at the holes (P).
    let mut weighted = plane()?;
    let precondition = |r: &[f64], out: &mut [f64]| -> Result<()> {
        weighted.par_chunks_mut(w).zip(r.par_chunks(w)).enumerate().for_each(|(y, (o, r))| {
            for ((o, r), m) in o.iter_mut().zip(r).zip(wx.iter()) {
                *o = r / (m * wy[y]);
            }
        });
        b.vertical.inverse(&weighted, lambda, b.epsilon, out)?;
        out.par_iter_mut().zip(holes).for_each(|(o, &hole)| {
            if hole {
                *o = 0.0;
            }
        });
        Ok(())
    };
    let mut rhs = plane()?;
    gx.par_chunks_mut(w).zip(gy.par_chunks_mut(w)).enumerate().for_each(|(y, (rx, ry))| slopes(y, rx, ry));
    weigh(&mut gx, &mut gy);
    patch.adjoint(&mut gx, &mut gy, &mut rhs);
    rhs.par_iter_mut().zip(holes).for_each(|(b, &hole)| {
        if hole {
            *b = 0.0;
        }
    });
    preconditioned_cg(z, &rhs, (w, TOLERANCE), normal, precondition, (&mut gx, &mut gy), budget)
}

/// Bytes the solve with holes holds besides the slopes and heights: nine
/// planes of f64 (the conjugate gradients' five, the slopes' two, the
/// right-hand side and the preconditioner's input), the ratios and their
/// directions, three masks, and what the inverse without holes holds for
/// its solve (the preconditioner's: the transform's spectra, or the dense
/// bases or banded solves, or the nearest transform's).
///
/// Errors: those of the forward fit's options (the re-fit's plan).
pub(super) fn bytes(w: usize, h: usize, opts: &HeightOptions) -> Result<u64> {
    let planes = (w as u64).saturating_mul(h as u64).saturating_mul(9 * 8 + 8 + 1 + 3);
    Ok(planes.saturating_add(super::memory::exact_bytes(w, h, opts)?))
}
