//! Streaming conversion: rows go from the decoder through the fit to the
//! encoder, so memory grows with the width and the patch size, not with
//! the image's height.
//!
//! Inputs that stream: PNG that is not interlaced ([`PngRows`]) and
//! scan-line OpenEXR parts ([`ExrRows`]). Outputs: PNG ([`convert_png`],
//! [`convert_png_seekable`]) and OpenEXR ([`convert_exr`]). Other inputs
//! (interlaced PNG, tiled or multi-resolution EXR, TIFF, JPEG, …) are decoded
//! whole by [`crate::io::read`].
//!
//! Three stages run at once: a thread decodes rows into bands of heights;
//! a thread fits each band (its row tiles in parallel on rayon's pool) and
//! prepares it for the encoder (PNG filtering, in parallel too); the
//! caller's thread compresses and writes it. The pixels are the same, bit
//! for bit, as decoding the whole image and calling
//! [`normals_into`](crate::normals_into): the fit is cut into the same
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
mod png;

use std::ops::Range;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

pub use self::exr::{ExrFormat, ExrRows, convert_exr};
pub use self::png::{PngDepth, PngOutput, PngRows, convert_png, convert_png_seekable};

use crate::error::{Error, Result};
use crate::fit::{BandFit, FromNormal, first_non_finite};
use crate::io::write::Layout;
use crate::options::{Border, Options};
use crate::samples::try_vec;

/// The rows of a height map, top to bottom, decoded as they are asked for.
///
/// Rows are `f64` values, each the stored sample (an 8- or 16-bit
/// integer, or a float) or a height computed from several (luma): `f64`
/// holds them all exactly, and the height of a value v is
/// v · [`unit`](Self::unit). Integers are not divided before the fit,
/// which folds the unit into its gain, as it does for the same samples
/// decoded whole ([`crate::samples`]), and so gives the same bits.
pub trait RowSource: Send {
    /// Columns.
    fn width(&self) -> usize;

    /// Rows.
    fn height(&self) -> usize;

    /// The height of a row value of 1: 1 / (2^bits − 1) for integer
    /// samples as stored, 1 for floats and heights.
    fn unit(&self) -> f64;

    /// Decodes the next row into `out` (`width` values).
    ///
    /// Errors: [`Error::Decode`] for corrupt or truncated data, or when all
    /// rows have been read.
    fn next_row(&mut self, out: &mut [f64]) -> Result<()>;

    /// Reads every row, giving each to `visit` as heights in contract
    /// units, and returns the last `rows` rows (fewer if the image is
    /// shorter), as stored: the first pass of a conversion that wraps
    /// across the top and bottom.
    ///
    /// Errors: those of [`next_row`](Self::next_row); [`Error::Limits`]
    /// if the memory for the rows is not there.
    fn read_tail(mut self, rows: usize, mut visit: impl FnMut(&[f32])) -> Result<Vec<f64>>
    where
        Self: Sized,
    {
        let (w, h, unit) = (self.width(), self.height(), self.unit());
        let keep = rows.min(h);
        let mut tail = zeroed(keep * w)?;
        let mut row = zeroed(w)?;
        let mut heights = zeroed(w)?;
        for y in 0..h {
            self.next_row(&mut row)?;
            to_heights(&row, unit, &mut heights);
            visit(&heights);
            if y + keep >= h {
                tail[(y + keep - h) * w..][..w].copy_from_slice(&row);
            }
        }
        Ok(tail)
    }
}

/// `len` zeros, allocated fallibly: a row of a very wide image may not fit
/// in what the process may still take, which is an error, not an abort.
fn zeroed<T: Default + Clone>(len: usize) -> Result<Vec<T>> {
    let mut v = try_vec(len)?;
    v.resize(len, T::default());
    Ok(v)
}

/// A row of values in units of `unit` as heights in contract units,
/// rounded to `f32` (what the tiling check and an alpha of heights take):
/// the same numbers as [`crate::Samples::to_f32`] gives of the same
/// samples decoded whole.
fn to_heights(row: &[f64], unit: f64, out: &mut [f32]) {
    for (o, &v) in out.iter_mut().zip(row) {
        *o = (v * unit) as f32;
    }
}

/// `tail` if it is what a conversion with `opts` of a `w` × `h` image
/// needs: the last N/2 rows when it wraps in y (where it is required).
fn checked_tail<'a>(tail: Option<&'a [f64]>, w: usize, h: usize, opts: &Options) -> Result<Option<&'a [f64]>> {
    let expected = (opts.patch / 2).min(h) * w;
    match tail {
        Some(t) if t.len() == expected => Ok(Some(t)),
        Some(t) => Err(Error::BufferSize { expected, actual: t.len() }),
        None if opts.borders.y == Border::Wrap => {
            Err(Error::InvalidOption("a wrap in y needs the image's last rows from a first pass".into()))
        }
        None => Ok(None),
    }
}

/// The heights of the image's `rows` in contract units, one row after the
/// other, for a layout that writes them (an alpha of heights); nothing
/// otherwise.
fn heights_for(layout: Layout, rows: Range<usize>, row: &Rows<'_>, unit: f64) -> Vec<f32> {
    if layout.needs_heights() {
        rows.flat_map(|y| row(y).iter().map(move |&v| (v * unit) as f32)).collect()
    } else {
        Vec::new()
    }
}

/// A band of rows between stages: its first row and its values (heights,
/// or what the encoder takes).
type Band<T> = Result<(usize, Vec<T>)>;

/// Source row y of the image, while the band that reads it is fitted.
type Rows<'a> = dyn Fn(usize) -> &'a [f64] + 'a;

/// What is done with each fitted band.
struct Stages<Prepare, Consume> {
    /// On the fit thread: turns the band's rows (range, texels) into what
    /// the encoder takes; it may read the band's heights.
    prepare: Prepare,
    /// On the caller's thread: encodes and writes a prepared band, given
    /// with its first row.
    consume: Consume,
}

/// Runs the three stages over every band of `fit`, top to bottom, or with
/// `deferred` the top band last (when the image's last rows are in).
/// `visit` sees every decoded row, in order.
fn run<S, T, B, Prepare, Consume>(
    mut rows: S,
    fit: &BandFit,
    tail: Option<&[f64]>,
    deferred: bool,
    mut visit: impl FnMut(&[f32]) + Send,
    stages: Stages<Prepare, Consume>,
) -> Result<()>
where
    S: RowSource,
    T: FromNormal + Default,
    B: Send,
    Prepare: for<'r> FnMut(Range<usize>, Vec<T>, &Rows<'r>) -> Vec<B> + Send,
    Consume: FnMut(usize, Vec<B>) -> Result<()>,
{
    let Stages { prepare, mut consume } = stages;
    check_stream_memory::<T, B>(fit, tail.map_or(0, <[f64]>::len))?;
    // Two bands in flight between stages keep every stage busy without
    // holding more than a few bands.
    let (heights_tx, heights_rx) = sync_channel::<Band<f64>>(2);
    let (out_tx, out_rx) = sync_channel::<Band<B>>(2);
    let band = fit.band_rows();
    let unit = rows.unit();
    std::thread::scope(|scope| -> Result<()> {
        scope.spawn(move || decode_stage(&mut rows, band, &heights_tx));
        scope.spawn(move || fit_stage(fit, unit, tail, deferred, &mut visit, prepare, heights_rx, &out_tx));
        // Returning early drops the receiver, which stops the other stages.
        for message in out_rx {
            let (y0, values) = message?;
            consume(y0, values)?;
        }
        Ok(())
    })
}

/// Refuses a streamed conversion whose bands do not fit in the memory the
/// process may still take (under `ulimit -v` and the like), in one line,
/// before any band is allocated: a failed allocation in a stage would
/// otherwise abort the process. Bands are at most 2^24 texels or one row
/// ([`BandFit`]), so only images some 10^7 texels wide get here.
///
/// What is held at once, per texel of a band: the heights (f64) of the
/// band being decoded, two queued and two that the fit reads (the band and
/// the rows above it); the normals (`T`) and what the encoder takes (`B`,
/// counted as one more `T` and 4 bytes) of the band being fitted, two
/// queued and the one being written. Besides, a copy of the first 2r rows,
/// the tail and a row of heights for `visit`.
fn check_stream_memory<T, B>(fit: &BandFit, tail_len: usize) -> Result<()> {
    let (w, h, r, band) = (fit.width() as u64, fit.height() as u64, fit.radius() as u64, fit.band_rows() as u64);
    // No more rows than the image has.
    let height_rows = (5 * band).min(h);
    let output_rows = (4 * band).min(h);
    let output_bytes = (2 * size_of::<T>() as u64 + 4).max(size_of::<B>() as u64);
    let head_rows = (2 * r).min(h);
    let bytes = (height_rows + head_rows) * w * 8 + tail_len as u64 * 8 + output_rows * w * output_bytes + 4 * w;
    crate::io::check_memory("converting by rows", bytes)
}

/// Decodes bands of `band` rows and sends them on; stops at the first
/// error (sent on) or when the receiver is gone. Decoding is the one stage
/// that cannot be split, so it does nothing else.
fn decode_stage(rows: &mut impl RowSource, band: usize, tx: &SyncSender<Band<f64>>) {
    let (w, h) = (rows.width(), rows.height());
    for y0 in (0..h).step_by(band) {
        let n = band.min(h - y0);
        let mut heights = match zeroed(n * w) {
            Ok(heights) => heights,
            Err(e) => {
                let _ = tx.send(Err(e));
                return;
            }
        };
        let result = heights.chunks_exact_mut(w).try_for_each(|row| rows.next_row(row));
        let failed = result.is_err();
        if tx.send(result.map(|()| (y0, heights))).is_err() || failed {
            return;
        }
    }
}

/// The first NaN or infinite height in row order among the bands `rx`
/// delivers, knowing that texel `known` of a later row is one: the error
/// that names it (or the decoder's error, if one comes first).
fn first_bad_texel(rx: Receiver<Band<f64>>, w: usize, known: (usize, usize)) -> Error {
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

/// Fits each band once the rows it reads are in, prepares it for the
/// encoder and sends it on; gives every row that comes in to `visit`, as
/// heights (values times `unit`). `deferred`: the top band is fitted last,
/// when the image's last rows are in.
#[allow(clippy::too_many_arguments)] // the stage's inputs, outputs and the two ends of its channels
fn fit_stage<T: FromNormal + Default, B>(
    fit: &BandFit,
    unit: f64,
    tail: Option<&[f64]>,
    deferred: bool,
    visit: &mut dyn FnMut(&[f32]),
    mut prepare: impl for<'r> FnMut(Range<usize>, Vec<T>, &Rows<'r>) -> Vec<B>,
    rx: Receiver<Band<f64>>,
    tx: &SyncSender<Band<B>>,
) {
    let (w, h, r) = (fit.width(), fit.height(), fit.radius());
    if let Some(tail) = tail {
        if let Some((x, y)) = first_non_finite(tail, w) {
            // The top band reads these last rows first, through the wrap:
            // fitting it would name this texel before the rows above are
            // read. SPEC §1 names the first bad texel in row order, so the
            // rows are read on and checked in order instead.
            let _ = tx.send(Err(first_bad_texel(rx, w, (x, y + h - tail.len() / w))));
            return;
        }
    }
    // The decoded bands that later bands still read, as they came (first
    // row, heights), and a copy of the image's first 2r rows, which the top
    // band and a wrap at the bottom read after they have left.
    let mut window: std::collections::VecDeque<(usize, Vec<f64>)> = std::collections::VecDeque::new();
    let mut decoded = 0;
    let head_rows = (2 * r).min(h);
    let mut head: Vec<f64> = Vec::new();
    let mut heights = vec![0.0f32; w];
    let mut incoming = rx.into_iter();
    let mut bands: Vec<_> = fit.bands().collect();
    if deferred {
        bands.rotate_left(1);
    }
    for rows in bands {
        let (y0, y1) = (rows.start, rows.end);
        let needed = if deferred && y0 == 0 { h } else { (y1 + r).min(h) };
        while decoded < needed {
            match incoming.next() {
                Some(Ok((first, rows))) => {
                    for row in rows.chunks_exact(w) {
                        to_heights(row, unit, &mut heights);
                        visit(&heights);
                    }
                    let wanted = (head_rows * w).saturating_sub(head.len()).min(rows.len());
                    head.extend_from_slice(&rows[..wanted]);
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
        let row = |y: usize| -> &[f64] {
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
        let mut normals = vec![T::default(); (y1 - y0) * w];
        let result = fit.fit_band(rows.clone(), &row, &mut normals).map(|()| prepare(rows, normals, &row));
        let failed = result.is_err();
        if tx.send(result.map(|values| (y0, values))).is_err() || failed {
            return;
        }
        // The next band reads from r rows above its start (with the top
        // band last, the last r rows stay for it): older bands can go.
        let keep_from = y1.saturating_sub(r);
        while window.front().is_some_and(|(first, rows)| first + rows.len() / w <= keep_from) {
            window.pop_front();
        }
    }
}
