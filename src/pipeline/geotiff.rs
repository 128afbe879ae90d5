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
use crate::io::write::{Container, ExrDepth, Layout, Sample, TiffTags, lay_out};
use crate::options::Options;

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
        TiffDepth::Eight => stream_normals::<u8, _>(rows, job, None, visit, out)?,
        TiffDepth::Sixteen => stream_normals::<u16, _>(rows, job, None, visit, out)?,
        TiffDepth::Float => {
            // n itself, or (n + 1)/2: the rule of EXR's samples.
            let store: fn(f32) -> f32 = |c| ExrOptions::new(ExrDepth::Float).stored(c);
            stream_normals::<f32, _>(rows, job, (!options.signed).then_some(store), visit, out)?;
        }
    }
    Ok(fit.missing())
}

/// [`convert_tiff_counting`] with samples of type `S`, each normal
/// component changed by `store` if given.
fn stream_normals<S, W: Write + Seek>(
    rows: impl RowSource,
    (fit, tail, options, tags): (&BandFit, Option<&[f64]>, TiffOptions, TiffTags<'_>),
    store: Option<fn(S) -> S>,
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
    // Red-green maps' B is 0 as stored, not a component to store.
    let components = if layout == Layout::Rg { 2 } else { 3 };
    let (w, h) = (fit.width(), fit.height());
    write_tiff_rows(out, (w, h), channels, tags, |push| {
        let prepare = |_: Range<usize>, normals: &mut [[S; 3]], heights: Vec<f32>| {
            let mut samples = Vec::with_capacity(normals.len() * channels);
            lay_out(normals, &heights, layout, Container::Png, &mut samples);
            if let Some(store) = store {
                for texel in samples.chunks_exact_mut(channels) {
                    texel[..components].iter_mut().for_each(|c| *c = store(*c));
                }
            }
            samples
        };
        let consume = |_: usize, samples: Vec<S>| push(&samples);
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
