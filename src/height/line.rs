//! The patch's sums along one line (a row or a column) through its
//! border, and their transposes, in time linear in the line whatever N.
//!
//! For a line of n values and a patch of radius r (N = 2r + 1), the box
//! and the ramp are
//!
//! ```text
//! box[x] = Σ_{k=−r..r} e[x + k]        ramp[x] = Σ_{k=−r..r} k · e[x + k]
//! ```
//!
//! where e is the line extended past its ends. Two kinds of extension
//! cover every border:
//!
//! * **periodic**, period P: e[t] = sign(t) · in[index(t)] for t in one
//!   period. Wrap (P = n) and mirror (P = 2(n − 1)) through the borders'
//!   index maps ([`Border::map`]); the transforms' even and odd extensions
//!   (`solve.rs`: whole-sample P = 2(n − 1), half-sample P = 2n, the sign
//!   −1 on reflected texels and 0 on those an odd reflection fixes).
//! * **clamp**: e[t] = in[clamp(t, 0, n − 1)], which is not periodic.
//!
//! A patch as wide as the period or wider (a large N on a small image)
//! holds q = N div P whole periods and a remainder of m = N mod P values:
//! the box is the remainder's sum plus q·T, T the period's sum, and the
//! ramp the remainder's first moment about x plus, for the whole periods
//! (starting at s_j = x − r + m + jP, j < q), T·Σ_j (s_j − x) + q·M, M the
//! period's first moment from that start. Clamp's patches read the first
//! and last value beyond the ends with weights in closed form (a count and
//! a sum of offsets); the rest is a window of the line itself, clipped to
//! it.
//!
//! Every sum over values is an interval of at most L of them (L = N, or
//! the period or the line where shorter), from sums over blocks of L
//! values (van Herk, Gil–Werman, as the forward fit sums floats): the
//! suffix of one block and the prefix of the next, or a difference within
//! one block, first moments taken about the block's start. So a sum is
//! rounded as one of at most 2L terms, and the cost is a few operations a
//! value whatever N. Patches of radius at most [`DIRECT_RADIUS`] add their
//! N values outright: at that size it is as cheap.
//!
//! Transposes: a periodic operator is R·C·E (E the extension to the
//! period, C the circular correlation, R the restriction to the line), so
//! its transpose is Eᵀ·Cᵀ·Rᵀ: the line in a period of zeros, the
//! correlation with the reversed kernel (the box itself, the ramp negated),
//! then each texel of the period added, with its sign, into the texel it
//! was read from. Clamp's window part is a band of the line (symmetric for
//! the box, antisymmetric for the ramp), and its edge weights become sums
//! added into the first and last value.
//!
//! A line is computed whole, in a fixed order: the same bits whatever the
//! thread count.

use crate::options::Border;
use crate::par::prelude::*;

/// Patches of radius up to this add their values outright.
pub(super) const DIRECT_RADIUS: usize = 3;

/// Columns gathered per task of [`columns`].
pub(super) const COLUMNS_PER_TASK: usize = 16;

/// How a line extends past its ends.
#[derive(Clone, Debug)]
enum Extension {
    /// One period: for each texel t of it, the line's index and the sign.
    Periodic(Vec<(usize, f64)>),
    /// The first and last value repeated.
    Clamp,
}

/// The box and ramp of a patch of radius r along a line of n values.
#[derive(Clone, Debug)]
pub(super) struct Line {
    n: usize,
    r: usize,
    ext: Extension,
}

/// Work space for a line's sums, reused from line to line.
#[derive(Default)]
pub(super) struct Scratch {
    /// The extended values: padded, or two periods.
    values: Vec<f64>,
    /// A transpose's sums on the period.
    box_out: Vec<f64>,
    ramp_out: Vec<f64>,
    blocks: Blocks,
}

impl Line {
    /// The line of `n` values read through `border` (the fit's index maps).
    pub(super) fn border(n: usize, border: Border, r: usize) -> Line {
        let periodic = |p: usize| Line::periodic(n, r, (0..p).map(|t| (border.map(t as isize, n), 1.0)).collect());
        match border {
            Border::Clamp if n >= 2 => Line { n, r, ext: Extension::Clamp },
            Border::Mirror if n > 2 => periodic(2 * (n - 1)),
            // One texel, or a mirrored pair: the line is its own period.
            _ => periodic(n),
        }
    }

    /// The line of `n` values extended periodically: `map[t]` is the line's
    /// index and the sign of texel t of the period.
    pub(super) fn periodic(n: usize, r: usize, map: Vec<(usize, f64)>) -> Line {
        debug_assert!(map.len() >= n && map.iter().all(|&(i, _)| i < n));
        Line { n, r, ext: Extension::Periodic(map) }
    }

    /// `boxed` = box and `ramped` = ramp of `input` (those asked for).
    pub(super) fn apply(
        &self,
        input: &[f64],
        boxed: Option<&mut [f64]>,
        ramped: Option<&mut [f64]>,
        scratch: &mut Scratch,
    ) {
        debug_assert_eq!(input.len(), self.n);
        let Scratch { values, blocks, .. } = scratch;
        match &self.ext {
            Extension::Periodic(map) => {
                let value = |t: usize| {
                    let (i, s) = map[t];
                    s * input[i]
                };
                periodic_sums(map.len(), value, self.n, self.r, boxed, ramped, values, blocks);
            }
            Extension::Clamp => {
                let (mut boxed, mut ramped) = (boxed, ramped);
                clamp_window(input, self.r, 1.0, boxed.as_deref_mut(), ramped.as_deref_mut(), values, blocks);
                let (first, last) = (input[0], input[self.n - 1]);
                for (out, k) in [(boxed, 0), (ramped, 1)] {
                    let Some(out) = out else { continue };
                    for (x, o) in out.iter_mut().enumerate() {
                        let (f, l) = (self.edge_weights(Edge::First, x)[k], self.edge_weights(Edge::Last, x)[k]);
                        if f != 0.0 {
                            *o += f * first;
                        }
                        if l != 0.0 {
                            *o += l * last;
                        }
                    }
                }
            }
        }
    }

    /// The transpose of [`Self::apply`]: `boxed` = boxᵀ and `ramped` =
    /// rampᵀ of `input` (those asked for).
    pub(super) fn apply_transposed(
        &self,
        input: &[f64],
        boxed: Option<&mut [f64]>,
        ramped: Option<&mut [f64]>,
        scratch: &mut Scratch,
    ) {
        debug_assert_eq!(input.len(), self.n);
        let Scratch { values, box_out, ramp_out, blocks } = scratch;
        match &self.ext {
            Extension::Periodic(map) => {
                let (p, n) = (map.len(), self.n);
                box_out.resize(p, 0.0);
                ramp_out.resize(p, 0.0);
                let (want_box, want_ramp) = (boxed.is_some(), ramped.is_some());
                // The line in a period of zeros.
                let value = |t: usize| if t < n { input[t] } else { 0.0 };
                periodic_sums(
                    p,
                    value,
                    p,
                    self.r,
                    want_box.then_some(&mut box_out[..]),
                    want_ramp.then_some(&mut ramp_out[..]),
                    values,
                    blocks,
                );
                // The reversed kernel: the box, and the ramp negated.
                for (out, sums, sign) in [(boxed, &*box_out, 1.0), (ramped, &*ramp_out, -1.0)] {
                    let Some(out) = out else { continue };
                    out.fill(0.0);
                    for (&(i, s), &v) in map.iter().zip(sums) {
                        out[i] += s * v;
                    }
                    if sign < 0.0 {
                        out.iter_mut().for_each(|o| *o = -*o);
                    }
                }
            }
            Extension::Clamp => {
                let (mut boxed, mut ramped) = (boxed, ramped);
                clamp_window(input, self.r, -1.0, boxed.as_deref_mut(), ramped.as_deref_mut(), values, blocks);
                // The edges' weights, summed into the first and last value.
                let (mut first, mut last) = ([0.0; 2], [0.0; 2]);
                for (x, &u) in input.iter().enumerate() {
                    let (f, l) = (self.edge_weights(Edge::First, x), self.edge_weights(Edge::Last, x));
                    for k in 0..2 {
                        first[k] += f[k] * u;
                        last[k] += l[k] * u;
                    }
                }
                let n = self.n;
                for (out, k) in [(boxed, 0), (ramped, 1)] {
                    if let Some(out) = out {
                        out[0] += first[k];
                        out[n - 1] += last[k];
                    }
                }
            }
        }
    }

    /// Clamp: the weights [box, ramp] with which texel x's patch reads the
    /// first value from beyond the start (offsets −r … −x − 1) or the
    /// last from beyond the end (offsets n − x … r).
    fn edge_weights(&self, edge: Edge, x: usize) -> [f64; 2] {
        let r = self.r;
        // The edge texel's distance from x: offsets d + 1 … r reach past it.
        let d = match edge {
            Edge::First => x,
            Edge::Last => self.n - 1 - x,
        };
        if d >= r {
            return [0.0; 2];
        }
        let count = (r - d) as f64;
        let sum = ((r * (r + 1) - d * (d + 1)) / 2) as f64;
        match edge {
            Edge::First => [count, -sum],
            Edge::Last => [count, sum],
        }
    }
}

/// Clamp's two ends.
#[derive(Clone, Copy)]
enum Edge {
    First,
    Last,
}

/// The box and ramp over x = 0 … `n_out` − 1 of the periodic sequence of
/// period `p` whose texel t of a period is `value(t)`, patch radius `r`.
#[allow(clippy::too_many_arguments)]
fn periodic_sums(
    p: usize,
    value: impl Fn(usize) -> f64,
    n_out: usize,
    r: usize,
    boxed: Option<&mut [f64]>,
    ramped: Option<&mut [f64]>,
    values: &mut Vec<f64>,
    blocks: &mut Blocks,
) {
    let n = 2 * r + 1;
    // The values from x = −r: texel (j − r) mod p of the period.
    let padded = |values: &mut Vec<f64>, len: usize| {
        values.clear();
        let mut t = (p - r % p) % p;
        for _ in 0..len {
            values.push(value(t));
            t = if t + 1 == p { 0 } else { t + 1 };
        }
    };
    if r <= DIRECT_RADIUS {
        padded(values, n_out + 2 * r);
        direct(values, r, 1.0, boxed, ramped);
        return;
    }
    let (q, m) = (n / p, n % p);
    if q == 0 {
        // The patch is shorter than the period: windows of the values
        // padded by r on either side, in blocks of N.
        padded(values, n_out + 2 * r);
        blocks.build(values, n);
        let sums = |x: usize| blocks.query(x, x + 2 * r, (x + r) as f64);
        fill(boxed, ramped, n_out, sums);
        return;
    }
    // Two periods, in blocks of one: the remainder's window and the whole
    // periods' moments are intervals of at most a period in them.
    values.clear();
    values.extend((0..2 * p).map(|t| value(if t < p { t } else { t - p })));
    blocks.build(values, p);
    let qf = q as f64;
    // The whole periods: q·T in the box; T·Σ_j (s_j − x) + q·M in the ramp,
    // Σ_j (s_j − x) = q(r + 1) − qP(q + 1)/2.
    let total = blocks.query(0, p - 1, 0.0).0;
    let (whole_box, whole_shift) = (qf * total, total * qf * (r as f64 + 1.0 - p as f64 * (qf + 1.0) / 2.0));
    let sums = |x: usize| {
        // The remainder [x − r, x − r + m − 1], from lo in the two periods.
        let lo = (x as isize - r as isize).rem_euclid(p as isize) as usize;
        let (s0, s1) = if m > 0 { blocks.query(lo, lo + m - 1, (lo + r) as f64) } else { (0.0, 0.0) };
        let start = (lo + m) % p;
        let whole_ramp = whole_shift + qf * blocks.query(start, start + p - 1, start as f64).1;
        (s0 + whole_box, s1 + whole_ramp)
    };
    fill(boxed, ramped, n_out, sums);
}

/// `boxed[x]` and `ramped[x]` (those asked for) = `sums(x)`, x < `n_out`.
#[inline(always)]
fn fill(boxed: Option<&mut [f64]>, ramped: Option<&mut [f64]>, n_out: usize, sums: impl Fn(usize) -> (f64, f64)) {
    match (boxed, ramped) {
        (Some(b), Some(ramp)) => {
            for (x, (b, ramp)) in b[..n_out].iter_mut().zip(&mut ramp[..n_out]).enumerate() {
                (*b, *ramp) = sums(x);
            }
        }
        (Some(b), None) => b[..n_out].iter_mut().enumerate().for_each(|(x, b)| *b = sums(x).0),
        (None, Some(ramp)) => ramp[..n_out].iter_mut().enumerate().for_each(|(x, v)| *v = sums(x).1),
        (None, None) => {}
    }
}

/// Clamp's window part: the box and `ramp_sign` × the ramp of the line
/// `input` with zeros beyond its ends (a window clipped to the line).
fn clamp_window(
    input: &[f64],
    r: usize,
    ramp_sign: f64,
    boxed: Option<&mut [f64]>,
    ramped: Option<&mut [f64]>,
    values: &mut Vec<f64>,
    blocks: &mut Blocks,
) {
    let n = input.len();
    if r <= DIRECT_RADIUS {
        values.clear();
        values.resize(r, 0.0);
        values.extend_from_slice(input);
        values.resize(n + 2 * r, 0.0);
        direct(values, r, ramp_sign, boxed, ramped);
        return;
    }
    blocks.build(input, (2 * r + 1).min(n));
    let sums = |x: usize| {
        let (s0, s1) = blocks.query(x.saturating_sub(r), (x + r).min(n - 1), x as f64);
        (s0, ramp_sign * s1)
    };
    fill(boxed, ramped, n, sums);
}

/// Each patch's values added outright: `padded` holds the values from
/// r before the first output to r after the last.
fn direct(padded: &[f64], r: usize, ramp_sign: f64, boxed: Option<&mut [f64]>, ramped: Option<&mut [f64]>) {
    let n = 2 * r + 1;
    if let Some(b) = boxed {
        for (b, window) in b.iter_mut().zip(padded.windows(n)) {
            *b = window.iter().sum();
        }
    }
    if let Some(ramp) = ramped {
        for (v, window) in ramp.iter_mut().zip(padded.windows(n)) {
            let mut s = 0.0;
            for d in 1..=r {
                s += d as f64 * (window[r + d] - window[r - d]);
            }
            *v = ramp_sign * s;
        }
    }
}

/// Sums over blocks of L values of a sequence: each value's prefix and
/// suffix in its block, with first moments about the block's start.
#[derive(Default)]
struct Blocks {
    l: usize,
    len: usize,
    prefix: Vec<[f64; 2]>,
    suffix: Vec<[f64; 2]>,
}

impl Blocks {
    fn build(&mut self, s: &[f64], l: usize) {
        let l = l.max(1);
        (self.l, self.len) = (l, s.len());
        self.prefix.resize(s.len(), [0.0; 2]);
        self.suffix.resize(s.len(), [0.0; 2]);
        for start in (0..s.len()).step_by(l) {
            let end = (start + l).min(s.len());
            let (mut a0, mut a1) = (0.0, 0.0);
            for (t, &v) in s[start..end].iter().enumerate() {
                a0 += v;
                a1 += t as f64 * v;
                self.prefix[start + t] = [a0, a1];
            }
            let (mut a0, mut a1) = (0.0, 0.0);
            for (t, &v) in s[start..end].iter().enumerate().rev() {
                a0 += v;
                a1 += t as f64 * v;
                self.suffix[start + t] = [a0, a1];
            }
        }
    }

    /// Σ s[t] and Σ (t − c) s[t] over t = lo … hi, at most L values.
    #[inline]
    fn query(&self, lo: usize, hi: usize, c: f64) -> (f64, f64) {
        debug_assert!(lo <= hi && hi < self.len && hi - lo < self.l);
        let start = lo - lo % self.l;
        let next = start + self.l;
        let [a0, a1] = self.suffix[lo];
        if hi < next {
            // Within one block: the suffix from lo less the one past hi.
            let (s0, s1) = if hi + 1 < next.min(self.len) {
                let [b0, b1] = self.suffix[hi + 1];
                (a0 - b0, a1 - b1)
            } else {
                (a0, a1)
            };
            (s0, s1 + (start as f64 - c) * s0)
        } else {
            let [p0, p1] = self.prefix[hi];
            (a0 + p0, (a1 + (start as f64 - c) * a0) + (p1 + (next as f64 - c) * p0))
        }
    }
}

/// A task's work space for [`rows`] and [`columns`]: the lines' scratch
/// and four lines of temporaries (as long as the lines the task sees).
#[derive(Default)]
pub(super) struct Work {
    pub(super) scratch: Scratch,
    pub(super) temps: [Vec<f64>; 4],
}

impl Work {
    fn new(len: usize) -> Work {
        Work { scratch: Scratch::default(), temps: std::array::from_fn(|_| vec![0.0; len]) }
    }
}

/// Rows per task of [`rows`].
const ROWS_PER_TASK: usize = 8;

/// Runs `f(y, rows, work)` on every row y of the planes `planes` (width
/// `w`, all of one size): `rows` holds row y of each. Blocks of rows run in
/// parallel.
pub(super) fn rows(w: usize, planes: &mut [&mut [f64]], f: impl Fn(usize, &mut [&mut [f64]], &mut Work) + Sync) {
    let Some(len) = planes.first().map(|p| p.len()) else { return };
    let chunk = w * ROWS_PER_TASK;
    let mut tasks: Vec<Vec<&mut [f64]>> = (0..len.div_ceil(chunk.max(1))).map(|_| Vec::new()).collect();
    for plane in planes.iter_mut() {
        for (task, piece) in tasks.iter_mut().zip(plane.chunks_mut(chunk)) {
            task.push(piece);
        }
    }
    tasks.into_par_iter().enumerate().for_each(|(b, mut pieces)| {
        let mut work = Work::new(w);
        let count = pieces.first().map_or(0, |p| p.len() / w);
        for k in 0..count {
            let mut row: Vec<&mut [f64]> = pieces.iter_mut().map(|p| &mut p[k * w..][..w]).collect();
            f(b * ROWS_PER_TASK + k, &mut row, &mut work);
        }
    });
}

/// Runs `f(x, inputs, outputs, work)` on every column x of planes of
/// width `w`: `inputs` holds column x of each of `ins`, and `f` fills
/// `outputs`, which go into column x of each of `outs` (every plane of the
/// same size). Blocks of columns run in parallel, each gathered into
/// columns and scattered back.
pub(super) fn columns(
    w: usize,
    ins: &[&[f64]],
    outs: &mut [&mut [f64]],
    f: impl Fn(usize, &[&[f64]], &mut [&mut [f64]], &mut Work) + Sync,
) {
    column_pass(w, ins, outs, false, f);
}

/// [`columns`] on planes read and written in place: `f(x, columns, work)`
/// gets column x of each of `planes` to read and change.
pub(super) fn columns_in_place(
    w: usize,
    planes: &mut [&mut [f64]],
    f: impl Fn(usize, &mut [&mut [f64]], &mut Work) + Sync,
) {
    column_pass(w, &[], planes, true, |x, _, outs, work| f(x, outs, work));
}

fn column_pass(
    w: usize,
    ins: &[&[f64]],
    outs: &mut [&mut [f64]],
    gather_outs: bool,
    f: impl Fn(usize, &[&[f64]], &mut [&mut [f64]], &mut Work) + Sync,
) {
    let Some(len) = outs.first().map(|o| o.len()) else { return };
    let h = len / w.max(1);
    // For each block of columns, its piece of every row of every output.
    let blocks = w.div_ceil(COLUMNS_PER_TASK);
    let mut pieces: Vec<Vec<Vec<&mut [f64]>>> =
        (0..blocks).map(|_| (0..outs.len()).map(|_| Vec::with_capacity(h)).collect()).collect();
    for (o, plane) in outs.iter_mut().enumerate() {
        for row in plane.chunks_mut(w) {
            for (b, piece) in row.chunks_mut(COLUMNS_PER_TASK).enumerate() {
                pieces[b][o].push(piece);
            }
        }
    }
    pieces.into_par_iter().enumerate().for_each(|(b, mut rows)| {
        let x0 = b * COLUMNS_PER_TASK;
        let cols = COLUMNS_PER_TASK.min(w - x0);
        let mut work = Work::new(h);
        // Column c of input i at gathered[i][c * h ..].
        let gathered: Vec<Vec<f64>> = ins
            .iter()
            .map(|plane| {
                let mut g = vec![0.0; cols * h];
                for (y, row) in plane.chunks(w).enumerate() {
                    for (c, &v) in row[x0..x0 + cols].iter().enumerate() {
                        g[c * h + y] = v;
                    }
                }
                g
            })
            .collect();
        let mut results: Vec<Vec<f64>> = rows
            .iter()
            .map(|pieces| {
                let mut g = vec![0.0; cols * h];
                if gather_outs {
                    for (y, piece) in pieces.iter().enumerate() {
                        for (c, &v) in piece.iter().enumerate() {
                            g[c * h + y] = v;
                        }
                    }
                }
                g
            })
            .collect();
        for c in 0..cols {
            let inputs: Vec<&[f64]> = gathered.iter().map(|g| &g[c * h..][..h]).collect();
            let mut outputs: Vec<&mut [f64]> = results.iter_mut().map(|r| &mut r[c * h..][..h]).collect();
            f(x0 + c, &inputs, &mut outputs, &mut work);
        }
        for (result, pieces) in results.iter().zip(rows.iter_mut()) {
            for (y, piece) in pieces.iter_mut().enumerate() {
                for (c, v) in piece.iter_mut().enumerate() {
                    *v = result[c * h + y];
                }
            }
        }
    });
}

/// Whether the orthogonal fit's re-fit of a `w` × `h` image with patch `n`
/// takes its patch sums from these line sums rather than the forward
/// fit's (`Patch::refit_by_lines` in `iterative.rs` says why): an image
/// less than 8N texels wide or tall. Here, below both the solver and its
/// memory estimate, which ask it.
pub(super) fn refit_by_lines(w: usize, h: usize, n: usize) -> bool {
    w.min(h) < 8 * n
}
