//! Detail at several scales ([`Options::detail`](crate::Options::detail)):
//! each scale's plane fitted by its own plan, the slopes summed with their
//! weights, and the normal of the sum (docs/detail.md).
//!
//! The rows are fitted a chunk at a time: every scale's normals of the
//! chunk in f64, their weighted slopes added texel by texel in the order
//! the scales were given, then the texels written. Each scale's normals
//! are its own fit's bits under any cut (see the module docs of
//! [`crate::fit`]), and the sum is per texel in a fixed order, so threads,
//! bands and windows give the same bits. The cost per texel is a fit per
//! scale (each flat in N) plus a few operations a scale; memory is a
//! chunk's planes, not the image's.

use std::ops::Range;

use crate::par::prelude::*;
use crate::samples::Sample;

use super::Texel;
use super::plan::Plan;
use super::sums::SourceRows;

/// Texels a chunk of rows holds at least (unless the image is smaller).
const CHUNK_TEXELS: usize = 1 << 20;

/// Bytes a chunk holds per texel: a scale's normal ([f64; 3]), the sums
/// ([f64; 4]) and two validity flags.
const CHUNK_BYTES_PER_TEXEL: u64 = 24 + 32 + 2;

/// Output rows per chunk for rows of `w` texels: at least a block of the
/// largest scale's rows, so that starting its sums costs what it costs the
/// fit of that scale alone.
fn chunk_rows(plan: &Plan, w: usize) -> usize {
    plan.block_rows.max(CHUNK_TEXELS / w.max(1)).max(1)
}

/// [`Plan::fit_rows`] of `plan`, one patch size or several: the fit's
/// callers go through here. With detail, holes as one size has them: a
/// texel is missing when any scale misses it; no residual (refused before).
pub(super) fn fit_rows<H: Sample, T: Texel>(
    plan: &Plan,
    rows: &SourceRows<'_, '_, H>,
    unit: f64,
    (y0, cols): (usize, Range<usize>),
    out: &mut [T],
    residual: Option<&mut [f32]>,
    valid: Option<(&mut [bool], f64)>,
) {
    if plan.detail.is_empty() {
        return plan.fit_rows(rows, unit, (y0, cols), out, residual, valid);
    }
    debug_assert!(residual.is_none() && !plan.moments, "refused before the fit");
    fit_scales(plan, rows, unit, (y0, cols), out, valid);
}

/// The detail fit of `plan.detail`'s scales, a chunk of rows at a time.
fn fit_scales<H: Sample, T: Texel>(
    plan: &Plan,
    rows: &SourceRows<'_, '_, H>,
    unit: f64,
    (y0, cols): (usize, Range<usize>),
    out: &mut [T],
    mut valid: Option<(&mut [bool], f64)>,
) {
    let w = cols.len();
    if w == 0 || out.is_empty() {
        return;
    }
    let scales: Vec<(Plan, f64)> = plan.detail.iter().map(|&(n, weight)| (plan.with_patch(n), weight)).collect();
    let chunk = chunk_rows(plan, w) * w;
    let len = chunk.min(out.len());
    // The memory rule counted these (`work_bytes`).
    let mut normals = vec![[0.0f64; 3]; len];
    let mut sums = vec![[0.0f64; 4]; len];
    let mut scale_valid = if valid.is_some() { vec![false; len] } else { Vec::new() };
    let missing = T::make(plan.missing, &plan.frame);
    for (c, out) in out.chunks_mut(chunk).enumerate() {
        let (y, len) = (y0 + c * chunk / w, out.len());
        let (normals, sums) = (&mut normals[..len], &mut sums[..len]);
        sums.fill([0.0; 4]);
        let mut chunk_valid = valid.as_mut().map(|(v, nodata)| (&mut v[c * chunk..][..len], *nodata));
        if let Some((v, _)) = &mut chunk_valid {
            v.fill(true);
        }
        for (scale, weight) in &scales {
            let holes = chunk_valid.as_ref().map(|(_, nodata)| (&mut scale_valid[..len], *nodata));
            scale.fit_rows(rows, unit, (y, cols.clone()), normals, None, holes);
            sums.par_chunks_mut(w).zip(normals.par_chunks(w)).for_each(|(sums, normals)| {
                for (s, n) in sums.iter_mut().zip(normals) {
                    add_slopes(s, *n, *weight);
                }
            });
            if let Some((v, _)) = &mut chunk_valid {
                v.iter_mut().zip(&scale_valid[..len]).for_each(|(v, &s)| *v &= s);
            }
        }
        match chunk_valid {
            None => out.par_chunks_mut(w).zip(sums.par_chunks(w)).for_each(|(out, sums)| {
                for (texel, s) in out.iter_mut().zip(sums) {
                    *texel = T::make(normal_of(*s), &plan.frame);
                }
            }),
            Some((v, _)) => {
                out.par_chunks_mut(w).zip(sums.par_chunks(w)).zip(v.par_chunks(w)).for_each(|((out, sums), v)| {
                    for ((texel, s), &v) in out.iter_mut().zip(sums).zip(v) {
                        *texel = if v { T::make(normal_of(*s), &plan.frame) } else { missing };
                    }
                })
            }
        }
    }
}

/// Adds a scale's fitted normal `n`, times `weight`, to a texel's sums
/// `[Σ w·nx/nz, Σ w·ny/nz, Σ' w·nx, Σ' w·ny]`: its slopes negated,
/// −(p, q) = (nx, ny)/nz, or, for a vertical plane (nz = 0, whose slope is
/// infinite), its horizontal direction in the last two (Σ' over the
/// vertical planes only).
#[inline(always)]
pub(super) fn add_slopes(s: &mut [f64; 4], [nx, ny, nz]: [f64; 3], weight: f64) {
    if nz > 0.0 {
        s[0] += weight * (nx / nz);
        s[1] += weight * (ny / nz);
    } else {
        s[2] += weight * nx;
        s[3] += weight * ny;
    }
}

/// The unit normal of a texel's sums ([`add_slopes`]):
/// (Σ w·nx/nz, Σ w·ny/nz, 1) normalised, or, when some scale's plane is
/// vertical (an infinite slope outweighs every finite one), the limit of
/// that: the vertical planes' weighted horizontal directions, normalised,
/// z = 0. Where those cancel, the finite slopes decide.
#[inline(always)]
pub(super) fn normal_of([px, py, vx, vy]: [f64; 4]) -> [f64; 3] {
    let v2 = vx * vx + vy * vy;
    if v2 > 0.0 {
        let inv = 1.0 / v2.sqrt();
        return [vx * inv, vy * inv, 0.0];
    }
    let inv = 1.0 / (px * px + py * py + 1.0).sqrt();
    [px * inv, py * inv, inv]
}

/// The bytes [`fit_rows`] allocates for `rows` output rows of `cols`
/// columns ([`Plan::work_bytes`]); with detail, the largest any scale's
/// fit of a chunk takes (they run one after another) and the chunk's
/// planes.
pub(super) fn work_bytes(plan: &Plan, unit: f64, (cols, rows): (usize, usize), holes: bool, residual: bool) -> u64 {
    if plan.detail.is_empty() {
        return plan.work_bytes(unit, (cols, rows), holes, residual);
    }
    let chunk_rows = chunk_rows(plan, cols).min(rows);
    let fit = plan.detail.iter().map(|&(n, _)| plan.with_patch(n).work_bytes(unit, (cols, chunk_rows), holes, false));
    let chunk = (chunk_rows as u64).saturating_mul(cols as u64).saturating_mul(CHUNK_BYTES_PER_TEXEL);
    fit.max().unwrap_or(0).saturating_add(chunk)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slopes_add_and_a_vertical_plane_decides() {
        let mut s = [0.0; 4];
        // A 45° tilt towards −x twice at weight 0.5 is the same tilt.
        let n = [-(0.5f64.sqrt()), 0.0, 0.5f64.sqrt()];
        add_slopes(&mut s, n, 0.5);
        add_slopes(&mut s, n, 0.5);
        let m = normal_of(s);
        assert!((m[0] - n[0]).abs() < 1e-15 && m[1] == 0.0 && (m[2] - n[2]).abs() < 1e-15);
        // A vertical plane facing +y outweighs any finite slope.
        add_slopes(&mut s, [0.0, 1.0, 0.0], 0.25);
        assert_eq!(normal_of(s), [0.0, 1.0, 0.0]);
        // Flat in, flat out.
        assert_eq!(normal_of([0.0; 4]), [0.0, 0.0, 1.0]);
    }
}
