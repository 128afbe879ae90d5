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
//! In map units ([`Units::Map`]) texel centres are sx apart along a row
//! and sy down a column (per row for a geographic raster: the patch takes
//! its centre row's). Lengths are then counted in x spacings: z / sx, and
//! the rows ρ = sy / sx apart. Where ρ = 1 the formulas above run as they
//! are (on z / sx); otherwise (`unequal`) the vertical fit
//! n ∝ (−Cx, −Cy/ρ, A), the orthogonal fit the smallest eigenvector of
//! [[A, 0, Cx], [0, ρ²A, ρCy], [Cx, ρCy, Czz]] (docs/spec.md). The sums
//! do not change; only the last step does, and it too runs as loops over
//! a row's planes, without branches.
//!
//! # How the sums are found
//!
//! The four patch sums Σz, Σiz, Σjz, Σz² are separable: each is a sum
//! along a row's window, then a sum of those down the patch's rows. The
//! cost per texel is the same for N = 3 and N = 63, and every texel's sums
//! are made from its own patch alone, by operations fixed by the image and
//! N: so threads, the tiles a streaming caller asks for, and windows of the
//! image computed apart ([`FitRequest::window`], a Dask chunk) all give
//! the same bits.
//!
//! * Stored integers (8 and 16 bits) are summed as they are, unscaled:
//!   every sum is an integer below 2^53, exact in f64, so running sums
//!   (add the entering texel, remove the leaving one: two steps a texel)
//!   give each texel exactly its patch's sums wherever the run started.
//!   The gain S / (2^bits − 1) comes after, in f64, and Czz is formed as
//!   (N²·Σz² − (Σz)²)/N², whose numerator is exact too.
//! * Floats (z = S · h) would carry the rounding of wherever a running sum
//!   started, so their windows are summed over blocks aligned on the image
//!   (van Herk / Gil–Werman): texel t of block k (x = kN + t) has the
//!   suffix of the values [kN − r, kN + r] from x − r plus the prefix of
//!   the next N values up to x + r, each summed in a fixed order from the
//!   patch's values; the same down the rows. About three steps a texel,
//!   and no sum runs over more than 2N values, so rounding stays that of a
//!   few additions (no reference value needs subtracting: within SPEC's
//!   |S·h| ≤ 1000, Σz² − (Σz)²/N² keeps its digits).
//! * The first row tile is the top r rows, the only rows whose patches
//!   reach above row 0; the others start at row r. With a wrap in y, only
//!   that tile reads the image's last rows, so a streaming caller
//!   ([`BandFit`]) can fit the rest before it has them.
//! * A block of rows holds between 2^14 and 2^24 texels, whatever the
//!   image's shape: a narrow image (one column, 2^24 rows) gets blocks tall
//!   enough that the work of a block outweighs its setup, and a very wide one
//!   (2^26 columns) blocks of fewer rows, so that a band of blocks, which a
//!   streaming caller holds, stays a bounded number of texels. Each task's
//!   own sums are a strip of ~512 columns (at least 8·N, so starting a
//!   strip's sums costs at most an eighth of its work), and borders are
//!   mapped as they are read, so the fit's working memory does not grow
//!   with the image's width or height.

use std::ops::Range;

use crate::par::prelude::*;

use crate::error::{Error, Result};
use crate::options::{Borders, Fit, Options, Spacing, Units};
use crate::samples::{Sample, first_non_finite};

mod eigen;
mod masked;
mod request;
mod unequal;
mod window;
use masked::{MaskSums, MaskedRow, Moments, row_has_hole};
pub use request::{FitRequest, Heights};
use unequal::{RowSpacing, UnequalRow};
pub use window::{Halo, HaloPlan, Window};

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
    #[inline(always)]
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
    #[inline(always)]
    fn from_normal(n: [f64; 3]) -> Self {
        n.map(|c| ((c + 1.0) * 127.5 + ROUND_MAGIC).to_bits() as u8)
    }
}

impl FromNormal for [u16; 3] {
    #[inline(always)]
    fn from_normal(n: [f64; 3]) -> Self {
        n.map(|c| ((c + 1.0) * 32767.5 + ROUND_MAGIC).to_bits() as u16)
    }
}

/// Unit normals of a `width` × `height` height map, as `[x, y, z]` in
/// [−1, 1], row-major: a convenience over [`FitRequest`], the fit's one
/// way in, for the plainest request (the whole image, no residual, a new
/// buffer of `[f32; 3]`).
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
///
/// Errors: as [`FitRequest::normals_into`].
pub fn normals<H: Sample>(heights: &[H], width: usize, height: usize, opts: &Options) -> Result<Vec<[f32; 3]>> {
    let mut out = vec![[0.0f32; 3]; checked_len(width, height)?];
    FitRequest::new(opts).normals_into(heights, width, height, &mut out)?;
    Ok(out)
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
/// the same, bit for bit, as [`FitRequest`] gives for the whole image.
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
    /// Missing texels in the bands fitted so far.
    missing: std::sync::atomic::AtomicUsize,
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
        Ok(BandFit { plan, height, band_rows, unit: None, missing: 0.into() })
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
        self.fit_band_with(rows, row, out, None).map(|_| ())
    }

    /// Like [`fit_band`](Self::fit_band), with holes (see
    /// [`FitRequest::holes`]): `valid` (as long as `out`) gets whether
    /// each texel has a normal. Returns the band's count of missing texels.
    /// The texels and `valid` are the same, bit for bit, as
    /// [`FitRequest::holes`] gives for the whole image.
    ///
    /// Errors: as [`fit_band`](Self::fit_band), but no
    /// [`Error::NonFiniteHeight`].
    pub fn fit_band_masked<'a, H: Sample, T: FromNormal>(
        &self,
        rows: Range<usize>,
        row: &(dyn Fn(usize) -> &'a [H] + Sync),
        out: &mut [T],
        valid: &mut [bool],
    ) -> Result<usize> {
        self.fit_band_with(rows, row, out, Some(valid))
    }

    /// Whether the fit has holes ([`Options::nodata`] is set): then
    /// [`fit_band`](Self::fit_band) writes missing texels flat, and
    /// [`fit_band_masked`](Self::fit_band_masked) says which they are.
    #[must_use]
    pub fn has_nodata(&self) -> bool {
        self.plan.nodata.is_some()
    }

    /// The missing texels of every band fitted so far (by either call).
    #[must_use]
    pub fn missing(&self) -> usize {
        self.missing.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn fit_band_with<'a, H: Sample, T: FromNormal>(
        &self,
        rows: Range<usize>,
        row: &(dyn Fn(usize) -> &'a [H] + Sync),
        out: &mut [T],
        valid: Option<&mut [bool]>,
    ) -> Result<usize> {
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
        if let Some(valid) = &valid
            && valid.len() != out.len()
        {
            return Err(Error::BufferSize { expected: out.len(), actual: valid.len() });
        }
        let masked = self.plan.nodata.is_some() || valid.is_some();
        let nodata = self.plan.nodata.unwrap_or(f64::NAN);
        // Source row p − r's holes, for the padded rows p the band reads.
        let mut holes = Vec::new();
        for p in rows.start..rows.end + 2 * self.plan.r {
            let y = self.plan.source_y(p);
            let r = row(y);
            if r.len() != w {
                return Err(Error::BufferSize { expected: w, actual: r.len() });
            }
            if masked {
                holes.push(row_has_hole(r, nodata));
            } else if let Some((x, _)) = first_non_finite(r, w) {
                return Err(Error::NonFiniteHeight { x, y });
            }
        }
        let unit = self.unit.unwrap_or(H::UNIT);
        if !masked {
            let source = |v: isize| RowRef { values: row(self.plan.borders.y.map(v, h)), x0: 0, holes: false };
            self.plan.fit_rows(&source, unit, (rows.start, 0..w), out, None, None);
            return Ok(0);
        }
        let first = rows.start as isize - self.plan.r as isize;
        let source = |v: isize| RowRef {
            values: row(self.plan.borders.y.map(v, h)),
            x0: 0,
            holes: holes.get((v - first) as usize).copied().unwrap_or(true),
        };
        let mut own = if valid.is_none() { vec![false; out.len()] } else { Vec::new() };
        let valid = match valid {
            Some(valid) => valid,
            None => &mut own[..],
        };
        self.plan.fit_rows(&source, unit, (rows.start, 0..w), out, None, Some((&mut *valid, nodata)));
        let missing = valid.iter().filter(|&&v| !v).count();
        self.missing.fetch_add(missing, std::sync::atomic::Ordering::Relaxed);
        Ok(missing)
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

/// Texels per branch between the two loops of the orthogonal fit's
/// normals (see [`Plan::emit_with`]).
const EMIT_CHUNK: usize = 32;

/// Columns per parallel task of the fit (at least 8·N): the
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

/// A strip's holes: the valid points' moments, the strip's rows of
/// `valid`, and the nodata value.
struct StripHoles<'t> {
    mask: MaskSums,
    patches: MaskedRow,
    valid: Vec<&'t mut [bool]>,
    nodata: f64,
}

/// One parallel task of the fit: a strip of a tile, its rows from `y0`,
/// its columns from `x0`, as pieces of the output rows (and of the
/// residual rows, when asked for).
struct Strip<'t, T> {
    y0: usize,
    x0: usize,
    out: Vec<&'t mut [T]>,
    residual: Option<Vec<&'t mut [f32]>>,
    /// With holes: whether each texel has a normal, by row, and the
    /// nodata value.
    valid: Option<(Vec<&'t mut [bool]>, f64)>,
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
    /// Emit each texel's patch moments [Cx, Cy, Czz] instead of its normal
    /// (the height inverse's re-fit, [`BandFit::moments`]).
    moments: bool,
    /// Map units ([`Units::Map`]): the texel spacing, and heights taken as
    /// the values given whatever their type. `None`: the contract's units.
    spacing: Option<Spacing>,
    /// [`Options::nodata`].
    nodata: Option<f64>,
    /// The normal written at a missing texel ([`FitRequest::missing`]).
    missing: [f64; 3],
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
        let spacing = match &opts.units {
            Units::Texels => None,
            Units::Map(spacing) => {
                spacing.validate(Some(height))?;
                Some(spacing.clone())
            }
        };
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
            moments: false,
            spacing,
            nodata: opts.nodata,
            missing: [0.0, 0.0, 1.0],
        })
    }

    /// Fits the output rows from `y0`, columns `cols`, into `out` (rows of
    /// `cols.len()` texels), tile by tile and strip by strip in parallel.
    /// `rows(v)` gives source row v for every v the patches reach (beyond
    /// the image's edges too: the caller's source maps them). `residual`,
    /// when given, holds as many texels as `out` and gets the fit's RMS
    /// distances.
    ///
    /// Every texel's sums come from its own patch by the same operations
    /// whichever tile, strip or window holds it (see the module docs), so
    /// the cuts change no result. Tiles: the top r rows, then `block_rows`
    /// at a time, so that a streaming caller's bands are whole tiles.
    /// Strips of about 512 columns are the tasks that run in parallel: many
    /// small tasks keep both cores busy beside the pipeline's other threads
    /// (two tasks a band left one core idle while the other finished its
    /// tile), and a strip's sums stay in the core's cache.
    fn fit_rows<'a, H: Sample, T: FromNormal>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        unit: f64,
        (y0, cols): (usize, Range<usize>),
        out: &mut [T],
        residual: Option<&mut [f32]>,
        valid: Option<(&mut [bool], f64)>,
    ) {
        let w = cols.len();
        let strip = self.strip_cols();
        let mut tasks: Vec<Strip<'_, T>> = Vec::new();
        let nodata = valid.as_ref().map(|v| v.1);
        let (mut y, mut rest, mut rest_residual) = (y0, out, residual);
        let mut rest_valid = valid.map(|v| v.0);
        while !rest.is_empty() {
            let tile_rows = if y < self.r { self.r - y } else { self.block_rows - (y - self.r) % self.block_rows };
            let len = (tile_rows * w).min(rest.len());
            let (tile, tail) = rest.split_at_mut(len);
            let (tile_residual, residual_tail) = match rest_residual {
                Some(r) => {
                    let (head, tail) = r.split_at_mut(len);
                    (Some(head), Some(tail))
                }
                None => (None, None),
            };
            let (tile_valid, valid_tail) = match rest_valid {
                Some(v) => {
                    let (head, tail) = v.split_at_mut(len);
                    (Some(head), Some(tail))
                }
                None => (None, None),
            };
            let first = tasks.len();
            for x0 in cols.clone().step_by(strip) {
                let has_residual = tile_residual.is_some();
                let valid = nodata.map(|nd| (Vec::new(), nd));
                tasks.push(Strip { y0: y, x0, out: Vec::new(), residual: has_residual.then(Vec::new), valid });
            }
            if let Some(tile_valid) = tile_valid {
                for row in tile_valid.chunks_exact_mut(w) {
                    for (task, piece) in tasks[first..].iter_mut().zip(row.chunks_mut(strip)) {
                        task.valid.as_mut().expect("a valid strip").0.push(piece);
                    }
                }
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
            y += tile_rows;
            rest = tail;
            rest_residual = residual_tail;
            rest_valid = valid_tail;
        }
        // Map units take every value as it is given (a DEM's metres).
        let unit = if self.spacing.is_some() { 1.0 } else { unit };
        // The product of S and the unit, once: every path that fits these
        // samples forms the same gain, and so the same bits.
        let gain = self.scale * unit;
        // A unit below 1 is that of stored integers (1/255, 1/65535).
        let integers = unit != 1.0;
        tasks.into_par_iter().for_each(|task| match (integers, self.n) {
            (true, _) => self.fit_strip_sliding(rows, gain, task),
            (false, 3) => self.fit_strip_direct::<H, T, 3>(rows, gain, task),
            (false, 5) => self.fit_strip_direct::<H, T, 5>(rows, gain, task),
            (false, 7) => self.fit_strip_direct::<H, T, 7>(rows, gain, task),
            (false, _) => self.fit_strip_blocked(rows, gain, task),
        });
    }

    /// The holes of one strip: `None` when no row it reads holds one (every
    /// texel is then valid, and the strip is fitted as without holes).
    fn strip_holes<'t, 'a, H: Sample>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        y0: usize,
        len: usize,
        cols: Range<usize>,
        valid: Option<(Vec<&'t mut [bool]>, f64)>,
    ) -> Option<StripHoles<'t>> {
        let (mut valid, nodata) = valid?;
        let r = self.r as isize;
        if !(y0 as isize - r..(y0 + len) as isize + r).any(|v| rows(v).holes) {
            valid.iter_mut().for_each(|row| row.fill(true));
            return None;
        }
        Some(StripHoles { mask: MaskSums::new(cols), patches: MaskedRow::default(), valid, nodata })
    }

    /// Makes the valid points' sums those of output row `y`, and marks in
    /// `v` the patches that hold a hole, before [`Self::emit`].
    fn advance_holes<'a, H: Sample>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        y: usize,
        holes: &mut StripHoles<'_>,
        v: &mut WindowSums,
    ) {
        holes.mask.advance(self, rows, y as isize, holes.nodata);
        let n2 = (self.n * self.n) as i64;
        v.with_hole.clear();
        v.with_hole.extend(holes.mask.c.iter().map(|&c| c != n2));
    }

    /// Refits the texels of output row `y` (row `k` of the strip) whose
    /// patch has a hole, from the valid points' moments (see `masked`;
    /// [`Self::advance_holes`] made them), over what [`Self::emit`] wrote,
    /// and marks the missing ones. `v` and `gain` are as `emit` took them.
    fn patch_holes<T: FromNormal>(
        &self,
        v: &WindowSums,
        gain: f64,
        (y, k): (usize, usize),
        holes: &mut StripHoles<'_>,
        out: &mut [T],
        residual: Option<&mut [f32]>,
    ) {
        let StripHoles { mask, patches, valid, .. } = holes;
        let valid = &mut valid[k];
        valid.fill(true);
        let n2 = (self.n * self.n) as i64;
        if mask.full(n2) {
            return;
        }
        let ([sx, _], rho) = self.spacing_at(y);
        let g = gain / sx;
        patches.clear(out.len());
        for x in (0..out.len()).filter(|&x| mask.c[x] != n2) {
            let moments = Moments {
                c: mask.c[x],
                geometry: [mask.si[x], mask.sj[x], mask.sii[x], mask.sjj[x], mask.sij[x]],
                z: [g * v.s0[x], g * v.si[x], g * v.sj[x], g * g * v.szz[x]],
            };
            patches.push(x, mask.centre[x], &moments);
        }
        patches.solve(self.fit == Fit::Orthogonal, rho, self.sigma);
        patches.store(out, valid, residual, sx, T::from_normal(self.missing));
    }

    /// The source row of padded row p = y + j + r, through the y border.
    #[inline]
    fn source_y(&self, p: usize) -> usize {
        self.borders.y.map(p as isize - self.r as isize, self.height)
    }

    /// Columns per parallel task: about 512, and at least 8·N, so that
    /// starting a strip's sums (N steps a row) costs at most an eighth of
    /// the strip's work.
    fn strip_cols(&self) -> usize {
        STRIP_COLS.max(8 * self.n)
    }

    /// The heights of columns `lo .. hi` of `src`, times `gain`, into
    /// `padded`: those that `src` holds as they are, the others through
    /// the x border (which the caller made sure maps them into `src`).
    #[inline]
    fn padded_row<H: Sample>(&self, src: RowRef<'_, H>, (lo, hi): (isize, isize), gain: f64, padded: &mut Vec<f64>) {
        padded.clear();
        let (a, b) = (lo - src.x0, hi - src.x0);
        if src.holes {
            // A hole adds nothing to the z sums (see `masked`).
            let nodata = self.nodata.unwrap_or(f64::NAN);
            let value = |u: isize| {
                let at = if (src.x0..src.x0 + src.values.len() as isize).contains(&u) {
                    u
                } else {
                    self.borders.x.map(u, self.width) as isize
                };
                let h = src.values[(at - src.x0) as usize].to_f64();
                if masked::is_hole(h, nodata) { 0.0 } else { gain * h }
            };
            if a >= 0 && b <= src.values.len() as isize {
                let values = &src.values[a as usize..b as usize];
                padded.extend(values.iter().map(|&h| {
                    let h = h.to_f64();
                    if masked::is_hole(h, nodata) { 0.0 } else { gain * h }
                }));
            } else {
                padded.extend((lo..hi).map(value));
            }
        } else if a >= 0 && b <= src.values.len() as isize {
            // Away from the borders: a slice, and a loop that vectorises.
            padded.extend(src.values[a as usize..b as usize].iter().map(|&h| gain * h.to_f64()));
        } else {
            self.bordered_row(src, (lo, hi), gain, padded);
        }
    }

    /// [`Self::padded_row`] where some column is not in `src`. Out of
    /// line: only a row's first and last strips come here, and the hot
    /// loop stays small.
    #[inline(never)]
    fn bordered_row<H: Sample>(&self, src: RowRef<'_, H>, (lo, hi): (isize, isize), gain: f64, padded: &mut Vec<f64>) {
        let held = src.x0..src.x0 + src.values.len() as isize;
        let (inside_lo, inside_hi) = (lo.max(held.start).min(hi), hi.min(held.end).max(lo));
        let value = |u: isize| {
            let at = if held.contains(&u) { u } else { self.borders.x.map(u, self.width) as isize };
            gain * src.values[(at - src.x0) as usize].to_f64()
        };
        padded.extend((lo..inside_lo).map(value));
        let inside = &src.values[(inside_lo - src.x0) as usize..(inside_hi - src.x0) as usize];
        padded.extend(inside.iter().map(|&h| gain * h.to_f64()));
        padded.extend((inside_hi..hi).map(value));
    }

    /// Fits one strip of stored integers by running sums. Sums of the
    /// integers themselves are exact in f64 (below 2^53 for 16 bits and
    /// N ≤ 63), so adding the entering texel and removing the leaving one
    /// gives every texel exactly the sums of its own patch, wherever the
    /// run started; the gain comes after, in the normals.
    fn fit_strip_sliding<'a, H: Sample, T: FromNormal>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        gain: f64,
        strip: Strip<'_, T>,
    ) {
        let Strip { y0, x0, mut out, mut residual, valid } = strip;
        let Some(first) = out.first() else { return };
        let n = self.n;
        let cols = x0..x0 + first.len();
        let w = cols.len();
        let row_of = |p: usize| rows(p as isize - self.r as isize);
        let mut holes = self.strip_holes(rows, y0, out.len(), cols.clone(), valid);

        // Ring of the N rows' horizontal sums: slot p % N holds padded row p.
        let mut ring: Vec<RowSums> = (y0..y0 + n)
            .map(|p| {
                let mut sums = RowSums::zeros(w);
                self.sliding_row_sums(row_of(p), cols.clone(), &mut sums);
                sums
            })
            .collect();
        ring.rotate_right(y0 % n);
        let mut entering = RowSums::zeros(w);
        let mut scratch = EmitScratch::new(w);

        let mut v = WindowSums::zeros(w);
        for j in 0..n {
            v.add(&ring[(y0 + j) % n], j as f64 - self.r as f64);
        }

        let (rf, r1) = (self.r as f64, self.r as f64 + 1.0);
        for (k, out_row) in out.iter_mut().enumerate() {
            if k > 0 {
                // Slide down one row: padded row p_in enters, p_out leaves.
                let p_out = y0 + k - 1;
                let p_in = p_out + n;
                self.sliding_row_sums(row_of(p_in), cols.clone(), &mut entering);
                v.slide(&ring[p_out % n], &entering, rf, r1);
                std::mem::swap(&mut ring[p_out % n], &mut entering);
            }
            if let Some(holes) = holes.as_mut() {
                self.advance_holes(rows, y0 + k, holes, &mut v);
            }
            self.emit(&v, gain, y0 + k, &mut scratch, out_row);
            if let Some(residual) = residual.as_mut() {
                self.emit_residual(&v, gain, y0 + k, &mut scratch, residual[k]);
            }
            if let Some(holes) = holes.as_mut() {
                self.patch_holes(&v, gain, (y0 + k, k), holes, out_row, residual.as_mut().map(|r| &mut *r[k]));
            }
        }
    }

    /// Σh, Σih, Σh² over each column's horizontal window of one source row
    /// of integers, by a running sum along the strip.
    fn sliding_row_sums<H: Sample>(&self, src: RowRef<'_, H>, cols: Range<usize>, out: &mut RowSums) {
        // Disjoint borrows, and below slices of the strip's length: the
        // sliding loop then keeps every pointer in a register and has no
        // bounds checks (through `out`, it reloaded the planes' pointers
        // and lengths at every texel, 17 % more instructions).
        let RowSums { s0: out_s0, si: out_si, szz: out_szz, padded, .. } = out;
        let (n, r) = (self.n, self.r);
        let (rf, r1) = (r as f64, r as f64 + 1.0);
        let w = cols.len();
        self.padded_row(src, (cols.start as isize - r as isize, (cols.end + r) as isize), 1.0, padded);
        let (mut s0, mut si, mut szz) = (0.0, 0.0, 0.0);
        for (q, &z) in padded[..n].iter().enumerate() {
            s0 += z;
            si += (q as f64 - rf) * z;
            szz += z * z;
        }
        let (out_s0, out_si, out_szz) = (&mut out_s0[..w], &mut out_si[..w], &mut out_szz[..w]);
        out_s0[0] = s0;
        out_si[0] = si;
        out_szz[0] = szz;
        // Texel k (k ≥ 1): padded[k − 1] leaves the window, padded[k − 1 + n] enters it.
        let slides = padded.iter().zip(&padded[n..]);
        let outs = out_s0[1..].iter_mut().zip(&mut out_si[1..]).zip(&mut out_szz[1..]);
        for ((&leaving, &entering), ((o0, oi), ozz)) in slides.zip(outs) {
            s0 += entering - leaving;
            si += rf * leaving + r1 * entering - s0;
            szz += entering * entering - leaving * leaving;
            *o0 = s0;
            *oi = si;
            *ozz = szz;
        }
    }

    /// Fits one strip of floats with a small patch (N ≤ 7) by summing each
    /// texel's patch outright, its values in order along the row and then
    /// its rows in order: a texel's sums are made from its patch alone, the
    /// same bits in whatever strip, tile or window it is computed. At this
    /// size the sums take no more work than running sums, and the loops
    /// run across the columns, so they vectorise.
    fn fit_strip_direct<'a, H: Sample, T: FromNormal, const N: usize>(
        &self,
        rows: &SourceRows<'_, 'a, H>,
        gain: f64,
        strip: Strip<'_, T>,
    ) {
        let Strip { y0, x0, mut out, mut residual, valid } = strip;
        let Some(first) = out.first() else { return };
        let r = (N / 2) as isize;
        let cols = x0..x0 + first.len();
        let w = cols.len();
        let row_sums = |v: isize, sums: &mut RowSums| self.direct_row_sums::<H, N>(rows(v), gain, cols.clone(), sums);
        let mut holes = self.strip_holes(rows, y0, out.len(), cols.clone(), valid);
        let mut cache = RowCache::new(N, w);
        let mut v = WindowSums::zeros(w);
        let mut scratch = EmitScratch::new(w);
        for (k, out_row) in out.iter_mut().enumerate() {
            let y = (y0 + k) as isize;
            for j in 0..N as isize {
                cache.get(y - r + j, &row_sums);
            }
            let patch_rows: [&RowSums; N] = std::array::from_fn(|j| cache.held(y - r + j as isize));
            v.sum_rows(&patch_rows);
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

    /// Σz, Σiz, Σz² (z = gain · h) over each column's horizontal window of
    /// one source row, each window summed outright (see
    /// [`Self::fit_strip_direct`]).
    fn direct_row_sums<H: Sample, const N: usize>(
        &self,
        src: RowRef<'_, H>,
        gain: f64,
        cols: Range<usize>,
        out: &mut RowSums,
    ) {
        let RowSums { s0: out_s0, si: out_si, szz: out_szz, padded, squares, .. } = out;
        let r = N / 2;
        let w = cols.len();
        self.padded_row(src, (cols.start as isize - r as isize, (cols.end + r) as isize), gain, padded);
        // Σiz pairs the texels at ±d: Σ d·(z[r + d] − z[r − d]).
        squares.clear();
        squares.extend(padded.iter().map(|z| z * z));
        let outs = out_s0[..w].iter_mut().zip(&mut out_si[..w]).zip(&mut out_szz[..w]);
        for ((window, squares), ((o0, oi), ozz)) in padded.windows(N).zip(squares.windows(N)).zip(outs) {
            let z: &[f64; N] = window.try_into().expect("windows of N");
            let zz: &[f64; N] = squares.try_into().expect("windows of N");
            let (mut s0, mut si, mut szz) = (z[0], z[r + 1] - z[r - 1], zz[0]);
            for q in 1..N {
                s0 += z[q];
                szz += zz[q];
            }
            for d in 2..=r {
                si += d as f64 * (z[r + d] - z[r - d]);
            }
            *o0 = s0;
            *oi = si;
            *ozz = szz;
        }
    }

    /// Fits one strip of floats by sums over blocks aligned on the image
    /// (van Herk, Gil–Werman). Output texel t of block k (x = kN + t,
    /// 0 ≤ t < N) has the window [x − r, x + r]: the suffix of the values
    /// [kN − r, kN + r] from x − r, plus the prefix of the next N values up
    /// to x + r (empty for t = 0). Each is summed in a fixed order from
    /// values of the patch alone, across and then down, so a texel's sums
    /// are the same bits in whatever strip, tile or window it is computed
    /// (running sums of floats would carry the rounding of wherever they
    /// started); the cost per texel stays flat in N.
    fn fit_strip_blocked<'a, H: Sample, T: FromNormal>(
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
        let y_end = y0 + out.len();
        let mut holes = self.strip_holes(rows, y0, out.len(), cols.clone(), valid);

        // Horizontal sums of the source rows a block of output rows and
        // the next one read (2N rows), in slot v mod 2N.
        let mut cache = RowCache::new(2 * n, w);
        let row_sums = |v: isize, sums: &mut RowSums| self.blocked_row_sums(rows(v), gain, cols.clone(), sums);
        let mut suffix: Vec<WindowSums> = (0..n).map(|_| WindowSums::zeros(w)).collect();
        let (zero, mut prefix, mut v) = (WindowSums::zeros(w), WindowSums::zeros(w), WindowSums::zeros(w));
        let mut scratch = EmitScratch::new(w);

        for block in y0 / n..=(y_end - 1) / n {
            let top = (block * n) as isize;
            let ts = y0.saturating_sub(block * n)..(y_end - block * n).min(n);
            // Weights j relative to o = top + r + 1, the next block's first
            // source row; output row t's own offsets are j − (t − r − 1).
            let o = top + r + 1;
            // Suffixes, in place: suffix[t] = suffix[t + 1] + row top + t − r
            // (rows top + r down to top + t − r, the last alone).
            for t in (ts.start..n).rev() {
                let u = top + t as isize - r;
                let h = cache.get(u, &row_sums);
                let (lower, upper) = suffix.split_at_mut(t + 1);
                let previous = upper.first().unwrap_or(&zero);
                lower[t].set_sum(previous, h, (u - o) as f64);
            }
            // Prefixes: rows top + r + 1 up to top + r + t; the row that
            // completes one goes in with the combination, in one pass.
            prefix.clear();
            let mut through = top + r;
            for t in ts.clone() {
                let shift = (t as isize - r - 1) as f64;
                let wanted = top + r + t as isize;
                while through + 1 < wanted {
                    through += 1;
                    prefix.add(cache.get(through, &row_sums), (through - o) as f64);
                }
                if through < wanted {
                    through += 1;
                    prefix.add_then_combine(
                        cache.get(through, &row_sums),
                        (through - o) as f64,
                        &suffix[t],
                        shift,
                        &mut v,
                    );
                } else {
                    v.combine(&suffix[t], &prefix, shift);
                }
                let k = block * n + t - y0;
                if let Some(holes) = holes.as_mut() {
                    self.advance_holes(rows, y0 + k, holes, &mut v);
                }
                self.emit(&v, 1.0, y0 + k, &mut scratch, out[k]);
                if let Some(residual) = residual.as_mut() {
                    self.emit_residual(&v, 1.0, y0 + k, &mut scratch, residual[k]);
                }
                if let Some(holes) = holes.as_mut() {
                    self.patch_holes(&v, 1.0, (y0 + k, k), holes, out[k], residual.as_mut().map(|r| &mut *r[k]));
                }
            }
        }
    }

    /// Σz, Σiz, Σz² (z = gain · h) over each column's horizontal window of
    /// one source row, from block-aligned suffix and prefix sums (see
    /// [`Self::fit_strip_blocked`]).
    fn blocked_row_sums<H: Sample>(&self, src: RowRef<'_, H>, gain: f64, cols: Range<usize>, out: &mut RowSums) {
        let RowSums { s0: out_s0, si: out_si, szz: out_szz, padded, suffix, prefix, .. } = out;
        let (n, r) = (self.n, self.r);
        self.padded_row(src, (cols.start as isize - r as isize, (cols.end + r) as isize), gain, padded);
        // Weights relative to the next block's first value (q = 2r + 1).
        let weight = |q: usize| q as f64 - (2 * r + 1) as f64;
        suffix.resize(n, [0.0; 3]);
        prefix.resize(n, [0.0; 3]);
        for block in cols.start / n..=(cols.end - 1) / n {
            let bx = block * n;
            let ts = cols.start.saturating_sub(bx)..(cols.end - bx).min(n);
            // Value q of the block (column bx − r + q) is padded[bx + q − cols.start].
            let z = &padded[bx + ts.start - cols.start..];
            let at = |q: usize| z[q - ts.start];
            // The suffixes (values q = 2r down to t) and the prefixes
            // (values q = 2r + 1 up to 2r + t) in one loop while both run:
            // six chains of additions side by side rather than three.
            let (suffix_steps, prefix_steps) = (n - ts.start, ts.end.saturating_sub(1));
            let (mut a0, mut ai, mut azz) = (0.0, 0.0, 0.0);
            let (mut p0, mut pi, mut pzz) = (0.0, 0.0, 0.0);
            let mut suffix_step = |i: usize| {
                let q = 2 * r - i;
                let zq = at(q);
                a0 += zq;
                ai += weight(q) * zq;
                azz += zq * zq;
                suffix[q] = [a0, ai, azz];
            };
            let mut prefix_step = |i: usize| {
                let q = 2 * r + 1 + i;
                let zq = at(q);
                p0 += zq;
                pi += weight(q) * zq;
                pzz += zq * zq;
                prefix[i + 1] = [p0, pi, pzz];
            };
            let both = suffix_steps.min(prefix_steps);
            for i in 0..both {
                suffix_step(i);
                prefix_step(i);
            }
            (both..suffix_steps).for_each(&mut suffix_step);
            (both..prefix_steps).for_each(&mut prefix_step);
            prefix[0] = [0.0; 3];
            for t in ts {
                let ([a0, ai, azz], [p0, pi, pzz]) = (suffix[t], prefix[t]);
                let h0 = a0 + p0;
                let x = bx + t - cols.start;
                out_s0[x] = h0;
                out_si[x] = (ai + pi) - (t as f64 - r as f64 - 1.0) * h0;
                out_szz[x] = azz + pzz;
            }
        }
    }

    /// Turns the window sums of one row into normals, through `scratch`'s
    /// planes (x, y and z): the fit's loop then stores whole vectors, and
    /// the texel type's conversion is a loop of its own. The sums are in
    /// units of z / `gain` (stored integers), or of z (`gain` 1); `y` is
    /// the image row, whose spacing map units fit with.
    fn emit<T: FromNormal>(&self, v: &WindowSums, gain: f64, y: usize, scratch: &mut EmitScratch, out: &mut [T]) {
        let normal = &mut scratch.normal;
        if self.moments {
            let n2 = (self.n * self.n) as f64;
            let czz_gain = gain * gain / n2;
            let w = out.len();
            let (s0, si, sj, szz) = (&v.s0[..w], &v.si[..w], &v.sj[..w], &v.szz[..w]);
            for (x, texel) in out.iter_mut().enumerate() {
                *texel = T::from_normal([gain * si[x], gain * sj[x], Self::czz(n2, czz_gain, s0[x], szz[x])]);
            }
            return;
        }
        // Lengths in units of the x spacing: z / sx, and ρ = sy / sx the
        // rows' spacing. In texel units, and for square pixels, ρ = 1 and
        // the contract's square-grid formulas run (sx = 1: the same bits).
        let ([sx, _], rho) = self.spacing_at(y);
        let gain = gain / sx;
        // One loop per fit, so the per-texel work has no branch and vectorises.
        match self.fit {
            Fit::Orthogonal if rho == 1.0 => {
                pulp::Arch::new().dispatch(EmitRow::<T, true> { plan: self, v, gain, normal, out })
            }
            Fit::Vertical if rho == 1.0 => {
                pulp::Arch::new().dispatch(EmitRow::<T, false> { plan: self, v, gain, normal, out })
            }
            fit => {
                let row = RowSpacing { gain, rho, orthogonal: fit == Fit::Orthogonal };
                scratch.unequal.normals(self, v, row, normal, out);
            }
        }
    }

    /// Czz = (N²·Σz² − (Σz)²) / N² times the gain², from one column's
    /// sums: for stored integers the numerator is exact (below 2^53 for
    /// 8 bits, and for 16 bits up to N = 37; beyond, A dwarfs its
    /// rounding), and it does not cancel as Σz² − (Σz)²/N² would.
    #[inline(always)]
    fn czz(n2: f64, czz_gain: f64, s0: f64, szz: f64) -> f64 {
        ((n2 * szz - s0 * s0) * czz_gain).max(0.0)
    }

    /// The spacing `[sx, sy]` of image row `y` and ρ = sy / sx: `[1, 1]`
    /// and 1 in texel units.
    #[inline]
    fn spacing_at(&self, y: usize) -> ([f64; 2], f64) {
        match &self.spacing {
            None => ([1.0, 1.0], 1.0),
            Some(spacing) => {
                let [sx, sy] = spacing.at(y);
                ([sx, sy], sy / sx)
            }
        }
    }

    #[inline(always)]
    fn emit_with<const ORTHOGONAL: bool>(&self, v: &WindowSums, gain: f64, normal: &mut [Vec<f64>; 3]) {
        let n2 = (self.n * self.n) as f64;
        let czz_gain = gain * gain / n2;
        let (gx, gy) = (gain, self.sigma * gain);
        let [nx, ny, nz] = normal;
        let w = nx.len();
        let (s0, si, sj, szz) = (&v.s0[..w], &v.si[..w], &v.sj[..w], &v.szz[..w]);
        let (ny, nz) = (&mut ny[..w], &mut nz[..w]);
        let czz_at = |x: usize| Self::czz(n2, czz_gain, s0[x], szz[x]);
        for start in (0..w).step_by(EMIT_CHUNK) {
            let texels = start..(start + EMIT_CHUNK).min(w);
            // Only a patch whose heights spread more than its columns and
            // rows (Czz > A) needs the orthogonal fit's division; most
            // chunks have none, and their loop leaves it out (the
            // division took a tenth of the fit), with the same results.
            // A patch with a hole (read as 0: a cliff) is refitted after,
            // whatever this loop gives it, and does not make its chunk steep.
            let steep = ORTHOGONAL
                && if v.with_hole.is_empty() {
                    texels.clone().any(|x| czz_at(x) > self.a)
                } else {
                    texels.clone().any(|x| czz_at(x) > self.a && !v.with_hole[x])
                };
            if steep {
                for x in texels {
                    let n = normal_from_sums::<ORTHOGONAL, true>(self.a, gx * si[x], gy * sj[x], czz_at(x));
                    [nx[x], ny[x], nz[x]] = n;
                }
            } else {
                for x in texels {
                    let n = normal_from_sums::<ORTHOGONAL, false>(self.a, gx * si[x], gy * sj[x], czz_at(x));
                    [nx[x], ny[x], nz[x]] = n;
                }
            }
        }
    }

    /// The RMS distance of each texel's patch points from its fitted plane,
    /// in surface units, from the window sums of one row. A loop of its
    /// own, run only when asked for, so the normals' loop stays as it is.
    /// In map units, the distances are in the heights' unit (the fit's
    /// lengths in x spacings, times sx).
    fn emit_residual(&self, v: &WindowSums, gain: f64, y: usize, scratch: &mut EmitScratch, out: &mut [f32]) {
        let ([sx, _], rho) = self.spacing_at(y);
        let gain = gain / sx;
        match self.fit {
            // The vertical fit's residual does not depend on ρ: ordinary
            // least squares leaves the same residual however its regressors
            // are scaled. The orthogonal fit's is the smallest eigenvalue
            // of the scatter matrix.
            Fit::Orthogonal if rho != 1.0 => {
                scratch.unequal.residuals(self, v, RowSpacing { gain, rho, orthogonal: true }, sx, out)
            }
            Fit::Orthogonal => self.emit_residual_with::<true>(v, gain, sx, out),
            Fit::Vertical => self.emit_residual_with::<false>(v, gain, sx, out),
        }
    }

    fn emit_residual_with<const ORTHOGONAL: bool>(&self, v: &WindowSums, gain: f64, sx: f64, out: &mut [f32]) {
        let n2 = (self.n * self.n) as f64;
        let (inv_n2, czz_gain) = (1.0 / n2, gain * gain / n2);
        let w = out.len();
        let (s0, si, sj, szz) = (&v.s0[..w], &v.si[..w], &v.sj[..w], &v.szz[..w]);
        for x in 0..w {
            let czz = Self::czz(n2, czz_gain, s0[x], szz[x]);
            let sum = squared_distance_sum::<ORTHOGONAL>(self.a, gain * si[x], gain * sj[x], czz);
            out[x] = ((sum * inv_n2).sqrt() * sx) as f32;
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

/// [`Plan::emit_with`] and the texels' conversion, for
/// [`pulp::Arch::dispatch`]: compiled for the widest vectors the processor
/// has (AVX2 where baseline x86-64 has SSE2's two lanes of f64), chosen at
/// run time. The square roots and divisions were a fifth of a lit view's
/// processor time. They, and the other operations, round alike in every
/// instruction set, and nothing fuses a multiply with an add: the same
/// bits on every processor.
struct EmitRow<'a, T, const ORTHOGONAL: bool> {
    plan: &'a Plan,
    v: &'a WindowSums,
    gain: f64,
    normal: &'a mut [Vec<f64>; 3],
    out: &'a mut [T],
}

impl<T: FromNormal, const ORTHOGONAL: bool> pulp::WithSimd for EmitRow<'_, T, ORTHOGONAL> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        // Inlined here, so that it is compiled for each instruction set.
        let EmitRow { plan, v, gain, normal, out } = self;
        plan.emit_with::<ORTHOGONAL>(v, gain, normal);
        store_normals(normal, out);
    }
}

/// The texels of a row's normals (x, y and z planes).
#[inline(always)]
fn store_normals<T: FromNormal>([nx, ny, nz]: &[Vec<f64>; 3], out: &mut [T]) {
    for (((texel, &x), &y), &z) in out.iter_mut().zip(nx.iter()).zip(ny.iter()).zip(nz.iter()) {
        *texel = T::from_normal([x, y, z]);
    }
}

/// A strip's planes for turning window sums into texels, kept from row
/// to row: the normals' x, y and z planes, and the unequal spacing's.
struct EmitScratch {
    normal: [Vec<f64>; 3],
    unequal: UnequalRow,
}

impl EmitScratch {
    fn new(width: usize) -> Self {
        EmitScratch { normal: [vec![0.0; width], vec![0.0; width], vec![0.0; width]], unequal: UnequalRow::default() }
    }
}

/// A source row as the fit reads it: heights, and the image column of the
/// first (a window's rows start left of the image's edge, or inside it).
struct RowRef<'a, H> {
    values: &'a [H],
    x0: isize,
    /// Whether the row may hold holes (values read as 0 in the z sums).
    holes: bool,
}

impl<H> Clone for RowRef<'_, H> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<H> Copy for RowRef<'_, H> {}

/// Source row v of the fit, for every v its patches reach: an image row,
/// or (beyond the image's top and bottom) the row the y border gives.
type SourceRows<'s, 'a, H> = dyn Fn(isize) -> RowRef<'a, H> + Sync + 's;

/// One row's horizontal sums per column, as planes so the loops vectorise.
struct RowSums {
    s0: Vec<f64>,
    si: Vec<f64>,
    szz: Vec<f64>,
    /// Scratch: the row's heights with their borders.
    padded: Vec<f64>,
    /// Scratch: a block's suffix and prefix sums (floats).
    suffix: Vec<[f64; 3]>,
    prefix: Vec<[f64; 3]>,
    /// Scratch: the squares of `padded` (floats).
    squares: Vec<f64>,
}

impl RowSums {
    fn zeros(width: usize) -> Self {
        let z = vec![0.0; width];
        RowSums {
            s0: z.clone(),
            si: z.clone(),
            szz: z,
            padded: Vec::new(),
            suffix: Vec::new(),
            prefix: Vec::new(),
            squares: Vec::new(),
        }
    }
}

/// The horizontal sums of the last source rows read, by row: slot v mod
/// the slots holds row v.
struct RowCache {
    rows: Vec<(isize, RowSums)>,
}

impl RowCache {
    fn new(slots: usize, width: usize) -> Self {
        RowCache { rows: (0..slots).map(|_| (isize::MIN, RowSums::zeros(width))).collect() }
    }

    /// Row v's sums, which [`Self::get`] made last.
    fn held(&self, v: isize) -> &RowSums {
        let (held, sums) = &self.rows[v.rem_euclid(self.rows.len() as isize) as usize];
        debug_assert_eq!(*held, v);
        sums
    }

    /// Row v's sums, made by `fill` unless held.
    fn get(&mut self, v: isize, fill: &impl Fn(isize, &mut RowSums)) -> &RowSums {
        let slot = v.rem_euclid(self.rows.len() as isize) as usize;
        let (held, sums) = &mut self.rows[slot];
        if *held != v {
            fill(v, sums);
            *held = v;
        }
        sums
    }
}

/// The patch sums of the current output row, per column.
struct WindowSums {
    s0: Vec<f64>,
    si: Vec<f64>,
    sj: Vec<f64>,
    szz: Vec<f64>,
    /// Whether each column's patch holds a hole (empty in a strip without
    /// holes): [`Plan::patch_holes`] refits it after [`Plan::emit`].
    with_hole: Vec<bool>,
}

impl WindowSums {
    fn zeros(width: usize) -> Self {
        let z = vec![0.0; width];
        WindowSums { s0: z.clone(), si: z.clone(), sj: z.clone(), szz: z, with_hole: Vec::new() }
    }

    fn clear(&mut self) {
        for plane in [&mut self.s0, &mut self.si, &mut self.sj, &mut self.szz] {
            plane.fill(0.0);
        }
    }

    /// The sums of a suffix and a prefix of rows, Σj·z moved by `shift`
    /// texels' weight (the rows' weights were counted from another row).
    fn combine(&mut self, a: &WindowSums, b: &WindowSums, shift: f64) {
        let w = self.s0.len();
        let (s0, si, sj, szz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (a0, ai, aj, azz) = (&a.s0[..w], &a.si[..w], &a.sj[..w], &a.szz[..w]);
        let (b0, bi, bj, bzz) = (&b.s0[..w], &b.si[..w], &b.sj[..w], &b.szz[..w]);
        for x in 0..w {
            s0[x] = a0[x] + b0[x];
            si[x] = ai[x] + bi[x];
            sj[x] = (aj[x] + bj[x]) - shift * s0[x];
            szz[x] = azz[x] + bzz[x];
        }
    }

    /// The sums of the patch's N rows, `rows[j]` at vertical offset
    /// j − N/2, added in order.
    fn sum_rows<const N: usize>(&mut self, rows: &[&RowSums; N]) {
        let w = self.s0.len();
        let r = N / 2;
        let (s0, si, sj, szz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let h0: [&[f64]; N] = std::array::from_fn(|j| &rows[j].s0[..w]);
        let hi: [&[f64]; N] = std::array::from_fn(|j| &rows[j].si[..w]);
        let hzz: [&[f64]; N] = std::array::from_fn(|j| &rows[j].szz[..w]);
        // A pass per row and plane, each a loop of two slices that
        // vectorises (the sums stay in the core's first cache); every
        // texel's additions keep the rows' order. Σjz pairs the rows at ±d,
        // as the row sums pair the columns.
        for (out, h) in [(&mut *s0, &h0), (&mut *si, &hi), (&mut *szz, &hzz)] {
            out.iter_mut().zip(h[0]).zip(h[1]).for_each(|((a, p), q)| *a = p + q);
        }
        for j in 2..N {
            s0.iter_mut().zip(h0[j]).for_each(|(a, b)| *a += b);
            si.iter_mut().zip(hi[j]).for_each(|(a, b)| *a += b);
            szz.iter_mut().zip(hzz[j]).for_each(|(a, b)| *a += b);
        }
        sj.iter_mut().zip(h0[r + 1]).zip(h0[r - 1]).for_each(|((a, p), m)| *a = p - m);
        for d in 2..=r {
            let k = d as f64;
            sj.iter_mut().zip(h0[r + d]).zip(h0[r - d]).for_each(|((a, p), m)| *a += k * (p - m));
        }
    }

    /// `previous` plus the row sums `h` at vertical offset `j`.
    fn set_sum(&mut self, previous: &WindowSums, h: &RowSums, j: f64) {
        let w = self.s0.len();
        let (s0, si, sj, szz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (p0, pi, pj, pzz) = (&previous.s0[..w], &previous.si[..w], &previous.sj[..w], &previous.szz[..w]);
        let (h0, hi, hzz) = (&h.s0[..w], &h.si[..w], &h.szz[..w]);
        for x in 0..w {
            s0[x] = p0[x] + h0[x];
            si[x] = pi[x] + hi[x];
            sj[x] = pj[x] + j * h0[x];
            szz[x] = pzz[x] + hzz[x];
        }
    }

    /// Adds the row sums `h` (offset `j`) to these prefix sums, and writes
    /// `out` = `suffix` + them, as [`Self::combine`] does, in one pass.
    fn add_then_combine(&mut self, h: &RowSums, j: f64, suffix: &WindowSums, shift: f64, out: &mut WindowSums) {
        let w = self.s0.len();
        let (p0, pi, pj, pzz) = (&mut self.s0[..w], &mut self.si[..w], &mut self.sj[..w], &mut self.szz[..w]);
        let (h0, hi, hzz) = (&h.s0[..w], &h.si[..w], &h.szz[..w]);
        let (a0, ai, aj, azz) = (&suffix.s0[..w], &suffix.si[..w], &suffix.sj[..w], &suffix.szz[..w]);
        let (o0, oi, oj, ozz) = (&mut out.s0[..w], &mut out.si[..w], &mut out.sj[..w], &mut out.szz[..w]);
        for x in 0..w {
            p0[x] += h0[x];
            pi[x] += hi[x];
            pj[x] += j * h0[x];
            pzz[x] += hzz[x];
            o0[x] = a0[x] + p0[x];
            oi[x] = ai[x] + pi[x];
            oj[x] = (aj[x] + pj[x]) - shift * o0[x];
            ozz[x] = azz[x] + pzz[x];
        }
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
        let rows = |v: isize| RowRef { values: &heights[plan.borders.y.map(v, h) * w..][..w], x0: 0, holes: false };
        plan.fit_rows(&rows, 1.0, (0, 0..w), &mut out, None, None);
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
        plan.emit_with::<true>(&v, 1.0, &mut normal);
        let mut cancelling = 0;
        for x in 0..w {
            let czz = ((9.0 * v.szz[x] - v.s0[x] * v.s0[x]) * (1.0 / 9.0)).max(0.0);
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
