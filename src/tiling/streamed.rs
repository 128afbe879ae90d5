//! [`HeightSeams`]: the tiling check of a height map fed row by row, in
//! memory O(W + H), and [`RowSeams`], the profiles it keeps.

use super::kernels::{
    CHUNK, Cols, EdgeLog, HOLE, LEVELS, Lanes, RowStack, Runs, UNSCALE, XSums, flush_cols, judged, y_crease, y_value,
};
use super::report::{TilingOptions, TilingReport};
use super::score::{Cut, Profiles, report};
use crate::Samples;
use crate::normal_map::ImageKind;
use crate::samples::try_vec;
use crate::{Error, Result};

/// The tiling check of a height map fed one row at a time, top to bottom:
/// [`check`](super::check) for an image too large to hold, such as one streamed from a
/// decoder, or held in pieces (a chunked array) of which only the edges
/// need be read.
///
/// Gives the report of
/// `check(&[&heights], width, height, &opts.with_kind(KindChoice::Height))`:
/// the same profiles and scores (see [below](#same-as-check)), judged as
/// [`ImageKind::Height`] whatever `opts.kind` says. For a colour image, push
/// rows of its luma (0.2126 R + 0.7152 G + 0.0722 B, as `check` takes it).
///
/// Two ways to feed it:
/// * whole rows, top to bottom: [`push_row`](Self::push_row),
///   [`push_heights`](Self::push_heights), [`push_samples`](Self::push_samples);
/// * only the lines the check reads (see the
///   [module docs](crate::tiling#the-reference-lies-near-the-seam)): every row's
///   [`edge_columns`](Self::edge_columns), top to bottom, through
///   [`push_edge_columns`](Self::push_edge_columns), and the
///   [`edge_rows`](Self::edge_rows) whole, in order, through
///   [`push_edge_rows`](Self::push_edge_rows) (in any interleaving with
///   the columns). On an image more than 512 texels wide and tall, that is
///   the 256 columns and 256 rows at each edge: a caller holding the image
///   in pieces reads those strips and nothing else.
///
/// Memory is O(W + H), never the image: at each of the 6 levels of the
/// [module docs](crate::tiling#levels-the-seam-smoothed-along-itself), the x
/// profiles (4 values a kept column) and the y profiles (2 a kept row);
/// the first 2 rows and the last 4 with their runs along x (about 2 W
/// each; the pairs that cross the y wrap, value H−1 → 0 and crease H−2,
/// H−1, 0, 1, need rows H−2, H−1, 0 and 1); one run of rows in progress per
/// level (W each); and the rows pushed but not yet measured, up to 32
/// (fewer when 32 rows would take more than 4 MiB). Every 32nd row measures
/// the rows that wait, O(W) work a row on the caller's thread, in
/// branch-free loops over slices that vectorise, 1024 columns at a time;
/// [`finish`](Self::finish) measures the rest, adds the pairs across the
/// wrap and selects the references, O(W + H).
///
/// # Same as check
///
/// The per-line sums are computed by the same kernels as in `check`, in the
/// same order, at every level (the runs of rows and of texels are added in
/// the same order too): the y sums and the x sums of each block of 32 rows
/// (kept in f32 by `check`, and so here) are bit for bit the same; only the
/// f64 total over the blocks is added in another order (`check` adds them
/// per thread). Those f64 sums of f32 values are exact unless the block
/// sums span about 2²⁹ in size, so the scores are in practice identical
/// (they were in every test) and at worst about 10⁻¹⁵ apart relative;
/// verdicts can then differ only for a score that close to the threshold.
/// The two ways of feeding give the same bits.
///
/// ```
/// use normalfit::normal_map::KindChoice;
/// use normalfit::tiling::{check, HeightSeams, TilingOptions};
/// // A ramp along x, fed row by row.
/// let (w, h) = (64, 32);
/// let ramp: Vec<f32> = (0..w * h).map(|k| (k % w) as f32 / (w - 1) as f32).collect();
/// let mut seams = HeightSeams::new(w, h)?;
/// for row in ramp.chunks_exact(w) {
///     seams.push_row(row)?;
/// }
/// let opts = TilingOptions::new();
/// let report = seams.finish(&opts)?;
/// assert!(!report.x.seamless && report.y.seamless);
/// let whole = check(&[&ramp], w, h, &opts.with_kind(KindChoice::Height))?;
/// assert!((report.x.score / whole.x.score - 1.0).abs() < 1e-12);
/// # Ok::<(), normalfit::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct HeightSeams {
    width: usize,
    height: usize,
    /// The columns and rows the check reads.
    cols: Cut,
    rows: Cut,
    /// The x profiles, fed the kept columns of every row. When every
    /// column is kept, it is fed whole rows and gives the y profiles too.
    x: RowSeams,
    /// The y profiles, fed the kept rows whole: when some columns are not
    /// kept.
    y: Option<RowSeams>,
    /// Rows fed to `y`.
    y_rows: usize,
    /// A row's kept columns, converted.
    kept: Vec<f32>,
    /// Whether a NaN or infinite height is an error rather than a hole.
    refuse_non_finite: bool,
    /// The nodata value whose texels are holes; NaN: none.
    nodata: f64,
}

impl HeightSeams {
    /// A check of a `width` × `height` height map, no rows in yet.
    ///
    /// Refused when the check's memory ([`bytes_needed`](Self::bytes_needed))
    /// is more than the process may still take (under `ulimit -v` and the
    /// like), instead of aborting on a failed allocation: an image 2^24
    /// texels wide or tall needs 1.6 to 3.7 GB for it.
    ///
    /// Errors: [`Error::Limits`] saying how much is needed,
    /// [`Error::InvalidOption`] when a side is 0 or `width * height`
    /// overflows.
    pub fn new(width: usize, height: usize) -> Result<Self> {
        // An image without texels has no seams to judge (the fit's rule).
        crate::fit::checked_len(width, height)?;
        crate::io::check_memory("the tiling check", Self::bytes_needed(width, height))?;
        let (cols, rows) = (Cut::of(width), Cut::of(height));
        let y = (!cols.is_whole()).then(|| RowSeams::new(width, rows.kept()));
        Ok(HeightSeams {
            width,
            height,
            cols,
            rows,
            x: RowSeams::new(cols.kept(), height),
            y,
            y_rows: 0,
            kept: Vec::with_capacity(cols.kept()),
            refuse_non_finite: false,
            nodata: f64::NAN,
        })
    }

    /// The same check with holes at the texels equal to `nodata` (as
    /// pushed: a row's f32 value, a sample's stored value), besides the
    /// non-finite ones: the pairs that read one are skipped (see the
    /// [module docs](crate::tiling#holes)). `None` or NaN: only non-finite
    /// texels are holes.
    #[must_use]
    pub fn with_nodata(mut self, nodata: Option<f64>) -> Self {
        self.nodata = nodata.unwrap_or(f64::NAN);
        self
    }

    /// The same check refusing a NaN or infinite height among the lines it
    /// reads, as [`check`](super::check) refuses one anywhere: each push
    /// holding one fails with [`Error::NonFiniteHeight`] naming its texel
    /// in the image (the first in the order pushed), and pushes nothing.
    /// Without it such heights are holes (the rule `--border auto` needs
    /// for maps with nodata holes). Python's `normalfit.dask.check_tiling`
    /// refuses them, as `normalfit.check_tiling` of the whole array does.
    #[must_use]
    pub fn refusing_non_finite(mut self) -> Self {
        self.refuse_non_finite = true;
        self
    }

    /// [`Error::NonFiniteHeight`] for the first NaN or infinite height of
    /// `count` rows of `per_row` values, converted to the contract's f32
    /// units, when this check refuses them; `at(row, column)` places a
    /// value in the image.
    fn refuse_non_finite<H: crate::Sample>(
        &self,
        texels: &[H],
        per_row: usize,
        count: usize,
        at: impl Fn(usize, usize) -> (usize, usize),
    ) -> Result<()> {
        if !self.refuse_non_finite || per_row == 0 {
            return Ok(());
        }
        let mut row = try_vec(per_row)?;
        row.resize(per_row, 0.0f32);
        for (i, part) in texels.chunks_exact(per_row).take(count).enumerate() {
            convert_row(part, &mut row, f64::NAN);
            if let Some((k, _)) = crate::samples::first_non_finite(&row, per_row) {
                let (x, y) = at(i, k);
                return Err(Error::NonFiniteHeight { x, y });
            }
        }
        Ok(())
    }

    /// The bytes a check of a `width` × `height` image holds (its profiles,
    /// row buffers and pending rows, at every level): about 450 a column
    /// and 192 a row.
    #[must_use]
    pub fn bytes_needed(width: usize, height: usize) -> u64 {
        let (cols, rows) = (Cut::of(width), Cut::of(height));
        let y = if cols.is_whole() { 0 } else { RowSeams::bytes_needed(width, rows.kept()) };
        RowSeams::bytes_needed(cols.kept(), height) + y + 4 * cols.kept() as u64
    }

    /// The columns of every row that the check reads, as two ranges (the
    /// second empty when the first is the whole row): what
    /// [`push_edge_columns`](Self::push_edge_columns) takes, in this order.
    #[must_use]
    pub fn edge_columns(&self) -> [std::ops::Range<usize>; 2] {
        self.cols.ranges()
    }

    /// The rows that [`push_edge_rows`](Self::push_edge_rows) takes whole,
    /// as two ranges: the first and last 256 rows of a tall image, all
    /// rows of a short one, none when [`edge_columns`](Self::edge_columns)
    /// is every column (the whole rows pushed as columns serve the y axis
    /// too).
    #[must_use]
    pub fn edge_rows(&self) -> [std::ops::Range<usize>; 2] {
        if self.y.is_some() { self.rows.ranges() } else { [0..0, 0..0] }
    }

    /// The rows pushed so far: whole rows, or rows of edge columns.
    #[must_use]
    pub fn rows(&self) -> usize {
        self.x.rows
    }

    /// Adds the next row, `width` heights. Non-finite values and the
    /// [nodata value](Self::with_nodata) are holes (unlike
    /// [`check`](super::check) without a nodata value, which refuses
    /// them): this check settles `--border auto` for maps with holes.
    ///
    /// Errors: [`Error::BufferSize`] when `row.len() != width`,
    /// [`Error::InvalidOption`] when all `height` rows are in already, or
    /// rows came through [`push_edge_rows`](Self::push_edge_rows) too; the
    /// check is unchanged then.
    pub fn push_row(&mut self, row: &[f32]) -> Result<()> {
        let w = self.width;
        if row.len() != w {
            return Err(Error::BufferSize { expected: w, actual: row.len() });
        }
        self.check_room(1)?;
        let y = self.x.rows;
        self.refuse_non_finite(row, w, 1, |_, x| (x, y))?;
        let nodata = self.nodata;
        // Without a nodata value (NaN equals nothing) the row is not
        // searched: a search of every texel cost as much as the check's
        // own sums of the 4096² rows it reads a quarter of.
        if !nodata.is_nan() && row.iter().any(|&v| f64::from(v) == nodata) {
            let mut holes = try_vec(w)?;
            holes.extend(row.iter().map(|&v| if f64::from(v) == nodata { HOLE } else { v }));
            self.push_judged(&holes)
        } else {
            self.push_judged(row)
        }
    }

    /// Adds the next row (its length and room checked by the caller), its
    /// holes NaN.
    fn push_judged(&mut self, row: &[f32]) -> Result<()> {
        let y = self.x.rows;
        let is_kept = |y: usize| self.rows.ranges().iter().any(|r| r.contains(&y));
        if self.y.is_some() && is_kept(y) && self.rows.line(self.y_rows) != y {
            return Err(Error::InvalidOption("the tiling check was given edge rows and whole rows both".into()));
        }
        if let Some(seams) = self.y.as_mut().filter(|_| is_kept(y)) {
            seams.push_row(row);
            self.y_rows += 1;
        }
        if self.cols.is_whole() {
            self.x.push_row(row);
        } else {
            self.kept.clear();
            for part in self.cols.ranges() {
                self.kept.extend_from_slice(&row[part]);
            }
            self.x.push_row(&self.kept);
        }
        Ok(())
    }

    /// Pushes every row of `heights`, an image of this check's width held
    /// whole in the samples' own type, converting one row at a time (no
    /// `f32` copy of the image).
    ///
    /// Errors: [`Error::BufferSize`] when `heights` is not whole rows of
    /// this width, or holds more rows than are still to come (nothing is
    /// pushed then).
    pub fn push_samples(&mut self, heights: &Samples) -> Result<()> {
        crate::samples::with_slice!(heights, s => self.push_heights(s))
    }

    /// Pushes every row of `heights`, whole rows of this check's width in
    /// any [`Sample`](crate::Sample) type (a caller's array, such as the
    /// Python package's), converting one row at a time.
    ///
    /// Errors: as [`push_samples`](Self::push_samples).
    pub fn push_heights<H: crate::Sample>(&mut self, heights: &[H]) -> Result<()> {
        let w = self.width;
        let count = whole_rows(heights.len(), w, self.height - self.x.rows)?;
        let first = self.x.rows;
        self.refuse_non_finite(heights, w, count, |i, x| (x, first + i))?;
        let mut row = try_vec(w)?;
        row.resize(w, 0.0f32);
        for rows in heights.chunks_exact(w.max(1)).take(count) {
            convert_row(rows, &mut row, self.nodata);
            self.check_room(1)?;
            self.push_judged(&row)?;
        }
        Ok(())
    }

    /// Pushes the [`edge_columns`](Self::edge_columns) of the next rows:
    /// rows of that many values (the first range's columns, then the
    /// second's), top to bottom, in any [`Sample`](crate::Sample) type.
    ///
    /// Errors: [`Error::BufferSize`] when `texels` is not whole rows of
    /// edge columns, or holds more rows than are still to come (nothing is
    /// pushed then).
    pub fn push_edge_columns<H: crate::Sample>(&mut self, texels: &[H]) -> Result<()> {
        let n = self.cols.kept();
        let count = whole_rows(texels.len(), n, self.height - self.x.rows)?;
        let (first, cols) = (self.x.rows, self.cols);
        self.refuse_non_finite(texels, n, count, |i, k| (cols.line(k), first + i))?;
        let mut row = std::mem::take(&mut self.kept);
        row.resize(n, 0.0);
        for part in texels.chunks_exact(n.max(1)).take(count) {
            convert_row(part, &mut row, self.nodata);
            self.x.push_row(&row);
        }
        self.kept = row;
        Ok(())
    }

    /// Pushes the next of the [`edge_rows`](Self::edge_rows), whole rows of
    /// this check's width in order, in any [`Sample`](crate::Sample) type.
    ///
    /// Errors: [`Error::BufferSize`] when `heights` is not whole rows, or
    /// holds more than the edge rows still to come (nothing is pushed
    /// then).
    pub fn push_edge_rows<H: crate::Sample>(&mut self, heights: &[H]) -> Result<()> {
        let w = self.width;
        let Some(left) = self.y.as_ref().map(|y| y.height - y.rows) else {
            return match heights.is_empty() {
                true => Ok(()),
                false => Err(Error::BufferSize { expected: 0, actual: heights.len() }),
            };
        };
        let count = whole_rows(heights.len(), w, left)?;
        let (pushed, rows) = (self.y_rows, self.rows);
        self.refuse_non_finite(heights, w, count, |i, x| (x, rows.line(pushed + i)))?;
        let nodata = self.nodata;
        let Some(y) = self.y.as_mut() else { return Ok(()) };
        let mut row = try_vec(w)?;
        row.resize(w, 0.0f32);
        for rows in heights.chunks_exact(w.max(1)).take(count) {
            convert_row(rows, &mut row, nodata);
            y.push_row(&row);
        }
        self.y_rows += count;
        Ok(())
    }

    /// Fails unless `n` more rows may come.
    fn check_room(&self, n: usize) -> Result<()> {
        if self.x.rows + n > self.height {
            return Err(Error::InvalidOption(format!("all {} rows of the tiling check are in already", self.height)));
        }
        Ok(())
    }

    /// The report, judged as [`ImageKind::Height`] under `opts.threshold`,
    /// once every row (or every row's edge columns, and the edge rows) is
    /// in.
    ///
    /// Errors: [`Error::InvalidOption`] saying how many rows are in, when
    /// some are missing (a stream cut short is not the image).
    pub fn finish(self, opts: &TilingOptions) -> Result<TilingReport> {
        let (w, h) = (self.width, self.height);
        let y_needed = self.y.as_ref().map_or(0, |y| y.height);
        if self.x.rows < h || self.y_rows < y_needed {
            let got = if self.x.rows < h { self.x.rows } else { self.y_rows };
            let of = if self.x.rows < h { h } else { y_needed };
            let what = if self.x.rows < h { "rows" } else { "edge rows" };
            return Err(Error::InvalidOption(format!("the tiling check has {got} of its {of} {what}")));
        }
        let all_rows = Cut::whole(h);
        let px = self.x.profiles().expect("texels, so profiles");
        let x = px.x_axis(h, self.cols);
        let y = match self.y {
            Some(y) => y.profiles().expect("texels, so profiles").y_axis(w, self.rows, self.rows),
            None => px.y_axis(w, all_rows, self.rows),
        };
        Ok(report(&x, &y, ImageKind::Height, opts))
    }
}

/// How many rows of `per_row` values `len` values make, refused when not
/// whole or more than `left`.
fn whole_rows(len: usize, per_row: usize, left: usize) -> Result<usize> {
    // Rows of no values: none, unless values came.
    let count = len.checked_div(per_row).unwrap_or(if len == 0 { 0 } else { usize::MAX });
    if (per_row > 0 && !len.is_multiple_of(per_row)) || count > left {
        return Err(Error::BufferSize { expected: left * per_row, actual: len });
    }
    Ok(count)
}

/// Converts a row of samples into the contract's f32 units, the samples
/// equal to `nodata` (as stored: the fit's rule) made holes, NaN.
fn convert_row<H: crate::Sample>(from: &[H], to: &mut [f32], nodata: f64) {
    for (o, &v) in to.iter_mut().zip(from) {
        *o = if v.to_f64() == nodata { HOLE } else { crate::samples::contract(v) as f32 };
    }
}

/// The profiles of a height map fed one row at a time, top to bottom, in
/// memory O(W + H): the engine of [`HeightSeams`], which feeds it the
/// lines the check reads (see [`HeightSeams`] for the memory and the order
/// of the sums).
#[derive(Clone, Debug)]
struct RowSeams {
    width: usize,
    height: usize,
    /// Rows pushed so far, the pending ones included.
    rows: usize,
    /// Rows pushed and not yet measured, judged (times [`JUDGE_SCALE`](super::kernels::JUDGE_SCALE),
    /// non-finite values as 0): `pending_rows` of `width` values. They are
    /// measured [`TILE_COLS`] columns at a time, so that each pass's rows
    /// and sums stay in a core's cache however wide the image.
    pending: Vec<f32>,
    pending_rows: usize,
    /// Rows measured at once: up to [`CHUNK`], fewer for very wide images.
    block_rows: usize,
    /// Columns per pass: [`TILE_COLS`] (tests change it).
    tile_cols: usize,
    /// Whether the kernels use the processor's widest vectors (tests turn
    /// it off to compare with the baseline build).
    widest: bool,
    /// Rows 0 and 1 as far as pushed (non-finite values as 0), at every
    /// level.
    first: Runs,
    /// The last 4 rows measured, at every level: row y in slot y mod 4.
    ring: Runs,
    /// The runs of rows that the x pairs of the coarser levels compare.
    stack: RowStack,
    /// What a pass over some columns leaves to the passes over the others.
    edges: EdgeLog,
    /// The y sums of the pending rows in progress, row after row, level
    /// after level: value then crease.
    lanes: Vec<[Lanes; 2]>,
    /// The x sums of the current block of [`CHUNK`] rows, in f32 as in
    /// the whole-image check's `Block`, level after level.
    vx_block: Vec<f32>,
    cx_block: Vec<f32>,
    /// Their counts of valid pairs.
    nvx_block: Vec<f32>,
    ncx_block: Vec<f32>,
    /// The profiles of the [module docs](crate::tiling), laid out as in
    /// [`Profiles`]; x over the finished blocks. The crease pairs 0 and
    /// H − 2 stay 0: their stencils cross the wrap, but they are neither
    /// the seam nor interior pairs, so no score reads them.
    vx: Vec<f64>,
    cx: Vec<f64>,
    vy: Vec<f64>,
    cy: Vec<f64>,
    /// Their counts of valid pairs, as in [`Profiles`].
    nvx: Vec<f64>,
    ncx: Vec<f64>,
    nvy: Vec<f64>,
    ncy: Vec<f64>,
}

impl RowSeams {
    /// The profiles of a `width` × `height` image, no rows in yet (the
    /// caller has checked the memory, [`bytes_needed`](Self::bytes_needed)).
    fn new(width: usize, height: usize) -> Self {
        let block_rows = pending_rows_for(width, height);
        RowSeams {
            width,
            height,
            rows: 0,
            pending: vec![0.0; block_rows * width],
            pending_rows: 0,
            block_rows,
            tile_cols: TILE_COLS,
            widest: true,
            first: Runs::new(width, 2.min(height)),
            ring: Runs::new(width, 4.min(height)),
            stack: RowStack::new(width),
            edges: EdgeLog::default(),
            lanes: vec![[Lanes::default(); 2]; block_rows * LEVELS],
            vx_block: vec![0.0; LEVELS * width],
            cx_block: vec![0.0; LEVELS * width],
            nvx_block: vec![0.0; LEVELS * width],
            ncx_block: vec![0.0; LEVELS * width],
            vx: vec![0.0; LEVELS * width],
            cx: vec![0.0; LEVELS * width],
            vy: vec![0.0; LEVELS * height],
            cy: vec![0.0; LEVELS * height],
            nvx: vec![0.0; LEVELS * width],
            ncx: vec![0.0; LEVELS * width],
            nvy: vec![0.0; LEVELS * height],
            ncy: vec![0.0; LEVELS * height],
        }
    }

    /// The bytes a check of a `width` × `height` image holds (its profiles,
    /// row buffers and pending rows, at every level, with the counts of
    /// valid pairs): about 450 a column and 192 a row.
    fn bytes_needed(width: usize, height: usize) -> u64 {
        let (w, h, levels) = (width as u64, height as u64, LEVELS as u64);
        // One row at every level: ⌈W / 2^l⌉ values each.
        let row_levels: u64 = (0..LEVELS).map(|l| w.div_ceil(1 << l)).sum();
        let runs = (2.min(h) + 4.min(h)) * row_levels * 4;
        let x_sums = levels * w * 4 + 4 * levels * w * 4 + 4 * levels * w * 8;
        let pending = pending_rows_for(width, height) as u64 * w * 4;
        runs + x_sums + pending + 4 * levels * h * 8
    }

    /// Adds the next row, `width` heights (the caller has checked its
    /// length and that rows are still to come). Non-finite values count as
    /// 0, as in [`check`](super::check).
    fn push_row(&mut self, row: &[f32]) {
        let w = self.width;
        debug_assert!(row.len() == w && self.rows < self.height);
        self.rows += 1;
        if w == 0 {
            return;
        }
        // Holes (non-finite) stay NaN.
        for (o, &v) in self.pending[self.pending_rows * w..][..w].iter_mut().zip(row) {
            *o = judged(v);
        }
        self.pending_rows += 1;
        if self.pending_rows == self.block_rows {
            self.measure_pending(false);
        }
    }

    /// Measures the pending rows, [`TILE_COLS`] columns at a time: each
    /// pass runs every row's kernels over its columns, so the kernels add
    /// into every sum in the order of the rows, as a pass over whole rows
    /// would, and give the same bits. With `last`, the runs of rows cut
    /// short by the end are closed too, as [`check`](super::check) ends them.
    fn measure_pending(&mut self, last: bool) {
        if self.widest {
            pulp::Arch::new().dispatch(MeasurePending { seams: self, last });
        } else {
            pulp::WithSimd::with_simd(MeasurePending { seams: self, last }, pulp::Scalar::new());
        }
    }

    /// [`measure_pending`](Self::measure_pending), inlined into the
    /// dispatch so that it is compiled for each instruction set.
    #[inline(always)]
    fn measure_pending_here(&mut self, last: bool) {
        let (w, n) = (self.width, self.pending_rows);
        let y0 = self.rows - n;
        let counts = self.stack.count;
        self.lanes[..n * LEVELS].fill([Lanes::default(); 2]);
        for x0 in (0..w).step_by(self.tile_cols) {
            let cols = Cols { x0, x1: (x0 + self.tile_cols).min(w), w };
            // Every pass replays the same runs of rows.
            self.stack.count = counts;
            self.edges.next = 0;
            for i in 0..n {
                let y = y0 + i;
                let slot = y % 4;
                self.ring.slot_mut(slot)[cols.range()].copy_from_slice(&self.pending[i * w..][cols.range()]);
                self.ring.coarsen(slot, &cols);
                if y < 2 {
                    self.first.copy_slot(y, &self.ring, slot, &cols);
                }
                let mut sums = XSums {
                    vx: &mut self.vx_block,
                    cx: &mut self.cx_block,
                    nvx: &mut self.nvx_block,
                    ncx: &mut self.ncx_block,
                    crease: true,
                    edges: &mut self.edges,
                };
                self.stack.push(self.ring.row(0, slot), &cols, &mut sums);
                if (y + 1).is_multiple_of(CHUNK) {
                    self.flush(&cols);
                }
                // The y pairs whose stencils end at this row and do not wrap.
                let ring = &self.ring;
                for (level, lanes) in self.lanes[i * LEVELS..][..LEVELS].iter_mut().enumerate() {
                    let r = |j: usize| ring.row(level, j % 4);
                    let part = cols.at_level(level, ring.widths[level]);
                    if y >= 3 {
                        // Both sums in one loop: two chains of additions
                        // that do not wait for each other.
                        let [value, crease] = lanes;
                        Lanes::add_both(value, crease, part, [r(y - 3), r(y - 2), r(y - 1), r(y)]);
                    } else if y >= 1 {
                        lanes[0].add(part, [r(y - 1), r(y)], |[b, c]| (c - b).abs());
                    }
                }
            }
            if last {
                let mut sums = XSums {
                    vx: &mut self.vx_block,
                    cx: &mut self.cx_block,
                    nvx: &mut self.nvx_block,
                    ncx: &mut self.ncx_block,
                    crease: true,
                    edges: &mut self.edges,
                };
                self.stack.finish(&cols, &mut sums);
                self.flush(&cols);
            }
        }
        for (i, lanes) in self.lanes[..n * LEVELS].chunks_exact(LEVELS).enumerate() {
            let y = y0 + i;
            for (level, [value, crease]) in lanes.iter().enumerate() {
                if y >= 1 {
                    self.vy[(y - 1) * LEVELS + level] = value.total();
                    self.nvy[(y - 1) * LEVELS + level] = value.count();
                }
                if y >= 3 {
                    self.cy[(y - 2) * LEVELS + level] = crease.total();
                    self.ncy[(y - 2) * LEVELS + level] = crease.count();
                }
            }
        }
        self.pending_rows = 0;
    }

    /// Adds the x sums of the block and their counts, over the columns
    /// `cols` owns, into the totals.
    #[inline(always)]
    fn flush(&mut self, cols: &Cols) {
        flush_cols(&mut self.vx, &mut self.vx_block, &mut self.cx, &mut self.cx_block, cols, UNSCALE);
        flush_cols(&mut self.nvx, &mut self.nvx_block, &mut self.ncx, &mut self.ncx_block, cols, 1.0);
    }

    /// The profiles of the image of the rows pushed (its last row wraps
    /// to its first), or none for an image without texels.
    fn profiles(mut self) -> Option<Profiles> {
        let (w, h) = (self.width, self.rows);
        if w == 0 || h == 0 {
            return None;
        }
        // The pending rows, and the runs of rows cut short by the last row.
        self.measure_pending(true);
        let (first, ring) = (&self.first, &self.ring);
        let (mut vy, mut cy, mut nvy, mut ncy) = (self.vy, self.cy, self.nvy, self.ncy);
        for p in [&mut vy, &mut cy, &mut nvy, &mut ncy] {
            p.truncate(h * LEVELS);
        }
        // The seams; the passes did the interior pairs. Row j mod H: the
        // seam stencils only reach rows H − 2, H − 1, 0, 1.
        for level in 0..LEVELS {
            let row = |j: usize| {
                let j = j % h;
                if j < 2 { first.row(level, j) } else { ring.row(level, j % 4) }
            };
            let at = (h - 1) * LEVELS + level;
            (vy[at], nvy[at]) = y_value(row(h - 1), row(h));
            (cy[at], ncy[at]) = y_crease(row(2 * h - 2), row(h - 1), row(h), row(h + 1));
        }
        Some(Profiles { vx: self.vx, cx: self.cx, vy, cy, nvx: self.nvx, ncx: self.ncx, nvy, ncy, signals: 1.0 })
    }
}

/// [`RowSeams::measure_pending`] for [`pulp::Arch::dispatch`]: the
/// kernels built for the widest vectors the processor has (AVX2 on most
/// x86-64 of the last decade; baseline x86-64 has only SSE2's 4 lanes),
/// chosen at run time. The kernels add, subtract and take absolute values
/// lane by lane, in the same order in every build, and nothing fuses a
/// multiply with an add: the same bits on every processor
/// (`tests::every_instruction_set_gives_the_same_bits`).
struct MeasurePending<'a> {
    seams: &'a mut RowSeams,
    last: bool,
}

impl pulp::WithSimd for MeasurePending<'_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        self.seams.measure_pending_here(self.last);
    }
}

/// Columns of one pass of [`RowSeams`] over its pending rows: a
/// multiple of 8 · 2^(LEVELS − 1), so that every pass starts on whole runs
/// at every level and on lane 0 of the y sums. The pass's rows and sums,
/// about 330 bytes a column with 32 pending rows, then stay in a core's
/// cache (at 32768 columns, whole rows took 3 MB and did not).
const TILE_COLS: usize = 1024;

/// Bytes of pending rows [`RowSeams`] holds at most (unless one row is
/// longer).
const PENDING_BYTES: usize = 4 << 20;

/// Rows [`RowSeams`] measures at once for an image `width` wide: as many
/// as [`CHUNK`] (more add nothing: the x sums are flushed every CHUNK rows
/// anyway), fewer when they would take more than [`PENDING_BYTES`].
fn pending_rows_for(width: usize, height: usize) -> usize {
    (PENDING_BYTES / (4 * width.max(1))).clamp(1, CHUNK).min(height.max(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The profiles of a [`RowSeams`] fed `rows` (`w` wide), measured
    /// `tile_cols` columns at a time.
    fn streamed_profiles(rows: &[f32], w: usize, h: usize, tile_cols: usize) -> Vec<Vec<u64>> {
        profiles_of(rows, w, h, tile_cols, true)
    }

    /// The same, with the kernels built for the widest vectors or not.
    fn profiles_of(rows: &[f32], w: usize, h: usize, tile_cols: usize, widest: bool) -> Vec<Vec<u64>> {
        let mut seams = RowSeams::new(w, h);
        seams.tile_cols = tile_cols;
        seams.widest = widest;
        for row in rows.chunks_exact(w) {
            seams.push_row(row);
        }
        seams.measure_pending(true);
        [&seams.vx, &seams.cx, &seams.vy, &seams.cy, &seams.nvx, &seams.ncx, &seams.nvy, &seams.ncy]
            .map(|p| p.iter().map(|v| v.to_bits()).collect())
            .to_vec()
    }

    #[test]
    fn passes_over_some_columns_give_the_bits_of_whole_rows() {
        // Passes of 256 columns (the narrowest that keeps every level's
        // runs and the 8 lanes whole) against one pass over the whole row:
        // pass edges after 1, 2 and 3 columns of the last pass, wide and
        // narrow last passes, heights that end blocks and runs early.
        let mut state = 7u64;
        let mut random = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        for w in [257, 258, 259, 260, 300, 511, 512, 513, 700, 1029] {
            for h in [1, 2, 3, 4, 5, 33, 70] {
                // Structure along both axes, so every level's sums differ.
                let rows: Vec<f32> = (0..w * h)
                    .map(|k| ((k % w) / 7 % 3) as f32 * 5.0 + ((k / w) / 3 % 2) as f32 * 3.0 + random())
                    .collect();
                let whole = streamed_profiles(&rows, w, h, w.next_multiple_of(256));
                assert_eq!(streamed_profiles(&rows, w, h, 256), whole, "{w}×{h}");
                assert!(whole[0].iter().any(|&v| f64::from_bits(v) > 0.0), "{w}×{h}: zero sums");
            }
        }
    }

    #[test]
    fn every_instruction_set_gives_the_same_bits() {
        // The kernels as built for this processor's widest vectors, and for
        // baseline x86-64 (or the target's baseline elsewhere): the same
        // sums, to the bit, on values of every size the judge sees.
        let (w, h) = (1000, 75);
        let rows: Vec<f32> = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f32, (k / w) as f32);
                (x * 0.37).sin() * 1e3 + (y * 0.11).cos() * 7.0 + ((k * 7919) % 101) as f32 * 1e-3
            })
            .collect();
        let widest = profiles_of(&rows, w, h, 256, true);
        assert_eq!(profiles_of(&rows, w, h, 256, false), widest);
        assert!(widest[1].iter().any(|&v| f64::from_bits(v) > 0.0), "zero creases");
    }
}
