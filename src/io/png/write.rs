//! Whole PNG images through the `image` crate's encoder: normal maps (8 or
//! 16 bits, RGB or RGBA) and one-channel maps.

use std::borrow::Cow;
use std::io::Write;

use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder, ImageError};

use crate::error::{Error, Result, one_line};
use crate::io::encoding::{Layout, PngCompression, PngOptions};
use crate::io::texels::{Container, Sample, check_buffer, lay_out};

/// A PNG sample type (`u8`, `u16`): its depth and its bytes.
pub trait PngSample: Sample {
    /// Bits per sample.
    const BITS: u8;
    /// The samples as native-endian bytes (what `image`'s encoder takes).
    #[doc(hidden)]
    fn ne_bytes(samples: &[Self]) -> Cow<'_, [u8]>;
    /// The samples as big-endian bytes (what a PNG stores).
    #[doc(hidden)]
    fn be_bytes(samples: &[Self]) -> Cow<'_, [u8]>;
}

impl PngSample for u8 {
    const BITS: u8 = 8;
    fn ne_bytes(samples: &[Self]) -> Cow<'_, [u8]> {
        Cow::Borrowed(samples)
    }
    fn be_bytes(samples: &[Self]) -> Cow<'_, [u8]> {
        Cow::Borrowed(samples)
    }
}

impl PngSample for u16 {
    const BITS: u8 = 16;
    fn ne_bytes(samples: &[Self]) -> Cow<'_, [u8]> {
        Cow::Owned(samples.iter().flat_map(|v| v.to_ne_bytes()).collect())
    }
    fn be_bytes(samples: &[Self]) -> Cow<'_, [u8]> {
        Cow::Owned(samples.iter().flat_map(|v| v.to_be_bytes()).collect())
    }
}

/// `image`'s colour type of `channels` (1, 3 or 4) samples of `bits` bits.
fn color_type(bits: u8, channels: usize) -> ExtendedColorType {
    match (bits, channels) {
        (8, 1) => ExtendedColorType::L8,
        (8, 3) => ExtendedColorType::Rgb8,
        (8, _) => ExtendedColorType::Rgba8,
        (_, 1) => ExtendedColorType::L16,
        (_, 3) => ExtendedColorType::Rgb16,
        _ => ExtendedColorType::Rgba16,
    }
}

/// The `image` setting of a PNG compression.
fn compression_type(compression: PngCompression) -> CompressionType {
    match compression {
        PngCompression::Fast => CompressionType::Fast,
        PngCompression::Default => CompressionType::Default,
        PngCompression::Best => CompressionType::Best,
    }
}

/// A one-channel PNG of `u8` or `u16` values.
pub(crate) fn png_gray<S: PngSample>(
    values: &[S],
    (width, height): (usize, usize),
    compression: PngCompression,
    out: impl Write,
) -> Result<()> {
    let (w, h) = png_size(values.len(), width, height)?;
    png_encoder(out, compression)
        .write_image(&S::ne_bytes(values), w, h, color_type(S::BITS, 1))
        .map_err(from_image_error)
}

/// A gray-and-alpha PNG of 16-bit samples, `pairs` holding each texel's
/// value then its alpha: the heights of a map with holes (alpha 0 there).
pub(crate) fn png_gray_alpha16(
    pairs: &[u16],
    (width, height): (usize, usize),
    compression: PngCompression,
    out: impl Write,
) -> Result<()> {
    let (w, h) = png_size(pairs.len() / 2, width, height)?;
    check_buffer(pairs.len(), width.saturating_mul(2), height)?;
    png_encoder(out, compression)
        .write_image(&u16::ne_bytes(pairs), w, h, ExtendedColorType::La16)
        .map_err(from_image_error)
}

/// A PNG normal map, 8 or 16 bits by the sample type.
///
/// `image`'s `PngEncoder::write_image` takes 16-bit samples as
/// native-endian bytes and swaps them to PNG's big-endian order itself.
pub(crate) fn png_normals<S: PngSample>(
    texels: &[[S; 3]],
    heights: &[f32],
    (width, height): (usize, usize),
    options: &PngOptions,
    out: impl Write,
) -> Result<()> {
    let PngOptions { layout, compression, .. } = *options;
    let (w, h) = png_size(texels.len(), width, height)?;
    let channels = layout.png_samples();
    let color = color_type(S::BITS, channels);
    if layout == Layout::Rgb {
        // Written as they are: no copy of the image.
        let bytes = S::ne_bytes(texels.as_flattened());
        return png_encoder(out, compression).write_image(&bytes, w, h, color).map_err(from_image_error);
    }
    let mut samples = Vec::new();
    samples
        .try_reserve_exact(texels.len() * channels)
        .map_err(|_| Error::Encode("out of memory for the png rows".into()))?;
    lay_out(texels, heights, layout, Container::Png, &mut samples);
    png_encoder(out, compression).write_image(&S::ne_bytes(&samples), w, h, color).map_err(from_image_error)
}

/// A PNG encoder with the adaptive filter, which suits smooth gradients.
fn png_encoder<W: Write>(out: W, compression: PngCompression) -> PngEncoder<W> {
    PngEncoder::new_with_quality(out, compression_type(compression), FilterType::Adaptive)
}

/// Checks the buffer and the PNG size limits before `image`, which panics
/// on a buffer of the wrong length.
fn png_size(len: usize, width: usize, height: usize) -> Result<(u32, u32)> {
    check_buffer(len, width, height)?;
    let side = |n: usize| u32::try_from(n).ok().filter(|&n| n > 0 && n <= i32::MAX as u32);
    match (side(width), side(height)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(Error::Encode(format!("png cannot hold {width} × {height} texels"))),
    }
}

/// Maps `image`'s errors: I/O stays I/O (the caller's writer failed),
/// everything else is an encoding failure.
fn from_image_error(e: ImageError) -> Error {
    match e {
        ImageError::IoError(e) => Error::Io(e),
        other => Error::Encode(one_line(&other.to_string()).to_lowercase()),
    }
}
