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
//! rows. Below [`FFT_FROM`](super::convolve::FFT_FROM) both are summed
//! outright, in the order of q and of j, from the patch's values alone: a
//! texel's sums are the same bits in whatever strip, tile, band or window
//! holds it, on any thread. The cost is O(N) per texel along each axis
//! (each row's sums are made once a strip and held while the patch's N
//! rows need them), each step a loop across the strip's columns that
//! vectorises. From `FFT_FROM` on, both axes' sums are correlations by FFT
//! in blocks aligned on the image ([`super::convolve`]): O(log N) a texel
//! an axis, and still a texel's sums the same bits wherever it is made,
//! since a block's outputs come from its own inputs alone.
//!
//! Holes read as 0 in the z sums, as for the unweighted fit; the valid
//! points' weighted moments (Σw·m, Σw·i·m, …, m the 0/1 mask) are summed
//! the same way by [`super::masked::WeightedMask`]. Which patches hold a hole, and
//! whether their points determine a plane, are still decided on the
//! unweighted integers (`masked`): the weights are positive, so a set of
//! points is collinear weighted or not alike.

use std::cell::RefCell;
use std::ops::Range;

use super::Texel;
use super::convolve::{Blocks, Kernel, Layout, Scratch};
use super::emit::EmitScratch;
use super::plan::{Plan, Strip};
use super::sums::{RowCache, RowRef, RowSums, SourceRows, WindowSums};
use crate::samples::Sample;

/// One strip's buffers for the sums by blocks: a vertical block's inputs
/// (the row sums of its B + 2r rows) and outputs (its window sums), each
/// plane column by column, so that a column's transform reads a slice.
struct BlockSums {
    /// s0, si, szz of the inputs: column x, input i at x·m + i.
    inputs: [Vec<f64>; 3],
    /// s0, si, sj, szz of the outputs: column x, row t at x·b + t.
    outputs: [Vec<f64>; 4],
    /// The block's rows [start, end), and its inputs m and outputs b.
    rows: (usize, usize),
    m: usize,
    b: usize,
}

impl Plan {
    /// Fits one strip with weights (see the module docs): every output
    /// row's sums from the N rows' weighted sums its patch covers.
    #[inline(always)]
    pub(super) fn fit_strip_weighted<'a, H: Sample, T: Texel>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        gain: f64,
        strip: Strip<'_, T>,
    ) {
        if let Some(blocks) = self.blocks.as_deref() {
            return self.fit_strip_blocks(blocks, rows, gain, strip);
        }
        let Strip { y0, x0, mut out, mut residual, valid } = strip;
        let Some(first) = out.first() else { return };
        let (n, r) = (self.n, self.r as isize);
        let cols = x0..x0 + first.len();
        let w = cols.len();
        let mut holes = self.strip_holes(rows, y0, out.len(), cols.clone(), valid);
        let mut cache = RowCache::new(n, w);
        let mut v = WindowSums::zeros(w);
        let mut scratch = EmitScratch::new(w);
        for (k, out_row) in out.iter_mut().enumerate() {
            let y = (y0 + k) as isize;
            for u in y - r..=y + r {
                if let Some(sums) = cache.stale(u) {
                    self.weighted_row_sums(rows(u), gain, cols.clone(), sums);
                }
            }
            self.weighted_window(&cache, y, &mut v);
            let residual = residual.as_mut().map(|r| &mut *r[k]);
            self.finish_row(rows, &mut v, 1.0, (y0 + k, k), holes.as_mut(), &mut scratch, out_row, residual);
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
    #[inline(always)]
    fn weighted_row_sums<H: Sample>(&self, src: RowRef<'_, H>, gain: f64, cols: Range<usize>, out: &mut RowSums) {
        let RowSums { s0: out_s0, si: out_si, szz: out_szz, padded, squares, .. } = out;
        let r = self.r;
        let w = cols.len();
        self.padded_row(src, (cols.start as isize - r as isize, (cols.end + r) as isize), gain, padded);
        squares.clear();
        squares.extend(padded.iter().map(|z| z * z));
        self.weighted_sums_of(padded, squares, (&mut out_s0[..w], &mut out_si[..w], &mut out_szz[..w]));
    }

    /// Σw·z, Σw·u·z, Σw·z² over the windows of `padded` (its squares in
    /// `squares`), one a value of `o0` (as long as `oi`, `ozz`), added in
    /// the window's order.
    fn weighted_sums_of(&self, padded: &[f64], squares: &[f64], (o0, oi, ozz): (&mut [f64], &mut [f64], &mut [f64])) {
        let w = o0.len();
        let [wq, wuq, _] = &self.axis;
        let (oi, ozz) = (&mut oi[..w], &mut ozz[..w]);
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

impl Plan {
    /// [`Self::fit_strip_weighted`] by blocks (see [`super::convolve`]):
    /// the rows' sums block by block along x, and the window sums block by
    /// block down y, each block whole from its own inputs (the top r rows,
    /// a block of their own, summed directly down y).
    fn fit_strip_blocks<'a, H: Sample, T: Texel>(
        &self,
        blocks: &Blocks,
        rows: &SourceRows<'_, 'a, H>,
        gain: f64,
        strip: Strip<'_, T>,
    ) {
        let Strip { y0, x0, mut out, mut residual, valid } = strip;
        let Some(first) = out.first() else { return };
        let (n, r) = (self.n, self.r);
        let cols = x0..x0 + first.len();
        let w = cols.len();
        let scratch = RefCell::new((blocks.scratch(), RowSums::zeros(blocks.len)));
        let row_sums = |v: isize, sums: &mut RowSums| {
            let (s, block) = &mut *scratch.borrow_mut();
            self.block_row_sums(blocks, rows(v), gain, cols.clone(), sums, block, s);
        };
        let mut holes = self.strip_holes(rows, y0, out.len(), cols.clone(), valid);
        let mut cache = RowCache::new(n, w);
        let mut v = WindowSums::zeros(w);
        let mut emit = EmitScratch::new(w);
        let layout = Layout { len: blocks.len, first: r };
        let mut block: Option<BlockSums> = None;
        let mut row = RowSums::zeros(w);
        for (k, out_row) in out.iter_mut().enumerate() {
            let y = y0 + k;
            if y < r {
                // The top block: its rows' patches reach above row 0, and
                // are summed directly down y.
                for j in 0..n as isize {
                    cache.get(y as isize - r as isize + j, &row_sums);
                }
                self.weighted_window(&cache, y as isize, &mut v);
            } else {
                let b = block.get_or_insert_with(|| BlockSums::new(blocks, w));
                if !(b.rows.0..b.rows.1).contains(&y) {
                    let start = layout.start_of(y);
                    b.fill(blocks, (start, layout.end_of(start, self.height)), r, &mut row, &row_sums);
                    b.window(blocks, &mut scratch.borrow_mut().0);
                }
                b.row(y, &mut v);
            }
            let residual = residual.as_mut().map(|r| &mut *r[k]);
            self.finish_row(rows, &mut v, 1.0, (y, k), holes.as_mut(), &mut emit, out_row, residual);
        }
    }

    /// Σw·z, Σw·u·z, Σw·z² of source row `src` at columns `cols`, block
    /// by block along x (blocks from column 0): each block whole, from its
    /// own inputs, by FFT, or directly when an input is a hole. `block`
    /// holds one block's sums.
    #[allow(clippy::too_many_arguments)]
    fn block_row_sums<H: Sample>(
        &self,
        blocks: &Blocks,
        src: RowRef<'_, H>,
        gain: f64,
        cols: Range<usize>,
        out: &mut RowSums,
        block: &mut RowSums,
        s: &mut Scratch,
    ) {
        let r = self.r as isize;
        let layout = Layout { len: blocks.len, first: 0 };
        let (mut start, end) = layout.cover(cols.clone(), self.width);
        while start < end {
            let stop = layout.end_of(start, self.width);
            let b = stop - start;
            let RowSums { s0, si, szz, padded, squares, .. } = block;
            self.padded_row(src, (start as isize - r, stop as isize + r), gain, padded);
            let (s0, si, szz) = (&mut s0[..b], &mut si[..b], &mut szz[..b]);
            if self.reads_hole(src, (start as isize - r, stop as isize + r)) {
                squares.clear();
                squares.extend(padded.iter().map(|z| z * z));
                self.weighted_sums_of(padded, squares, (s0, si, szz));
            } else {
                let reference = padded[0];
                blocks.transform(padded, reference, false, 0, s);
                blocks.transform(padded, reference, true, 1, s);
                blocks.correlate(0, Kernel::W, s, s0);
                blocks.correlate(0, Kernel::Wu, s, si);
                blocks.correlate(1, Kernel::W, s, szz);
                let (c0, c00) = (reference * blocks.w_sum, reference * reference * blocks.w_sum);
                for (zz, &z) in szz.iter_mut().zip(s0.iter()) {
                    *zz = (*zz + 2.0 * reference * z) + c00;
                }
                s0.iter_mut().for_each(|z| *z += c0);
            }
            // The block's columns in the strip.
            let (lo, hi) = (start.max(cols.start), stop.min(cols.end));
            let (a, o) = (lo - start, lo - cols.start);
            out.s0[o..o + hi - lo].copy_from_slice(&s0[a..a + hi - lo]);
            out.si[o..o + hi - lo].copy_from_slice(&si[a..a + hi - lo]);
            out.szz[o..o + hi - lo].copy_from_slice(&szz[a..a + hi - lo]);
            start = stop;
        }
    }

    /// Whether columns `lo .. hi` of `src` (through the x border) hold a
    /// hole.
    fn reads_hole<H: Sample>(&self, src: RowRef<'_, H>, (lo, hi): (isize, isize)) -> bool {
        if !src.holes {
            return false;
        }
        let nodata = self.nodata.unwrap_or(f64::NAN);
        let held = src.x0..src.x0 + src.values.len() as isize;
        (lo..hi).any(|u| {
            let at = if held.contains(&u) { u } else { self.borders.x.map(u, self.width) as isize };
            super::masked::is_hole(src.values[(at - src.x0) as usize].to_f64(), nodata)
        })
    }
}

impl BlockSums {
    fn new(blocks: &Blocks, w: usize) -> BlockSums {
        let (b, m) = (blocks.len, blocks.len + 2 * blocks.r);
        BlockSums {
            inputs: std::array::from_fn(|_| vec![0.0; w * m]),
            outputs: std::array::from_fn(|_| vec![0.0; w * b]),
            rows: (0, 0),
            m,
            b,
        }
    }

    /// The row sums of the inputs of the block of rows [start, end):
    /// rows start − r … end − 1 + r, through `row_sums`.
    fn fill(
        &mut self,
        blocks: &Blocks,
        (start, end): (usize, usize),
        r: usize,
        row: &mut RowSums,
        row_sums: &impl Fn(isize, &mut RowSums),
    ) {
        debug_assert!(end - start <= blocks.len);
        let m = end - start + 2 * r;
        let w = self.inputs[0].len() / self.m;
        (self.rows, self.b) = ((start, end), end - start);
        for i in 0..m {
            row_sums(start as isize - r as isize + i as isize, row);
            for (plane, sums) in self.inputs.iter_mut().zip([&row.s0, &row.si, &row.szz]) {
                for (x, &value) in sums[..w].iter().enumerate() {
                    plane[x * self.m + i] = value;
                }
            }
        }
    }

    /// The window sums of the block's rows from its inputs, column by
    /// column: Σw·s0 and Σw·u·s0 (s0 less its first input), Σw·si, and
    /// Σw·szz (less its first input), the references added back.
    fn window(&mut self, blocks: &Blocks, s: &mut Scratch) {
        let (b, stride) = (self.b, self.m);
        let m = b + (self.m - blocks.len);
        let w = self.inputs[0].len() / stride;
        let [in0, ini, inzz] = &self.inputs;
        let [o0, oi, oj, ozz] = &mut self.outputs;
        for x in 0..w {
            let (c0, ci, czz) = (&in0[x * stride..][..m], &ini[x * stride..][..m], &inzz[x * stride..][..m]);
            let (ref0, refzz) = (c0[0], czz[0]);
            blocks.transform(c0, ref0, false, 0, s);
            blocks.transform(ci, 0.0, false, 1, s);
            blocks.transform(czz, refzz, false, 2, s);
            let (o0, oi, oj, ozz) =
                (&mut o0[x * b..][..b], &mut oi[x * b..][..b], &mut oj[x * b..][..b], &mut ozz[x * b..][..b]);
            blocks.correlate(0, Kernel::W, s, o0);
            blocks.correlate(0, Kernel::Wu, s, oj);
            blocks.correlate(1, Kernel::W, s, oi);
            blocks.correlate(2, Kernel::W, s, ozz);
            let (a0, azz) = (ref0 * blocks.w_sum, refzz * blocks.w_sum);
            o0.iter_mut().for_each(|v| *v += a0);
            ozz.iter_mut().for_each(|v| *v += azz);
        }
    }

    /// Output row `y`'s window sums into `v`.
    fn row(&self, y: usize, v: &mut WindowSums) {
        let (t, b) = (y - self.rows.0, self.b);
        let [o0, oi, oj, ozz] = &self.outputs;
        for (x, (((s0, si), sj), szz)) in v.s0.iter_mut().zip(&mut v.si).zip(&mut v.sj).zip(&mut v.szz).enumerate() {
            *s0 = o0[x * b + t];
            *si = oi[x * b + t];
            *sj = oj[x * b + t];
            *szz = ozz[x * b + t];
        }
    }
}
