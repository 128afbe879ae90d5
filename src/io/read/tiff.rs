//! TIFF. Gray TIFF that `image` refuses is read with the `tiff` crate:
//! 32- and 64-bit float (what terrain generators and GIS tools export),
//! half float, 32- and 64-bit unsigned and 8- to 64-bit signed integers.
//! Every other TIFF (8- and 16-bit gray, RGB, float RGB, …) stays with
//! `image`, which reads it.

use std::io::Cursor;

use crate::par::prelude::*;
use image::ImageFormat;
use tiff::tags::{SampleFormat, Tag};

use super::image_crate::decode_with_image;
use super::{InputFormat, Plane, Raster, ReadOptions, SampleType, check_size, message, par_collect, to_usize};
use crate::error::{Error, Result};
use crate::io::memory;
use crate::samples::{Samples, try_vec};

/// Decodes a TIFF: the gray layouts `image` refuses here, the rest with
/// `image`.
pub(super) fn decode(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    match decode_tiff_gray(bytes, opts)? {
        Some(raster) => Ok(raster),
        None => decode_with_image(bytes, opts, ImageFormat::Tiff, InputFormat::Tiff),
    }
}

/// The gray sample layouts read here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum TiffGray {
    F16,
    F32,
    F64,
    U32,
    U64,
    I8,
    I16,
    I32,
    I64,
}

impl TiffGray {
    /// The layout of a sample format and depth, if it is one read here.
    fn of(format: SampleFormat, bits: u8) -> Option<TiffGray> {
        use TiffGray::*;
        Some(match (format, bits) {
            (SampleFormat::IEEEFP, 16) => F16,
            (SampleFormat::IEEEFP, 32) => F32,
            (SampleFormat::IEEEFP, 64) => F64,
            (SampleFormat::Uint, 32) => U32,
            (SampleFormat::Uint, 64) => U64,
            (SampleFormat::Int, 8) => I8,
            (SampleFormat::Int, 16) => I16,
            (SampleFormat::Int, 32) => I32,
            (SampleFormat::Int, 64) => I64,
            _ => return None,
        })
    }

    /// Bytes per sample.
    fn bytes(self) -> usize {
        use TiffGray::*;
        match self {
            I8 => 1,
            F16 | I16 => 2,
            F32 | U32 | I32 => 4,
            F64 | U64 | I64 => 8,
        }
    }

    /// What was stored, for [`Raster::sample`].
    fn sample(self) -> SampleType {
        use TiffGray::*;
        // At most 8 bytes, so the bit count fits a u8.
        let bits = (self.bytes() * 8) as u8;
        match self {
            F16 | F32 | F64 => SampleType::Float,
            U32 | U64 => SampleType::Int { bits },
            I8 | I16 | I32 | I64 => SampleType::SignedInt { bits },
        }
    }
}

/// Decodes a gray TIFF whose samples `image` does not read. `Ok(None)`
/// leaves the file to `image`: every other layout, and files whose header
/// `tiff` cannot parse (`image` parses it with the same crate and reports
/// the error as it always has).
///
/// Units (SPEC §1): floats as stored (a double beyond f32's range becomes
/// ±inf, which [`Raster::heights`] rejects like any infinity); unsigned
/// integers value / (2^bits − 1); signed integers value / (2^bits − 1) too
/// (see [`SampleType::SignedInt`]). 64-bit integers are divided in f64, so
/// they keep 53 bits before the f32 rounding.
fn decode_tiff_gray(bytes: &[u8], opts: &ReadOptions) -> Result<Option<Raster>> {
    let Ok(mut decoder) = tiff::decoder::Decoder::new(Cursor::new(bytes)) else { return Ok(None) };
    let Ok(tiff::ColorType::Gray(bits)) = decoder.colortype() else { return Ok(None) };
    let format = match decoder.find_tag_unsigned_vec::<u16>(Tag::SampleFormat) {
        Ok(None) => SampleFormat::Uint,
        Ok(Some(formats)) => match formats.first() {
            Some(&f) => SampleFormat::from_u16_exhaustive(f),
            None => return Ok(None),
        },
        Err(_) => return Ok(None),
    };
    let Some(kind) = TiffGray::of(format, bits) else { return Ok(None) };

    // From here on the file is ours: its errors are reported as such.
    let (width, height) = decoder.dimensions().map_err(from_tiff_error)?;
    check_size(u64::from(width), u64::from(height), opts)?;
    let texels = to_usize(u64::from(width) * u64::from(height))?;
    let len = texels
        .checked_mul(kind.bytes())
        .ok_or_else(|| Error::Limits(format!("{texels} samples of {} bytes do not fit in memory", kind.bytes())))?;
    let mut decoder = decoder.with_limits(tiff_limits(opts, kind));
    let layout = decoder.image_buffer_layout().map_err(from_tiff_error)?;
    if layout.planes != 1 || layout.complete_len != len {
        return Err(Error::Decode(format!(
            "tiff layout of {} bytes in {} planes does not match {width} × {height} {kind:?} samples",
            layout.complete_len, layout.planes
        )));
    }
    memory::check_memory("decoding", (len as u64).saturating_add(4 * texels as u64))?;
    let mut buf = try_vec::<u8>(len)?;
    buf.resize(len, 0);
    decoder.read_image_bytes(&mut buf).map_err(from_tiff_error)?;
    let data = tiff_samples(&buf, kind, texels)?;
    Ok(Some(Raster {
        width: to_usize(width.into())?,
        height: to_usize(height.into())?,
        format: InputFormat::Tiff,
        sample: kind.sample(),
        planes: vec![Plane { name: "Y".into(), data }],
    }))
}

/// Limits handed to `tiff`: a decoded buffer may hold `max_texels` samples
/// of this image's type and no more. The stored bytes of one strip or tile
/// are streamed from memory, not buffered, so their limit only refuses
/// counts no honest file has: twice the decoded size (LZW, the worst
/// expander, stays under 1.5×) plus 1 MiB.
fn tiff_limits(opts: &ReadOptions, kind: TiffGray) -> tiff::decoder::Limits {
    let decoded = u64::try_from(kind.bytes())
        .ok()
        .and_then(|b| opts.max_texels.checked_mul(b))
        .and_then(|n| usize::try_from(n).ok())
        .unwrap_or(usize::MAX);
    let mut limits = tiff::decoder::Limits::default();
    limits.decoding_buffer_size = decoded;
    limits.intermediate_buffer_size = decoded.saturating_mul(2).saturating_add(1 << 20);
    limits
}

/// Native-endian samples (as `tiff` leaves them) to samples the fit reads:
/// floats as stored (half widened to `f32`), other integers as heights in
/// contract units in f64.
fn tiff_samples(buf: &[u8], kind: TiffGray, texels: usize) -> Result<Samples> {
    let size = kind.bytes();
    if buf.len() != texels.saturating_mul(size) {
        return Err(Error::Decode(format!("decoder gave {} bytes for {texels} texels of {size} bytes", buf.len())));
    }
    fn ne<const N: usize>(p: &[u8]) -> [u8; N] {
        std::array::from_fn(|i| p[i])
    }
    // 2^32 − 1 and 2^64 − 1 (the latter rounds to 2^64 in f64).
    const U32_TOP: f64 = u32::MAX as f64;
    const U64_TOP: f64 = u64::MAX as f64;
    let px = buf.par_chunks_exact(size);
    let f32s = |f: fn(&[u8]) -> f32| par_collect(texels, px.clone().map(f)).map(Samples::F32);
    let f64s = |f: fn(&[u8]) -> f64| par_collect(texels, px.clone().map(f)).map(Samples::F64);
    match kind {
        TiffGray::F16 => f32s(|p| exr::prelude::f16::from_bits(u16::from_ne_bytes(ne(p))).to_f32()),
        TiffGray::F32 => f32s(|p| f32::from_ne_bytes(ne(p))),
        TiffGray::F64 => f64s(|p| f64::from_ne_bytes(ne(p))),
        TiffGray::U32 => f64s(|p| f64::from(u32::from_ne_bytes(ne(p))) / U32_TOP),
        TiffGray::U64 => f64s(|p| u64::from_ne_bytes(ne(p)) as f64 / U64_TOP),
        TiffGray::I8 => f64s(|p| f64::from(i8::from_ne_bytes(ne(p))) / 255.0),
        TiffGray::I16 => f64s(|p| f64::from(i16::from_ne_bytes(ne(p))) / 65535.0),
        TiffGray::I32 => f64s(|p| f64::from(i32::from_ne_bytes(ne(p))) / U32_TOP),
        TiffGray::I64 => f64s(|p| i64::from_ne_bytes(ne(p)) as f64 / U64_TOP),
    }
}

/// Maps `tiff`'s errors onto ours. Reading from memory cannot fail at the
/// operating system, so its I/O errors mean the data ended early.
fn from_tiff_error(e: tiff::TiffError) -> Error {
    use tiff::TiffError as E;
    match e {
        E::IoError(e) => Error::Decode(format!("truncated or corrupt: {}", message(&e.to_string()))),
        E::UnsupportedError(e) => Error::Unsupported(message(&e.to_string())),
        E::LimitsExceeded => Error::Limits("tiff data exceeds the decoder's limits".into()),
        e @ (E::FormatError(_) | E::IntSizeError | E::UsageError(_)) => Error::Decode(message(&e.to_string())),
    }
}
