//! Weighted fits ([`Weights::Binomial`](crate::Weights::Binomial)): the
//! patch's points weigh w(i)·w(j), one axis's weights w summing to 1.
//!
//! The weighted least-squares plane has the unweighted fit's formulas with
//! every sum weighted (docs/spec.md §2, "Weights"): on a full patch
//! Σw·i = Σw·j = Σw·ij = 0 (the weights are symmetric and separable),
//! so with
//!
//! ```text
//! A   = Σ w(i)w(j)·i²  (= Σ w(i)·i², = (N − 1)/4 for Pascal's row)
//! Cx  = Σ w·i·z        Cy = σ·Σ w·j·z
//! Czz = Σ w·z² − (Σ w·z)²
//! ```
//!
//! the vertical fit is n ∝ (−Cx, −Cy, A) and the orthogonal fit the
//! smallest eigenvector of [[A, 0, Cx], [0, A, Cy], [Cx, Cy, Czz]], as
//! [`Plan::emit`] forms them from any sums (its `count`, the patch's total
//! weight, is 1 here). At N = 3 the vertical fit's slope Cx / A is Horn's
//! ((c + 2f + i) − (a + 2d + g)) / 8.
//!
//! # How the sums are made
//!
//! Each sum is separable: along a row, s0 = Σ w(q)·z, si = Σ w(q)·u·z,
//! szz = Σ w(q)·z² over the window's values q = 0 … N − 1 (u = q − r);
//! down the patch, Σ w(j)·s0, Σ w(j)·si, Σ w(j)·u·s0, Σ w(j)·szz over its
//! rows. Both are summed outright, in the order of q and of j, from the
//! patch's values alone: a texel's sums are the same bits in whatever
//! strip, tile, band or window holds it, on any thread. The cost is O(N)
//! per texel along each axis (each row's sums are made once a strip and
//! held while the patch's N rows need them), each step a loop across the
//! strip's columns that vectorises.
//!
//! Holes read as 0 in the z sums, as for the unweighted fit; the valid
//! points' weighted moments (Σw·m, Σw·i·m, …, m the 0/1 mask) are summed
//! the same way by [`super::masked::WeightedMask`]. Which patches hold a hole, and
//! whether their points determine a plane, are still decided on the
//! unweighted integers (`masked`): the weights are positive, so a set of
//! points is collinear weighted or not alike.

use std::ops::Range;

use super::FromNormal;
use super::emit::EmitScratch;
use super::plan::{Plan, Strip};
use super::sums::{RowCache, RowRef, RowSums, SourceRows, WindowSums};
use crate::samples::Sample;

impl Plan {
    /// Fits one strip with weights (see the module docs): every output
    /// row's sums from the N rows' weighted sums its patch covers.
    pub(super) fn fit_strip_weighted<'a, H: Sample, T: FromNormal>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        gain: f64,
        strip: Strip<'_, T>,
    ) {
        let Strip { y0, x0, mut out, mut residual, valid } = strip;
        let Some(first) = out.first() else { return };
        let (n, r) = (self.n, self.r as isize);
        let cols = x0..x0 + first.len();
        let w = cols.len();
        let row_sums = |v: isize, sums: &mut RowSums| self.weighted_row_sums(rows(v), gain, cols.clone(), sums);
        let mut holes = self.strip_holes(rows, y0, out.len(), cols.clone(), valid);
        let mut cache = RowCache::new(n, w);
        let mut v = WindowSums::zeros(w);
        let mut scratch = EmitScratch::new(w);
        for (k, out_row) in out.iter_mut().enumerate() {
            let y = (y0 + k) as isize;
            for j in 0..n as isize {
                cache.get(y - r + j, &row_sums);
            }
            self.weighted_window(&cache, y, &mut v);
            if let Some(holes) = holes.as_mut() {
                self.advance_holes(rows, y0 + k, holes, &mut v);
            }
            self.emit(&v, 1.0, y0 + k, &mut scratch, out_row);
            if let Some(residual) = residual.as_mut() {
                self.emit_residual(&v, 1.0, y0 + k, &mut scratch, residual[k]);
            }
            if let Some(holes) = holes.as_mut() {
                self.patch_holes(&v, 1.0, (y0 + k, k), holes, out_row, residual.as_mut().map(|r| &mut *r[k]));
            }
        }
    }

    /// The window sums of output row `y` from the rows' sums `cache` holds
    /// (rows y − r … y + r), added in the rows' order.
    fn weighted_window(&self, cache: &RowCache, y: isize, v: &mut WindowSums) {
        let w = v.s0.len();
        let r = self.r as isize;
        let [wj, wuj, _] = &self.axis;
        let (s0, si, sj, szz) = (&mut v.s0[..w], &mut v.si[..w], &mut v.sj[..w], &mut v.szz[..w]);
        for j in 0..self.n {
            let h = cache.held(y - r + j as isize);
            let (h0, hi, hzz) = (&h.s0[..w], &h.si[..w], &h.szz[..w]);
            let (a, b) = (wj[j], wuj[j]);
            if j == 0 {
                s0.iter_mut().zip(h0).for_each(|(o, h)| *o = a * h);
                si.iter_mut().zip(hi).for_each(|(o, h)| *o = a * h);
                sj.iter_mut().zip(h0).for_each(|(o, h)| *o = b * h);
                szz.iter_mut().zip(hzz).for_each(|(o, h)| *o = a * h);
            } else {
                s0.iter_mut().zip(h0).for_each(|(o, h)| *o += a * h);
                si.iter_mut().zip(hi).for_each(|(o, h)| *o += a * h);
                sj.iter_mut().zip(h0).for_each(|(o, h)| *o += b * h);
                szz.iter_mut().zip(hzz).for_each(|(o, h)| *o += a * h);
            }
        }
    }

    /// Σw·z, Σw·u·z, Σw·z² (z = gain · h) over each column's horizontal
    /// window of one source row, added in the window's order.
    fn weighted_row_sums<H: Sample>(&self, src: RowRef<'_, H>, gain: f64, cols: Range<usize>, out: &mut RowSums) {
        let RowSums { s0: out_s0, si: out_si, szz: out_szz, padded, squares, .. } = out;
        let r = self.r;
        let w = cols.len();
        self.padded_row(src, (cols.start as isize - r as isize, (cols.end + r) as isize), gain, padded);
        squares.clear();
        squares.extend(padded.iter().map(|z| z * z));
        let [wq, wuq, _] = &self.axis;
        let (o0, oi, ozz) = (&mut out_s0[..w], &mut out_si[..w], &mut out_szz[..w]);
        for q in 0..self.n {
            let (z, zz) = (&padded[q..q + w], &squares[q..q + w]);
            let (a, b) = (wq[q], wuq[q]);
            if q == 0 {
                o0.iter_mut().zip(z).for_each(|(o, z)| *o = a * z);
                oi.iter_mut().zip(z).for_each(|(o, z)| *o = b * z);
                ozz.iter_mut().zip(zz).for_each(|(o, zz)| *o = a * zz);
            } else {
                o0.iter_mut().zip(z).for_each(|(o, z)| *o += a * z);
                oi.iter_mut().zip(z).for_each(|(o, z)| *o += b * z);
                ozz.iter_mut().zip(zz).for_each(|(o, zz)| *o += a * zz);
            }
        }
    }
}
