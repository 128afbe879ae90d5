//! Streaming conversion: rows go from the decoder through the fit to the
//! encoder, so memory grows with the width and the patch size, not with
//! the image's height.
//!
//! A pipeline, not I/O: it runs the fit between a decoder and an encoder,
//! so it sits beside [`crate::io`] (which knows nothing of the fit), and
//! [`crate::convert`] chooses it for the files that can stream. The
//! encoders' options are the whole-image writers' own
//! ([`PngOptions`], [`ExrOptions`]), and give the same samples.
//!
//! Inputs that stream: PNG that is not interlaced ([`PngRows`]),
//! scan-line OpenEXR parts ([`ExrRows`]) and the TIFF bands the `tiff`
//! crate reads (`TiffRows`: float, half, 32- and 64-bit and signed
//! integer GeoTIFF, striped or tiled, chunky or planar, and any TIFF with
//! a band asked for). Outputs: PNG ([`convert_png`],
//! [`convert_png_seekable`]) and OpenEXR ([`convert_exr`]). Other inputs
//! (interlaced PNG, tiled or multi-resolution EXR, 8- and 16-bit TIFF
//! without a band, JPEG, …) are decoded whole by [`crate::io::read`].
//!
//! Three stages run at once: a thread decodes rows into bands of heights;
//! a thread fits each band (its row tiles in parallel on rayon's pool) and
//! prepares it for the encoder (PNG filtering and deflate, EXR blocks, in
//! parallel too); the caller's thread writes it. The pixels are the same, bit
//! for bit, as decoding the whole image and calling
//! [`FitRequest`](crate::FitRequest): the fit is cut into the same
//! tiles either way ([`BandFit`]).
//!
//! A wrap across the top and bottom needs the image's last rows for the top
//! N/2 output rows. Into a PNG file ([`convert_png_seekable`]), those rows
//! are fitted last and written into room kept for them after the header,
//! so the input is read once. Otherwise the caller hands the last rows in
//! first: an EXR gives them cheaply ([`ExrRows::last_rows`] reads only the
//! blocks that hold them, through the file's offset table); a PNG cannot
//! seek, so [`RowSource::read_tail`] decodes it once more.

mod exr;
#[cfg(feature = "tiff")]
mod geotiff;
mod png;

use std::ops::Range;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

pub use self::exr::convert_exr;
pub(crate) use self::exr::{convert_exr_counting, curvature_exr};
#[cfg(feature = "tiff")]
pub(crate) use self::geotiff::{convert_tiff_counting, measure_tiff, shade_tiff};
pub use self::png::{convert_png, convert_png_seekable, png_codec_floor};
pub(crate) use self::png::{convert_png_counting, convert_png_seekable_counting};
pub(crate) use self::png::{curvature_png_seekable, shade_png_seekable};
// The rows it reads are io's, by format.
pub use crate::io::encoding::{ExrOptions, PngDepth, PngOptions};
pub use crate::io::rows::RowSource;
pub(crate) use crate::io::rows::StoredRows;
#[cfg(feature = "tiff")]
pub use crate::io::tiff::rows::TiffRows;
pub use crate::io::{ExrRows, PngRows};

use crate::error::{Error, Result};
use crate::fit::quadratic::CurvatureBands;
use crate::fit::{BandFit, Texel};
use crate::options::{Border, Options};
use crate::samples::Sample;
use crate::samples::first_non_finite;

/// A row of values in units of `unit` as heights in contract units,
/// rounded to `f32` (what the tiling check and an alpha of heights take):
/// the same numbers as [`crate::Samples::to_f32`] gives of the same
/// samples decoded whole.
fn to_heights<H: RowValue>(row: &[H], unit: f64, out: &mut [f32]) {
    for (o, &v) in out.iter_mut().zip(row) {
        *o = (v.to_f64() * unit) as f32;
    }
}

/// The types a conversion holds its rows in: `f32` for sources whose
/// values are exact in it, `f64` for the others.
trait RowValue: Sample + Default {
    /// The next row of `rows`, in this type.
    fn read(rows: &mut impl RowSource, out: &mut [Self]) -> Result<()>;
    /// A value given as `f64` (exact where the source is exact in `Self`).
    fn from_f64(v: f64) -> Self;
}

impl RowValue for f32 {
    fn read(rows: &mut impl RowSource, out: &mut [f32]) -> Result<()> {
        rows.next_row_f32(out)
    }
    fn from_f64(v: f64) -> f32 {
        v as f32
    }
}

impl RowValue for f64 {
    fn read(rows: &mut impl RowSource, out: &mut [f64]) -> Result<()> {
        rows.next_row(out)
    }
    fn from_f64(v: f64) -> f64 {
        v
    }
}

/// What the fit stage hands `prepare` beside the texels, per texel of the
/// band.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Extra {
    /// Nothing.
    None,
    /// The heights in contract units (an alpha of heights).
    Heights,
    /// Whether the texel has a normal, 1 or 0 (an alpha of validity; the
    /// lit view's nodata grey).
    Valid,
}

impl Extra {
    /// What a normal map of `layout` needs.
    pub(super) fn of(layout: crate::io::Layout) -> Extra {
        match layout {
            crate::io::Layout::RgbHeight => Extra::Heights,
            crate::io::Layout::RgbValid => Extra::Valid,
            _ => Extra::None,
        }
    }
}

/// `tail` if it is what a conversion with `opts` of a `w` × `h` image
/// needs: the last N/2 rows when it wraps in y (where it is required).
fn checked_tail<'a>(tail: Option<&'a [f64]>, w: usize, h: usize, opts: &Options) -> Result<Option<&'a [f64]>> {
    let expected = (opts.largest_patch() / 2).min(h) * w;
    match tail {
        Some(t) if t.len() == expected => Ok(Some(t)),
        Some(t) => Err(Error::BufferSize { expected, actual: t.len() }),
        None if opts.borders.y == Border::Wrap => {
            Err(Error::InvalidOption("a wrap in y needs the image's last rows from a first pass".into()))
        }
        None => Ok(None),
    }
}

/// The heights of the image's `rows` (of `w` values) in contract units,
/// one row after the other, for a layout that writes them (an alpha of
/// heights).
///
/// Errors: [`Error::Limits`] when the memory for them is not there.
fn heights_of<H: RowValue>(rows: Range<usize>, row: &Rows<'_, H>, unit: f64, w: usize) -> Result<Vec<f32>> {
    let mut heights = crate::samples::try_vec(rows.len() * w)?;
    heights.extend(rows.flat_map(|y| row(y).iter().map(move |&v| (v.to_f64() * unit) as f32)));
    Ok(heights)
}

/// An alpha of heights with holes: 0 at the texels without a normal (a
/// hole's value, NaN or the nodata value, is no height), as the alpha of
/// validity has there; `valid` empty (no holes) changes nothing.
pub(crate) fn zero_missing(alpha: &mut [f32], valid: &[bool]) {
    for (a, _) in alpha.iter_mut().zip(valid).filter(|&(_, &v)| !v) {
        *a = 0.0;
    }
}

/// What the fit stage makes of each band's rows: the normals
/// ([`BandFit`], texels `T`) or the curvature ([`CurvatureBands`], f32).
/// Either cuts the image into the same bands, the top N/2 rows first.
trait BandStage<T>: Sync {
    fn width(&self) -> usize;
    fn height(&self) -> usize;
    fn radius(&self) -> usize;
    fn band_rows(&self) -> usize;
    fn has_nodata(&self) -> bool;
    /// The texels without a value in the bands fitted so far.
    fn missing(&self) -> usize;
    /// The bands of output rows, in order.
    fn band_list(&self) -> Vec<Range<usize>>;
    /// The bytes fitting a band allocates, for rows of `H`.
    fn work_bytes<H: Sample>(&self) -> u64;
    /// Fits the band `rows` into `out`; with holes, `valid` (as long)
    /// says which texels have a value.
    fn fit_into<'a, H: Sample>(
        &self,
        rows: Range<usize>,
        row: &(dyn Fn(usize) -> &'a [H] + Sync),
        out: &mut [T],
        valid: &mut [bool],
    ) -> Result<()>;
}

impl<T: Texel> BandStage<T> for BandFit {
    fn width(&self) -> usize {
        BandFit::width(self)
    }
    fn height(&self) -> usize {
        BandFit::height(self)
    }
    fn radius(&self) -> usize {
        BandFit::radius(self)
    }
    fn band_rows(&self) -> usize {
        BandFit::band_rows(self)
    }
    fn has_nodata(&self) -> bool {
        BandFit::has_nodata(self)
    }
    fn missing(&self) -> usize {
        BandFit::missing(self)
    }
    fn band_list(&self) -> Vec<Range<usize>> {
        self.bands().collect()
    }
    fn work_bytes<H: Sample>(&self) -> u64 {
        BandFit::work_bytes::<H>(self, false)
    }
    fn fit_into<'a, H: Sample>(
        &self,
        rows: Range<usize>,
        row: &(dyn Fn(usize) -> &'a [H] + Sync),
        out: &mut [T],
        valid: &mut [bool],
    ) -> Result<()> {
        let valid = BandFit::has_nodata(self).then_some(valid);
        self.fit_band_with(rows, row, out, valid).map(|_| ())
    }
}

impl BandStage<f32> for CurvatureBands {
    fn width(&self) -> usize {
        CurvatureBands::width(self)
    }
    fn height(&self) -> usize {
        CurvatureBands::height(self)
    }
    fn radius(&self) -> usize {
        CurvatureBands::radius(self)
    }
    fn band_rows(&self) -> usize {
        CurvatureBands::band_rows(self)
    }
    fn has_nodata(&self) -> bool {
        CurvatureBands::has_nodata(self)
    }
    fn missing(&self) -> usize {
        CurvatureBands::missing(self)
    }
    fn band_list(&self) -> Vec<Range<usize>> {
        self.bands().collect()
    }
    fn work_bytes<H: Sample>(&self) -> u64 {
        CurvatureBands::work_bytes(self)
    }
    fn fit_into<'a, H: Sample>(
        &self,
        rows: Range<usize>,
        row: &(dyn Fn(usize) -> &'a [H] + Sync),
        out: &mut [f32],
        valid: &mut [bool],
    ) -> Result<()> {
        self.fit_band(rows, row, out)?;
        // A hole's curvature is NaN.
        valid.iter_mut().zip(out.iter()).for_each(|(v, k)| *v = !k.is_nan());
        Ok(())
    }
}

/// A band of rows between stages: its first row and its values (heights,
/// or what the encoder takes).
type Band<T> = Result<(usize, Vec<T>)>;

/// Source row y of the image, while the band that reads it is fitted.
type Rows<'a, H> = dyn Fn(usize) -> &'a [H] + 'a;

/// What is done with each fitted band.
struct Stages<Prepare, Consume> {
    /// On the fit thread: turns the band's rows (range, texels, and its
    /// heights in contract units when the layout writes them, else none)
    /// into what the encoder takes. The texels are the fit stage's buffer,
    /// lent for the band (it may change them: EXR stores its encoding in
    /// place).
    prepare: Prepare,
    /// On the caller's thread: encodes and writes a prepared band, given
    /// with its first row.
    consume: Consume,
}

/// Runs the three stages over every band of `fit`, top to bottom, or with
/// `deferred` the top band last (when the image's last rows are in).
/// `visit` sees every decoded row, in order, as heights. With
/// `needs_heights`, `prepare` gets each band's heights too.
fn run<S, T, B, F, Prepare, Consume>(
    rows: S,
    fit: &F,
    tail: Option<&[f64]>,
    (deferred, needs_heights): (bool, Extra),
    visit: impl FnMut(&[f32]) + Send,
    stages: Stages<Prepare, Consume>,
) -> Result<()>
where
    S: RowSource,
    T: Default + Clone + Send,
    B: Send,
    F: BandStage<T>,
    Prepare: FnMut(Range<usize>, &mut [T], Vec<f32>) -> Vec<B> + Send,
    Consume: FnMut(usize, Vec<B>) -> Result<()>,
{
    // Rows in f32 where that is exact: half the memory and bandwidth.
    if rows.exact_in_f32() {
        run_as::<f32, _, _, _, _, _, _>(rows, fit, tail, (deferred, needs_heights), visit, stages)
    } else {
        run_as::<f64, _, _, _, _, _, _>(rows, fit, tail, (deferred, needs_heights), visit, stages)
    }
}

/// [`run`], the rows held as `H`.
fn run_as<H, S, T, B, F, Prepare, Consume>(
    mut rows: S,
    fit: &F,
    tail: Option<&[f64]>,
    (deferred, needs_heights): (bool, Extra),
    mut visit: impl FnMut(&[f32]) + Send,
    stages: Stages<Prepare, Consume>,
) -> Result<()>
where
    H: RowValue,
    S: RowSource,
    T: Default + Clone + Send,
    B: Send,
    F: BandStage<T>,
    Prepare: FnMut(Range<usize>, &mut [T], Vec<f32>) -> Vec<B> + Send,
    Consume: FnMut(usize, Vec<B>) -> Result<()>,
{
    let Stages { prepare, mut consume } = stages;
    check_stream_memory::<H, T, F>(fit, tail.map_or(0, <[f64]>::len))?;
    let tail: Option<Vec<H>> = tail.map(|t| t.iter().map(|&v| H::from_f64(v)).collect());
    let tail = tail.as_deref();
    // Two bands in flight between stages keep every stage busy without
    // holding more than a few bands.
    let (heights_tx, heights_rx) = sync_channel::<Band<H>>(2);
    let (out_tx, out_rx) = sync_channel::<Band<B>>(2);
    // A band of heights the fit is done with goes back to the decoder, to
    // be filled again: a new band each time would cost its zeroing and
    // its page faults (4 % of a 32768² conversion's processor time).
    let (spare_tx, spare_rx) = sync_channel::<Vec<H>>(1);
    let band = fit.band_rows();
    let unit = rows.unit();
    std::thread::scope(|scope| -> Result<()> {
        // `visit` runs where the rows are made, while they are in cache.
        scope.spawn(move || decode_stage(&mut rows, band, unit, &mut visit, &heights_tx, &spare_rx));
        let fitting = Fitting { fit, unit, tail, deferred, needs_heights };
        scope.spawn(move || fit_stage(&fitting, prepare, heights_rx, &out_tx, &spare_tx));
        // Returning early drops the receiver, which stops the other stages.
        for message in out_rx {
            let (y0, values) = message?;
            consume(y0, values)?;
        }
        Ok(())
    })
}

/// A band's greys made 0 where `valid` (one per texel, or empty without
/// holes) is 0: gdaldem's nodata.
fn holes_grey(valid: &[f32], grey: &mut [u8]) {
    for (g, _) in grey.iter_mut().zip(valid).filter(|(_, v)| **v == 0.0) {
        *g = 0;
    }
}

/// Refuses a streamed conversion whose bands do not fit in the memory the
/// process may still take (under `ulimit -v` and the like), in one line,
/// before any band is allocated: a failed allocation in a stage would
/// otherwise abort the process. Bands are at most 2^24 texels or one row
/// ([`BandFit`]), so only images some 10^7 texels wide get here.
///
/// What is held at once, per texel of a band: the heights (`H`) of the
/// band being decoded, two queued, two that the fit reads (the band and
/// the rows above it) and one given back to the decoder; the normals (`T`)
/// and what the encoder takes (counted as one more `T` and 4 bytes: a
/// band's samples, or its bytes deflated or stored, never more) of the
/// band being fitted, two queued, the one being written and one given
/// back to be filled again. Besides, a copy of the first 2r rows, the
/// tail, a row of heights for `visit`, and the fit's own work on a band
/// ([`BandFit::work_bytes`]: its sums, which grow with N, on every thread;
/// with holes, the band's validity).
fn check_stream_memory<H: Sample, T, F: BandStage<T>>(fit: &F, tail_len: usize) -> Result<()> {
    let (w, h, r, band) = (fit.width() as u64, fit.height() as u64, fit.radius() as u64, fit.band_rows() as u64);
    // No more rows than the image has.
    let height_rows = (6 * band).min(h);
    let output_rows = (5 * band).min(h);
    let output_bytes = 2 * size_of::<T>() as u64 + 4;
    let head_rows = (2 * r).min(h);
    let height_bytes = size_of::<H>() as u64;
    let bytes = (height_rows + head_rows) * w * height_bytes
        + tail_len as u64 * (8 + height_bytes)
        + output_rows * w * output_bytes
        + 4 * w;
    // Two threads of its own beside the pool's: decoding and fitting.
    crate::memory::check_work("converting by rows", bytes.saturating_add(fit.work_bytes::<H>()), 2)
}

/// Decodes bands of `band` rows and sends them on; stops at the first
/// error (sent on) or when the receiver is gone. Gives every row decoded
/// to `visit`, in order, as heights (values times `unit`): the tiling
/// check reads the row while it is in this core's cache (measured: 10 to
/// 20 ms less processor time for a 4096² map than on the fit's thread,
/// which would read it from the other core's).
fn decode_stage<H: RowValue>(
    rows: &mut impl RowSource,
    band: usize,
    unit: f64,
    visit: &mut dyn FnMut(&[f32]),
    tx: &SyncSender<Band<H>>,
    spares: &Receiver<Vec<H>>,
) {
    let (w, h) = (rows.width(), rows.height());
    let mut visited = vec![0.0f32; w];
    for y0 in (0..h).step_by(band) {
        let n = band.min(h - y0);
        // A band given back, of this size, is filled again (every value is
        // overwritten below); else a new one, zeroed by the allocator. The
        // room for the bands was checked before the stages started.
        let mut heights = match spares.try_recv() {
            Ok(spare) if spare.len() == n * w => spare,
            // Reserved fallibly besides: an estimate that fell short is
            // an error, not an abort.
            _ => match crate::samples::try_filled(n * w, H::default()) {
                Ok(heights) => heights,
                Err(e) => {
                    let _ = tx.send(Err(e));
                    return;
                }
            },
        };
        let result = heights.chunks_exact_mut(w).try_for_each(|row| {
            H::read(rows, row)?;
            to_heights(row, unit, &mut visited);
            visit(&visited);
            Ok(())
        });
        let failed = result.is_err();
        if tx.send(result.map(|()| (y0, heights))).is_err() || failed {
            return;
        }
    }
}

/// The first NaN or infinite height in row order among the bands `rx`
/// delivers, knowing that texel `known` of a later row is one: the error
/// that names it (or the decoder's error, if one comes first).
fn first_bad_texel<H: RowValue>(rx: Receiver<Band<H>>, w: usize, known: (usize, usize)) -> Error {
    for band in rx {
        match band {
            Ok((first, rows)) => {
                if let Some((x, y)) = first_non_finite(&rows, w) {
                    return Error::NonFiniteHeight { x, y: first + y };
                }
                if first + rows.len() / w > known.1 {
                    break;
                }
            }
            Err(e) => return e,
        }
    }
    Error::NonFiniteHeight { x: known.0, y: known.1 }
}

/// What the fit stage works with besides its channels.
struct Fitting<'a, H, F> {
    fit: &'a F,
    /// The height of a row value of 1.
    unit: f64,
    /// The image's last N/2 rows, for a wrap in y fitted in order.
    tail: Option<&'a [H]>,
    /// The top band is fitted last, when the image's last rows are in.
    deferred: bool,
    /// What `prepare` takes beside the texels.
    needs_heights: Extra,
}

/// Fits each band once the rows it reads are in, prepares it for the
/// encoder and sends it on.
fn fit_stage<H: RowValue, T: Default + Clone + Send, B, F: BandStage<T>>(
    &Fitting { fit, unit, tail, deferred, needs_heights }: &Fitting<'_, H, F>,
    mut prepare: impl FnMut(Range<usize>, &mut [T], Vec<f32>) -> Vec<B>,
    rx: Receiver<Band<H>>,
    tx: &SyncSender<Band<B>>,
    spares: &SyncSender<Vec<H>>,
) {
    let (w, h, r) = (fit.width(), fit.height(), fit.radius());
    if let Some(tail) = tail
        && !fit.has_nodata()
        && let Some((x, y)) = first_non_finite(tail, w)
    {
        // The top band reads these last rows first, through the wrap:
        // fitting it would name this texel before the rows above are
        // read. SPEC §1 names the first bad texel in row order, so the
        // rows are read on and checked in order instead.
        let _ = tx.send(Err(first_bad_texel(rx, w, (x, y + h - tail.len() / w))));
        return;
    }
    // The decoded bands that later bands still read, as they came (first
    // row, heights), and a copy of the image's first 2r rows, which the top
    // band and a wrap at the bottom read after they have left.
    let mut window: std::collections::VecDeque<(usize, Vec<H>)> = std::collections::VecDeque::new();
    let mut decoded = 0;
    let head_rows = (2 * r).min(h);
    let mut head: Vec<H> = Vec::new();
    let mut normals: Vec<T> = Vec::new();
    let mut valid: Vec<bool> = Vec::new();
    let mut incoming = rx.into_iter();
    let mut bands = fit.band_list();
    if deferred {
        bands.rotate_left(1);
    }
    for rows in bands {
        let (y0, y1) = (rows.start, rows.end);
        let needed = if deferred && y0 == 0 { h } else { (y1 + r).min(h) };
        while decoded < needed {
            match incoming.next() {
                Some(Ok((first, rows))) => {
                    let wanted = (head_rows * w).saturating_sub(head.len()).min(rows.len());
                    if let Err(e) = crate::samples::try_extend(&mut head, &rows[..wanted]) {
                        let _ = tx.send(Err(e));
                        return;
                    }
                    decoded = first + rows.len() / w;
                    window.push_back((first, rows));
                }
                Some(Err(e)) => {
                    let _ = tx.send(Err(e));
                    return;
                }
                None => {
                    let _ = tx.send(Err(Error::Decode("image data ends early".into())));
                    return;
                }
            }
        }
        let in_window = &window;
        let row = |y: usize| -> &[H] {
            if let Some((first, rows)) =
                in_window.iter().find(|(first, rows)| (*first..first + rows.len() / w).contains(&y))
            {
                &rows[(y - first) * w..][..w]
            } else if y < head_rows {
                &head[y * w..][..w]
            } else {
                // Only a wrap at the top, fitted first, reads below the window.
                let t = tail.expect("a wrap in y comes with the tail");
                &t[(y + r.min(h) - h) * w..][..w]
            }
        };
        // One buffer for every band's texels, each overwritten whole by the
        // fit: no zeroing per band.
        let grown = crate::samples::try_resize(&mut normals, (y1 - y0) * w, T::default());
        if let Err(e) = grown.and_then(|()| match fit.has_nodata() {
            true => crate::samples::try_resize(&mut valid, (y1 - y0) * w, false),
            false => Ok(()),
        }) {
            let _ = tx.send(Err(e));
            return;
        }
        if !fit.has_nodata() {
            valid.clear();
        }
        let fitted = fit.fit_into(rows.clone(), &row, &mut normals, &mut valid);
        let result = fitted.and_then(|()| {
            let extra = match needs_heights {
                Extra::None => Vec::new(),
                Extra::Heights => {
                    let mut heights = heights_of(rows.clone(), &row, unit, w)?;
                    zero_missing(&mut heights, &valid);
                    heights
                }
                Extra::Valid => {
                    let mut extra = crate::samples::try_vec(normals.len())?;
                    match valid.is_empty() {
                        true => extra.resize(normals.len(), 1.0),
                        false => extra.extend(valid.iter().map(|&v| if v { 1.0 } else { 0.0 })),
                    }
                    extra
                }
            };
            Ok(prepare(rows, &mut normals, extra))
        });
        let failed = result.is_err();
        if tx.send(result.map(|values| (y0, values))).is_err() || failed {
            return;
        }
        // The next band reads from r rows above its start (with the top
        // band last, the last r rows stay for it): older bands can go.
        let keep_from = y1.saturating_sub(r);
        while window.front().is_some_and(|(first, rows)| first + rows.len() / w <= keep_from) {
            if let Some((_, rows)) = window.pop_front() {
                // Dropped when the decoder has one already.
                let _ = spares.try_send(rows);
            }
        }
    }
}
