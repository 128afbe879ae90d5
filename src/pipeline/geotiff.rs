//! A TIFF normal map or lit view written band by band
//! ([`crate::io::geotiff`]): the samples laid out on the fit's thread, the
//! rows written on the caller's as they come, a GeoTIFF's tags copied.

use std::io::{Seek, Write};
use std::ops::Range;

use super::{Extra, RowSource, Stages, checked_tail, run};
use crate::error::Result;
use crate::fit::{BandFit, Texel};
use crate::io::encoding::{ExrDepth, ExrOptions, Layout, TiffDepth, TiffOptions, TiffTags};
use crate::io::texels::{Container, Sample, lay_out};
use crate::io::tiff::write::{TiffSample, write_tiff_rows};
use crate::light::Grey;
use crate::options::Options;
use crate::par::prelude::*;
use crate::units::{Measure, MeasureTexel, WithTexel};

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
    let layout = options.layout;
    let shape = (layout.png_samples(), Extra::of(layout));
    match options.depth {
        TiffDepth::Eight => stream_tiff(rows, tail, (opts, NORTH_UP), shape, tags, laid_out::<u8>(layout), visit, out),
        TiffDepth::Sixteen => {
            stream_tiff(rows, tail, (opts, NORTH_UP), shape, tags, laid_out::<u16>(layout), visit, out)
        }
        TiffDepth::Float => {
            // n itself, or (n + 1)/2: the rule of EXR's samples, in place
            // before the layout (a red-green map's B is then written 0).
            let rule = ExrOptions::new(ExrDepth::Float).with_signed(options.signed);
            let mut lay_out = laid_out::<f32>(layout);
            let samples = move |normals: &mut [[f32; 3]], heights: &[f32], samples: &mut Vec<f32>| {
                normals.par_chunks_mut(1 << 14).for_each(|chunk| rule.store_all(chunk));
                lay_out(normals, heights, samples);
            };
            stream_tiff(rows, tail, (opts, NORTH_UP), shape, tags, samples, visit, out)
        }
    }
}

/// A band's normals (and heights) appended in `layout`, as a PNG holds
/// them.
fn laid_out<S: Sample>(layout: Layout) -> impl FnMut(&mut [[S; 3]], &[f32], &mut Vec<S>) + Send {
    move |normals, heights, samples| lay_out(normals, heights, layout, Container::Png, samples)
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
    lamp: crate::light::Lamp,
    tags: TiffTags<'_>,
    visit: impl FnMut(&[f32]) + Send,
    out: W,
) -> Result<usize> {
    let extra = if opts.nodata.is_some() { Extra::Valid } else { Extra::None };
    fn greys<const SUN: bool>(texels: &mut [Grey<SUN>], valid: &[f32], grey: &mut Vec<u8>) {
        grey.extend(texels.iter().map(|g| g.0));
        super::holes_grey(valid, grey);
    }
    let frame = (opts, (None, Some(lamp)));
    match lamp.is_sun() {
        true => stream_tiff(rows, tail, frame, (1, extra), tags, greys::<true>, visit, out),
        false => stream_tiff(rows, tail, frame, (1, extra), tags, greys::<false>, visit, out),
    }
}

/// A height map's slope or aspect ([`crate::units::Measure`]), a float
/// TIFF of one sample with `tags` (the nodata value among them), written as
/// it is fitted: the values the whole image gives (the texels
/// [`crate::units::Measure::with_texel`] chooses, on the raster placed by
/// the affine given with the measure). `tail` (the image's last rows) is
/// needed for a wrap in y. Returns the count of missing texels.
///
/// Errors: as [`convert_tiff_counting`].
pub(crate) fn measure_tiff<W: Write + Seek>(
    rows: impl RowSource,
    tail: Option<&[f64]>,
    opts: &Options,
    (measure, affine): (Measure, Option<&crate::io::Affine>),
    tags: TiffTags<'_>,
    visit: impl FnMut(&[f32]) + Send,
    out: W,
) -> Result<usize> {
    measure.with_texel(MeasureStream { rows, tail, opts, affine: affine.copied(), tags, visit, out })
}

/// [`measure_tiff`]'s arguments, for the measure's texel.
struct MeasureStream<'a, R, V, W> {
    rows: R,
    tail: Option<&'a [f64]>,
    opts: &'a Options,
    affine: Option<crate::io::Affine>,
    tags: TiffTags<'a>,
    visit: V,
    out: W,
}

impl<R: RowSource, V: FnMut(&[f32]) + Send, W: Write + Seek> WithTexel for MeasureStream<'_, R, V, W> {
    type Output = Result<usize>;

    fn run<T: MeasureTexel>(self) -> Result<usize> {
        let MeasureStream { rows, tail, opts, affine, tags, visit, out } = self;
        let extra = if opts.nodata.is_some() { Extra::Valid } else { Extra::None };
        let values = move |texels: &mut [T], valid: &[f32], values: &mut Vec<f32>| {
            values.extend(texels.iter().map(|t| t.value()));
            // `valid` is one a texel with holes, else empty.
            for (v, _) in values.iter_mut().zip(valid).filter(|(_, valid)| **valid == 0.0) {
                *v = crate::units::NODATA;
            }
        };
        let frame = (affine.as_ref(), None);
        stream_tiff(rows, tail, (opts, frame), (1, extra), tags, values, visit, out)
    }
}

/// What a fit's texels are made on beside their normals
/// ([`crate::fit::TexelFrame`]): the raster's geotransform (`None`:
/// north-up) and a lit view's lamp.
type Frame<'a> = (Option<&'a crate::io::Affine>, Option<crate::light::Lamp>);

/// Normals, which need no frame.
const NORTH_UP: Frame<'static> = (None, None);

/// Fits `rows` band by band into a TIFF of `channels` samples `S` a
/// texel, with `tags`: `samples` turns a band's texels `T` (and what
/// `extra` asks for beside them) into its samples, appended to a buffer
/// that is written on the caller's thread as it comes. Returns the count
/// of missing texels.
///
/// `tail` (the image's last rows) is needed for a wrap in y, as for
/// [`super::convert_exr`].
#[expect(clippy::too_many_arguments, reason = "the conversion's parts, as its callers take them")]
fn stream_tiff<S, T, W: Write + Seek>(
    rows: impl RowSource,
    tail: Option<&[f64]>,
    (opts, (affine, lamp)): (&Options, Frame<'_>),
    (channels, extra): (usize, Extra),
    tags: TiffTags<'_>,
    mut samples: impl FnMut(&mut [T], &[f32], &mut Vec<S>) + Send,
    visit: impl FnMut(&[f32]) + Send,
    out: W,
) -> Result<usize>
where
    S: TiffSample + Send,
    [S]: tiff::encoder::TiffValue,
    T: Texel + Default,
{
    let (w, h) = (rows.width(), rows.height());
    let tail = checked_tail(tail, w, h, opts)?;
    let mut fit = BandFit::new(w, h, opts)?.with_unit(rows.unit()).on_map(affine);
    if let Some(lamp) = lamp {
        fit = fit.lit(lamp);
    }
    // A band's samples, once written, go back to be filled again: a new
    // buffer for each band cost its page faults (a float band is 6 MiB at
    // 4096 wide), as much processor time as the rest of the writing.
    let (spare_tx, spare_rx) = std::sync::mpsc::sync_channel::<Vec<S>>(2);
    write_tiff_rows(out, (w, h), channels, tags, |push| {
        let prepare = move |_: Range<usize>, texels: &mut [T], extra: Vec<f32>| {
            let mut band = spare_rx.try_recv().unwrap_or_default();
            band.clear();
            samples(texels, &extra, &mut band);
            band
        };
        let consume = |_: usize, band: Vec<S>| {
            push(&band)?;
            // Dropped when two are waiting already.
            let _ = spare_tx.try_send(band);
            Ok(())
        };
        run(rows, &fit, tail, (false, extra), visit, Stages { prepare, consume })
    })?;
    Ok(fit.missing())
}
