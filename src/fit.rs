//! The plane fit: heights in, unit normals out. Knows nothing of files.
//!
//! For texel (x, y), patch size N = 2r + 1, the points are
//! p(i, j) = (i, σ·j, z(x + i, y + j)) for i, j ∈ [−r, r], z = S · h, with
//! σ = −1 for OpenGL and +1 for DirectX. With the mean removed only these
//! sums remain (Σi = Σj = Σij = 0 on the square grid):
//!
//! ```text
//! A   = Σ i²  (= Σ j²)  = N · r(r + 1)(2r + 1) / 3
//! Cx  = Σ i · z         Cy = σ · Σ j · z
//! Czz = Σ z² − (Σ z)² / N²
//! ```
//!
//! * vertical fit: n ∝ (−Cx, −Cy, A);
//! * orthogonal fit: n ∝ (−Cx, −Cy, A − λ), λ the covariance's smallest
//!   eigenvalue; with d = (A − Czz)/2, q = √(d² + Cx² + Cy²),
//!   A − λ = d + q if d ≥ 0, else (Cx² + Cy²)/(q − d) (the same value,
//!   written so that it does not cancel);
//! * a patch with Cx² + Cy² ≤ 1e-20 · (A + Czz)² is flat: n = (0, 0, 1).
//!
//! # How the sums are found
//!
//! The four patch sums Σz, Σiz, Σjz, Σz² are separable, so each is a
//! horizontal running sum along a row followed by a vertical running sum
//! down the columns. Every step adds the entering texel and removes the
//! leaving one, so the cost per texel is the same for N = 3 and N = 63.
//!
//! Rules the loops obey, and why:
//! * Sums are f64 over z − c, where c is one texel's value per tile
//!   (a block of rows × a segment of columns). Subtracting c leaves Cx, Cy
//!   and Czz unchanged, and keeps Σz² − (Σz)²/N² from cancelling when the
//!   heights sit far from zero (a float map around 1000 with fine detail).
//! * Running sums restart from scratch at every tile edge, so rounding drift
//!   is bounded by the tile size, and the tiles are fixed by the image and
//!   N alone. Rows are split among threads by whole tiles, so every texel is
//!   computed by the same operations in the same order whatever the number
//!   of threads: the output is identical bit for bit.
//! * The first row tile is the top r rows, the only rows whose patches
//!   reach above row 0; the others start at row r. With a wrap in y, only
//!   that tile reads the image's last rows, so a streaming caller
//!   ([`BandFit`]) can fit the rest before it has them, and get the same
//!   bits as the whole-image path.
//! * Tiles are at least 8·N long, so restarting (N steps) costs at most an
//!   eighth of the sliding work (2 steps a texel): the cost stays flat in N.
//! * A block of rows holds between 2^14 and 2^24 texels, whatever the
//!   image's shape: a narrow image (one column, 2^24 rows) gets blocks tall
//!   enough that the work of a block outweighs its setup, and a very wide one
//!   (2^26 columns) blocks of fewer rows, so that a band of blocks, which a
//!   streaming caller holds, stays a bounded number of texels. (Only beyond
//!   2^24 / (8·N) columns do blocks get shorter than 8·N, and the cost grows
//!   with N there.) Each task's own sums are a strip of ~512 columns, and
//!   borders are mapped as they are read, so the fit's working memory does
//!   not grow with the image's width or height.

use std::ops::Range;

use crate::par::prelude::*;

use crate::error::{Error, Result};
use crate::options::{Borders, Fit, Options};
use crate::samples::Sample;

/// A type an output texel can be made from a unit normal.
///
/// Implemented for `[f32; 3]` (the normal n itself, components in [−1, 1])
/// and for `[u8; 3]` / `[u16; 3]` (the contract's RGB encoding
/// c = (n + 1)/2, rounded). Writing texels straight from the fit saves a
/// pass and a float copy of the image.
pub trait FromNormal: Copy + Send + Sync {
    /// Makes the texel from the normal's (x, y, z), a unit vector with z ≥ 0.
    fn from_normal(n: [f64; 3]) -> Self;
}

impl FromNormal for [f32; 3] {
    #[inline]
    fn from_normal(n: [f64; 3]) -> Self {
        [n[0] as f32, n[1] as f32, n[2] as f32]
    }
}

/// The normal itself, in f64.
impl FromNormal for [f64; 3] {
    #[inline(always)]
    fn from_normal(n: [f64; 3]) -> Self {
        n
    }
}

/// 2⁵²: adding it to an x in [0, 2⁵²) leaves round(x) (to nearest, ties
/// to even) in the low bits of the sum's mantissa.
const ROUND_MAGIC: f64 = 4_503_599_627_370_496.0;

// Rounding by the magic number, in plain float and integer instructions
// that vectorise, where `f64::round` is a library call on baseline x86-64
// and a saturating `as` cast is a chain of compares. The scaled value
// (n + 1) · (2^bits − 1) / 2 lies in [0, 2^bits − 1] for |n| ≤ 1; its ties
// (x.5 exactly) fall only at n = 0, where nearest-even gives 128 and 32768,
// as rounding half up does.
impl FromNormal for [u8; 3] {
    #[inline]
    fn from_normal(n: [f64; 3]) -> Self {
        n.map(|c| ((c + 1.0) * 127.5 + ROUND_MAGIC).to_bits() as u8)
    }
}

impl FromNormal for [u16; 3] {
    #[inline]
    fn from_normal(n: [f64; 3]) -> Self {
        n.map(|c| ((c + 1.0) * 32767.5 + ROUND_MAGIC).to_bits() as u16)
    }
}

/// Unit normals of a `width` × `height` height map, as `[x, y, z]` in
/// [−1, 1], row-major.
///
/// `heights` is row-major, `width * height` long, of any [`Sample`] type:
/// `f32` and `f64` are heights in the contract's units, `u8` and `u16`
/// stored integer values whose heights are v / 255 and v / 65535 (SPEC
/// §1). Integers are read as they are and 1 / (2^bits − 1) goes into the
/// gain, in f64, so no rounding comes between the file and the fit. Rows
/// are computed in parallel on rayon's current pool.
///
/// ```
/// use normalfit::{normals, Options};
/// // A ramp rising to the right: normals lean left (−x), green stays 0.
/// let (w, h) = (8, 4);
/// let heights: Vec<f32> = (0..w * h).map(|k| (k % w) as f32 * 0.25).collect();
/// let opts = Options::default().with_borders(normalfit::Borders::both(normalfit::Border::Clamp));
/// let n = normals(&heights, w, h, &opts).unwrap();
/// let [nx, ny, nz] = n[w + 3];
/// assert!(nx < 0.0 && ny.abs() < 1e-6 && nz > 0.0);
/// ```
pub fn normals<H: Sample>(heights: &[H], width: usize, height: usize, opts: &Options) -> Result<Vec<[f32; 3]>> {
    let mut out = vec![[0.0f32; 3]; checked_len(width, height)?];
    normals_into(heights, width, height, opts, &mut out)?;
    Ok(out)
}

/// Like [`normals`], but writes into `out` (`width * height` texels) in
/// any texel type: `[f32; 3]` for the normal itself, `[u8; 3]` or
/// `[u16; 3]` for the encoded RGB of the contract.
pub fn normals_into<H: Sample, T: FromNormal>(
    heights: &[H],
    width: usize,
    height: usize,
    opts: &Options,
    out: &mut [T],
) -> Result<()> {
    fit_image(heights, width, height, opts, out, None)
}

/// Like [`normals_into`], and also the fit's residual: `residual[k]` is
/// the root-mean-square distance of texel k's N² patch points from the
/// plane fitted to them, in texel widths (the units of the surface
/// z = S · h, so it grows with the gain S).
///
/// The distance is the one the fit minimises: perpendicular to the plane
/// for [`Fit::Orthogonal`] (√(λ / N²), λ the covariance's smallest
/// eigenvalue), vertical for [`Fit::Vertical`]. A planar patch gives 0;
/// bumps, pits and grain finer than the patch give more, so the map is a
/// hint of cavities and roughness at the patch's scale. Where the normal
/// is the flat (0, 0, 1) of a tilt-free patch, the residual is the
/// points' distance from that horizontal plane. It comes from the sums
/// the fit already has, at the cost of a few operations per texel.
///
/// ```
/// use normalfit::{normals_and_residual_into, Options};
/// // A plane plus a checkerboard of amplitude 0.1: the plane is found, and
/// // the points lie about 0.1 from it (exactly 0.1 · √(1 − 1/N⁴), N = 3).
/// let (w, h) = (16, 16);
/// let heights: Vec<f32> = (0..w * h)
///     .map(|k| 0.01 * (k % w) as f32 + if (k % w + k / w) % 2 == 0 { 0.1 } else { -0.1 })
///     .collect();
/// let opts = Options::new().with_fit(normalfit::Fit::Vertical)
///     .with_borders(normalfit::Borders::both(normalfit::Border::Mirror));
/// let mut normals = vec![[0.0f32; 3]; w * h];
/// let mut residual = vec![0.0f32; w * h];
/// normals_and_residual_into(&heights, w, h, &opts, &mut normals, &mut residual)?;
/// let expected = 0.1 * (1.0f32 - 1.0 / 81.0).sqrt();
/// assert!((residual[5 * w + 7] - expected).abs() < 1e-5);
/// # Ok::<(), normalfit::Error>(())
/// ```
///
/// Errors: as [`normals_into`]; [`Error::BufferSize`] also for a
/// `residual` of the wrong length.
pub fn normals_and_residual_into<H: Sample, T: FromNormal>(
    heights: &[H],
    width: usize,
    height: usize,
    opts: &Options,
    out: &mut [T],
    residual: &mut [f32],
) -> Result<()> {
    fit_image(heights, width, height, opts, out, Some(residual))
}

/// The whole-image fit behind [`normals_into`] and
/// [`normals_and_residual_into`].
fn fit_image<H: Sample, T: FromNormal>(
    heights: &[H],
    width: usize,
    height: usize,
    opts: &Options,
    out: &mut [T],
    residual: Option<&mut [f32]>,
) -> Result<()> {
    let plan = Plan::new(width, height, opts)?;
    let len = width * height;
    for actual in [heights.len(), out.len()].into_iter().chain(residual.as_ref().map(|r| r.len())) {
        if actual != len {
            return Err(Error::BufferSize { expected: len, actual });
        }
    }
    if let Some((x, y)) = first_non_finite(heights, width) {
        return Err(Error::NonFiniteHeight { x, y });
    }
    let source_row = |y: usize| &heights[y * width..][..width];
    plan.fit_rows(&source_row, H::UNIT, 0, out, residual);
    Ok(())
}

/// The fit of an image whose rows arrive in bands, top to bottom, for
/// callers that stream rows from a decoder to an encoder without holding
/// the image: memory grows with the width and N, not with the height.
///
/// The output rows are cut into [`bands`](Self::bands): first the top r =
/// N / 2 rows, the only ones whose patches reach above row 0, then bands of
/// [`band_rows`](Self::band_rows) (the last one shorter). So with a wrap in
/// y, only the top band needs the image's last rows, and a caller can fit
/// and write every other band first. A band of rows y0 … y1 − 1 reads the
/// source rows y0 − r … y1 − 1 + r, through the y border. The texels are
/// the same, bit for bit, as [`normals_into`] gives for the whole image.
///
/// ```
/// use normalfit::fit::BandFit;
/// use normalfit::{normals, Options};
///
/// let (w, h) = (40, 300);
/// let heights: Vec<f32> = (0..w * h).map(|k| ((k % w) as f32 * 0.3).sin() + (k / w) as f32 * 0.01).collect();
/// let opts = Options::new().with_patch(5);
/// let fit = BandFit::new(w, h, &opts)?;
/// let mut streamed = Vec::new();
/// for rows in fit.bands() {
///     let mut band = vec![[0.0f32; 3]; rows.len() * w];
///     // Any row store will do; this one has the whole image.
///     fit.fit_band(rows, &|y| &heights[y * w..][..w], &mut band)?;
///     streamed.extend(band);
/// }
/// assert_eq!(streamed, normals(&heights, w, h, &opts)?);
/// # Ok::<(), normalfit::Error>(())
/// ```
pub struct BandFit {
    plan: Plan,
    height: usize,
    band_rows: usize,
    /// The height of a row value of 1, when not the sample type's own.
    unit: Option<f64>,
}

impl BandFit {
    /// Plans the fit of a `width` × `height` image.
    ///
    /// Errors: [`Error::InvalidOption`] for invalid options or a zero size.
    pub fn new(width: usize, height: usize, opts: &Options) -> Result<BandFit> {
        let plan = Plan::new(width, height, opts)?;
        // Enough blocks per band to keep every core busy, but a band of at
        // most 2^24 texels: a block already holds enough strips (tasks) to
        // share among the threads.
        let blocks = crate::par::current_num_threads().clamp(1, (MAX_BLOCK_TEXELS / (plan.block_rows * width)).max(1));
        let band_rows = plan.block_rows * blocks;
        Ok(BandFit { plan, height, band_rows, unit: None })
    }

    /// The same fit of rows whose values are heights in units of `unit`
    /// (a height is value × `unit`), whatever their type: for a decoder
    /// that gives 16-bit samples as `f64` values, 1 / 65535. The texels
    /// are then the same, bit for bit, as the whole-image fit of the
    /// samples in their own type. Without it, the sample type's
    /// [`Sample::UNIT`].
    #[must_use]
    pub fn with_unit(mut self, unit: f64) -> BandFit {
        self.unit = Some(unit);
        self
    }

    /// Columns.
    #[must_use]
    pub fn width(&self) -> usize {
        self.plan.width
    }

    /// Rows.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Rows per band after the top band, a whole number of the fit's tiles.
    #[must_use]
    pub fn band_rows(&self) -> usize {
        self.band_rows
    }

    /// The patch radius r = N / 2, the rows of the top band (fewer in an
    /// image of fewer rows).
    #[must_use]
    pub fn radius(&self) -> usize {
        self.plan.r
    }

    /// The bands of output rows, in order: the top r rows, then bands of
    /// [`band_rows`](Self::band_rows).
    pub fn bands(&self) -> impl Iterator<Item = Range<usize>> + use<> {
        let (h, b) = (self.height, self.band_rows);
        let top = self.plan.r.min(h);
        std::iter::once(0..top).chain((top..h).step_by(b).map(move |y0| y0..(y0 + b).min(h))).filter(|r| !r.is_empty())
    }

    /// Fits the band `rows` (one of [`bands`](Self::bands)) into `out`,
    /// which holds its texels. `row(y)` gives source row y (`width`
    /// heights) for every y the band reads. Rows run in parallel on rayon's
    /// current pool.
    ///
    /// Errors: [`Error::BufferSize`] for a range that is not a band or a
    /// wrong `out` length, [`Error::NonFiniteHeight`] if a row read holds NaN
    /// or ±inf.
    pub fn fit_band<'a, H: Sample, T: FromNormal>(
        &self,
        rows: Range<usize>,
        row: &(dyn Fn(usize) -> &'a [H] + Sync),
        out: &mut [T],
    ) -> Result<()> {
        let w = self.plan.width;
        let (h, top) = (self.height, self.plan.r.min(self.height));
        let is_band = if rows.start < top {
            rows == (0..top)
        } else {
            (rows.start - top).is_multiple_of(self.band_rows)
                && rows.start < h
                && rows.end == (rows.start + self.band_rows).min(h)
        };
        if !is_band || out.len() != rows.len() * w {
            return Err(Error::BufferSize { expected: rows.len() * w, actual: out.len() });
        }
        for p in rows.start..rows.end + 2 * self.plan.r {
            let y = self.plan.source_y(p);
            let r = row(y);
            if r.len() != w {
                return Err(Error::BufferSize { expected: w, actual: r.len() });
            }
            if let Some((x, _)) = first_non_finite(r, w) {
                return Err(Error::NonFiniteHeight { x, y });
            }
        }
        self.plan.fit_rows(row, self.unit.unwrap_or(H::UNIT), rows.start, out, None);
        Ok(())
    }
}

impl BandFit {
    /// The patch moments of the band `rows` instead of its normals: per
    /// texel [Cx, Cy, Czz] = [Σ i·z, Σ j·z, Σ (z − z̄)²] over its N×N patch
    /// (z = the row value × the gain; j down, whatever the convention), by
    /// the same sliding sums. The height inverse re-fits its heights with
    /// these.
    pub(crate) fn moments<'a>(
        &mut self,
        rows: Range<usize>,
        row: &(dyn Fn(usize) -> &'a [f64] + Sync),
        out: &mut [[f64; 3]],
    ) -> Result<()> {
        self.plan.moments = true;
        let done = self.fit_band(rows, row, out);
        self.plan.moments = false;
        done
    }
}

/// `width * height`, refusing zero sizes and overflow.
pub(crate) fn checked_len(width: usize, height: usize) -> Result<usize> {
    if width == 0 || height == 0 {
        return Err(Error::InvalidOption(format!("image is {width}×{height}: both sides must be at least 1")));
    }
    width
        .checked_mul(height)
        .ok_or_else(|| Error::InvalidOption(format!("image of {width}×{height} texels is too large")))
}

/// The first texel (x, y) in row order whose height is NaN or infinite.
pub(crate) fn first_non_finite<H: Sample>(heights: &[H], width: usize) -> Option<(usize, usize)> {
    // A loop without an early exit vectorises (a search one value at a time
    // took 2.5 % of a conversion): it finds whether there is one, and only
    // then is it looked for.
    let all_finite = heights.iter().fold(true, |all, h| all & h.is_finite());
    if all_finite {
        return None;
    }
    heights.iter().position(|h| !h.is_finite()).map(|k| (k % width, k / width))
}

/// Texels per branch between the two loops of the orthogonal fit's
/// normals (see [`Plan::emit_with`]).
const EMIT_CHUNK: usize = 32;

/// Columns per parallel task of the fit, rounded to whole segments: the
/// task's sums (a few rows of f64 per column) then fit in a core's cache.
const STRIP_COLS: usize = 512;

/// Texels a block of rows holds at least (unless the image is smaller):
/// a narrow image's blocks are tall enough that a block's work outweighs
/// setting it up.
const MIN_BLOCK_TEXELS: usize = 1 << 14;

/// Texels a block of rows, and a band of blocks, holds at most (unless one
/// row is longer): what a streaming caller holds stays bounded whatever the
/// width.
const MAX_BLOCK_TEXELS: usize = 1 << 24;

/// One parallel task of the fit: a strip of a tile, its rows from `y0`,
/// its columns from `x0`, as pieces of the output rows (and of the
/// residual rows, when asked for).
struct Strip<'t, T> {
    y0: usize,
    x0: usize,
    out: Vec<&'t mut [T]>,
    residual: Option<Vec<&'t mut [f32]>>,
}

/// Everything about a conversion that is the same for every tile.
struct Plan {
    width: usize,
    n: usize,
    r: usize,
    /// S: surface z per unit of height, sign included. The fit multiplies
    /// the samples by S times their unit ([`Sample::UNIT`]).
    scale: f64,
    sigma: f64,
    fit: Fit,
    /// A = Σ i² over the patch.
    a: f64,
    borders: Borders,
    height: usize,
    block_rows: usize,
    segment_cols: usize,
    /// Emit each texel's patch moments [Cx, Cy, Czz] instead of its normal
    /// (the height inverse's re-fit, [`BandFit::moments`]).
    moments: bool,
}

impl Plan {
    fn new(width: usize, height: usize, opts: &Options) -> Result<Plan> {
        opts.validate()?;
        checked_len(width, height)?;
        let n = opts.patch;
        let r = n / 2;
        let tile = (8 * n).max(64);
        // Rows of a block: at least a tile, more for a narrow image, fewer
        // (down to one) for a very wide one (see the module docs).
        let block_rows = tile.max(MIN_BLOCK_TEXELS.div_ceil(width)).min((MAX_BLOCK_TEXELS / width).max(1));
        let rf = r as f64;
        Ok(Plan {
            width,
            n,
            r,
            scale: opts.scale_for_width(width),
            sigma: opts.convention.sigma(),
            fit: opts.fit,
            a: n as f64 * rf * (rf + 1.0) * (2.0 * rf + 1.0) / 3.0,
            borders: opts.borders,
            height,
            block_rows,
            segment_cols: tile,
            moments: false,
        })
    }

    /// Fits the output rows `y0 .. y0 + out.len() / width` (from a tile
    /// edge), tile by tile in parallel.
    ///
    /// The tiles are fixed by the image and N alone: the top r rows, whose
    /// patches reach above row 0 (through a wrap, to the image's last rows),
    /// then `block_rows` at a time. Every texel is then made by the same
    /// operations whichever rows a caller asks for at once. `residual`,
    /// when given, holds as many texels as `out` and gets the fit's RMS
    /// distances.
    ///
    /// Each tile is cut further into strips of whole segments, the tasks
    /// that run in parallel: a column's sums depend only on its own segment,
    /// so the strips change no result, while many small tasks keep both
    /// cores busy beside the pipeline's other threads (two tasks a band left
    /// one core idle while the other finished its tile) and a strip's sums
    /// stay in the core's cache.
    fn fit_rows<'a, H: Sample, T: FromNormal>(
        &self,
        source_row: &(dyn Fn(usize) -> &'a [H] + Sync),
        unit: f64,
        y0: usize,
        out: &mut [T],
        residual: Option<&mut [f32]>,
    ) {
        let w = self.width;
        let strip = self.strip_cols();
        let mut tasks: Vec<Strip<'_, T>> = Vec::new();
        let (mut y, mut rest, mut rest_residual) = (y0, out, residual);
        while !rest.is_empty() {
            let rows = if y < self.r { self.r - y } else { self.block_rows - (y - self.r) % self.block_rows };
            let len = (rows * w).min(rest.len());
            let (tile, tail) = rest.split_at_mut(len);
            let (tile_residual, residual_tail) = match rest_residual {
                Some(r) => {
                    let (head, tail) = r.split_at_mut(len);
                    (Some(head), Some(tail))
                }
                None => (None, None),
            };
            let first = tasks.len();
            for x0 in (0..w).step_by(strip) {
                let has_residual = tile_residual.is_some();
                tasks.push(Strip { y0: y, x0, out: Vec::new(), residual: has_residual.then(Vec::new) });
            }
            for row in tile.chunks_exact_mut(w) {
                for (task, piece) in tasks[first..].iter_mut().zip(row.chunks_mut(strip)) {
                    task.out.push(piece);
                }
            }
            if let Some(tile_residual) = tile_residual {
                for row in tile_residual.chunks_exact_mut(w) {
                    for (task, piece) in tasks[first..].iter_mut().zip(row.chunks_mut(strip)) {
                        task.residual.as_mut().expect("a residual strip").push(piece);
                    }
                }
            }
            y += rows;
            rest = tail;
            rest_residual = residual_tail;
        }
        // The product of S and the unit, once: every path that fits these
        // samples forms the same gain, and so the same bits.
        let gain = self.scale * unit;
        tasks.into_par_iter().for_each(|task| self.fit_strip(source_row, gain, task));
    }

    /// The source row of padded row p = y + j + r, through the y border.
    #[inline]
    fn source_y(&self, p: usize) -> usize {
        self.borders.y.map(p as isize - self.r as isize, self.height)
    }

    /// Columns per parallel task: whole segments, about 512 columns.
    fn strip_cols(&self) -> usize {
        self.segment_cols * (STRIP_COLS / self.segment_cols).max(1)
    }

    /// Fits one strip: the output rows from `y0`, the columns from `x0`.
    fn fit_strip<'a, H: Sample, T: FromNormal>(
        &self,
        source_row: &(dyn Fn(usize) -> &'a [H] + Sync),
        gain: f64,
        strip: Strip<'_, T>,
    ) {
        let Strip { y0, x0, mut out, mut residual } = strip;
        let Some(first) = out.first() else { return };
        let (n, r) = (self.n, self.r);
        let cols = x0..x0 + first.len();
        let w = cols.len();
        let row_of = |p: usize| source_row(self.source_y(p));

        // The reference c of each column: one texel per (block, segment).
        let reference: Vec<f64> = cols
            .clone()
            .map(|x| {
                let s0 = x - x % self.segment_cols;
                // Column s0 is inside the image: its own value.
                gain * row_of(y0 + r)[s0].to_f64()
            })
            .collect();

        // Ring of the N rows' horizontal sums: slot p % N holds padded row p.
        let mut ring: Vec<RowSums> = (y0..y0 + n)
            .map(|p| {
                let mut sums = RowSums::zeros(w);
                self.horizontal_sums(row_of(p), gain, cols.clone(), &reference, &mut sums);
                sums
            })
            .collect();
        ring.rotate_right(y0 % n);
        let mut entering = RowSums::zeros(w);
        let mut normal = [vec![0.0; w], vec![0.0; w], vec![0.0; w]];

        // Vertical sums over the window, started from scratch at the block's top.
        let mut v = WindowSums::zeros(w);
        for j in 0..n {
            let offset = j as f64 - r as f64;
            let h = &ring[(y0 + j) % n];
            v.add(h, offset);
        }

        let (rf, r1) = (r as f64, r as f64 + 1.0);
        for (k, out_row) in out.iter_mut().enumerate() {
            if k > 0 {
                // Slide down one row: padded row p_in enters, p_out leaves.
                let p_out = y0 + k - 1;
                let p_in = p_out + n;
                self.horizontal_sums(row_of(p_in), gain, cols.clone(), &reference, &mut entering);
                v.slide(&ring[p_out % n], &entering, rf, r1);
                std::mem::swap(&mut ring[p_out % n], &mut entering);
            }
            self.emit(&v, &mut normal, out_row);
            if let Some(residual) = residual.as_mut() {
                self.emit_residual(&v, residual[k]);
            }
        }
    }

    /// Σz, Σiz, Σz² over each column's horizontal window of one source row,
    /// z relative to the column's reference.
    fn horizontal_sums<H: Sample>(
        &self,
        src: &[H],
        gain: f64,
        cols: Range<usize>,
        reference: &[f64],
        out: &mut RowSums,
    ) {
        // Disjoint borrows, and below slices of the segment's length: the
        // sliding loop then keeps every pointer in a register and has no
        // bounds checks (through `out`, it reloaded the planes' pointers
        // and lengths at every texel, 17 % more instructions).
        let RowSums { s0: out_s0, si: out_si, szz: out_szz, padded } = out;
        let (n, r) = (self.n, self.r);
        let (rf, r1) = (r as f64, r as f64 + 1.0);
        // Indices into `out` and `reference` count from the strip's first column.
        let base = cols.start;
        for start in cols.clone().step_by(self.segment_cols) {
            let end = (start + self.segment_cols).min(cols.end);
            let (x0, x1) = (start - base, end - base);
            let c = reference[x0];
            // The segment's texels with their borders: padded[q] is column start + q − r.
            padded.clear();
            // `move`: gain and c by value, kept in registers (by reference,
            // the loop reloaded them from memory at every texel).
            let to_z = move |h: H| gain * h.to_f64() - c;
            if start >= r && end + r <= src.len() {
                // Away from the borders the columns are the source's own, in
                // order: read as a slice, the loop vectorises.
                padded.extend(src[start - r..end + r].iter().map(|&h| to_z(h)));
            } else {
                self.bordered_segment(src, start..end, (gain, c), padded);
            }
            let (mut s0, mut si, mut szz) = (0.0, 0.0, 0.0);
            for (q, &z) in padded[..n].iter().enumerate() {
                s0 += z;
                si += (q as f64 - rf) * z;
                szz += z * z;
            }
            let (seg_s0, seg_si, seg_szz) = (&mut out_s0[x0..x1], &mut out_si[x0..x1], &mut out_szz[x0..x1]);
            seg_s0[0] = s0;
            seg_si[0] = si;
            seg_szz[0] = szz;
            // Texel k (k ≥ 1) of the segment: padded[k − 1] leaves the
            // window, padded[k − 1 + n] enters it.
            let slides = padded.iter().zip(&padded[n..]);
            let outs = seg_s0[1..].iter_mut().zip(&mut seg_si[1..]).zip(&mut seg_szz[1..]);
            for ((&leaving, &entering), ((o0, oi), ozz)) in slides.zip(outs) {
                s0 += entering - leaving;
                si += rf * leaving + r1 * entering - s0;
                szz += entering * entering - leaving * leaving;
                *o0 = s0;
                *oi = si;
                *ozz = szz;
            }
        }
    }

    /// The z values of columns `segment.start − r … segment.end + r − 1`
    /// of `src` into `padded`: those outside the image through the x
    /// border, the rest as a slice. Out of line: only the first and last
    /// segments of a row come here, and the hot loop stays small.
    #[inline(never)]
    fn bordered_segment<H: Sample>(
        &self,
        src: &[H],
        segment: Range<usize>,
        (gain, c): (f64, f64),
        padded: &mut Vec<f64>,
    ) {
        let to_z = |h: H| gain * h.to_f64() - c;
        let r = self.r as isize;
        let (lo, hi, w) = (segment.start as isize - r, segment.end as isize + r, self.width as isize);
        let (inside_lo, inside_hi) = (lo.max(0), hi.min(w));
        let outside = |x: isize| to_z(src[self.borders.x.map(x, self.width)]);
        padded.extend((lo..inside_lo).map(outside));
        padded.extend(src[inside_lo as usize..inside_hi as usize].iter().map(|&h| to_z(h)));
        padded.extend((inside_hi..hi).map(outside));
    }

    /// Turns the window sums of one row into normals, through `normal`
    /// (x, y and z planes): the fit's loop then stores whole vectors, and
    /// the texel type's conversion is a loop of its own.
    fn emit<T: FromNormal>(&self, v: &WindowSums, normal: &mut [Vec<f64>; 3], out: &mut [T]) {
        if self.moments {
            let inv_n2 = 1.0 / (self.n * self.n) as f64;
            let w = out.len();
            let (s0, si, sj, szz) = (&v.s0[..w], &v.si[..w], &v.sj[..w], &v.szz[..w]);
            for (x, texel) in out.iter_mut().enumerate() {
                *texel = T::from_normal([si[x], sj[x], (szz[x] - s0[x] * s0[x] * inv_n2).max(0.0)]);
            }
            return;
        }
        // One loop per fit, so the per-texel work has no branch and vectorises.
        match self.fit {
            Fit::Orthogonal => self.emit_with::<true>(v, normal),
            Fit::Vertical => self.emit_with::<false>(v, normal),
        }
        let [nx, ny, nz] = normal;
        for (((texel, &x), &y), &z) in out.iter_mut().zip(nx.iter()).zip(ny.iter()).zip(nz.iter()) {
            *texel = T::from_normal([x, y, z]);
        }
    }

    fn emit_with<const ORTHOGONAL: bool>(&self, v: &WindowSums, normal: &mut [Vec<f64>; 3]) {
        let inv_n2 = 1.0 / (self.n * self.n) as f64;
        let [nx, ny, nz] = normal;
        let w = nx.len();
        let (s0, si, sj, szz) = (&v.s0[..w], &v.si[..w], &v.sj[..w], &v.szz[..w]);
        let (ny, nz) = (&mut ny[..w], &mut nz[..w]);
        let czz_at = |x: usize| (szz[x] - s0[x] * s0[x] * inv_n2).max(0.0);
        for start in (0..w).step_by(EMIT_CHUNK) {
            let texels = start..(start + EMIT_CHUNK).min(w);
            // Only a patch whose heights spread more than its columns and
            // rows (Czz > A) needs the orthogonal fit's division; most
            // chunks have none, and their loop leaves it out (the
            // division took a tenth of the fit), with the same results.
            let steep = ORTHOGONAL && texels.clone().any(|x| czz_at(x) > self.a);
            if steep {
                for x in texels {
                    let n = normal_from_sums::<ORTHOGONAL, true>(self.a, si[x], self.sigma * sj[x], czz_at(x));
                    [nx[x], ny[x], nz[x]] = n;
                }
            } else {
                for x in texels {
                    let n = normal_from_sums::<ORTHOGONAL, false>(self.a, si[x], self.sigma * sj[x], czz_at(x));
                    [nx[x], ny[x], nz[x]] = n;
                }
            }
        }
    }

    /// The RMS distance of each texel's patch points from its fitted plane,
    /// in surface units, from the window sums of one row. A loop of its
    /// own, run only when asked for, so the normals' loop stays as it is.
    fn emit_residual(&self, v: &WindowSums, out: &mut [f32]) {
        match self.fit {
            Fit::Orthogonal => self.emit_residual_with::<true>(v, out),
            Fit::Vertical => self.emit_residual_with::<false>(v, out),
        }
    }

    fn emit_residual_with<const ORTHOGONAL: bool>(&self, v: &WindowSums, out: &mut [f32]) {
        let inv_n2 = 1.0 / (self.n * self.n) as f64;
        let w = out.len();
        let (s0, si, sj, szz) = (&v.s0[..w], &v.si[..w], &v.sj[..w], &v.szz[..w]);
        for x in 0..w {
            let czz = (szz[x] - s0[x] * s0[x] * inv_n2).max(0.0);
            let sum = squared_distance_sum::<ORTHOGONAL>(self.a, si[x], sj[x], czz);
            out[x] = (sum * inv_n2).sqrt() as f32;
        }
    }
}

/// The summed squared distance of the patch's points from the fitted
/// plane, from the patch sums. The scatter matrix of the points is
/// [[A, 0, Cx], [0, A, Cy], [Cx, Cy, Czz]]; with t² = Cx² + Cy², the
/// product of its two eigenvalues in the (tilt, z) plane is A·Czz − t².
///
/// * orthogonal: the smallest eigenvalue λ = (A·Czz − t²) / λmax, with
///   λmax = (A + Czz)/2 + √(d² + t²) ≥ A > 0: the product over the largest
///   one, which does not cancel as (A + Czz)/2 − √(…) would on a near-planar
///   patch;
/// * vertical: Czz − t²/A = (A·Czz − t²) / A, the residual sum of squares
///   of ordinary least squares (the design is orthogonal: ΣiΣj = 0);
/// * a flat patch (see [`normal_from_sums`]) has the horizontal plane,
///   at summed squared distance Czz.
#[inline(always)]
fn squared_distance_sum<const ORTHOGONAL: bool>(a: f64, cx: f64, cy: f64, czz: f64) -> f64 {
    let tilt2 = cx * cx + cy * cy;
    let flat = tilt2 <= 1e-20 * (a + czz) * (a + czz);
    let largest = if ORTHOGONAL {
        let d = 0.5 * (a - czz);
        0.5 * (a + czz) + (d * d + tilt2).sqrt()
    } else {
        a
    };
    let tilted = (a * czz - tilt2).max(0.0) / largest;
    if flat { czz } else { tilted }
}

/// The fitted plane's unit normal from the patch sums (see the module
/// docs), written without branches: every case is computed and the right
/// one selected, so that a loop of it vectorises. The unused
/// cases may divide by zero; their values are discarded.
///
/// `STEEP`: some patch of the loop may have Czz > A (d < 0), the case that
/// divides; without it, d ≥ 0 is taken as given.
#[inline(always)]
fn normal_from_sums<const ORTHOGONAL: bool, const STEEP: bool>(a: f64, cx: f64, cy: f64, czz: f64) -> [f64; 3] {
    let tilt2 = cx * cx + cy * cy;
    let flat = tilt2 <= 1e-20 * (a + czz) * (a + czz);
    let nz = if ORTHOGONAL {
        let d = 0.5 * (a - czz);
        let q = (d * d + tilt2).sqrt();
        if STEEP {
            let sloped = tilt2 / (q - d);
            if d >= 0.0 { d + q } else { sloped }
        } else {
            d + q
        }
    } else {
        a
    };
    let inv = 1.0 / (tilt2 + nz * nz).sqrt();
    let n = [-cx * inv, -cy * inv, nz * inv];
    if flat { [0.0, 0.0, 1.0] } else { n }
}

/// One row's horizontal sums per column, as planes so the loops vectorise.
struct RowSums {
    s0: Vec<f64>,
    si: Vec<f64>,
    szz: Vec<f64>,
    /// Scratch: one segment's heights with their borders.
    padded: Vec<f64>,
}

impl RowSums {
    fn zeros(width: usize) -> Self {
        let z = vec![0.0; width];
        RowSums { s0: z.clone(), si: z.clone(), szz: z, padded: Vec::new() }
    }
}

/// The patch sums of the current output row, per column.
struct WindowSums {
    s0: Vec<f64>,
    si: Vec<f64>,
    sj: Vec<f64>,
    szz: Vec<f64>,
}

impl WindowSums {
    fn zeros(width: usize) -> Self {
        let z = vec![0.0; width];
        WindowSums { s0: z.clone(), si: z.clone(), sj: z.clone(), szz: z }
    }

    /// Adds the row sums `h` of the window's row at vertical offset `j`.
    fn add(&mut self, h: &RowSums, j: f64) {
        // Every slice cut to one length: the loop then has no bounds
        // checks and vectorises.
        let w = self.s0.len();
        let (s0, si, sj, szz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (h0, hi, hzz) = (&h.s0[..w], &h.si[..w], &h.szz[..w]);
        for x in 0..w {
            s0[x] += h0[x];
            si[x] += hi[x];
            sj[x] += j * h0[x];
            szz[x] += hzz[x];
        }
    }

    /// Slides the window down one row: row sums `leaving` (offset −r) go,
    /// `entering` (offset r + 1 before the slide) come. Σj·z moves by
    /// r·leaving + (r + 1)·entering − the new Σz, as every row's offset
    /// drops by one.
    fn slide(&mut self, leaving: &RowSums, entering: &RowSums, r: f64, r1: f64) {
        let w = self.s0.len();
        let (s0, si, sj, szz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (l0, li, lzz) = (&leaving.s0[..w], &leaving.si[..w], &leaving.szz[..w]);
        let (e0, ei, ezz) = (&entering.s0[..w], &entering.si[..w], &entering.szz[..w]);
        for x in 0..w {
            let new_s0 = s0[x] - l0[x] + e0[x];
            sj[x] += r * l0[x] + r1 * e0[x] - new_s0;
            s0[x] = new_s0;
            si[x] += ei[x] - li[x];
            szz[x] += ezz[x] - lzz[x];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::Border;

    /// The whole-image fit with blocks of `block_rows` rows.
    fn fitted_with_blocks(heights: &[f32], w: usize, h: usize, opts: &Options, block_rows: usize) -> Vec<[f32; 3]> {
        let mut plan = Plan::new(w, h, opts).unwrap();
        plan.block_rows = block_rows;
        let mut out = vec![[0.0f32; 3]; w * h];
        plan.fit_rows(&|y: usize| &heights[y * w..][..w], 1.0, 0, &mut out, None);
        out
    }

    /// The patch moments of the sliding sums against the sums written out
    /// over each N×N patch, through the borders' index maps.
    #[test]
    fn moments_are_the_patch_sums() {
        let (w, h) = (37, 23);
        let z: Vec<f64> = (0..w * h).map(|k| ((k * 7919) % 1009) as f64 * 0.013 + (k % w) as f64 * 0.5).collect();
        for (n, bx, by) in
            [(3, Border::Wrap, Border::Mirror), (5, Border::Mirror, Border::Clamp), (7, Border::Clamp, Border::Wrap)]
        {
            let opts = Options::new()
                .with_patch(n)
                .with_fit(Fit::Vertical)
                .with_borders(Borders { x: bx, y: by })
                .with_strength(crate::Strength::Scale(1.0));
            let mut fit = BandFit::new(w, h, &opts).unwrap().with_unit(1.0);
            let mut got = Vec::new();
            for rows in fit.bands().collect::<Vec<_>>() {
                let mut band = vec![[0.0; 3]; rows.len() * w];
                fit.moments(rows, &|y| &z[y * w..][..w], &mut band).unwrap();
                got.extend(band);
            }
            let r = (n / 2) as isize;
            for y in 0..h {
                for x in 0..w {
                    let mut values = Vec::new();
                    let (mut cx, mut cy) = (0.0, 0.0);
                    for j in -r..=r {
                        for i in -r..=r {
                            let v = z[by.map(y as isize + j, h) * w + bx.map(x as isize + i, w)];
                            cx += i as f64 * v;
                            cy += j as f64 * v;
                            values.push(v);
                        }
                    }
                    let mean = values.iter().sum::<f64>() / values.len() as f64;
                    let czz: f64 = values.iter().map(|v| (v - mean) * (v - mean)).sum();
                    let [gx, gy, gzz] = got[y * w + x];
                    let scale = 1.0 + czz;
                    assert!((gx - cx).abs() < 1e-9 * scale && (gy - cy).abs() < 1e-9 * scale, "{n} {x},{y}");
                    assert!((gzz - czz).abs() < 1e-9 * scale, "{n} {x},{y}: {gzz} against {czz}");
                }
            }
        }
    }

    /// Blocks of a few rows, as a very wide image gets, and taller ones, as
    /// a narrow image gets: the sums restart at other rows, the normals are
    /// the same up to rounding.
    #[test]
    fn blocks_of_any_height_give_the_same_normals() {
        let (w, h) = (150, 70);
        let heights: Vec<f32> =
            (0..w * h).map(|k| (((k * 7919) % 1013) as f32 / 1013.0) + (k % w) as f32 * 0.01).collect();
        for n in [3, 9] {
            for borders in [Borders::both(Border::Wrap), Borders::both(Border::Mirror), Borders::both(Border::Clamp)] {
                let opts =
                    Options::new().with_patch(n).with_borders(borders).with_strength(crate::Strength::Scale(3.0));
                let default = fitted_with_blocks(&heights, w, h, &opts, Plan::new(w, h, &opts).unwrap().block_rows);
                for rows in [1, 2, 3, 7, 200] {
                    let other = fitted_with_blocks(&heights, w, h, &opts, rows);
                    for (k, (a, b)) in default.iter().zip(&other).enumerate() {
                        for c in 0..3 {
                            assert!(
                                (a[c] - b[c]).abs() < 1e-6,
                                "N {n} {borders:?} blocks of {rows}: texel {k} {a:?} {b:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// The rows of a block for the shapes of the module docs.
    #[test]
    fn blocks_hold_a_bounded_number_of_texels() {
        let rows = |w: usize, h: usize, n: usize| Plan::new(w, h, &Options::new().with_patch(n)).unwrap().block_rows;
        assert_eq!(rows(4096, 4096, 3), 64);
        assert_eq!(rows(4096, 4096, 63), 504);
        assert_eq!(rows(32768, 32768, 63), 504, "flat in N up to 2^24 / 504 columns");
        assert_eq!(rows(1, 1 << 24, 3), 1 << 14);
        assert_eq!(rows(100, 100, 3), 164);
        assert_eq!(rows(1 << 24, 1, 3), 1);
        assert_eq!(rows(1 << 26, 16, 3), 1);
        assert_eq!(rows(1 << 20, 16, 63), 16);
        let band = |w: usize, h: usize| BandFit::new(w, h, &Options::new()).unwrap().band_rows() * w;
        assert!(band(1 << 20, 64) <= MAX_BLOCK_TEXELS);
        assert!(band(1 << 26, 16) == 1 << 26, "one row when a row is more than the bound");
    }

    /// The orthogonal fit's normals, a chunk of texels at a time: chunks
    /// without a steep patch (Czz ≤ A) leave the division out, and get the
    /// same bits as the formula with it; a chunk with one divides.
    #[test]
    #[allow(clippy::needless_range_loop)] // x indexes the sums and the three planes
    fn chunks_with_and_without_steep_patches_give_the_formula_bit_for_bit() {
        let w = 3 * EMIT_CHUNK + 5;
        let plan = Plan::new(w, 4, &Options::new().with_patch(3)).unwrap();
        let steep = |x: usize| (EMIT_CHUNK + 3..EMIT_CHUNK + 9).contains(&x) || x == w - 2;
        let mut v = WindowSums::zeros(w);
        for x in 0..w {
            let t = x as f64;
            v.s0[x] = 0.37 * t - 3.0;
            v.si[x] = 0.9 - 0.031 * t;
            v.sj[x] = 0.2 + 0.017 * t;
            let czz = if steep(x) { 40.0 + t } else { 0.05 * t };
            v.szz[x] = czz + v.s0[x] * v.s0[x] / 9.0;
        }
        let mut normal = [vec![0.0; w], vec![0.0; w], vec![0.0; w]];
        plan.emit_with::<true>(&v, &mut normal);
        let mut cancelling = 0;
        for x in 0..w {
            let czz = (v.szz[x] - v.s0[x] * v.s0[x] * (1.0 / 9.0)).max(0.0);
            assert_eq!(czz > plan.a, steep(x), "texel {x}: czz {czz}");
            let with_division = normal_from_sums::<true, true>(plan.a, v.si[x], plan.sigma * v.sj[x], czz);
            let got = [normal[0][x], normal[1][x], normal[2][x]];
            assert_eq!(got.map(f64::to_bits), with_division.map(f64::to_bits), "texel {x}");
            let without = normal_from_sums::<true, false>(plan.a, v.si[x], plan.sigma * v.sj[x], czz);
            if without.map(f64::to_bits) != with_division.map(f64::to_bits) {
                assert!(steep(x), "texel {x}: gentle, but the formulas differ");
                cancelling += 1;
            }
        }
        // The steep texels are ones where leaving the division out would show.
        assert!(cancelling >= 4, "{cancelling}");
    }
}
