//! PNG, read with the `png` crate, and zlib's checksum of its image data
//! (`zlib.rs`), verified whole-image and streamed alike.

pub(crate) mod deflate;
pub(crate) mod rows;
pub(crate) mod stream;
pub(crate) mod write;
pub(crate) mod zlib;

use std::io::Cursor;

use image::ColorType;

use self::zlib::{self as png_zlib, IdatWatch, finish_checked, png_error};
use crate::error::{Error, Result};
use crate::io::read::image_crate::{deinterleave, image_limits, layout};
use crate::io::{InputFormat, Raster, ReadOptions, check_size, to_usize};
use crate::memory;
use crate::samples::try_vec;

/// Decodes a PNG: the size its header claims checked first
/// ([`check_png_header`]), then [`decode_png`].
pub(crate) fn decode(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    check_png_header(bytes, opts)?;
    decode_png(bytes, opts)
}

/// The eight bytes every PNG file starts with.
pub(crate) const PNG_SIGNATURE: [u8; 8] = *b"\x89PNG\r\n\x1a\n";

/// Checks the size a PNG's IHDR claims, from the file's first bytes,
/// before a decoder sees it: against the limit, and against PNG's own
/// maximum side, 2^31 − 1. The decoders check too, but report the limit
/// they hit (their buffers), not the size; here the message names it.
/// Too few bytes, or no IHDR first, is left to the decoder to report.
pub(crate) fn check_png_header(start: &[u8], opts: &ReadOptions) -> Result<()> {
    // Signature (8 bytes), IHDR length (4) and type (4), width, height.
    let Some(ihdr) = start.get(8..24) else { return Ok(()) };
    if &ihdr[4..8] != b"IHDR" {
        return Ok(());
    }
    let width = u32::from_be_bytes([ihdr[8], ihdr[9], ihdr[10], ihdr[11]]);
    let height = u32::from_be_bytes([ihdr[12], ihdr[13], ihdr[14], ihdr[15]]);
    const PNG_MAX_SIDE: u32 = i32::MAX as u32;
    if width > PNG_MAX_SIDE || height > PNG_MAX_SIDE {
        return Err(Error::Decode(format!("png header claims {width} × {height}, but a side is at most 2^31 − 1")));
    }
    check_size(u64::from(width), u64::from(height), opts)
}

/// Decodes a PNG with the `png` crate (which `image` uses too, without a
/// way to have zlib's checksum verified; see [`png_zlib`]): header, size
/// check, rows, then the rest of the file up to IEND and the checksum.
/// Samples come out as `image` gives them: low bit depths expanded to 8
/// bits, palettes to RGB(A), 16-bit samples in native byte order.
fn decode_png(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let (watch, idat) = IdatWatch::new(Cursor::new(bytes));
    let mut decoder = png::Decoder::new_with_options(watch, png_zlib::decode_options());
    let max_alloc = image_limits(opts).max_alloc.unwrap_or(u64::MAX);
    decoder.set_limits(png::Limits { bytes: usize::try_from(max_alloc).unwrap_or(usize::MAX) });
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(png_error)?;
    check_png_palette(reader.info())?;
    let (width, height, interlaced) = (reader.info().width, reader.info().height, reader.info().interlaced);
    check_size(u64::from(width), u64::from(height), opts)?;
    let (png_color, depth) = reader.output_color_type();
    let color = match (png_color, depth) {
        (png::ColorType::Grayscale, png::BitDepth::Eight) => ColorType::L8,
        (png::ColorType::Grayscale, png::BitDepth::Sixteen) => ColorType::L16,
        (png::ColorType::GrayscaleAlpha, png::BitDepth::Eight) => ColorType::La8,
        (png::ColorType::GrayscaleAlpha, png::BitDepth::Sixteen) => ColorType::La16,
        (png::ColorType::Rgb, png::BitDepth::Eight) => ColorType::Rgb8,
        (png::ColorType::Rgb, png::BitDepth::Sixteen) => ColorType::Rgb16,
        (png::ColorType::Rgba, png::BitDepth::Eight) => ColorType::Rgba8,
        (png::ColorType::Rgba, png::BitDepth::Sixteen) => ColorType::Rgba16,
        (color, depth) => {
            let color = match color {
                png::ColorType::Grayscale => "gray",
                png::ColorType::GrayscaleAlpha => "gray and alpha",
                png::ColorType::Rgb => "RGB",
                png::ColorType::Rgba => "RGBA",
                png::ColorType::Indexed => "palette",
            };
            return Err(Error::Unsupported(format!("png of {} bits {color} is not supported", depth as u8)));
        }
    };
    let (names, sample) = layout(color)?;
    let texels = to_usize(u64::from(width) * u64::from(height))?;
    let line = reader.output_line_size(width).ok_or_else(|| Error::Limits(format!("{width} texels a row")))?;
    let len = reader.output_buffer_size().ok_or_else(|| Error::Limits(format!("{width} × {height} texels")))?;
    memory::check_memory("decoding", (len as u64).saturating_add(4 * texels as u64 * names.len() as u64))?;
    let mut buf = try_vec::<u8>(len)?;
    buf.resize(len, 0);
    // The image data read when the last row is out, before the call that
    // finds no more rows reads on.
    let mut at_last_row = idat.get();
    if interlaced {
        // Adam7's seven passes, each row spread over the image as it comes.
        let bits = png_color.samples() as u8 * depth as u8;
        while let Some(row) = reader.next_interlaced_row().map_err(png_error)? {
            let png::InterlaceInfo::Adam7(pass) = row.interlace() else {
                return Err(Error::Decode("png: interlaced image gave a row of no pass".into()));
            };
            png::expand_interlaced_row(&mut buf, line, row.data(), pass, bits);
            at_last_row = idat.get();
        }
    } else {
        for (y, row) in buf.chunks_exact_mut(line).enumerate() {
            if reader.read_row(row).map_err(png_error)?.is_none() {
                return Err(Error::Decode(format!("image data ends after {y} of {height} rows")));
            }
        }
        at_last_row = idat.get();
    }
    finish_checked(&mut reader, &idat, at_last_row, || Ok(Cursor::new(bytes)))?;
    if depth == png::BitDepth::Sixteen && cfg!(target_endian = "little") {
        // `png` gives samples big-endian, `deinterleave` reads them native.
        // One loop that vectorises, as `image` does it: in parallel, it
        // cost more (measured: 15 ms more processor time for 4096²).
        for sample in buf.chunks_exact_mut(2) {
            sample.swap(0, 1);
        }
    }
    let planes = deinterleave(&buf, names, sample, texels)?;
    Ok(Raster {
        width: to_usize(width.into())?,
        height: to_usize(height.into())?,
        format: InputFormat::Png,
        sample,
        planes,
        georef: None,
    })
}

/// Refuses a PNG palette that is not a whole number of RGB entries, which
/// the PNG spec makes an error. `png` 0.18.1 does not check it, and panics
/// (a slice index out of range) expanding such a palette into the first
/// row, whole-image and streamed alike. Found by fuzzing
/// (tests/integration/fuzz_regressions.rs); the `png` crate's header has the palette
/// before any row is decoded.
pub(crate) fn check_png_palette(info: &png::Info) -> Result<()> {
    match info.palette.as_deref() {
        Some(p) if p.len() % 3 != 0 => {
            Err(Error::Decode(format!("png palette of {} bytes is not a whole number of 3-byte RGB entries", p.len())))
        }
        _ => Ok(()),
    }
}
