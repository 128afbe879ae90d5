//! The whole-image measure of [`check`](super::check): the planes' rows in
//! parallel blocks, each row read once for both axes, into [`Profiles`].

use crate::par::prelude::*;

use super::kernels::{
    CHUNK, Cols, EdgeLog, HOLE, JUDGE_SCALE, LEVELS, RowStack, Runs, XSums, finite, judged, unscaled, y_crease, y_value,
};
use super::score::{Cut, Profiles};
use crate::normal_map::ImageKind;

/// The whole-image measure of [`Profiles`]: planes in, rows in parallel.
impl Profiles {
    /// The bytes [`measure`](Self::measure) holds at most: the y profiles,
    /// and per thread (and once more while they are summed) two x
    /// profiles and a [`Block`].
    pub(super) fn bytes_needed(width: usize, height: usize) -> u64 {
        let (w, h, levels) = (width as u64, height as u64, LEVELS as u64);
        let block = 4 * 2 * w * 4 + levels * w * 4 + 2 * levels * w * 4;
        let per_thread = 2 * levels * w * 8 + block;
        2 * levels * h * 8 + (crate::par::current_num_threads() as u64 + 1) * per_thread
    }

    /// The first texel (x, y) in row order where a plane
    /// [`measure`](Self::measure) judges is NaN or infinite: R, G or B
    /// (a height map's luma of them, a normal map's components), or a
    /// gray image's first plane.
    pub(super) fn first_non_finite(planes: &[&[f32]], len: usize, width: usize) -> Option<(usize, usize)> {
        let judged = if planes.len() >= 3 { &planes[..3] } else { &planes[..1] };
        judged.iter().filter_map(|p| crate::samples::first_non_finite(&p[..len], width)).min_by_key(|&(x, y)| (y, x))
    }

    /// The profiles of the image made of the columns `cols` keeps of the
    /// rows `rows` keeps, in their order; texels equal to `nodata` (NaN:
    /// none) are holes, as non-finite ones are.
    pub(super) fn measure(planes: &[&[f32]], cols: Cut, rows: Cut, kind: ImageKind, nodata: f64) -> Profiles {
        let (w, h) = (cols.kept(), rows.kept());
        let signals: Vec<Signal> = match kind {
            ImageKind::Height if planes.len() >= 3 => {
                vec![Signal::Luma(planes[0], planes[1], planes[2], nodata)]
            }
            ImageKind::Normal if planes.len() >= 3 => planes[..3].iter().map(|p| Signal::Plane(p, nodata)).collect(),
            _ => vec![Signal::Plane(planes[0], nodata)],
        };
        let crease = kind == ImageKind::Height;
        // The y sums, then their counts of valid pairs, per row pair.
        let mut y = vec![[0.0f64; 4]; LEVELS * h];
        let zeros = || vec![[0.0f64; 4]; LEVELS * w];
        // Each task owns CHUNK row pairs of the y profiles and adds its rows
        // to a per-thread x profile; the x profiles are summed at the end.
        let (x, _) = crate::par::fold_reduce(
            y.par_chunks_mut(CHUNK * LEVELS).enumerate(),
            || (zeros(), Block::new(w)),
            |(mut x, mut block), (c, y)| {
                for signal in &signals {
                    block.measure(signal, cols, rows, c * CHUNK, y.len() / LEVELS, crease);
                    for (k, acc) in y.iter_mut().enumerate() {
                        acc[0] += block.vy[k];
                        acc[1] += block.cy[k];
                        acc[2] += block.nvy[k];
                        acc[3] += block.ncy[k];
                    }
                    for (k, acc) in x.iter_mut().enumerate() {
                        acc[0] += unscaled(block.vx[k]);
                        acc[1] += unscaled(block.cx[k]);
                        acc[2] += f64::from(block.nvx[k]);
                        acc[3] += f64::from(block.ncx[k]);
                    }
                }
                (x, block)
            },
            |(mut x, block), (x2, _)| {
                for (a, b) in x.iter_mut().zip(x2) {
                    for i in 0..4 {
                        a[i] += b[i];
                    }
                }
                (x, block)
            },
        );
        let part = |p: &[[f64; 4]], i: usize| -> Vec<f64> { p.iter().map(|s| s[i]).collect() };
        Profiles {
            vx: part(&x, 0),
            cx: part(&x, 1),
            vy: part(&y, 0),
            cy: part(&y, 1),
            nvx: part(&x, 2),
            ncx: part(&x, 3),
            nvy: part(&y, 2),
            ncy: part(&y, 3),
            signals: signals.len() as f64,
        }
    }
}

/// What is measured of one signal, before it is compared.
/// Each with the nodata value (NaN: none) whose texels are holes.
enum Signal<'a> {
    /// A plane as it is.
    Plane(&'a [f32], f64),
    /// The luma of three planes: a hole where any of them has one.
    Luma(&'a [f32], &'a [f32], &'a [f32], f64),
}

impl Signal<'_> {
    /// Writes the kept columns `cols` of image row `y` into `out`
    /// (`cols.kept()` values), times [`JUDGE_SCALE`], holes (non-finite
    /// values, the nodata value) as [`HOLE`].
    fn fill(&self, y: usize, cols: Cut, out: &mut [f32]) {
        let w = cols.len;
        let mut at = 0;
        for part in cols.ranges() {
            let out = &mut out[at..][..part.len()];
            at += part.len();
            let part = y * w + part.start..y * w + part.end;
            match *self {
                Signal::Plane(p, nodata) => {
                    for (o, &v) in out.iter_mut().zip(&p[part]) {
                        *o = if f64::from(v) == nodata { HOLE } else { judged(v) };
                    }
                }
                Signal::Luma(r, g, b, nodata) => {
                    let rows = r[part.clone()].iter().zip(&g[part.clone()]).zip(&b[part]);
                    // The weights carry the scale: w·S·r is S·(w·r) exactly.
                    let [wr, wg, wb] = [0.2126, 0.7152, 0.0722].map(|w: f32| w * JUDGE_SCALE);
                    for (o, ((&r, &g), &b)) in out.iter_mut().zip(rows) {
                        let hole = [r, g, b].iter().any(|&v| f64::from(v) == nodata);
                        *o = if hole { HOLE } else { finite(wr * r + wg * g + wb * b) };
                    }
                }
            }
        }
    }
}

/// One task's rows and its partial sums.
///
/// Rule of the loops: every row of the block is read for both axes while it
/// is in cache; x sums of up to CHUNK rows are kept in f32 (error ≲ 10⁻⁵
/// relative), then added into f64; y sums run in 8 f32 lanes so they
/// vectorise, each lane then added in f64.
struct Block {
    /// The last 4 of rows y0 − 1 … y0 + n + 1 (mod H) of one signal at
    /// every level (block row i in slot i mod 4): the n rows of the task
    /// and the halo its crease stencils need, as they come.
    rows: Runs,
    /// The runs of rows of the task's rows (CHUNK is a multiple of the
    /// longest run, so a task's runs are whole but at the image's end).
    stack: RowStack,
    /// Level-major, as in [`Profiles`], with their counts.
    vx: Vec<f32>,
    cx: Vec<f32>,
    nvx: Vec<f32>,
    ncx: Vec<f32>,
    /// Row after row, as in [`Profiles`], with their counts.
    vy: Vec<f64>,
    cy: Vec<f64>,
    nvy: Vec<f64>,
    ncy: Vec<f64>,
    /// Unused: a block's rows are measured whole.
    edges: EdgeLog,
}

impl Block {
    fn new(w: usize) -> Self {
        Block {
            rows: Runs::new(w, 4),
            stack: RowStack::new(w),
            vx: vec![0.0; LEVELS * w],
            cx: vec![0.0; LEVELS * w],
            nvx: vec![0.0; LEVELS * w],
            ncx: vec![0.0; LEVELS * w],
            vy: Vec::with_capacity(CHUNK * LEVELS),
            cy: Vec::with_capacity(CHUNK * LEVELS),
            nvy: Vec::with_capacity(CHUNK * LEVELS),
            ncy: Vec::with_capacity(CHUNK * LEVELS),
            edges: EdgeLog::default(),
        }
    }

    /// The sums of rows y0 … y0 + n − 1 (x pairs) and of row pairs
    /// y0 … y0 + n − 1 → next (y pairs) of the image made of the columns
    /// `kept_cols` keeps of the rows `kept_rows` keeps.
    fn measure(&mut self, signal: &Signal, kept_cols: Cut, kept_rows: Cut, y0: usize, n: usize, crease: bool) {
        let h = kept_rows.kept();
        self.vx.fill(0.0);
        self.cx.fill(0.0);
        self.nvx.fill(0.0);
        self.ncx.fill(0.0);
        self.vy.clear();
        self.cy.clear();
        self.nvy.clear();
        self.ncy.clear();
        // Block row i is image row (y0 − 1 + i) mod H. Each row is measured
        // as soon as it is made, while it and the three before it are in
        // cache: its x pairs (rows 1 … n), and the y pair whose stencil it
        // ends (pair i − 2, over rows i − 3 … i).
        let whole = Cols::whole(self.vx.len() / LEVELS);
        self.edges.next = 0;
        for i in 0..n + 3 {
            signal.fill(kept_rows.line((y0 + h - 1 + i) % h), kept_cols, self.rows.slot_mut(i % 4));
            self.rows.coarsen(i % 4, &whole);
            let rows = &self.rows;
            if (1..=n).contains(&i) {
                let mut sums = XSums {
                    vx: &mut self.vx,
                    cx: &mut self.cx,
                    nvx: &mut self.nvx,
                    ncx: &mut self.ncx,
                    crease,
                    edges: &mut self.edges,
                };
                self.stack.push(rows.row(0, i % 4), &whole, &mut sums);
            }
            if i >= 3 {
                for level in 0..LEVELS {
                    // Rows y − 1, y, y + 1, y + 2 for the pair y → y + 1.
                    let r = |j: usize| rows.row(level, j % 4);
                    let (value, count) = y_value(r(i - 2), r(i - 1));
                    self.vy.push(value);
                    self.nvy.push(count);
                    let (c, count) = if crease { y_crease(r(i - 3), r(i - 2), r(i - 1), r(i)) } else { (0.0, 0.0) };
                    self.cy.push(c);
                    self.ncy.push(count);
                }
            }
        }
        let mut sums = XSums {
            vx: &mut self.vx,
            cx: &mut self.cx,
            nvx: &mut self.nvx,
            ncx: &mut self.ncx,
            crease,
            edges: &mut self.edges,
        };
        self.stack.finish(&whole, &mut sums);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profiles_match_the_formulas() {
        // 4×3 image, hand-checked sums.
        let h = [0.0, 1.0, 3.0, 6.0, 0.0, 1.0, 3.0, 6.0, 1.0, 1.0, 1.0, 1.0];
        let p = Profiles::measure(&[&h], Cut::whole(4), Cut::whole(3), ImageKind::Height, f64::NAN);
        let y_level = |p: &[f64], level: usize| -> Vec<f64> { p.iter().skip(level).step_by(LEVELS).copied().collect() };
        // x pairs: rows 0, 1 give |1|, |2|, |3|, |−6|; row 2 gives 0.
        assert_eq!(p.vx[..4], [2.0, 4.0, 6.0, 12.0]);
        // Crease at k: (h(k+2) − h(k+1)) − (h(k) − h(k−1)); row 0 at k = 0:
        // (3 − 1) − (0 − 6) = 8; k = 1: 3 − 1 = 2; k = 2: −6 − 2 = −8;
        // k = 3: (1 − 0) − (6 − 3) = −2.
        assert_eq!(p.cx[..4], [16.0, 4.0, 16.0, 4.0]);
        // y pairs: row 0 → 1 equal; 1 → 2: |1|+0+|2|+|5|; 2 → 0 the same.
        assert_eq!(y_level(&p.vy, 0), [0.0, 8.0, 8.0]);
        // Level 1: rows 0 + 1 and row 2 alone are the runs along y for the
        // x pairs: 0 1 3 6 doubled, then 1 1 1 1; pairs |2|+0, |4|+0,
        // |6|+0, |−12|+0.
        assert_eq!(p.vx[4..8], [2.0, 4.0, 6.0, 12.0]);
        // Level 1 along x for the y pairs: runs (0 + 1, 3 + 6) = (1, 9)
        // twice, then (2, 2): row 1 → 2 gives |1| + |7| = 8, 2 → 0 too.
        assert_eq!(y_level(&p.vy, 1), [0.0, 8.0, 8.0]);
        // Level 2: the runs of 4 along x: 10, 10, 4: row 1 → 2 gives 6.
        assert_eq!(y_level(&p.vy, 2), [0.0, 6.0, 6.0]);
    }
}
