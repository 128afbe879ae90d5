//! Reading height maps: bytes in, planes of `f32` in contract units out.
//!
//! Rules this module keeps, and why:
//! * The decoder is chosen from the content, never the file name: a renamed
//!   file cannot pick a decoder that then misreads it. A file whose
//!   extension names another format than its content (a `.png` that is
//!   really a JPEG) is refused ([`formats::check_extension`]): in a
//!   pipeline that is a mix-up upstream; its bytes without the name
//!   ([`decode`]) still read. The one exception is RAW heightmaps
//!   (`raw.rs`), bare samples with no content to know them by: they are
//!   known by their extension (`.raw`, `.r16`, `.r8`) or by the caller's
//!   [`ReadOptions::raw`]. The formats, their signatures, names
//!   and decoders are listed once, in [`formats`]; OpenEXR goes to the
//!   `exr` crate (a file with subsampled channels, which it refuses, to
//!   `exr/subsampled.rs`), gray TIFF with samples `image` refuses (float,
//!   half, 32/64-bit and signed integers) to the `tiff` crate, PNG to the
//!   `png` crate (with zlib's checksum verified, `png/zlib.rs`),
//!   everything else to `image`.
//! * The size a header claims is checked against [`ReadOptions::max_texels`]
//!   before any pixel buffer exists. A 100-byte file can claim
//!   100000 × 100000 texels, and both `image` and `exr` would otherwise try
//!   to allocate for it (the `exr` crate can abort the process on a failed
//!   allocation, which no `Result` can catch).
//! * Headers are checked before the decoders trust them: a PNG's IHDR size
//!   (so the message names the size, not a decoder's buffer), an EXR's
//!   data and display windows (the `exr` crate would silently swap the
//!   corners of an inverted one) and its offset tables (8 bytes a chunk
//!   must be in the file).
//! * Large buffers are reserved with `try_reserve_exact`, so running out of
//!   memory for an image under the limit is an error, not an abort.
//! * Values are kept as they were stored ([`Samples`](crate::Samples)): 8- and 16-bit
//!   integers as integers, whose height is value / (2^bits − 1) (SPEC §1),
//!   floats as floats. Dividing first and rounding to `f32` would move
//!   normals at high gains (see [`crate::samples`]). NaN and infinities are
//!   kept in the planes; only [`Raster::heights`] rejects them, because only
//!   the channel that becomes the height matters.
//!
//! * Terrain (docs/terrain.md): a TIFF's band of any sample type
//!   ([`ReadOptions::band`]) and its GeoTIFF georeferencing
//!   ([`Raster::georef`], `georef.rs`); heights packed in RGB tiles,
//!   unpacked to metres after the tile is decoded
//!   ([`ReadOptions::decode`], `packed.rs`).
//!
//! Where things are: this file holds the types every format shares and
//! [`decode`]; `channel.rs` the channel rule (SPEC §1); [`formats`] the
//! registry of formats; the decoders of PNG, OpenEXR and TIFF live with
//! their format's rows and writers (`io/png/`, `io/exr/`, `io/tiff/`), and
//! `image_crate.rs` here reads the formats the `image` crate reads. A new format is an entry in the registry and, if `image` does
//! not read it, a decoder beside the others.

#[cfg(feature = "tiff")]
mod buffered;
mod channel;
pub mod formats;
pub mod georef;
pub(crate) mod image_crate;
mod packed;
mod raw;

use std::path::Path;

#[cfg(feature = "tiff")]
pub(crate) use self::buffered::SeekableBufReader;
pub use self::channel::Channel;
pub(crate) use self::channel::{Source, select_channel};
pub use self::formats::FormatInfo;
pub use self::georef::{Affine, Georef, ModelType, RasterType, metres_per_degree};
pub use self::packed::PackedElevation;
pub use self::raw::{ByteOrder, RawOptions, parse_size};
use crate::error::{Error, Result};
use crate::io::{InputFormat, Raster, ReadOptions, no_bands, no_layers};

/// Decodes an image from its bytes, choosing the decoder from the content
/// (or RAW, which has none, when [`ReadOptions::raw`] is given).
///
/// Errors: [`Error::Decode`] for empty, unknown, corrupt, truncated or
/// zero-size data, or a RAW length that does not fit its layout;
/// [`Error::Limits`] when the header claims more than `opts.max_texels`
/// texels; [`Error::Unsupported`] for a layout normalfit does not read, a
/// layer or band asked for in a format that has none, a band the file does
/// not have, a packing asked for in a file that is not an 8-bit RGB tile
/// or is a lossy WebP;
/// [`Error::InvalidOption`] for options [`ReadOptions::validate`] refuses.
pub fn decode(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    decode_as(bytes, opts.raw.as_ref(), opts)
}

/// Reads the file at `path` and [`decode`]s it: by its content, except a
/// RAW heightmap, known by its extension (`.raw`, `.r16`, `.r8`) or, with
/// [`ReadOptions::raw`], by an extension that names no format. Failing to
/// read the file is [`Error::Io`]; a file whose extension names another
/// format than its content is [`Error::Misnamed`]
/// ([`formats::check_extension`]).
pub fn read_path(path: &Path, opts: &ReadOptions) -> Result<Raster> {
    formats::check_extension(path)?;
    let raw = raw_layout_for(path, opts);
    if raw.is_none() {
        // An OpenEXR file is decoded from the file, a block at a time, not
        // from a copy of it in memory.
        let file = std::fs::File::open(path)?;
        let file_len = file.metadata()?.len();
        let mut read = std::io::BufReader::with_capacity(1 << 16, file);
        if std::io::BufRead::fill_buf(&mut read)?.starts_with(&crate::io::exr::EXR_MAGIC) {
            opts.validate()?;
            return decode_checked(InputFormat::Exr, opts, || crate::io::exr::decode_exr_from(read, file_len, opts));
        }
    }
    let bytes = std::fs::read(path)?;
    decode_as(&bytes, raw.as_ref(), opts)
}

/// The RAW layout `path` is read with, `None` when it is read by content.
pub(crate) fn raw_layout_for(path: &Path, opts: &ReadOptions) -> Option<RawOptions> {
    let extension = path.extension().and_then(|e| e.to_str());
    match extension.and_then(InputFormat::from_extension) {
        Some(InputFormat::Raw) => {
            Some(opts.raw.clone().unwrap_or_default().with_extension_bits(extension.unwrap_or_default()))
        }
        Some(_) => None,
        None => opts.raw.clone(),
    }
}

/// Decodes `bytes` as RAW with `raw`, else by their content; then the
/// packing, if any.
fn decode_as(bytes: &[u8], raw: Option<&RawOptions>, opts: &ReadOptions) -> Result<Raster> {
    opts.validate()?;
    if bytes.is_empty() {
        return Err(Error::Decode("file is empty".into()));
    }
    let format = match raw {
        Some(_) => InputFormat::Raw,
        None => InputFormat::recognise(bytes)?,
    };
    if let Some(packing) = opts.decode {
        packed::check_bytes(&format, bytes, packing)?;
    }
    decode_checked(format.clone(), opts, || match raw {
        Some(raw) => raw::decode_raw(bytes, raw, opts),
        None => format.info().decode(bytes, opts),
    })
}

/// `decode` of a file in `format`, with the rules every format shares:
/// no layer asked of a format without layers, nor a band of one without
/// bands; then the packing, if any.
fn decode_checked(format: InputFormat, opts: &ReadOptions, decode: impl FnOnce() -> Result<Raster>) -> Result<Raster> {
    if let Some(layer) = &opts.layer
        && format != InputFormat::Exr
    {
        return Err(no_layers(&format, layer));
    }
    if let Some(band) = opts.band
        && format != InputFormat::Tiff
    {
        return Err(no_bands(&format, band));
    }
    let raster = decode()?;
    match opts.decode {
        Some(packing) => packed::unpack(raster, packing),
        None => Ok(raster),
    }
}
