//! An OpenEXR normal map written band by band ([`convert_exr`]) from any
//! rows ([`RowSource`]).

use std::io::{Seek, Write};
use std::ops::Range;

use super::{Extra, RowSource, Stages, checked_tail, run};
use crate::error::Result;
use crate::fit::BandFit;
use crate::fit::quadratic::CurvatureBands;
use crate::io::encoding::{ExrDepth, ExrOptions, Layout};
use crate::io::exr::write::{ExrBlocks, IndexedChunk, write_exr_blocks};
use crate::io::texels::{Container, lay_out};
use crate::options::Options;

/// Converts the rows of `rows` to an OpenEXR normal map (ZIP compression
/// in blocks of 16 rows) written to `out`, band by band: the values are
/// (n + 1)/2, or n itself with `signed`, as half or float, in the channels
/// of the layout; the same file as
/// [`encode_normals`](crate::io::encode_normals) writes.
///
/// EXR's offset table comes before the pixels and is filled in at the end,
/// so `out` must seek. The rows are written in order, so `tail` (the
/// image's last N/2 rows, [`ExrRows::last_rows`](crate::io::ExrRows::last_rows) or
/// [`RowSource::read_tail`]) is needed when `opts` wraps in y. Every
/// decoded row is also given to `visit`.
///
/// Errors: those of decoding, [`Error::InvalidOption`](crate::Error::InvalidOption) for bad options or
/// a wrap in y without `tail`, [`Error::Io`](crate::Error::Io) if writing fails.
pub fn convert_exr<W: Write + Seek>(
    rows: impl RowSource,
    tail: Option<&[f64]>,
    opts: &Options,
    options: impl Into<ExrOptions>,
    visit: impl FnMut(&[f32]) + Send,
    out: W,
) -> Result<()> {
    convert_exr_counting(rows, tail, opts, options, visit, out).map(|_| ())
}

/// [`convert_exr`], returning the count of missing texels (holes, with
/// [`Options::nodata`]).
pub(crate) fn convert_exr_counting<W: Write + Seek>(
    rows: impl RowSource,
    tail: Option<&[f64]>,
    opts: &Options,
    options: impl Into<ExrOptions>,
    visit: impl FnMut(&[f32]) + Send,
    out: W,
) -> Result<usize> {
    let (w, h) = (rows.width(), rows.height());
    let tail = checked_tail(tail, w, h, opts)?;
    let unit = rows.unit();
    let fit = BandFit::new(w, h, opts)?.with_unit(unit);
    let options: ExrOptions = options.into();
    let ExrOptions { depth, layout, .. } = options;
    // Blocks are laid out and compressed on the fit's side, in parallel,
    // into buffers kept from band to band; the caller's thread only writes
    // them.
    let mut blocks = ExrBlocks::new(w, h, depth, layout.exr_channels())?;
    let (header, spares) = (blocks.header(), blocks.spares());
    let mut samples = Vec::new();
    write_exr_blocks(out, &header, &spares, |write| {
        let prepare = |_: Range<usize>, normals: &mut [[f32; 3]], heights: Vec<f32>| {
            options.store_all(normals);
            if layout == Layout::Rgb {
                // The normals are the samples, in order.
                return vec![blocks.push(normals.as_flattened())];
            }
            samples.clear();
            lay_out(normals, &heights, layout, Container::Exr, &mut samples);
            vec![blocks.push(&samples)]
        };
        let consume = |_: usize, chunks: Vec<Result<Vec<IndexedChunk>>>| chunks.into_iter().try_for_each(|c| write(c?));
        run(rows, &fit, tail, (false, Extra::of(layout)), visit, Stages { prepare, consume })?;
        blocks.finish()
    })?;
    Ok(fit.missing())
}

/// The curvature of the rows of `rows` ([`CurvatureBands`]) as a
/// one-channel OpenEXR (`Y`, ZIP in blocks of 16 rows) written to `out`
/// band by band: the file the whole image's curvature makes
/// (`io::write::encode_gray_tagged`). `tail` as for [`convert_exr`].
/// Returns the count of holes.
///
/// Errors: as [`convert_exr`], and those of [`CurvatureBands::new`].
pub(crate) fn curvature_exr<W: Write + Seek>(
    rows: impl RowSource,
    tail: Option<&[f64]>,
    opts: &Options,
    depth: ExrDepth,
    visit: impl FnMut(&[f32]) + Send,
    out: W,
) -> Result<usize> {
    let (w, h) = (rows.width(), rows.height());
    let fit = CurvatureBands::new(w, h, opts)?.with_unit(rows.unit());
    let tail = checked_tail(tail, w, h, opts)?;
    let mut blocks = ExrBlocks::new(w, h, depth, &["Y"])?;
    let (header, spares) = (blocks.header(), blocks.spares());
    write_exr_blocks(out, &header, &spares, |write| {
        let prepare = |_: Range<usize>, values: &mut [f32], _: Vec<f32>| vec![blocks.push(values)];
        let consume = |_: usize, chunks: Vec<Result<Vec<IndexedChunk>>>| chunks.into_iter().try_for_each(|c| write(c?));
        run(rows, &fit, tail, (false, Extra::None), visit, Stages { prepare, consume })?;
        blocks.finish()
    })?;
    Ok(fit.missing())
}
