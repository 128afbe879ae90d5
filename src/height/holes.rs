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
//! min ‖W^½ K (D P z − g)‖² + λ ‖P z‖²,   the solution of least W-norm
//! ```
//!
//! by conjugate gradients on the normal equations, preconditioned by W⁻¹
//! alone and started from 0: every step then lies in W⁻¹ times the range
//! of Dᵀ, so the heights are the least-squares solution of least W-norm
//! (unique). That fixes the freedom the holes leave: each connected piece
//! (texels linked through kept patches) gets W-weighted mean 0, and the
//! extra null modes that a patch of N ≥ 5 has along the edges of holes
//! are 0. No transform preconditioner: it would change the metric, and
//! with it which of the many solutions the iteration ends on.
//!
//! Texels that are not holes but that no kept equation sees are
//! undetermined: they come back NaN, counted in
//! [`HeightReport::undetermined`](super::HeightReport::undetermined).
//!
//! The orthogonal fit runs the same fixed point as without holes (slopes
//! g · (A − λ)/A asked of the vertical solve, `iterative.rs`), each solve
//! started from the last heights (the steps stay in the same range, so the
//! least norm holds), without the Gauss–Newton finish.

use crate::error::Result;
use crate::options::Fit;
use crate::par::prelude::*;
use crate::samples::try_filled;

use super::HeightOptions;
use super::iterative::preconditioned_cg;
use super::line::{Work, columns_in_place, rows};
use super::patch::Patch;
use super::solve::SlopeRows as Slopes;

/// The conjugate gradients stop when the normal equations' residual has
/// fallen to this fraction of the right-hand side (in norm), as without
/// holes.
const TOLERANCE: f64 = 1e-10;

/// The iterations the whole inverse may take: unpreconditioned conjugate
/// gradients need some multiple of the longest side (the slowest mode is
/// the lowest frequency, whose condition grows as the side squared), and
/// clamp with N ≥ 5 thousands more for the modes its box barely sees
/// (41 × 33, N = 5, a band of holes: over 2000 to 1e-10).
fn budget(w: usize, h: usize) -> usize {
    10_000usize.max(16 * w.max(h))
}

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
    // The slopes of the kept equations; 0 where an equation is dropped
    // (the orthogonal fit's ratios there then settle with the heights).
    let kept = |y: usize, gx: &mut [f64], gy: &mut [f64]| {
        slopes(y, gx, gy);
        for ((gx, gy), &k) in gx.iter_mut().zip(gy.iter_mut()).zip(&support.kept[y * w..][..w]) {
            if !k {
                (*gx, *gy) = (0.0, 0.0);
            }
        }
    };
    z.iter_mut().for_each(|z| *z = 0.0);
    let mut budget = budget(w, h);
    let mut iterations = 1;
    let mut converged = conjugate_gradients(&patch, support, &weights, &kept, lambda, z, &mut budget)?;
    if opts.fit.fit == Fit::Vertical {
        return Ok((iterations, converged));
    }
    let len = w * h;
    let mut rho = try_filled(len, 1.0)?;
    let mut direction = try_filled(len, 0i8)?;
    patch.update_ratios(z, &kept, &mut rho, &mut direction, 1.0)?;
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
        if !conjugate_gradients(&patch, support, &weights, &weighted, lambda, z, &mut budget)? {
            break;
        }
        let (change, _, _) = patch.update_ratios(z, &kept, &mut rho, &mut direction, damping)?;
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

/// Conjugate gradients on P(DᵀKWD + λ)P z = PDᵀKW g, preconditioned by
/// W⁻¹ on the texels that are not holes, from `z` (0 at the holes), until
/// the residual falls below [`TOLERANCE`] of the right-hand side's or
/// `budget` runs out. Returns whether it met the tolerance.
fn conjugate_gradients(
    patch: &Patch,
    support: &Support,
    (wx, wy): &(Vec<f64>, Vec<f64>),
    slopes: Slopes<'_>,
    lambda: f64,
    z: &mut [f64],
    budget: &mut usize,
) -> Result<bool> {
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
    let precondition = |r: &[f64], out: &mut [f64]| -> Result<()> {
        out.par_chunks_mut(w).zip(r.par_chunks(w)).enumerate().for_each(|(y, (o, r))| {
            for ((o, r), m) in o.iter_mut().zip(r).zip(wx.iter()) {
                *o = r / (m * wy[y]);
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

/// Bytes the solve with holes holds besides the slopes and heights: eight
/// planes of f64 (the conjugate gradients' and the slopes'), the ratios
/// and their directions, and three masks.
pub(super) fn bytes(w: usize, h: usize) -> u64 {
    (w as u64).saturating_mul(h as u64).saturating_mul(8 * 8 + 8 + 1 + 3)
}
