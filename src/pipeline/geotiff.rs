//! A TIFF normal map or lit view written band by band
//! ([`crate::io::geotiff`]): the samples laid out on the fit's thread, the
//! rows written on the caller's as they come, a GeoTIFF's tags copied.

use std::io::{Seek, Write};
use std::ops::Range;

use super::{Extra, RowSource, Stages, checked_tail, run};
use crate::error::Result;
use crate::fit::{BandFit, FromNormal};
use crate::io::encoding::{ExrOptions, TiffDepth, TiffOptions};
use crate::io::geotiff::{TiffSample, write_tiff_rows};
use crate::io::write::{Container, ExrDepth, Sample, TiffTags, lay_out};
use crate::options::Options;
use crate::par::prelude::*;

/// Converts a height map's rows to a TIFF normal map as `options` says,
/// with `tags`: the samples [`crate::io::encode_normals`] writes for the
/// same map, written as they are fitted. `tail` (the image's last rows) is
/// needed for a wrap in y, as for [`super::convert_exr`]. Returns the
/// count of missing texels.
///
/// Errors: those of the fit and the rows; [`crate::Error::Io`] and
/// [`crate::Error::Encode`] from writing.
pub(crate) fn convert_tiff_counting<W: Write + Seek>(
    rows: impl RowSource,
    tail: Option<&[f64]>,
    opts: &Options,
    options: TiffOptions,
    tags: TiffTags<'_>,
    visit: impl FnMut(&[f32]) + Send,
    out: W,
) -> Result<usize> {
    let (w, h) = (rows.width(), rows.height());
    let tail = checked_tail(tail, w, h, opts)?;
    let fit = BandFit::new(w, h, opts)?.with_unit(rows.unit());
    let job = (&fit, tail, options, tags);
    match options.depth {
        TiffDepth::Eight => stream_normals::<u8, _>(rows, job, |_| (), visit, out)?,
        TiffDepth::Sixteen => stream_normals::<u16, _>(rows, job, |_| (), visit, out)?,
        TiffDepth::Float => {
            // n itself, or (n + 1)/2: the rule of EXR's samples, in place
            // before the layout (a red-green map's B is then written 0).
            let rule = ExrOptions::new(ExrDepth::Float).with_signed(options.signed);
            let store = |normals: &mut [[f32; 3]]| {
                normals.par_chunks_mut(1 << 14).for_each(|chunk| rule.store_all(chunk));
            };
            stream_normals::<f32, _>(rows, job, store, visit, out)?;
        }
    }
    Ok(fit.missing())
}

/// [`convert_tiff_counting`] with samples of type `S`, a band's normals
/// stored by `store` (in place) before they are laid out.
fn stream_normals<S, W: Write + Seek>(
    rows: impl RowSource,
    (fit, tail, options, tags): (&BandFit, Option<&[f64]>, TiffOptions, TiffTags<'_>),
    store: impl Fn(&mut [[S; 3]]) + Send,
    visit: impl FnMut(&[f32]) + Send,
    out: W,
) -> Result<()>
where
    S: TiffSample + Sample,
    [S]: tiff::encoder::TiffValue,
    [S; 3]: FromNormal + Default,
{
    let layout = options.layout;
    let channels = layout.png_samples();
    let (w, h) = (fit.width(), fit.height());
    // A band's samples, once written, go back to be filled again: a new
    // buffer for each band cost its page faults (a float band is 6 MiB at
    // 4096 wide), as much processor time as the rest of the writing.
    let (spare_tx, spare_rx) = std::sync::mpsc::sync_channel::<Vec<S>>(2);
    write_tiff_rows(out, (w, h), channels, tags, |push| {
        let prepare = move |_: Range<usize>, normals: &mut [[S; 3]], heights: Vec<f32>| {
            store(normals);
            let mut samples = spare_rx.try_recv().unwrap_or_default();
            samples.clear();
            lay_out(normals, &heights, layout, Container::Png, &mut samples);
            samples
        };
        let consume = |_: usize, samples: Vec<S>| {
            push(&samples)?;
            // Dropped when two are waiting already.
            let _ = spare_tx.try_send(samples);
            Ok(())
        };
        run(rows, fit, tail, (false, Extra::of(layout)), visit, Stages { prepare, consume })
    })
}

/// A height map's lit view, an 8-bit grey TIFF with `tags` (see
/// [`crate::shade::LitView::encode_tiff`]): the greys of
/// [`super::shade_png_seekable`], written as they are fitted. `tail` (the
/// image's last rows) is needed for a wrap in y. Returns the count of
/// missing texels.
///
/// Errors: as [`convert_tiff_counting`].
pub(crate) fn shade_tiff<W: Write + Seek>(
    rows: impl RowSource,
    tail: Option<&[f64]>,
    opts: &Options,
    lamp: crate::shade::Lamp,
    tags: TiffTags<'_>,
    visit: impl FnMut(&[f32]) + Send,
    out: W,
) -> Result<usize> {
    let (w, h) = (rows.width(), rows.height());
    let tail = checked_tail(tail, w, h, opts)?;
    let fit = BandFit::new(w, h, opts)?.with_unit(rows.unit());
    let extra = if opts.nodata.is_some() { Extra::Valid } else { Extra::None };
    write_tiff_rows(out, (w, h), 1, tags, |push| {
        let prepare = |_: Range<usize>, normals: &mut [[f32; 3]], valid: Vec<f32>| {
            let mut grey = vec![0u8; normals.len()];
            super::lit_greys(lamp, normals, &valid, &mut grey);
            grey
        };
        let consume = |_: usize, grey: Vec<u8>| push(&grey);
        run(rows, &fit, tail, (false, extra), visit, Stages { prepare, consume })
    })?;
    Ok(fit.missing())
}
