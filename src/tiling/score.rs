//! From the measure to the verdict: the lines the check reads ([`Cut`]),
//! the per-pair sums of each axis ([`Profiles`], [`Axis`]), and the score
//! of the seam against the interior pairs, level by level.

use super::kernels::LEVELS;
use super::report::{AxisReport, TilingOptions, TilingReport};
use crate::normal_map::ImageKind;

/// The reference is at least the `MIN_RANK`-th largest interior pair…
const MIN_RANK: usize = 4;

/// …and at least the top `RANK_FRACTION` of the interior pairs.
const RANK_FRACTION: f64 = 0.01;

/// A level is judged only when the seam holds at least this many of its
/// runs: fewer, and its per-line sums are too few draws to rank well.
const MIN_RUNS: usize = 8;

/// Lines of an axis read at each of its ends when the axis is longer than
/// twice this: the seam is compared with the pairs within them (see the
/// [module docs](crate::tiling#the-reference-lies-near-the-seam)). 256 keeps every
/// image up to 512 texels along an axis whole, the sizes the threshold was
/// chosen on.
pub const EDGE_LINES: usize = 256;

/// ε relative to the mean neighbour difference: above f32 rounding and
/// 16-bit quantisation noise, far below any visible seam.
const FLOOR_FRACTION: f64 = 1e-3;

/// The lines of one axis that the check reads: all of them, or, on an axis
/// longer than 2 · [`EDGE_LINES`], the first and the last `EDGE_LINES`
/// (the reference pairs lie within them; see the
/// [module docs](crate::tiling#the-reference-lies-near-the-seam)). Read in order,
/// the kept lines make an image whose wrap is the image's own seam and
/// whose pair across the cut, the *joint*, joins two lines that are not
/// neighbours and is judged by nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Cut {
    /// Lines of the axis.
    pub(super) len: usize,
    /// Lines kept at each end: `len` when all are kept.
    edge: usize,
}

impl Cut {
    /// The lines a check of an axis `len` long reads.
    pub(super) fn of(len: usize) -> Cut {
        Cut { len, edge: if len > 2 * EDGE_LINES { EDGE_LINES } else { len } }
    }

    /// Every line.
    pub(super) fn whole(len: usize) -> Cut {
        Cut { len, edge: len }
    }

    pub(super) fn is_whole(self) -> bool {
        self.edge == self.len
    }

    /// How many lines are kept.
    pub(super) fn kept(self) -> usize {
        if self.is_whole() { self.len } else { 2 * self.edge }
    }

    /// The image line of kept line `i`.
    pub(super) fn line(self, i: usize) -> usize {
        if i < self.edge { i } else { i + self.len - 2 * self.edge }
    }

    /// The kept lines, first end then last.
    pub(super) fn ranges(self) -> [std::ops::Range<usize>; 2] {
        if self.is_whole() { [0..self.len, self.len..self.len] } else { [0..self.edge, self.len - self.edge..self.len] }
    }

    /// The kept pair across the cut, which is no pair of the image.
    fn joint(self) -> Option<usize> {
        (!self.is_whole()).then(|| self.edge - 1)
    }
}

/// The per-pair sums of one axis, level after level, over the kept lines
/// of a [`Cut`]: pair i joins kept line i to i + 1, the last pair is the
/// seam; `line` texels are summed along each line.
pub(super) struct Axis {
    value: Vec<f64>,
    crease: Vec<f64>,
    /// How many pairs (creases) of valid texels each sum holds.
    nvalue: Vec<f64>,
    ncrease: Vec<f64>,
    /// Signals summed per texel: each valid texel pair counts once per
    /// signal.
    signals: f64,
    /// Pairs per level.
    pairs: usize,
    line: usize,
    /// The pair across the cut, judged by nothing.
    joint: Option<usize>,
}

impl Axis {
    /// The profile of every line of an axis (`pairs` per level) reduced to
    /// the lines `cut` keeps.
    fn kept(sums: [Vec<f64>; 4], signals: f64, line: usize, cut: Cut) -> Axis {
        let [value, crease, nvalue, ncrease] = sums;
        let pairs = value.len() / LEVELS;
        if cut.is_whole() {
            return Axis { value, crease, nvalue, ncrease, signals, pairs, line, joint: None };
        }
        // The pairs between kept lines are the image's pairs of the same
        // lines; those across the cut are taken from anywhere, unread.
        let gather = |p: &[f64]| -> Vec<f64> {
            (0..LEVELS).flat_map(|level| (0..cut.kept()).map(move |i| p[level * pairs + cut.line(i)])).collect()
        };
        Axis {
            value: gather(&value),
            crease: gather(&crease),
            nvalue: gather(&nvalue),
            ncrease: gather(&ncrease),
            signals,
            pairs: cut.kept(),
            line,
            joint: cut.joint(),
        }
    }

    /// The pairs that are the image's own (all but the joint).
    fn own_pairs(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.pairs).filter(|&k| Some(k) != self.joint)
    }
}

/// The per-pair sums of the [module docs](crate::tiling), summed over the signals,
/// at every level: `vx[l·W + k]`, `cx[l·W + k]` for the column pair
/// k → k+1 at level l (k = W−1 the wrap), `vy[y·LEVELS + l]`,
/// `cy[y·LEVELS + l]` for the row pair y → y+1 (row after row, so that
/// the parallel tasks own whole chunks of it). The crease sums stay 0 when
/// not asked for. `n*`, laid out alike, count the pairs (creases) of valid
/// texels each sum holds: a pair reading a hole adds to neither.
pub(super) struct Profiles {
    pub(super) vx: Vec<f64>,
    pub(super) cx: Vec<f64>,
    pub(super) vy: Vec<f64>,
    pub(super) cy: Vec<f64>,
    pub(super) nvx: Vec<f64>,
    pub(super) ncx: Vec<f64>,
    pub(super) nvy: Vec<f64>,
    pub(super) ncy: Vec<f64>,
    /// Signals summed per texel (3 for a normal map's R, G, B; else 1).
    pub(super) signals: f64,
}

impl Profiles {
    /// The x axis's profiles, measured over the columns `cols` keeps of
    /// every row (lines `line` rows long).
    pub(super) fn x_axis(&self, line: usize, cols: Cut) -> Axis {
        Axis {
            value: self.vx.clone(),
            crease: self.cx.clone(),
            nvalue: self.nvx.clone(),
            ncrease: self.ncx.clone(),
            signals: self.signals,
            pairs: self.vx.len() / LEVELS,
            line,
            joint: cols.joint(),
        }
    }

    /// The y axis's profiles, level after level, measured over the rows
    /// `measured` keeps (lines `line` columns long), reduced to the rows
    /// `kept` keeps (the same cut, or every row reduced).
    pub(super) fn y_axis(&self, line: usize, measured: Cut, kept: Cut) -> Axis {
        // The y profiles level after level, as the x ones are.
        let by_level = |p: &[f64]| -> Vec<f64> {
            (0..LEVELS).flat_map(|level| p.iter().skip(level).step_by(LEVELS).copied()).collect()
        };
        let sums = [&self.vy, &self.cy, &self.nvy, &self.ncy].map(|p| by_level(p));
        if measured == kept {
            let [value, crease, nvalue, ncrease] = sums;
            let pairs = value.len() / LEVELS;
            Axis { value, crease, nvalue, ncrease, signals: self.signals, pairs, line, joint: kept.joint() }
        } else {
            Axis::kept(sums, self.signals, line, kept)
        }
    }
}

/// The report from complete profiles of both axes (W, H ≥ 1): ε from the
/// mean |Δ| of level 0 over the pairs judged, then [`axis_score`] per axis.
pub(super) fn report(x: &Axis, y: &Axis, kind: ImageKind, opts: &TilingOptions) -> TilingReport {
    // ε from the mean |Δ| per texel over both axes (every pair's texels,
    // the seam's included: 2·W·H differences when all lines are kept),
    // times the line length each axis's profile sums over.
    // Holes: the valid pairs only (each counted once per signal); an image
    // of holes alone has no pairs, and ε its floor.
    let total: f64 = x.own_pairs().map(|k| x.value[k]).chain(y.own_pairs().map(|k| y.value[k])).sum();
    let valid = |a: &Axis| a.own_pairs().map(|k| a.nvalue[k]).sum::<f64>() / a.signals;
    let count = valid(x) + valid(y);
    let mean = if count > 0.0 { total / count } else { 0.0 };
    let eps_x = FLOOR_FRACTION * mean * x.line as f64 + 1e-30;
    let eps_y = FLOOR_FRACTION * mean * y.line as f64 + 1e-30;
    let crease = kind == ImageKind::Height;
    TilingReport {
        kind,
        x: axis_report(axis_score(x, crease, eps_x), opts),
        y: axis_report(axis_score(y, crease, eps_y), opts),
    }
}

/// The score of one axis: the largest of its levels' scores. Infinite
/// when level 0 cannot be judged (no pair across the seam, or none inside,
/// holds two valid texels): nothing shows that the axis tiles, so it is
/// not seamless (and `--border auto` mirrors it). A coarser level that
/// cannot be judged is left out.
fn axis_score(axis: &Axis, with_crease: bool, eps: f64) -> f64 {
    let n = axis.pairs;
    let mut score = 0.0f64;
    for level in (0..LEVELS).filter(|&level| level == 0 || axis.line >= MIN_RUNS << level) {
        let at = |p: &[f64]| -> Vec<f64> { p[level * n..][..n].to_vec() };
        let sums = [at(&axis.value), at(&axis.crease)];
        let counts = [at(&axis.nvalue), at(&axis.ncrease)];
        match level_score(sums, counts, axis.joint, with_crease, eps) {
            Some(s) => score = score.max(s),
            None if level == 0 => return f64::INFINITY,
            None => {}
        }
    }
    score
}

/// The score of one level from its value and crease profiles (seam last)
/// and their counts of valid pairs: the seam against the interior pairs,
/// those whose stencils neither cross the seam nor the `joint` of a cut.
/// A sum over fewer valid pairs than the level's fullest is scaled up to
/// that many (a sum over every pair is left as it is, bit for bit), and a
/// sum of no valid pair is no sample; `None` when the seam, or every
/// interior pair, is such a sum.
fn level_score(
    [value, crease]: [Vec<f64>; 2],
    [nvalue, ncrease]: [Vec<f64>; 2],
    joint: Option<usize>,
    with_crease: bool,
    eps: f64,
) -> Option<f64> {
    let n = value.len();
    if n < 2 {
        return Some(1.0);
    }
    // A value pair reads lines k, k + 1; a crease k − 1 … k + 2, so the
    // creases k = joint − 1 … joint + 1 reach across the cut.
    let apart = |k: usize, reach: usize| joint.is_none_or(|j| k + reach < j || k > j + reach);
    // The sum of pair k as if all the level's fullest count were valid.
    let scaled = |p: &[f64], counts: &[f64], full: f64, k: usize| {
        if counts[k] == full { p[k] } else { p[k] * (full / counts[k]) }
    };
    let ratio = |p: &[f64], counts: &[f64], ks: std::ops::Range<usize>, reach| -> Option<f64> {
        if counts[n - 1] == 0.0 {
            return None;
        }
        // The fullest of the pairs judged (the interior and the seam; the
        // streamed check leaves the other creases unmeasured).
        let judged: Vec<usize> = ks.filter(|&k| apart(k, reach)).collect();
        let full = judged.iter().chain([&(n - 1)]).map(|&k| counts[k]).fold(0.0, f64::max);
        let interior: Vec<f64> =
            judged.iter().filter(|&&k| counts[k] > 0.0).map(|&k| scaled(p, counts, full, k)).collect();
        (!interior.is_empty()).then(|| seam_ratio(scaled(p, counts, full, n - 1), interior, eps))
    };
    let mut score = ratio(&value, &nvalue, 0..n - 1, 0)?;
    if with_crease && n >= 4 {
        // A crease seam with no valid stencil leaves the value's verdict.
        if let Some(c) = ratio(&crease, &ncrease, 1..n - 2, 1) {
            score = score.max(c);
        }
    }
    Some(score)
}

/// (seam + ε) / (R + ε), R the k-th largest of `interior` (see module docs).
fn seam_ratio(seam: f64, mut interior: Vec<f64>, eps: f64) -> f64 {
    let n = interior.len();
    let k = MIN_RANK.max((n as f64 * RANK_FRACTION).ceil() as usize).min(n.div_ceil(2)).max(1);
    // The k-th largest is the (n − k)-th smallest: linear-time selection.
    let (_, reference, _) = interior.select_nth_unstable_by(n - k, f64::total_cmp);
    (seam + eps) / (*reference + eps)
}

/// The [`AxisReport`] of a score under `opts.threshold`.
fn axis_report(score: f64, opts: &TilingOptions) -> AxisReport {
    AxisReport { score, seamless: score <= opts.threshold }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_rank_is_clamped_for_short_axes() {
        // Three interior pairs: the rank is the median-or-above (2nd largest).
        assert_eq!(seam_ratio(2.0, vec![1.0, 2.0, 4.0], 0.0), 1.0);
        // One pair: itself.
        assert_eq!(seam_ratio(3.0, vec![1.5], 0.0), 2.0);
        // Many: the 4th largest while 1 % is fewer than 4.
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(seam_ratio(97.0, v, 0.0), 1.0);
        let v: Vec<f64> = (1..=1000).map(f64::from).collect();
        assert_eq!(seam_ratio(991.0, v, 0.0), 1.0);
    }

    #[test]
    fn a_level_counts_only_when_the_seam_holds_8_of_its_runs() {
        let axis = |value: Vec<f64>, crease: &[f64], line| Axis {
            pairs: value.len() / LEVELS,
            nvalue: vec![1.0; value.len()],
            ncrease: vec![1.0; crease.len()],
            signals: 1.0,
            value,
            crease: crease.to_vec(),
            line,
            joint: None,
        };
        // 8 pairs per level, all 1 but level 1's seam, 5 times larger.
        let n = 8;
        let mut value = vec![1.0; LEVELS * n];
        value[n + n - 1] = 5.0;
        let crease = vec![0.0; LEVELS * n];
        // Level 1 sums runs of 2: a seam of 15 texels holds 7, of 16 holds 8.
        assert_eq!(axis_score(&axis(value.clone(), &crease, 15), true, 0.0), 1.0);
        assert_eq!(axis_score(&axis(value, &crease, 16), true, 0.0), 5.0);
        // The crease counts at every level too (interior creases 1 … n − 3).
        let mut crease = vec![1.0; LEVELS * n];
        crease[5 * n + n - 1] = 3.0;
        assert_eq!(axis_score(&axis(vec![1.0; LEVELS * n], &crease, 256), true, 0.0), 3.0);
        assert_eq!(axis_score(&axis(vec![1.0; LEVELS * n], &crease, 255), true, 0.0), 1.0);
        assert_eq!(axis_score(&axis(vec![1.0; LEVELS * n], &crease, 256), false, 0.0), 1.0);
    }
}
