//! A normal map's texels as the samples a file stores: the sample types
//! ([`Sample`]), and the channels of a [`Layout`] laid out from the fit's
//! texels (and heights, for an alpha of heights). Every writer, whole or
//! streamed, lays texels out here, so all give the same samples.

use super::encoding::Layout;
use crate::error::{Error, Result};

/// A sample of an encoded normal map: `u8` and `u16` (PNG), `f32` (EXR).
pub trait Sample: Copy + Default + Send + Sync + 'static {
    /// An opaque alpha.
    const ONE: Self;
    /// The sample of a height in an alpha channel: `round(h · max)` of h
    /// clamped to [0, 1] for integers, h itself for floats.
    fn from_height(h: f32) -> Self;
}

impl Sample for u8 {
    const ONE: Self = u8::MAX;
    fn from_height(h: f32) -> Self {
        (f64::from(h.clamp(0.0, 1.0)) * 255.0).round() as u8
    }
}

impl Sample for u16 {
    const ONE: Self = u16::MAX;
    fn from_height(h: f32) -> Self {
        (f64::from(h.clamp(0.0, 1.0)) * 65535.0).round() as u16
    }
}

impl Sample for f32 {
    const ONE: Self = 1.0;
    fn from_height(h: f32) -> Self {
        h
    }
}

/// Where a layout's samples go: a PNG keeps the blue slot of [`Layout::Rg`]
/// (as 0), an EXR drops the channel.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Container {
    Png,
    Exr,
}

/// Appends the samples of `normals` laid out as `layout` says, texel after
/// texel, to `out`. `heights` (one per texel) is read for
/// [`Layout::RgbHeight`] alone.
pub(crate) fn lay_out<S: Sample>(
    normals: &[[S; 3]],
    heights: &[f32],
    layout: Layout,
    container: Container,
    out: &mut Vec<S>,
) {
    match (layout, container) {
        (Layout::Rgb, _) => out.extend_from_slice(normals.as_flattened()),
        (Layout::RgbHeight | Layout::RgbValid, _) => {
            out.extend(normals.iter().zip(heights).flat_map(|(&[r, g, b], &h)| [r, g, b, S::from_height(h)]));
        }
        (Layout::RgbOpaque, _) => out.extend(normals.iter().flat_map(|&[r, g, b]| [r, g, b, S::ONE])),
        (Layout::Rg, Container::Png) => out.extend(normals.iter().flat_map(|&[r, g, _]| [r, g, S::default()])),
        (Layout::Rg, Container::Exr) => out.extend(normals.iter().flat_map(|&[r, g, _]| [r, g])),
    }
}

/// A change made to a band of normals in place before they are written
/// (a float TIFF's (n + 1)/2).
pub(crate) type StoreInPlace<'a, S> = &'a (dyn Fn(&mut [[S; 3]]) + Sync);

/// Checks that a buffer holds `width * height` texels.
pub(crate) fn check_buffer(len: usize, width: usize, height: usize) -> Result<()> {
    let expected = width
        .checked_mul(height)
        .ok_or_else(|| Error::Encode(format!("{width} × {height} texels do not fit in memory")))?;
    if len != expected {
        return Err(Error::BufferSize { expected, actual: len });
    }
    Ok(())
}
