//! The formats the `image` crate reads (those of [`super::formats`] without
//! a decoder of their own: JPEG, TGA, BMP, WebP, GIF, HDR, PNM, QOI, and
//! the TIFF layouts `tiff.rs` leaves to it), and the interleaved-pixel
//! helpers the PNG decoder shares.

use std::io::Cursor;

use crate::par::prelude::*;
use image::{ColorType, ImageDecoder, ImageError, ImageFormat, ImageReader, Limits};

use crate::error::{Error, Result};
use crate::io::{InputFormat, Plane, Raster, ReadOptions, SampleType, check_size, message, par_collect, to_usize};
use crate::memory;
use crate::samples::{Samples, try_vec};

/// Decodes with the `image` crate as `format` (ours: `ours`): header
/// first, size check, then pixels.
pub(crate) fn decode_with_image(
    bytes: &[u8],
    opts: &ReadOptions,
    format: ImageFormat,
    ours: InputFormat,
) -> Result<Raster> {
    let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
    reader.limits(image_limits(opts));
    let decoder = reader.into_decoder().map_err(from_image_error)?;
    let (width, height) = decoder.dimensions();
    check_size(u64::from(width), u64::from(height), opts)?;
    let color = decoder.color_type();
    let (names, sample) = layout(color)?;
    let texels = to_usize(u64::from(width) * u64::from(height))?;
    let len = to_usize(decoder.total_bytes())?;
    memory::check_memory("decoding", (len as u64).saturating_add(4 * texels as u64 * names.len() as u64))?;
    let mut buf = try_vec::<u8>(len)?;
    buf.resize(len, 0);
    decoder.read_image(&mut buf).map_err(from_image_error)?;
    let planes = deinterleave(&buf, names, sample, texels)?;
    Ok(Raster {
        width: to_usize(width.into())?,
        height: to_usize(height.into())?,
        format: ours,
        sample,
        planes,
        georef: None,
    })
}

/// Whether the bytes are a TGA file: TGA has no signature, so bytes no
/// signature matches are tried as TGA, and accepted only if its header
/// parses (its header has enough fixed fields, image type and pixel
/// depth, that text and most other data fail it).
#[cfg(feature = "tga")]
pub(crate) fn is_tga(bytes: &[u8]) -> bool {
    let tga = ImageReader::with_format(Cursor::new(bytes), ImageFormat::Tga);
    tga.into_decoder().is_ok()
}

/// The name of a format the `image` crate knows by its signature but
/// normalfit does not read (ICO, DDS, AVIF, farbfeld), for the error.
pub(crate) fn unread_format(bytes: &[u8]) -> Option<String> {
    image::guess_format(bytes).ok().map(|format| format!("{format:?}").to_lowercase())
}

/// Limits handed to `image`, so its own allocations (PNG chunks, decoder
/// state) are bounded too: per side no more than `max_texels`, and memory
/// for the largest pixel (RGBA f32, 16 bytes) of every texel plus slack.
pub(crate) fn image_limits(opts: &ReadOptions) -> Limits {
    let side = u32::try_from(opts.max_texels).unwrap_or(u32::MAX);
    let mut limits = Limits::default();
    limits.max_image_width = Some(side);
    limits.max_image_height = Some(side);
    limits.max_alloc = Some(opts.max_texels.saturating_mul(16).saturating_add(64 << 20));
    limits
}

/// Plane names and sample type of a decoded colour type.
pub(crate) fn layout(color: ColorType) -> Result<(&'static [&'static str], SampleType)> {
    use ColorType::*;
    const Y: &[&str] = &["Y"];
    const YA: &[&str] = &["Y", "A"];
    const RGB: &[&str] = &["R", "G", "B"];
    const RGBA: &[&str] = &["R", "G", "B", "A"];
    let eight = SampleType::Int { bits: 8 };
    let sixteen = SampleType::Int { bits: 16 };
    Ok(match color {
        L8 => (Y, eight),
        La8 => (YA, eight),
        Rgb8 => (RGB, eight),
        Rgba8 => (RGBA, eight),
        L16 => (Y, sixteen),
        La16 => (YA, sixteen),
        Rgb16 => (RGB, sixteen),
        Rgba16 => (RGBA, sixteen),
        Rgb32F => (RGB, SampleType::Float),
        Rgba32F => (RGBA, SampleType::Float),
        other => {
            return Err(Error::Unsupported(format!("pixel layout {} is not supported", layout_words(other))));
        }
    })
}

/// Splits interleaved native-endian samples into planes, as stored.
pub(crate) fn deinterleave(buf: &[u8], names: &[&str], sample: SampleType, texels: usize) -> Result<Vec<Plane>> {
    let bytes = match sample {
        SampleType::Int { bits: 8 } => 1,
        SampleType::Int { bits: 16 } => 2,
        SampleType::Float => 4,
        other => return Err(Error::Unsupported(format!("{other} are not read from interleaved pixels"))),
    };
    let stride = bytes * names.len();
    if buf.len() != texels.saturating_mul(stride) {
        return Err(Error::Decode(format!("decoder gave {} bytes for {texels} texels of {stride} bytes", buf.len())));
    }
    names
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let o = c * bytes;
            let px = buf.par_chunks_exact(stride);
            let data = match bytes {
                1 => Samples::U8(par_collect(texels, px.map(|p| p[o]))?),
                2 => Samples::U16(par_collect(texels, px.map(|p| u16::from_ne_bytes([p[o], p[o + 1]])))?),
                _ => Samples::F32(par_collect(
                    texels,
                    px.map(|p| f32::from_ne_bytes([p[o], p[o + 1], p[o + 2], p[o + 3]])),
                )?),
            };
            Ok(Plane { name: (*name).to_string(), data })
        })
        .collect()
}

/// Maps `image`'s errors onto ours. Reading from memory cannot fail at the
/// operating system, so its I/O errors mean the data ended early.
fn from_image_error(e: ImageError) -> Error {
    match e {
        ImageError::Limits(e) => Error::Limits(message(&e.to_string())),
        ImageError::Unsupported(e) => Error::Unsupported(message(&e.to_string())),
        ImageError::IoError(e) => Error::Decode(format!("truncated or corrupt: {}", message(&e.to_string()))),
        other => Error::Decode(message(&other.to_string())),
    }
}

/// An `image` pixel layout in words ("RGB of 32-bit floats"); its `Debug`
/// is a Rust name.
fn layout_words(color: ColorType) -> String {
    let channels = match color.channel_count() {
        1 => "gray",
        2 => "gray and alpha",
        3 => "RGB",
        _ => "RGBA",
    };
    let bits = color.bits_per_pixel() / u16::from(color.channel_count().max(1));
    let kind = if matches!(color, ColorType::Rgb32F | ColorType::Rgba32F) { "float" } else { "integer" };
    format!("{channels} of {bits}-bit {kind}s")
}
