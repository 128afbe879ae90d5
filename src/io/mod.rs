//! Reading height maps and writing normal maps: image files, bytes, atomic writes.
//!
//! Grouped by format, as image-rs groups its codecs: `png/`, `exr/` and
//! `tiff/` each hold their format's whole-image decoder, its rows read one
//! at a time for streaming ([`RowSource`]: [`PngRows`], [`ExrRows`],
//! `TiffRows`) and its writers (whole, and the pieces the streaming
//! pipeline writes band by band). [`read`] is the input side's registry and
//! shared vocabulary: bytes of any supported format into planes of `f32` in
//! the contract's height units (SPEC §1), the channel rule, GeoTIFF
//! georeferencing, and the formats the `image` crate reads, RAW heightmaps
//! and packed elevation tiles. [`encoding`] is the output side's one
//! vocabulary: an [`Encoding`] (PNG, EXR or TIFF and their options, the
//! layout of the channels), chosen from a file name and the input by its
//! rules; [`write`](mod@write) encodes whole normal maps (SPEC §3) through
//! each format's writer, `texels.rs` lays a layout's samples out for every
//! writer, `target.rs` says where an output path leads (links followed;
//! a device, FIFO or socket is a stream), and `atomic.rs` puts files in
//! place whole or not at all (SPEC §4). None of it knows about the fit's sums; the engine
//! ([`crate::engine`]) joins reading and writing through a stage.

mod atomic;
pub(crate) mod dds;
pub mod encoding;
pub(crate) mod exr;
pub(crate) mod from_normal;
pub mod gpu;
mod identity;
pub(crate) mod ktx2;
pub(crate) mod png;
pub mod read;
pub mod rows;
pub mod sidecar;
mod target;
pub(crate) mod texels;
pub(crate) mod texture;
#[cfg(feature = "tiff")]
pub(crate) mod tiff;
pub mod write;

use std::path::Path;

use crate::error::{Error, Result, one_line};
use crate::par::prelude::*;
use crate::samples::{Samples, try_vec};

pub use crate::memory::{check_memory, memory_limit};
pub use encoding::{
    Alpha, Encoding, ExrDepth, ExrOptions, Layout, OutputChannels, OutputFormat, PngCompression, PngDepth, PngOptions,
    TextureCompression, TextureOptions,
};
pub use exr::rows::ExrRows;
pub use identity::{FileId, Inputs, same_file};
pub use png::rows::PngRows;
pub use read::{
    Affine, ByteOrder, Channel, FormatInfo, Georef, ModelType, PackedElevation, RasterType, RawOptions, decode,
    metres_per_degree, parse_size, read_path,
};
pub use rows::RowSource;
pub use target::{OutputTarget, open_stream, output_target};
#[cfg(feature = "tiff")]
pub use tiff::rows::TiffRows;
pub use write::{
    FileSet, GrayValue, NormalTexel, PngSample, Replace, Sample, encode_gray, encode_normals, write_atomically,
    write_file_atomically,
};

// What every format reads into, and is asked to read: the vocabulary the
// decoders (read/, png/, exr/, tiff/) share, kept here, below them all.

/// The file format the bytes were decoded as, found from their content.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum InputFormat {
    /// Portable Network Graphics.
    Png,
    /// OpenEXR.
    Exr,
    /// JPEG.
    Jpeg,
    /// TIFF.
    Tiff,
    /// Truevision TGA.
    Tga,
    /// Windows bitmap.
    Bmp,
    /// WebP.
    WebP,
    /// Graphics Interchange Format.
    Gif,
    /// Radiance HDR (RGBE).
    Hdr,
    /// Netpbm (PBM, PGM, PPM, PAM).
    Pnm,
    /// Quite OK Image format.
    Qoi,
    /// A RAW heightmap: bare 8- or 16-bit samples, no header.
    Raw,
}

/// How the samples were stored in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum SampleType {
    /// Unsigned integers of `bits` bits per channel, as decoded (a 1-, 2- or
    /// 4-bit gray PNG arrives expanded to 8 bits, scaled so that the top
    /// value stays 1.0); read as value / (2^bits − 1) ∈ [0, 1].
    Int {
        /// Bits per channel.
        bits: u8,
    },
    /// Signed (two's complement) integers of `bits` bits per channel, from
    /// a TIFF (a GeoTIFF elevation model's int16 or int32 metres). Read as
    /// value / (2^bits − 1), the unsigned rule with the same step per
    /// stored unit, so h ∈ [−0.5, 0.5]: a signed map and the same map
    /// stored unsigned with an offset give the same normals, and a DEM's
    /// int16 and uint16 copies too. The values as stored (metres, for a
    /// DEM) are [`Raster::into_stored_heights`]; docs/terrain.md.
    SignedInt {
        /// Bits per channel.
        bits: u8,
    },
    /// Floating point (half, float, double, or EXR's u32, all taken as
    /// numbers).
    Float,
}

/// As messages name it: "16-bit integer samples", "16-bit signed integer
/// samples", "float samples".
impl std::fmt::Display for SampleType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SampleType::Int { bits } => write!(f, "{bits}-bit integer samples"),
            SampleType::SignedInt { bits } => write!(f, "{bits}-bit signed integer samples"),
            SampleType::Float => write!(f, "float samples"),
        }
    }
}

impl SampleType {
    /// The stored value of a height of 1 in contract units: 2^bits − 1 for
    /// integers, signed or not (255, 65535, …), 1 for floats. A stored
    /// value is its height times this: a DEM's metres, a RAW's integers.
    #[must_use]
    pub fn stored_per_unit(self) -> f64 {
        match self {
            SampleType::Int { bits } | SampleType::SignedInt { bits } => 2f64.powi(i32::from(bits)) - 1.0,
            SampleType::Float => 1.0,
        }
    }

    /// Whether a channel holds more than 8 bits; floats count as more.
    ///
    /// SPEC §3 picks the default PNG output depth with it: 16 bits when the
    /// input has more than 8, so precision the input has is not thrown away.
    #[must_use]
    pub fn more_than_8_bits(self) -> bool {
        match self {
            SampleType::Int { bits } | SampleType::SignedInt { bits } => bits > 8,
            SampleType::Float => true,
        }
    }
}

/// One channel of an image: row-major, `width * height` samples as stored
/// (see [`Samples`] for their heights in contract units).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct Plane {
    /// The channel's name: "Y" (gray), "R", "G", "B", "A" for the formats
    /// `image` and `tiff` read; the file's own channel names for EXR
    /// ("height", "diffuse.R", …).
    pub name: String,
    /// The samples, row 0 first.
    pub data: Samples,
}

/// A decoded image, one plane per channel.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct Raster {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The format the content was decoded as.
    pub format: InputFormat,
    /// How the samples were stored.
    pub sample: SampleType,
    /// The channels, in the file's order. An OpenEXR file's subsampled
    /// channels (a luminance/chroma file's RY and BY) are left out: they
    /// have fewer samples than texels and are never heights.
    pub planes: Vec<Plane>,
    /// A GeoTIFF's georeferencing (pixel size, model type, EPSG code,
    /// nodata value); `None` for other formats and TIFFs without the tags.
    pub georef: Option<Georef>,
}

/// Limits for a read of untrusted bytes, and which part of a file to read.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct ReadOptions {
    /// The largest width × height accepted, checked from the header before
    /// any pixel buffer is allocated. Default: 2^30 (32768²), which is
    /// 4 GiB for one `f32` plane: larger than any texture a GPU takes,
    /// small enough that a forged header cannot exhaust memory.
    pub max_texels: u64,
    /// OpenEXR: the layer to read, by name. A layer is a part of a
    /// multi-part file (its `name` attribute), else the channels of one
    /// part whose names start with `NAME.` ("diffuse.R", "diffuse.G", …);
    /// a part's name wins over a channel prefix. `None` reads the file's
    /// first part of flat (not deep) samples, all its channels. Any other
    /// format has no layers: asking for one there is an error.
    pub layer: Option<String>,
    /// TIFF: the band to read, 1-based as GDAL counts them, of a
    /// multi-band file (chunky or planar), whatever its sample type; the
    /// file is then read as that one gray band. `None` reads a file as its
    /// colour type says (gray, RGB, …), and a file of several bands that
    /// are not colours as its first band. Any other format has no bands:
    /// asking for one there is an error.
    pub band: Option<u32>,
    /// RAW heightmaps: their layout. A file named `.raw`, `.r16` or `.r8`
    /// is RAW whatever this holds (`None`: square, depth by extension or
    /// length, little-endian). `Some` also makes RAW the bytes given to
    /// [`decode`] and files whose extension names no format (`.bin`, none);
    /// files named as another format are still read by their content.
    pub raw: Option<RawOptions>,
    /// Heights packed in an 8-bit RGB tile (PNG or WebP), unpacked to float
    /// heights in metres; `None` reads the tile as a picture.
    pub decode: Option<PackedElevation>,
    /// TIFF: whether the GDAL_NODATA tag is read, as
    /// [`Georef::nodata`], which makes holes of the texels that hold its
    /// value unless the fit's own [`Options::nodata`](crate::Options::nodata)
    /// is given. `false` ignores the tag: every stored value is a height
    /// (the CLI's `--nodata none`), for a file whose tag is wrong, or whose
    /// "nodata" value is a real height. Default: `true`.
    pub nodata_tag: bool,
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions { max_texels: 1 << 30, layer: None, band: None, raw: None, decode: None, nodata_tag: true }
    }
}

impl ReadOptions {
    /// The same options with another texel limit.
    #[must_use]
    pub fn with_max_texels(mut self, max_texels: u64) -> Self {
        self.max_texels = max_texels;
        self
    }

    /// Checks the options as a caller gave them: the texel limit must be
    /// at least 1 (0 would refuse every image), a band at least 1 (bands
    /// count from 1, as in GDAL), a RAW layout as
    /// [`RawOptions::validate`] says.
    ///
    /// Errors: [`Error::InvalidOption`] naming the value.
    pub fn validate(&self) -> Result<()> {
        if self.max_texels == 0 {
            return Err(Error::InvalidOption("max_texels must be at least 1, got 0".into()));
        }
        if self.band == Some(0) {
            return Err(Error::InvalidOption("bands count from 1, as in GDAL: got band 0".into()));
        }
        if let Some(raw) = &self.raw {
            raw.validate()?;
        }
        Ok(())
    }

    /// The same options reading TIFF band `band` (1-based).
    #[must_use]
    pub fn with_band(mut self, band: u32) -> Self {
        self.band = Some(band);
        self
    }

    /// The same options with a RAW layout (see [`ReadOptions::raw`]).
    #[must_use]
    pub fn with_raw(mut self, raw: RawOptions) -> Self {
        self.raw = Some(raw);
        self
    }

    /// The same options reading a TIFF's GDAL_NODATA tag, or ignoring it
    /// (see [`ReadOptions::nodata_tag`]).
    #[must_use]
    pub fn with_nodata_tag(mut self, read: bool) -> Self {
        self.nodata_tag = read;
        self
    }

    /// The same options unpacking heights from RGB tiles.
    #[must_use]
    pub fn with_decode(mut self, packing: PackedElevation) -> Self {
        self.decode = Some(packing);
        self
    }

    /// Whether a file is read as rows streamed through the fit (PNG, EXR)
    /// with these options: not when a band, a packing or a RAW layout
    /// decides how it is read, which the streaming readers do not know.
    #[must_use]
    pub fn may_stream(&self, path: &Path) -> bool {
        self.band.is_none() && self.decode.is_none() && read::raw_layout_for(path, self).is_none()
    }

    /// The same options reading the OpenEXR layer `name`.
    #[must_use]
    pub fn with_layer(mut self, name: impl Into<String>) -> Self {
        self.layer = Some(name.into());
        self
    }
}

/// The error for a band asked for in a format without bands.
pub(crate) fn no_bands(format: &InputFormat, band: u32) -> Error {
    Error::Unsupported(format!("band {band} asked for, but {format} files have no bands (only TIFF has)"))
}

/// The error for a layer asked for in a format without layers.
pub(crate) fn no_layers(format: &InputFormat, layer: &str) -> Error {
    Error::Unsupported(format!("layer {layer} asked for, but {format} files have no layers (only OpenEXR has)"))
}

/// Checks a header's claimed size: not zero, not above the limit.
pub(crate) fn check_size(width: u64, height: u64, opts: &ReadOptions) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::Decode(format!("image has zero size ({width} × {height})")));
    }
    let texels = width.saturating_mul(height);
    if texels > opts.max_texels {
        return Err(Error::Limits(format!("{width} × {height} is {texels} texels, the limit is {}", opts.max_texels)));
    }
    Ok(())
}

/// A dependency's message made to read as part of ours: on one line,
/// "Format error decoding Png: …" as "png: …", chunk types printed by
/// `png` as `ChunkType { type: IDAT, … }` as IDAT, no final full stop,
/// and the first letter in lower case unless it starts an acronym (CRC).
pub(crate) fn message(s: &str) -> String {
    const CHUNK: &str = "ChunkType { type: ";
    let mut s = one_line(s);
    while let Some(start) = s.find(CHUNK) {
        let rest = &s[start + CHUNK.len()..];
        let (Some(kind), Some(end)) = (rest.get(..4), rest.find('}')) else { break };
        s = format!("{}{kind}{}", &s[..start], &rest[end + 1..]);
    }
    let s = s.trim_end_matches('.');
    match s.strip_prefix("Format error decoding ").and_then(|r| r.split_once(": ")) {
        Some((format, rest)) => format!("{}: {}", format.to_lowercase(), lower_first(rest)),
        None => lower_first(s),
    }
}

/// `s` with its first letter in lower case when its first word is an
/// ordinary one ("Unknown" → "unknown"; "CRC", "I/O", "IDAT" stay).
fn lower_first(s: &str) -> String {
    let word = s.split_whitespace().next().unwrap_or("");
    let mut chars = word.chars();
    match chars.next() {
        Some(first) if chars.all(char::is_lowercase) => {
            first.to_lowercase().chain(s[first.len_utf8()..].chars()).collect()
        }
        _ => s.to_string(),
    }
}

/// A size from a header as `usize`, or [`Error::Limits`] on a platform
/// where it does not fit.
pub(crate) fn to_usize(n: u64) -> Result<usize> {
    usize::try_from(n).map_err(|_| Error::Limits(format!("{n} does not fit in memory")))
}

/// The values of a parallel iterator of `len` items in a vector allocated
/// fallibly.
pub(crate) fn par_collect<T: Send>(len: usize, values: impl ParallelIterator<Item = T>) -> Result<Vec<T>> {
    let mut data = try_vec(len)?;
    data.par_extend(values);
    Ok(data)
}
