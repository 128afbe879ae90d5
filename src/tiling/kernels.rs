//! The row kernels that both measures run, the whole image's (`whole.rs`)
//! and the streamed one's ([`HeightSeams`](super::HeightSeams)): a row's
//! runs at every level, runs of rows, the x pairs of a row, the y sums in
//! lanes, and the scale the sums are taken at.

/// Rows per parallel task: large enough that the four halo rows each task
/// reads twice cost little, small enough to spread over threads.
pub(super) const CHUNK: usize = 32;

/// Levels of smoothing along the seam: level l compares lines whose
/// texels are summed in runs of 2^l along them, l = 0 … 5 (runs of 1 to
/// 32). [`CHUNK`] is a multiple of the longest run.
pub(super) const LEVELS: usize = 6;

/// The f32 kernels measure the heights times this, and the profiles are
/// scaled back in f64. Without it, finite heights near f32's range (an HDR
/// or float file of ±3.4·10³⁸, found by fuzzing) overflow to infinite
/// differences and sums, and the score to NaN. A power of two, so the
/// scaling is exact and the scores are the same bit for bit, except for
/// heights within about 10⁻²⁸ of zero whose differences become subnormal:
/// they lose what lies below 10⁻³⁵, far below the ε floor (10⁻³⁰) that
/// decides such scores anyway. With it, |Δ| ≤ 2⁹⁷ and a crease ≤ 2⁹⁸: the
/// x sums of 32 rows, and a y lane of up to 2²⁹ texels (rows of 2³² texels,
/// 16 GiB of f32), stay below f32's largest value, 2¹²⁸. The runs of the
/// levels hold it too: a run of 2^l texels or rows is up to 2^l times
/// larger, and a sum holds 2^l times fewer of them.
pub(super) const JUDGE_SCALE: f32 = 1.0 / 4_294_967_296.0;

/// 1 / [`JUDGE_SCALE`], to bring the sums back to height units.
pub(super) const UNSCALE: f64 = 4_294_967_296.0;

/// A texel as judged: a non-finite value is a hole, NaN.
#[inline]
pub(super) fn finite(v: f32) -> f32 {
    if v.is_finite() { v } else { HOLE }
}

/// A height as the kernels measure it: times [`JUDGE_SCALE`], a
/// non-finite value a hole.
#[inline]
pub(super) fn judged(v: f32) -> f32 {
    finite(v * JUDGE_SCALE)
}

/// A hole as the kernels hold it: NaN, so that every difference, crease
/// and run that reads it is NaN too, and [`add_valid`] skips it.
pub(super) const HOLE: f32 = f32::NAN;

/// Adds `d` to the sum `s` and 1 to the count `n`, unless `d` read a hole
/// (is NaN). Branch-free, so the loops still vectorise; adding 0 to a sum
/// of absolute values leaves its bits, so an image without holes gives
/// the sums it always gave.
#[inline(always)]
pub(super) fn add_valid(s: &mut f32, n: &mut f32, d: f32) {
    let ok = !d.is_nan();
    *s += if ok { d } else { 0.0 };
    *n += if ok { 1.0 } else { 0.0 };
}

/// A kernel's f32 sum back in height units, exactly.
#[inline]
pub(super) fn unscaled(s: f32) -> f64 {
    f64::from(s) * UNSCALE
}

/// The columns `x0 .. x1` of a row `w` wide that a pass measures.
#[derive(Clone, Copy, Debug)]
pub(super) struct Cols {
    pub(super) x0: usize,
    pub(super) x1: usize,
    pub(super) w: usize,
}

impl Cols {
    /// The whole row.
    pub(super) fn whole(w: usize) -> Self {
        Cols { x0: 0, x1: w, w }
    }

    pub(super) fn range(&self) -> std::ops::Range<usize> {
        self.x0..self.x1
    }

    fn is_first(&self) -> bool {
        self.x0 == 0
    }

    fn is_last(&self) -> bool {
        self.x1 == self.w
    }

    /// The values of a level-`level` row (`width` of them) made from these
    /// columns' texels.
    pub(super) fn at_level(&self, level: usize, width: usize) -> std::ops::Range<usize> {
        let end = if self.is_last() { width } else { self.x1 >> level };
        (self.x0 >> level)..end
    }
}

/// Rows of one signal at every level: level l of a row holds its texels
/// summed in runs of 2^l along the row (the last run shorter when 2^l does
/// not divide W), `slots` rows per level.
#[derive(Clone, Debug)]
pub(super) struct Runs {
    /// Values per row at each level: ⌈W / 2^l⌉.
    pub(super) widths: [usize; LEVELS],
    /// Level l: `slots` rows of `widths[l]` values.
    levels: [Vec<f32>; LEVELS],
}

impl Runs {
    pub(super) fn new(w: usize, slots: usize) -> Self {
        let widths: [usize; LEVELS] = std::array::from_fn(|level| w.div_ceil(1 << level));
        Runs { widths, levels: std::array::from_fn(|level| vec![0.0; slots * widths[level]]) }
    }

    /// Level `level` of the row in `slot`.
    pub(super) fn row(&self, level: usize, slot: usize) -> &[f32] {
        let n = self.widths[level];
        &self.levels[level][slot * n..][..n]
    }

    /// The texels of the row in `slot`, to be written before [`coarsen`](Self::coarsen).
    pub(super) fn slot_mut(&mut self, slot: usize) -> &mut [f32] {
        let n = self.widths[0];
        &mut self.levels[0][slot * n..][..n]
    }

    /// Levels 1 … of the row in `slot` from its texels in `cols`: each
    /// level sums pairs of the one below.
    #[inline(always)]
    pub(super) fn coarsen(&mut self, slot: usize, cols: &Cols) {
        for level in 1..LEVELS {
            let (below, above) = self.levels.split_at_mut(level);
            let (nb, na) = (self.widths[level - 1], self.widths[level]);
            let src = &below[level - 1][slot * nb..][cols.at_level(level - 1, nb)];
            let dst = &mut above[0][slot * na..][cols.at_level(level, na)];
            for (d, s) in dst.iter_mut().zip(src.chunks_exact(2)) {
                *d = s[0] + s[1];
            }
            if src.len() % 2 == 1 {
                dst[src.len() / 2] = src[src.len() - 1];
            }
        }
    }

    /// Copies every level of `from`'s row in `from_slot` into `slot`, the
    /// values made from `cols`.
    #[inline(always)]
    pub(super) fn copy_slot(&mut self, slot: usize, from: &Runs, from_slot: usize, cols: &Cols) {
        for level in 0..LEVELS {
            let n = self.widths[level];
            let part = cols.at_level(level, n);
            self.levels[level][slot * n..][part.clone()].copy_from_slice(&from.row(level, from_slot)[part]);
        }
    }
}

/// Rows summed in runs of 2^l rows (aligned on multiples of 2^l from row 0),
/// whose x pairs are level l's: each row pushed is level 0; two finished
/// runs of a level make one of the next. A pass over some columns keeps
/// those columns of the runs.
#[derive(Clone, Debug)]
pub(super) struct RowStack {
    /// Level l's run in progress (level 0 unused).
    sums: [Vec<f32>; LEVELS],
    /// How many runs of level l − 1 (rows for l = 1) `sums[l]` holds.
    pub(super) count: [usize; LEVELS],
}

impl RowStack {
    pub(super) fn new(w: usize) -> Self {
        RowStack { sums: std::array::from_fn(|_| vec![0.0; w]), count: [0; LEVELS] }
    }

    /// Adds the x pairs of row `r` (level 0) to the sums, and those of
    /// every run it completes, over `cols`.
    #[inline(always)]
    pub(super) fn push(&mut self, r: &[f32], cols: &Cols, sums: &mut XSums) {
        add_row_x(r, cols, 0, sums);
        self.add_into(1, r, cols);
        let mut level = 1;
        while level < LEVELS && self.count[level] == 2 {
            self.close(level, cols, sums);
            level += 1;
        }
    }

    /// Closes the runs cut short by the end of the rows, finest first (each
    /// then counts as one run of the next level).
    #[inline(always)]
    pub(super) fn finish(&mut self, cols: &Cols, sums: &mut XSums) {
        for level in 1..LEVELS {
            if self.count[level] > 0 {
                self.close(level, cols, sums);
            }
        }
    }

    #[inline(always)]
    fn add_into(&mut self, level: usize, r: &[f32], cols: &Cols) {
        // The first run of a level is copied, not added to zeros: no pass
        // to clear the sums when a run closes.
        let (sums, r) = (&mut self.sums[level][cols.range()], &r[cols.range()]);
        if self.count[level] == 0 {
            sums.copy_from_slice(r);
        } else {
            for (s, &v) in sums.iter_mut().zip(r) {
                *s += v;
            }
        }
        self.count[level] += 1;
    }

    /// Measures level `level`'s run, hands it to the next level, clears it.
    #[inline(always)]
    fn close(&mut self, level: usize, cols: &Cols, sums: &mut XSums) {
        let run = std::mem::take(&mut self.sums[level]);
        add_row_x(&run, cols, level, sums);
        if level + 1 < LEVELS {
            self.add_into(level + 1, &run, cols);
        }
        self.sums[level] = run;
        self.count[level] = 0;
    }
}

/// What the x kernels of a pass over some columns leave to the passes over
/// the others, per event (a row measured, or a run of rows closed), in the
/// order the events come: the last 3 values of the row, for the pairs that
/// straddle the next pass's first column, and the first 3, for the pairs
/// across the wrap, which the last pass adds.
#[derive(Clone, Debug, Default)]
pub(super) struct EdgeLog {
    /// The event being measured.
    pub(super) next: usize,
    ends: Vec<[f32; 3]>,
    starts: Vec<[f32; 3]>,
}

/// Where the x kernels add their sums (level-major, as in [`Profiles`](super::score::Profiles)),
/// and what they need from the other passes.
pub(super) struct XSums<'a> {
    pub(super) vx: &'a mut [f32],
    pub(super) cx: &'a mut [f32],
    /// How many pairs (creases) of two (four) valid texels each sum holds.
    pub(super) nvx: &'a mut [f32],
    pub(super) ncx: &'a mut [f32],
    pub(super) crease: bool,
    pub(super) edges: &'a mut EdgeLog,
}

/// Adds the x pairs of row `r` at `level` (W ≥ 1 values, of which a pass
/// over `cols` holds those columns) to the f32 sums and, with
/// `sums.crease`, its x creases. The one x kernel of [`check`](super::check) and
/// [`HeightSeams`](super::HeightSeams).
///
/// A pass adds the pairs whose stencils end in its columns: value pair k
/// (texels k, k + 1) for k = x0 − 1 … x1 − 2 and crease k (k − 1 … k + 2)
/// for k = x0 − 2 … x1 − 3, with the last 3 texels of the same event from
/// the pass before; the last pass adds the pairs across the wrap too, with
/// the first 3 texels from the first pass. A pass over the whole row does
/// it all with its own texels.
#[inline(always)]
fn add_row_x(r: &[f32], cols: &Cols, level: usize, sums: &mut XSums) {
    let Cols { x0, x1, w } = *cols;
    let (first, last) = (cols.is_first(), cols.is_last());
    let vx = &mut sums.vx[level * w..][..w];
    let cx = &mut sums.cx[level * w..][..w];
    let nvx = &mut sums.nvx[level * w..][..w];
    let ncx = &mut sums.ncx[level * w..][..w];
    let log = &mut *sums.edges;
    let event = log.next;
    log.next += 1;
    let (before, start) = if first { ([0.0; 3], [0.0; 3]) } else { (log.ends[event], log.starts[event]) };
    if !last {
        let end = [r[x1 - 3], r[x1 - 2], r[x1 - 1]];
        if first {
            set_or_push(&mut log.ends, event, end);
            set_or_push(&mut log.starts, event, [r[0], r[1], r[2]]);
        } else {
            log.ends[event] = end;
        }
    }
    // h(k) for any k a stencil of this pass reaches (mod W): its own
    // columns, the 3 before them, and across the wrap the row's first 3.
    // Only for the few columns at the pass's edges or across the wrap, so
    // the loops over the rest read `r` in place.
    let h = |k: usize| {
        let k = k % w;
        if k >= x0 {
            r[k]
        } else if k + 3 >= x0 {
            before[k + 3 - x0]
        } else {
            start[k]
        }
    };
    let crease_at = |k: usize| ((h(k + 2) - h(k + 1)) - (h(k) - h(k + w - 1))).abs();
    // Values: pair k → k + 1, the last one the wrap.
    let pairs = vx[x0..x1 - 1].iter_mut().zip(&mut nvx[x0..x1 - 1]);
    for (((v, n), &b), &c) in pairs.zip(&r[x0..x1]).zip(&r[x0 + 1..x1]) {
        add_valid(v, n, (c - b).abs());
    }
    if !first {
        add_valid(&mut vx[x0 - 1], &mut nvx[x0 - 1], (r[x0] - before[2]).abs());
    }
    if last {
        add_valid(&mut vx[w - 1], &mut nvx[w - 1], (h(0) - r[w - 1]).abs());
    }
    if !sums.crease {
        return;
    }
    if w >= 4 {
        // Creases: a, b, c, d = h(k−1), h(k), h(k+1), h(k+2); in place for
        // k = x0 + 1 … x1 − 3, from the pass before for k = x0 − 2 … x0,
        // through the wrap for k = 0, W−2 and W−1.
        let inside = (x0 + 1).min(x1.saturating_sub(2));
        let lo = if first { 1 } else { x0 - 2 };
        for k in lo..inside {
            add_valid(&mut cx[k], &mut ncx[k], crease_at(k));
        }
        if x1 >= inside + 3 {
            let (a, b, c, d) = (&r[inside - 1..x1 - 3], &r[inside..x1 - 2], &r[inside + 1..x1 - 1], &r[inside + 2..x1]);
            let creases = cx[inside..x1 - 2].iter_mut().zip(&mut ncx[inside..x1 - 2]);
            for (k, (s, n)) in creases.enumerate() {
                add_valid(s, n, ((d[k] - c[k]) - (b[k] - a[k])).abs());
            }
        }
        if last {
            for k in [0, w - 2, w - 1] {
                add_valid(&mut cx[k], &mut ncx[k], crease_at(k));
            }
        }
    } else {
        for k in 0..w {
            add_valid(&mut cx[k], &mut ncx[k], crease_at(k));
        }
    }
}

/// Sets `log[at]`, growing it by one when `at` is its length.
fn set_or_push(log: &mut Vec<[f32; 3]>, at: usize, value: [f32; 3]) {
    if at < log.len() {
        log[at] = value;
    } else {
        log.push(value);
    }
}

/// Adds the f32 block sums that a pass over `cols` adds to into the f64
/// totals, times `scale` ([`UNSCALE`] for sums, 1 for counts), and clears
/// them: the columns each pass's x kernels own (see [`add_row_x`]), so
/// that each column is flushed after all its rows' additions, as with
/// whole rows.
#[inline(always)]
pub(super) fn flush_cols(
    vx: &mut [f64],
    vx_block: &mut [f32],
    cx: &mut [f64],
    cx_block: &mut [f32],
    cols: &Cols,
    scale: f64,
) {
    let w = cols.w;
    let (first, last) = (cols.is_first(), cols.is_last());
    let value = if first { 0 } else { cols.x0 - 1 }..if last { w } else { cols.x1 - 1 };
    // Crease 0 crosses the wrap: the last pass adds it.
    let crease = match (first, last) {
        (true, true) => [0..w, 0..0],
        (true, false) => [1..cols.x1 - 2, 0..0],
        (false, true) => [cols.x0 - 2..w, 0..1],
        (false, false) => [cols.x0 - 2..cols.x1 - 2, 0..0],
    };
    for level in 0..LEVELS {
        let at = |r: &std::ops::Range<usize>| level * w + r.start..level * w + r.end;
        flush(&mut vx[at(&value)], &mut vx_block[at(&value)], scale);
        for part in &crease {
            flush(&mut cx[at(part)], &mut cx_block[at(part)], scale);
        }
    }
}

/// Adds the f32 block sums into the f64 totals, times `scale`, and
/// clears them (`unscaled` for sums, the counts as they are).
#[inline(always)]
fn flush(total: &mut [f64], block: &mut [f32], scale: f64) {
    for (t, b) in total.iter_mut().zip(block.iter_mut()) {
        *t += f64::from(*b) * scale;
        *b = 0.0;
    }
}

/// The y value sum of the row pair `b` → `c`, and how many valid pairs
/// it holds.
#[inline]
pub(super) fn y_value(b: &[f32], c: &[f32]) -> (f64, f64) {
    lane_sum([b, c], |[b, c]| (c - b).abs())
}

/// The y crease sum of the row pair `b` → `c`, `a` the row before `b` and
/// `d` the row after `c`, and how many valid creases it holds.
#[inline]
pub(super) fn y_crease(a: &[f32], b: &[f32], c: &[f32], d: &[f32]) -> (f64, f64) {
    lane_sum([a, b, c, d], |[a, b, c, d]| ((d - c) - (b - a)).abs())
}

/// Σ f(rows at x) for x in 0 … n − 1 (n the first row's length), and the
/// count of terms that read no hole: see [`Lanes`].
#[inline(always)]
fn lane_sum<const K: usize>(rows: [&[f32]; K], f: impl Fn([f32; K]) -> f32) -> (f64, f64) {
    let mut lanes = Lanes::default();
    lanes.add(0..rows[0].len(), rows, f);
    (lanes.total(), lanes.count())
}

/// A y sum over the texels of rows, some columns at a time: in 8 f32
/// lanes (lane l takes x ≡ l mod 8; the loop over fixed chunks
/// vectorises), the texels past the rows' last multiple of 8 in f64, all
/// added in f64 at the end and scaled back to height units. Parts added
/// left to right, each starting on a multiple of 8, give the bits of one
/// part over the whole rows.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Lanes {
    lanes: [f32; 8],
    tail: f64,
    /// The terms that read no hole, counted as the sums are.
    counts: [f32; 8],
    tail_count: f64,
}

impl Lanes {
    /// Adds f(rows at x) for x in `part` (starting on a multiple of 8).
    #[inline(always)]
    pub(super) fn add<const K: usize>(
        &mut self,
        part: std::ops::Range<usize>,
        rows: [&[f32]; K],
        f: impl Fn([f32; K]) -> f32,
    ) {
        let n = rows[0].len();
        let whole = (n - n % 8).min(part.end);
        let rows_whole = rows.map(|r| &r[part.start..whole]);
        // A local copy: through `self` the lanes were stored at every step.
        let (mut lanes, mut counts) = (self.lanes, self.counts);
        for x0 in (0..whole - part.start).step_by(8) {
            let at: [&[f32; 8]; K] = rows_whole.map(|r| r[x0..x0 + 8].try_into().expect("8 values"));
            for (l, (lane, count)) in lanes.iter_mut().zip(&mut counts).enumerate() {
                add_valid(lane, count, f(at.map(|c| c[l])));
            }
        }
        (self.lanes, self.counts) = (lanes, counts);
        if part.end > whole {
            (self.tail, self.tail_count) = tail_sum((whole..part.end).map(|x| f(rows.map(|r| r[x]))));
        }
    }

    /// Adds to `value` the y value sum of the row pair `b` → `c` and to
    /// `crease` its crease sum, over `part`, as [`add`](Self::add) does
    /// each (the same additions in the same order), in one loop.
    #[inline(always)]
    pub(super) fn add_both(value: &mut Lanes, crease: &mut Lanes, part: std::ops::Range<usize>, rows: [&[f32]; 4]) {
        let n = rows[0].len();
        let whole = (n - n % 8).min(part.end);
        let [a, b, c, d] = rows.map(|r| &r[part.start..whole]);
        let (mut v, mut k) = (value.lanes, crease.lanes);
        let (mut nv, mut nk) = (value.counts, crease.counts);
        for x0 in (0..whole - part.start).step_by(8) {
            let at = |r: &[f32]| -> [f32; 8] { r[x0..x0 + 8].try_into().expect("8 values") };
            let (a, b, c, d) = (at(a), at(b), at(c), at(d));
            for l in 0..8 {
                add_valid(&mut v[l], &mut nv[l], (d[l] - c[l]).abs());
                add_valid(&mut k[l], &mut nk[l], ((d[l] - c[l]) - (b[l] - a[l])).abs());
            }
        }
        (value.lanes, crease.lanes) = (v, k);
        (value.counts, crease.counts) = (nv, nk);
        if part.end > whole {
            let [a, b, c, d] = rows;
            (value.tail, value.tail_count) = tail_sum((whole..part.end).map(|x| (d[x] - c[x]).abs()));
            (crease.tail, crease.tail_count) =
                tail_sum((whole..part.end).map(|x| ((d[x] - c[x]) - (b[x] - a[x])).abs()));
        }
    }

    /// The sum, in height units.
    pub(super) fn total(&self) -> f64 {
        (self.tail + self.lanes.iter().map(|&l| f64::from(l)).sum::<f64>()) * UNSCALE
    }

    /// How many terms the sum holds that read no hole.
    pub(super) fn count(&self) -> f64 {
        self.tail_count + self.counts.iter().map(|&n| f64::from(n)).sum::<f64>()
    }
}

/// The f64 sum of the terms that read no hole, and their count: the tail
/// of a lane sum.
#[inline(always)]
fn tail_sum(terms: impl Iterator<Item = f32>) -> (f64, f64) {
    terms.filter(|d| !d.is_nan()).fold((0.0, 0.0), |(s, n), d| (s + f64::from(d), n + 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_x_kernel_is_the_wrapped_stencil_at_every_width() {
        // Each column's pair and crease, written with plain modular
        // indices, against the kernel's in-place loops and edge columns;
        // added onto earlier sums, as rows are.
        for w in 1..=11usize {
            let r: Vec<f32> = (0..w).map(|k| ((k * 7919 + 13) % 101) as f32 * 0.37 - 9.0).collect();
            let h = |k: usize| r[k % w];
            let earlier: Vec<f32> = (0..w).map(|k| k as f32 * 0.5).collect();
            // Whole, then in passes of 3 … W − 1 columns (a pass before
            // the last holds at least the 3 texels the next one needs).
            for pass in std::iter::once(w).chain(3..w) {
                let (mut vx, mut cx) = (earlier.clone(), earlier.clone());
                let mut edges = EdgeLog::default();
                for x0 in (0..w).step_by(pass) {
                    edges.next = 0;
                    let (nvx, ncx) = (&mut vec![0.0; w], &mut vec![0.0; w]);
                    let mut sums = XSums { vx: &mut vx, cx: &mut cx, nvx, ncx, crease: true, edges: &mut edges };
                    add_row_x(&r, &Cols { x0, x1: (x0 + pass).min(w), w }, 0, &mut sums);
                }
                for k in 0..w {
                    let value = (h(k + 1) - h(k)).abs();
                    let crease = ((h(k + 2) - h(k + 1)) - (h(k) - h(k + w - 1))).abs();
                    assert_eq!(vx[k], earlier[k] + value, "value of column {k}, W = {w}, passes of {pass}");
                    assert_eq!(cx[k], earlier[k] + crease, "crease of column {k}, W = {w}, passes of {pass}");
                }
            }
            let (mut vx, mut untouched) = (earlier.clone(), earlier.clone());
            let mut edges = EdgeLog::default();
            let (nvx, ncx) = (&mut vec![0.0; w], &mut vec![0.0; w]);
            let mut sums = XSums { vx: &mut vx, cx: &mut untouched, nvx, ncx, crease: false, edges: &mut edges };
            add_row_x(&r, &Cols::whole(w), 0, &mut sums);
            assert_eq!(untouched, earlier, "no creases asked for, W = {w}");
        }
    }
}
