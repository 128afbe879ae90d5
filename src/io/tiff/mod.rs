//! TIFF and GeoTIFF. Samples `image` refuses are read with the `tiff`
//! crate: 32- and 64-bit float (what terrain generators and GIS tools
//! export), half float, 32- and 64-bit unsigned and 8- to 64-bit signed
//! integers, in one band or several (chunky or planar, striped or tiled):
//! the first band, or the one [`ReadOptions::band`] asks for, which is
//! read here whatever its type. Every other TIFF (8- and 16-bit gray, RGB,
//! float RGB, …) without a band asked for stays with `image`, which reads
//! it as it always has. The georeferencing tags are read from every TIFF
//! ([`Georef`]).

pub(crate) mod rows;
pub(crate) mod write;

use std::io::{Cursor, Read, Seek};

use crate::par::prelude::*;
use image::ImageFormat;
use tiff::tags::{SampleFormat, Tag};

use crate::error::{Error, Result};
use crate::io::read::georef::{self, Georef, tags as georef_tags};
use crate::io::read::image_crate::decode_with_image;
use crate::io::{InputFormat, Plane, Raster, ReadOptions, SampleType, check_size, message, par_collect, to_usize};
use crate::memory;
use crate::samples::{Samples, try_vec};

/// Decodes a TIFF: its georeferencing always; its samples here when
/// `image` does not read them or a band is asked for, else with `image`.
pub(crate) fn decode(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    // A header `tiff` cannot parse goes to `image`, which parses it with the
    // same crate and reports the error as it always has.
    let Ok(mut decoder) = tiff::decoder::Decoder::new(Cursor::new(bytes)) else {
        return decode_with_image(bytes, opts, ImageFormat::Tiff, InputFormat::Tiff);
    };
    let georef = read_georef(&mut decoder, opts.nodata_tag)?;
    let mut raster = match TiffLayout::of(&mut decoder)? {
        Some(layout) if opts.band.is_some() || !layout.image_reads() => decode_band(decoder, layout, opts)?,
        None if opts.band.is_some() => {
            return Err(Error::Unsupported(format!(
                "band {} asked for, but bands are read from gray, RGB(A) or multi-band TIFF only, not from {}",
                opts.band.unwrap_or(1),
                describe_colortype(&mut decoder)
            )));
        }
        _ => decode_with_image(bytes, opts, ImageFormat::Tiff, InputFormat::Tiff)?,
    };
    raster.georef = (!georef.is_empty()).then_some(georef);
    Ok(raster)
}

/// The sample layouts decoded here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum TiffGray {
    U8,
    U16,
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
            (SampleFormat::Uint, 8) => U8,
            (SampleFormat::Uint, 16) => U16,
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
            U8 | I8 => 1,
            U16 | F16 | I16 => 2,
            F32 | U32 | I32 => 4,
            F64 | U64 | I64 => 8,
        }
    }

    /// The layout as messages name it: "32-bit float", ….
    fn name(self) -> String {
        let (format, bits) = match self.sample() {
            SampleType::Float => (SampleFormat::IEEEFP, self.bytes() * 8),
            SampleType::Int { bits } => (SampleFormat::Uint, usize::from(bits)),
            SampleType::SignedInt { bits } => (SampleFormat::Int, usize::from(bits)),
        };
        format!("{bits}-bit {}", format_name(format))
    }

    /// What was stored, for [`Raster::sample`].
    fn sample(self) -> SampleType {
        use TiffGray::*;
        // At most 8 bytes, so the bit count fits a u8.
        let bits = (self.bytes() * 8) as u8;
        match self {
            F16 | F32 | F64 => SampleType::Float,
            U8 | U16 | U32 | U64 => SampleType::Int { bits },
            I8 | I16 | I32 | I64 => SampleType::SignedInt { bits },
        }
    }
}

/// What a TIFF holds per texel, from its header: the colour type `tiff`
/// makes of it, how many samples (bands) a texel has, their format and
/// depth (one for all: `tiff` reads uniform samples only).
#[derive(Clone, Copy, Debug)]
struct TiffLayout {
    color: tiff::ColorType,
    bands: usize,
    format: SampleFormat,
    bits: u8,
}

impl TiffLayout {
    /// The layout of a file whose bands can be read one by one: gray,
    /// gray + alpha, RGB, RGBA, or multi-band (GDAL's several bands of
    /// BlackIsZero). `None` for palette, CMYK, YCbCr, Lab and a colour type
    /// `tiff` refuses: `image` reads or reports those.
    fn of<R: Read + Seek>(decoder: &mut tiff::decoder::Decoder<R>) -> Result<Option<TiffLayout>> {
        use tiff::ColorType as C;
        let Ok(color) = decoder.colortype() else { return Ok(None) };
        let (bands, bits) = match color {
            C::Gray(b) => (1, b),
            C::GrayA(b) => (2, b),
            C::RGB(b) => (3, b),
            C::RGBA(b) => (4, b),
            C::Multiband { bit_depth, num_samples } => (usize::from(num_samples), bit_depth),
            _ => return Ok(None),
        };
        let format = match decoder.find_tag_unsigned_vec::<u16>(Tag::SampleFormat) {
            Ok(None) => SampleFormat::Uint,
            Ok(Some(formats)) => match formats.first() {
                Some(&f) if formats.iter().all(|&g| g == f) => SampleFormat::from_u16_exhaustive(f),
                Some(_) => {
                    let names: Vec<String> =
                        formats.iter().map(|&g| format_name(SampleFormat::from_u16_exhaustive(g))).collect();
                    return Err(Error::Unsupported(format!(
                        "bands of different sample formats ({}) are not read",
                        names.join(", ")
                    )));
                }
                None => return Ok(None),
            },
            Err(_) => return Ok(None),
        };
        Ok(Some(TiffLayout { color, bands, format, bits }))
    }

    /// Whether `image` reads this layout (and did before bands were read
    /// here, so those files keep its channels: luma of an RGB TIFF, alpha).
    fn image_reads(&self) -> bool {
        use tiff::ColorType as C;
        matches!(
            (self.color, self.format),
            (C::Gray(1 | 8 | 16) | C::GrayA(8 | 16) | C::RGB(8 | 16) | C::RGBA(8 | 16), SampleFormat::Uint)
                | (C::RGB(32) | C::RGBA(32), SampleFormat::IEEEFP)
        )
    }
}

/// How `tiff` names a colour type it reads no bands from, for the error.
fn describe_colortype(decoder: &mut tiff::decoder::Decoder<Cursor<&[u8]>>) -> String {
    match decoder.colortype() {
        Ok(color) => color_words(color),
        Err(e) => from_tiff_error(e).to_string(),
    }
}

/// Decodes one band of a TIFF of any sample type read here: the band
/// asked for ([`ReadOptions::band`], 1-based), else the first. Striped or
/// tiled, chunky (bands interleaved per texel) or planar (one plane per
/// band), every compression `tiff` reads.
///
/// Units (SPEC §1, and `docs/terrain.md`): floats as stored (a double
/// beyond f32's range becomes ±inf, which [`Raster::heights`] rejects like
/// any infinity); 8- and 16-bit unsigned integers kept as stored (height
/// value / (2^bits − 1)); other unsigned integers value / (2^bits − 1) and
/// signed integers value / (2^bits − 1) too (see
/// [`SampleType::SignedInt`]), in f64, from which
/// [`Raster::into_stored_heights`](crate::io::Raster::into_stored_heights)
/// gives the stored values back. 64-bit integers are divided in f64, so
/// they keep 53 bits before the f32 rounding.
fn decode_band(
    mut decoder: tiff::decoder::Decoder<Cursor<&[u8]>>,
    layout: TiffLayout,
    opts: &ReadOptions,
) -> Result<Raster> {
    let (kind, index) = choose_band(layout, opts)?;
    let bands = layout.bands;
    let (width, height) = decoder.dimensions().map_err(from_tiff_error)?;
    check_size(u64::from(width), u64::from(height), opts)?;
    let texels = to_usize(u64::from(width) * u64::from(height))?;
    let size = kind.bytes();
    let too_big = || Error::Limits(format!("{texels} texels of {bands} samples of {size} bytes do not fit in memory"));
    let plane = texels.checked_mul(size).ok_or_else(too_big)?;
    let len = plane.checked_mul(bands).ok_or_else(too_big)?;
    let planar =
        bands > 1 && decoder.find_tag_unsigned::<u16>(Tag::PlanarConfiguration).map_err(from_tiff_error)? == Some(2);
    check_stored_bytes(&mut decoder, len as u64)?;
    let mut decoder = decoder.with_limits(tiff_limits(opts, kind, if planar { 1 } else { bands }));
    let data = if planar {
        // Only the band's own strips or tiles are read. The whole image's
        // layout is asked for first: `tiff` checks the chunk geometry there.
        decoder.image_buffer_layout().map_err(from_tiff_error)?;
        memory::check_memory("decoding", (plane as u64).saturating_add(8 * texels as u64))?;
        let buf = read_planar_band(&mut decoder, index, bands, (width, height), size)?;
        tiff_samples(&buf, kind, texels, size)?
    } else {
        let buffer = decoder.image_buffer_layout().map_err(from_tiff_error)?;
        if buffer.planes != 1 || buffer.complete_len != len {
            return Err(Error::Decode(format!(
                "tiff layout of {} bytes in {} planes does not match {width} × {height} texels of {bands} {} samples",
                buffer.complete_len,
                buffer.planes,
                kind.name()
            )));
        }
        memory::check_memory("decoding", (len as u64).saturating_add(8 * texels as u64))?;
        let mut buf = try_vec::<u8>(len)?;
        buf.resize(len, 0);
        decoder.read_image_bytes(&mut buf).map_err(from_tiff_error)?;
        // Every `bands`-th sample from the band's own.
        tiff_samples(&buf[index * size..], kind, texels, size * bands)?
    };
    Ok(Raster {
        width: to_usize(width.into())?,
        height: to_usize(height.into())?,
        format: InputFormat::Tiff,
        sample: kind.sample(),
        planes: vec![Plane { name: "Y".into(), data }],
        georef: None,
    })
}

/// Refuses a TIFF whose strips or tiles, as stored, cannot decode to the
/// `decoded` bytes its header describes, before those bytes are allocated:
/// a forged width, height or band count in a file of a few hundred bytes
/// would otherwise have its whole image allocated (and zeroed) first.
/// Uncompressed chunks hold their bytes as they are; each compression
/// `tiff` decodes here expands by at most a known ratio (PackBits 128
/// bytes from 2, Deflate 1032:1, an LZW code of at least 9 bits at most
/// 4096 bytes, JPEG a generous 1024:1 for a block coded in a few bits).
/// Other compressions are not bounded here; the memory check still is.
fn check_stored_bytes<R: Read + Seek>(decoder: &mut tiff::decoder::Decoder<R>, decoded: u64) -> Result<()> {
    // The codes of TIFF 6.0 and its technical notes.
    let ratio: u64 = match decoder.find_tag_unsigned::<u16>(Tag::Compression).map_err(from_tiff_error)?.unwrap_or(1) {
        1 => 1,
        32773 => 64,
        8 | 32946 => 1032,
        5 => 4096 * 8 / 9 + 1,
        6 | 7 => 1024,
        _ => return Ok(()),
    };
    let counts = match decoder.get_chunk_type() {
        tiff::decoder::ChunkType::Strip => Tag::StripByteCounts,
        tiff::decoder::ChunkType::Tile => Tag::TileByteCounts,
    };
    let stored = decoder.find_tag_unsigned_vec::<u64>(counts).map_err(from_tiff_error)?.unwrap_or_default();
    // A count past the end of the file is forged: no chunk holds more
    // bytes than the file.
    let reader = decoder.inner();
    let here = reader.stream_position().map_err(Error::Io)?;
    let file = reader.seek(std::io::SeekFrom::End(0)).map_err(Error::Io)?;
    reader.seek(std::io::SeekFrom::Start(here)).map_err(Error::Io)?;
    let chunks = stored.len() as u64;
    let stored: u64 = stored.iter().fold(0, |sum, &n| sum.saturating_add(n.min(file)));
    // JPEG chunks share tables kept elsewhere: a few hundred bytes each.
    let most = stored.saturating_add(if ratio == 1024 { chunks.saturating_mul(1024) } else { 0 }).saturating_mul(ratio);
    if most < decoded {
        return Err(Error::Decode(format!(
            "tiff strips or tiles of {stored} bytes in all cannot hold the {decoded} bytes of samples its header \
             describes"
        )));
    }
    Ok(())
}

/// The sample layout of `layout` and the 0-based index of the band read:
/// [`ReadOptions::band`], else the first.
///
/// Errors: [`Error::Unsupported`] for a sample format not read here, or a
/// band the file does not have.
fn choose_band(layout: TiffLayout, opts: &ReadOptions) -> Result<(TiffGray, usize)> {
    let Some(kind) = TiffGray::of(layout.format, layout.bits) else {
        return Err(Error::Unsupported(format!(
            "{}-bit {} samples are not read (8-, 16-, 32- and 64-bit integers, 16-, 32- and 64-bit floats are)",
            layout.bits,
            format_name(layout.format)
        )));
    };
    let band = opts.band.unwrap_or(1);
    let bands = layout.bands;
    let index = usize::try_from(band).ok().and_then(|b| b.checked_sub(1)).filter(|&i| i < bands).ok_or_else(|| {
        Error::Unsupported(format!("band {band} asked for, but the file has {bands} band{}", plural(bands)))
    })?;
    Ok((kind, index))
}

/// The samples of band `index` (0-based) of a planar TIFF, row-major,
/// native-endian: its strips or tiles one by one, each copied to its place
/// without the padding of the edge tiles.
///
/// Chunk by chunk, not `read_image_bytes`: besides reading one band of
/// several, `tiff` 0.11 takes the padding of a tile of the second and later
/// planes from its index across all planes, so a bottom-edge tile there
/// counts as whole and the whole-image read overruns its buffer (an
/// assertion, a panic). Each chunk's buffer here is as large as `tiff`
/// says that chunk is, and only the rows and columns inside the image
/// are copied, so the same mistake reads the tile's stored padding rows
/// and drops them.
fn read_planar_band(
    decoder: &mut tiff::decoder::Decoder<Cursor<&[u8]>>,
    index: usize,
    bands: usize,
    (width, height): (u32, u32),
    size: usize,
) -> Result<Vec<u8>> {
    let (w, h) = (to_usize(width.into())?, to_usize(height.into())?);
    let total = match decoder.get_chunk_type() {
        tiff::decoder::ChunkType::Tile => decoder.tile_count(),
        tiff::decoder::ChunkType::Strip => decoder.strip_count(),
    }
    .map_err(from_tiff_error)?;
    let total = to_usize(total.into())?;
    // Checked by `tiff` when the image's layout was read (see the caller).
    let (cw, ch) = decoder.chunk_dimensions();
    let (cw, ch) = (to_usize(cw.into())?.max(1), to_usize(ch.into())?.max(1));
    let (across, down) = (w.div_ceil(cw), h.div_ceil(ch));
    let per_plane = across * down;
    if total != per_plane * bands {
        return Err(Error::Decode(format!(
            "tiff has {total} strips or tiles, {bands} bands of {per_plane} each were expected"
        )));
    }
    let mut out = try_vec::<u8>(w * h * size)?;
    out.resize(w * h * size, 0);
    let mut chunk = Vec::new();
    for k in 0..per_plane {
        let id = u32::try_from(index * per_plane + k).map_err(|_| Error::Limits("too many tiff chunks".into()))?;
        let layout = decoder.image_chunk_buffer_layout(id).map_err(from_tiff_error)?;
        chunk.clear();
        chunk
            .try_reserve_exact(layout.len)
            .map_err(|_| Error::Limits(format!("{} bytes for a tiff chunk", layout.len)))?;
        chunk.resize(layout.len, 0);
        decoder.read_chunk_bytes(id, &mut chunk).map_err(from_tiff_error)?;
        let (x0, y0) = ((k % across) * cw, (k / across) * ch);
        let (cols, rows) = (cw.min(w - x0), ch.min(h - y0));
        let stride = layout.row_stride.map_or(0, std::num::NonZeroUsize::get);
        if stride < cols * size || layout.len < stride * (rows - 1) + cols * size {
            return Err(Error::Decode(format!(
                "tiff chunk {id} of {} bytes cannot hold its {cols} × {rows} texels",
                layout.len
            )));
        }
        for r in 0..rows {
            let from = &chunk[r * stride..][..cols * size];
            out[((y0 + r) * w + x0) * size..][..cols * size].copy_from_slice(from);
        }
    }
    Ok(out)
}

/// "s" for counts other than one.
fn plural(n: usize) -> &'static str {
    if n == 1 { "" } else { "s" }
}

/// A TIFF sample format as messages name it.
fn format_name(format: SampleFormat) -> String {
    match format {
        SampleFormat::Uint => "unsigned integer".into(),
        SampleFormat::Int => "signed integer".into(),
        SampleFormat::IEEEFP => "float".into(),
        SampleFormat::Void => "untyped".into(),
        other => format!("sample format {}", other.to_u16()),
    }
}

/// A TIFF colour type as messages name it: "8-bit palette", "3 bands of
/// 16 bits", ….
fn color_words(color: tiff::ColorType) -> String {
    use tiff::ColorType as C;
    let (what, bits) = match color {
        C::Gray(b) => ("gray", b),
        C::RGB(b) => ("RGB", b),
        C::Palette(b) => ("palette", b),
        C::GrayA(b) => ("gray and alpha", b),
        C::RGBA(b) => ("RGBA", b),
        C::CMYK(b) => ("CMYK", b),
        C::CMYKA(b) => ("CMYK and alpha", b),
        C::YCbCr(b) => ("YCbCr", b),
        C::Lab(b) => ("CIE L*a*b*", b),
        C::Multiband { bit_depth, num_samples } => return format!("{num_samples} bands of {bit_depth} bits"),
        _ => return "a colour type not read".into(),
    };
    format!("{bits}-bit {what}")
}

/// The georeferencing tags of the first image, checked (a tag of the
/// wrong length or a GDAL_NODATA that is not a number is an error: read
/// wrong, it would silently misplace or misfit the terrain). GDAL_NODATA
/// is not looked at without `nodata_tag` ([`ReadOptions::nodata_tag`]).
fn read_georef<R: Read + Seek>(decoder: &mut tiff::decoder::Decoder<R>, nodata_tag: bool) -> Result<Georef> {
    let mut georef = Georef::default();
    let doubles = |decoder: &mut tiff::decoder::Decoder<R>, code: u16, name: &str| {
        tag(decoder, code, name)?.map(|v| v.into_f64_vec().map_err(|e| tag_error(name, e))).transpose()
    };
    let scale = doubles(decoder, georef_tags::MODEL_PIXEL_SCALE, "ModelPixelScale")?;
    let tiepoints = doubles(decoder, georef_tags::MODEL_TIEPOINT, "ModelTiepoint")?;
    let transformation = doubles(decoder, georef_tags::MODEL_TRANSFORMATION, "ModelTransformation")?;
    georef.stored.pixel_scale = scale.clone().unwrap_or_default();
    georef.stored.tiepoints = tiepoints.clone().unwrap_or_default();
    georef.stored.transformation = transformation.clone().unwrap_or_default();
    georef::apply_model_tags(&mut georef, scale, tiepoints, transformation)?;
    if let Some(keys) = tag(decoder, georef_tags::GEO_KEY_DIRECTORY, "GeoKeyDirectory")? {
        let keys = keys.into_u16_vec().map_err(|e| tag_error("GeoKeyDirectory", e))?;
        georef::apply_key_directory(&mut georef, &keys)?;
        georef.stored.key_directory = keys;
        // The parameters the keys point into, kept for a GeoTIFF written
        // from this one; only the keys above are read here.
        if let Some(params) = doubles(decoder, georef_tags::GEO_DOUBLE_PARAMS, "GeoDoubleParams")? {
            georef.stored.double_params = params;
        }
        if let Some(text) = tag(decoder, georef_tags::GEO_ASCII_PARAMS, "GeoAsciiParams")? {
            georef.stored.ascii_params = text.into_string().map_err(|e| tag_error("GeoAsciiParams", e))?;
        }
    }
    if let Some(text) = nodata_tag.then(|| tag(decoder, georef_tags::GDAL_NODATA, "GDAL_NODATA")).transpose()?.flatten()
    {
        let text = text.into_string().map_err(|e| tag_error("GDAL_NODATA", e))?;
        georef.nodata = Some(georef::parse_nodata(&text)?);
    }
    Ok(georef)
}

/// A tag's value, if present.
fn tag<R: Read + Seek>(
    decoder: &mut tiff::decoder::Decoder<R>,
    code: u16,
    name: &str,
) -> Result<Option<tiff::decoder::ifd::Value>> {
    let tag = Tag::from_u16_exhaustive(code);
    // The count first: the decoder allocates by it (georef::most_values).
    if let Some(entry) = decoder.image_ifd().find_entry(tag)
        && entry.count() > georef::most_values(code)
    {
        return Err(Error::Decode(format!(
            "{name} tag holds {} values, GeoTIFF gives it at most {}",
            entry.count(),
            georef::most_values(code)
        )));
    }
    decoder.find_tag(tag).map_err(|e| tag_error(name, e))
}

/// A tag that cannot be read, named.
fn tag_error(name: &str, e: tiff::TiffError) -> Error {
    let inner = from_tiff_error(e);
    let text = match &inner {
        Error::Decode(m) | Error::Unsupported(m) | Error::Limits(m) => m.clone(),
        other => other.to_string(),
    };
    Error::Decode(format!("{name} tag: {text}"))
}

/// Limits handed to `tiff`: a decoded buffer may hold `max_texels` texels
/// of this image's bands and type and no more. The stored bytes of one strip or tile
/// are streamed from memory, not buffered, so their limit only refuses
/// counts no honest file has: twice the decoded size (LZW, the worst
/// expander, stays under 1.5×) plus 1 MiB.
fn tiff_limits(opts: &ReadOptions, kind: TiffGray, bands: usize) -> tiff::decoder::Limits {
    let decoded = u64::try_from(kind.bytes() * bands)
        .ok()
        .and_then(|b| opts.max_texels.checked_mul(b))
        .and_then(|n| usize::try_from(n).ok())
        .unwrap_or(usize::MAX);
    let mut limits = tiff::decoder::Limits::default();
    limits.decoding_buffer_size = decoded;
    limits.intermediate_buffer_size = decoded.saturating_mul(2).saturating_add(1 << 20);
    limits
}

/// Native-endian samples (as `tiff` leaves them), one every `stride`
/// bytes from the start of `buf`, to samples the fit reads: 8- and 16-bit
/// unsigned integers as stored, floats as stored (half widened to `f32`),
/// other integers as heights in contract units in f64.
fn tiff_samples(buf: &[u8], kind: TiffGray, texels: usize, stride: usize) -> Result<Samples> {
    let size = kind.bytes();
    let needed = texels.checked_sub(1).map_or(0, |last| last.saturating_mul(stride).saturating_add(size));
    if buf.len() < needed {
        return Err(Error::Decode(format!("decoder gave {} bytes for {texels} texels of {size} bytes", buf.len())));
    }
    fn ne<const N: usize>(p: &[u8]) -> [u8; N] {
        std::array::from_fn(|i| p[i])
    }
    // 2^32 − 1 and 2^64 − 1 (the latter rounds to 2^64 in f64).
    const U32_TOP: f64 = u32::MAX as f64;
    const U64_TOP: f64 = u64::MAX as f64;
    // Every texel's sample starts a chunk of `stride` bytes (the last chunk
    // may be shorter, but holds the sample).
    let px = buf[..needed].par_chunks(stride);
    let f32s = |f: fn(&[u8]) -> f32| par_collect(texels, px.clone().map(f)).map(Samples::F32);
    let f64s = |f: fn(&[u8]) -> f64| par_collect(texels, px.clone().map(f)).map(Samples::F64);
    match kind {
        TiffGray::U8 => par_collect(texels, px.clone().map(|p| p[0])).map(Samples::U8),
        TiffGray::U16 => par_collect(texels, px.clone().map(|p| u16::from_ne_bytes(ne(p)))).map(Samples::U16),
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

/// One band of a TIFF read a row of chunks at a time: a strip, or the
/// tiles across the image. What [`decode`] reads with `decode_band` (the
/// layouts `image` does not read, or any with [`ReadOptions::band`]),
/// for the streaming conversion (`crate::pipeline::TiffRows`), which
/// then holds one row of chunks, not the image.
///
/// Chunky files (bands interleaved per texel) decode every band of a
/// chunk and keep the one asked for; planar files read only the band's
/// own chunks. Values are the ones `decode_band` gives, sample for
/// sample ([`TiffBand::values`]).
pub(crate) struct TiffBand<R: Read + Seek> {
    decoder: tiff::decoder::Decoder<R>,
    kind: TiffGray,
    width: usize,
    height: usize,
    /// Columns and rows of a chunk (a strip is the image's width).
    chunk: (usize, usize),
    /// Chunks across the image.
    across: usize,
    /// The id of the band's first chunk (its plane's, when planar).
    first_chunk: usize,
    /// Where the band's sample starts in a decoded texel, and the bytes of
    /// a decoded texel (all bands when chunky, one when planar).
    offset: usize,
    texel_bytes: usize,
    georef: Option<Georef>,
    /// A decoded chunk, reused.
    scratch: Vec<u8>,
}

impl<R: Read + Seek> TiffBand<R> {
    /// Opens the band of the TIFF `reader` holds that `decode_band` would
    /// read; `Ok(None)` for a file that is not a TIFF `tiff` parses, or
    /// one `image` reads (8- and 16-bit gray, RGB, … with no band asked
    /// for) or reports (palette, CMYK, …): the whole-image reader takes
    /// those, with its messages. Reads the header and tags only.
    ///
    /// Errors: those of `decode_band` for the same file (a sample format
    /// not read, a band past the last, a size past
    /// [`ReadOptions::max_texels`], bad geo tags), and [`Error::Decode`]
    /// for a chunk count that does not match the image.
    pub(crate) fn open(reader: R, opts: &ReadOptions) -> Result<Option<Self>> {
        let Ok(mut decoder) = tiff::decoder::Decoder::new(reader) else { return Ok(None) };
        let georef = read_georef(&mut decoder, opts.nodata_tag)?;
        let Some(layout) = TiffLayout::of(&mut decoder)? else { return Ok(None) };
        if opts.band.is_none() && layout.image_reads() {
            return Ok(None);
        }
        let (kind, index) = choose_band(layout, opts)?;
        let bands = layout.bands;
        let (width, height) = decoder.dimensions().map_err(from_tiff_error)?;
        check_size(u64::from(width), u64::from(height), opts)?;
        let (w, h) = (to_usize(width.into())?, to_usize(height.into())?);
        let planar = bands > 1
            && decoder.find_tag_unsigned::<u16>(Tag::PlanarConfiguration).map_err(from_tiff_error)? == Some(2);
        let described = (w as u64).saturating_mul(h as u64).saturating_mul((bands * kind.bytes()) as u64);
        check_stored_bytes(&mut decoder, described)?;
        let mut decoder = decoder.with_limits(tiff_limits(opts, kind, if planar { 1 } else { bands }));
        // `tiff` checks the chunk geometry here.
        decoder.image_buffer_layout().map_err(from_tiff_error)?;
        let total = match decoder.get_chunk_type() {
            tiff::decoder::ChunkType::Tile => decoder.tile_count(),
            tiff::decoder::ChunkType::Strip => decoder.strip_count(),
        }
        .map_err(from_tiff_error)?;
        let (cw, ch) = decoder.chunk_dimensions();
        let (cw, ch) = (to_usize(cw.into())?.max(1).min(w.max(1)), to_usize(ch.into())?.max(1).min(h.max(1)));
        let (across, down) = (w.div_ceil(cw), h.div_ceil(ch));
        let per_plane = across * down;
        let planes = if planar { bands } else { 1 };
        if to_usize(total.into())? != per_plane * planes {
            return Err(Error::Decode(format!(
                "tiff has {total} strips or tiles, {planes} plane{} of {per_plane} each were expected",
                plural(planes)
            )));
        }
        let size = kind.bytes();
        let (first_chunk, offset, texel_bytes) =
            if planar { (index * per_plane, 0, size) } else { (0, index * size, bands * size) };
        Ok(Some(TiffBand {
            decoder,
            kind,
            width: w,
            height: h,
            chunk: (cw, ch),
            across,
            first_chunk,
            offset,
            texel_bytes,
            georef: (!georef.is_empty()).then_some(georef),
            scratch: Vec::new(),
        }))
    }

    /// Columns and rows.
    pub(crate) fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Rows in a row of chunks (the last may have fewer).
    pub(crate) fn rows_per_chunk(&self) -> usize {
        self.chunk.1
    }

    /// What was stored, as [`Raster::sample`] gives it.
    pub(crate) fn sample(&self) -> SampleType {
        self.kind.sample()
    }

    /// The file's georeferencing, as [`Raster::georef`] gives it.
    pub(crate) fn georef(&self) -> Option<&Georef> {
        self.georef.as_ref()
    }

    /// The height of a value of 1 from [`TiffBand::values`]: 1/255 and
    /// 1/65535 for 8- and 16-bit unsigned integers (kept as stored), 1
    /// for the rest (floats as stored, other integers already divided).
    pub(crate) fn unit(&self) -> f64 {
        match self.kind {
            TiffGray::U8 => 1.0 / 255.0,
            TiffGray::U16 => 1.0 / 65535.0,
            _ => 1.0,
        }
    }

    /// Whether every value is an `f32` exactly (8- and 16-bit unsigned
    /// integers, half and single floats).
    pub(crate) fn exact_in_f32(&self) -> bool {
        matches!(self.kind, TiffGray::U8 | TiffGray::U16 | TiffGray::F16 | TiffGray::F32)
    }

    /// Bytes of one sample of the band.
    pub(crate) fn sample_bytes(&self) -> usize {
        self.kind.bytes()
    }

    /// Decodes the row of chunks `k` (image rows from k · rows-per-chunk)
    /// into `out`: the band's samples of those rows, row-major, packed,
    /// native-endian, without the padding of edge tiles. `out` is resized.
    ///
    /// Errors: [`Error::Decode`] for a corrupt or truncated chunk,
    /// [`Error::Limits`] when its memory is not there.
    pub(crate) fn read_chunk_row(&mut self, k: usize, out: &mut Vec<u8>) -> Result<()> {
        let (w, h, (cw, ch)) = (self.width, self.height, self.chunk);
        let size = self.kind.bytes();
        let y0 = k * ch;
        if y0 >= h {
            return Err(Error::Decode(format!("all {h} rows have been read")));
        }
        let rows = ch.min(h - y0);
        let len = rows * w * size;
        out.clear();
        out.try_reserve_exact(len).map_err(|_| Error::Limits(format!("{len} bytes for a row of tiff chunks")))?;
        out.resize(len, 0);
        for i in 0..self.across {
            let id = self.first_chunk + k * self.across + i;
            let id = u32::try_from(id).map_err(|_| Error::Limits("too many tiff chunks".into()))?;
            let layout = self.decoder.image_chunk_buffer_layout(id).map_err(from_tiff_error)?;
            let chunk = &mut self.scratch;
            chunk.clear();
            chunk
                .try_reserve_exact(layout.len)
                .map_err(|_| Error::Limits(format!("{} bytes for a tiff chunk", layout.len)))?;
            chunk.resize(layout.len, 0);
            self.decoder.read_chunk_bytes(id, chunk).map_err(from_tiff_error)?;
            let x0 = i * cw;
            let cols = cw.min(w - x0);
            let stride = layout.row_stride.map_or(0, std::num::NonZeroUsize::get);
            let row_bytes = (cols - 1) * self.texel_bytes + self.offset + size;
            if stride < cols * self.texel_bytes || layout.len < stride * (rows - 1) + row_bytes {
                return Err(Error::Decode(format!(
                    "tiff chunk {id} of {} bytes cannot hold its {cols} × {rows} texels",
                    layout.len
                )));
            }
            for r in 0..rows {
                let to = &mut out[((r * w) + x0) * size..][..cols * size];
                let from = &chunk[r * stride + self.offset..];
                if self.texel_bytes == size {
                    to.copy_from_slice(&from[..cols * size]);
                } else {
                    for (t, f) in to.chunks_exact_mut(size).zip(from.chunks(self.texel_bytes)) {
                        t.copy_from_slice(&f[..size]);
                    }
                }
            }
        }
        Ok(())
    }

    /// The values of packed samples (from [`TiffBand::read_chunk_row`])
    /// in `f64`, as `decode_band` gives them: 8- and 16-bit unsigned
    /// integers and floats as stored, other integers divided by
    /// 2^bits − 1 (heights in contract units).
    /// The row value ([`TiffBand::values`]) of a stored value `v` (a
    /// nodata value as the GDAL_NODATA tag gives it): divided as the
    /// samples are, so that equal stored values give equal row values.
    pub(crate) fn row_value(&self, v: f64) -> f64 {
        const U32_TOP: f64 = u32::MAX as f64;
        const U64_TOP: f64 = u64::MAX as f64;
        match self.kind {
            TiffGray::U32 | TiffGray::I32 => v / U32_TOP,
            TiffGray::U64 | TiffGray::I64 => v / U64_TOP,
            TiffGray::I8 => v / 255.0,
            TiffGray::I16 => v / 65535.0,
            _ => v,
        }
    }

    pub(crate) fn values(&self, bytes: &[u8], out: &mut [f64]) {
        let size = self.kind.bytes();
        for (o, p) in out.iter_mut().zip(bytes.chunks_exact(size)) {
            *o = sample_value(self.kind, p);
        }
    }

    /// [`TiffBand::values`] in `f32`, exact when
    /// [`TiffBand::exact_in_f32`].
    ///
    /// The common kinds read chunks of a size the compiler knows, so the
    /// loops are plain copies and widenings: through the sample size as a
    /// run-time value (and a byte-by-byte array), the float case was 29 %
    /// of a lit view's decoding thread.
    pub(crate) fn values_f32(&self, bytes: &[u8], out: &mut [f32]) {
        match self.kind {
            TiffGray::F32 => {
                out.iter_mut().zip(bytes.as_chunks::<4>().0).for_each(|(o, p)| *o = f32::from_ne_bytes(*p))
            }
            TiffGray::U16 => {
                out.iter_mut().zip(bytes.as_chunks::<2>().0).for_each(|(o, p)| *o = f32::from(u16::from_ne_bytes(*p)))
            }
            TiffGray::U8 => out.iter_mut().zip(bytes).for_each(|(o, &p)| *o = f32::from(p)),
            kind => {
                let samples = bytes.chunks_exact(kind.bytes());
                out.iter_mut().zip(samples).for_each(|(o, p)| *o = sample_value(kind, p) as f32);
            }
        }
    }
}

/// One native-endian sample as `decode_band` reads it, in `f64` (see
/// [`TiffBand::values`]).
fn sample_value(kind: TiffGray, p: &[u8]) -> f64 {
    fn ne<const N: usize>(p: &[u8]) -> [u8; N] {
        std::array::from_fn(|i| p[i])
    }
    const U32_TOP: f64 = u32::MAX as f64;
    const U64_TOP: f64 = u64::MAX as f64;
    match kind {
        TiffGray::U8 => f64::from(p[0]),
        TiffGray::U16 => f64::from(u16::from_ne_bytes(ne(p))),
        TiffGray::F16 => f64::from(exr::prelude::f16::from_bits(u16::from_ne_bytes(ne(p))).to_f32()),
        TiffGray::F32 => f64::from(f32::from_ne_bytes(ne(p))),
        TiffGray::F64 => f64::from_ne_bytes(ne(p)),
        TiffGray::U32 => f64::from(u32::from_ne_bytes(ne(p))) / U32_TOP,
        TiffGray::U64 => u64::from_ne_bytes(ne(p)) as f64 / U64_TOP,
        TiffGray::I8 => f64::from(i8::from_ne_bytes(ne(p))) / 255.0,
        TiffGray::I16 => f64::from(i16::from_ne_bytes(ne(p))) / 65535.0,
        TiffGray::I32 => f64::from(i32::from_ne_bytes(ne(p))) / U32_TOP,
        TiffGray::I64 => i64::from_ne_bytes(ne(p)) as f64 / U64_TOP,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Messages name layouts in words, never as Rust values.
    #[test]
    fn layouts_are_named_in_words() {
        assert_eq!(TiffGray::F32.name(), "32-bit float");
        assert_eq!(TiffGray::U16.name(), "16-bit unsigned integer");
        assert_eq!(TiffGray::I64.name(), "64-bit signed integer");
        assert_eq!(format_name(SampleFormat::from_u16_exhaustive(7)), "sample format 7");
        assert_eq!(color_words(tiff::ColorType::Palette(8)), "8-bit palette");
        assert_eq!(color_words(tiff::ColorType::Multiband { bit_depth: 16, num_samples: 5 }), "5 bands of 16 bits");
    }
}
