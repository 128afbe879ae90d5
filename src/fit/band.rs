//! [`BandFit`]: the fit of an image whose rows arrive in bands, top to
//! bottom, for a caller that streams rows from a decoder to an encoder.

use std::ops::Range;

use crate::error::{Error, Result};
use crate::options::Options;
use crate::samples::{Sample, first_non_finite};

use super::masked::row_has_hole;
use super::plan::{MAX_BLOCK_TEXELS, Plan};
use super::sums::RowRef;
use super::{FromNormal, Texel};

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
/// the same, bit for bit, as [`FitRequest`](super::FitRequest) gives for the whole image.
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

    /// The same fit, its texels made on a raster placed on the map by
    /// `affine` (see [`super::FitRequest::on_map`]).
    #[must_use]
    #[cfg_attr(not(feature = "tiff"), allow(dead_code))]
    pub(crate) fn on_map(mut self, affine: Option<&crate::io::Affine>) -> BandFit {
        self.plan.frame.axes = super::MapAxes::of(affine);
        self
    }

    /// The same fit, its texels lit by `lamp` (a hillshade's greys).
    #[must_use]
    pub(crate) fn lit(mut self, lamp: super::Lamp) -> BandFit {
        self.plan.frame.lamp = lamp;
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
    /// [`FitRequest::holes`](super::FitRequest::holes)): `valid` (as long as `out`) gets whether
    /// each texel has a normal. Returns the band's count of missing texels.
    /// The texels and `valid` are the same, bit for bit, as
    /// [`FitRequest::holes`](super::FitRequest::holes) gives for the whole image.
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

    /// The bytes fitting one band allocates beyond the caller's buffers,
    /// for rows of `H` values: the fit's sums on every thread
    /// ([`Plan::work_bytes`], which grow with N), and with holes (`masked`,
    /// or [`Options::nodata`] set) which rows hold one and which texels
    /// have a normal. Callers that stream check it, with their bands,
    /// against the memory rule ([`crate::memory`]) before the first band.
    pub(crate) fn work_bytes<H: Sample>(&self, masked: bool) -> u64 {
        let unit = self.unit.unwrap_or(H::UNIT);
        let rows = self.band_rows.max(self.plan.r).min(self.height);
        let masked = masked || self.plan.nodata.is_some();
        let holes = if masked { (rows + 2 * self.plan.r + rows * self.plan.width) as u64 } else { 0 };
        super::detail::work_bytes(&self.plan, unit, (self.plan.width, rows), masked, false).saturating_add(holes)
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

    /// [`fit_band`](Self::fit_band) (`valid` `None`) or
    /// [`fit_band_masked`](Self::fit_band_masked), for any texel the crate
    /// makes ([`Texel`]).
    pub(crate) fn fit_band_with<'a, H: Sample, T: Texel>(
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
            super::detail::fit_rows(&self.plan, &source, unit, (rows.start, 0..w), out, None, None);
            return Ok(0);
        }
        let first = rows.start as isize - self.plan.r as isize;
        let source = |v: isize| RowRef {
            values: row(self.plan.borders.y.map(v, h)),
            x0: 0,
            holes: holes.get((v - first) as usize).copied().unwrap_or(true),
        };
        let mut own = if valid.is_none() { crate::samples::try_filled(out.len(), false)? } else { Vec::new() };
        let valid = match valid {
            Some(valid) => valid,
            None => &mut own[..],
        };
        super::detail::fit_rows(&self.plan, &source, unit, (rows.start, 0..w), out, None, Some((&mut *valid, nodata)));
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
