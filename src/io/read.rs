//! Reading height maps: bytes in, planes of `f32` in contract units out.
//!
//! Rules this module keeps, and why:
//! * The decoder is chosen from the content, never the file name: a `.png`
//!   that is really a JPEG still reads, and a renamed file cannot pick a
//!   decoder that then misreads it. OpenEXR goes to the `exr` crate, gray
//!   TIFF with samples `image` refuses (float, half, 32/64-bit and signed
//!   integers) to the `tiff` crate, everything else to `image`.
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
//! * Values are stored already in contract units (SPEC §1): integer samples
//!   divided by 2^bits − 1, float samples as stored. NaN and infinities are
//!   kept in the planes; only [`Raster::heights`] rejects them, because only
//!   the channel that becomes the height matters.

use std::fmt;
use std::io::{BufRead, Cursor, Read};
use std::path::Path;

use image::{ColorType, ImageDecoder, ImageError, ImageFormat, ImageReader, Limits};
use rayon::prelude::*;
use tiff::tags::{SampleFormat, Tag};

use super::memory;
use super::png_zlib::{self, IdatWatch, finish_checked, png_error};
use crate::error::{Error, Result, one_line};

/// Which channel of the image gives the height (SPEC §1, `--channel`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Channel {
    /// 0.2126 R + 0.7152 G + 0.0722 B of the stored values; the gray
    /// channel of a gray image.
    Luma,
    /// Red (the gray channel of a gray image).
    R,
    /// Green (the gray channel of a gray image).
    G,
    /// Blue (the gray channel of a gray image).
    B,
    /// Alpha; an error when the image has none.
    A,
}

/// The file format the bytes were decoded as, found from their content.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
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
    /// Another format `image` reads (gif, hdr, pnm, qoi), by its lower-case
    /// name.
    Other(String),
}

impl fmt::Display for InputFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            InputFormat::Png => "png",
            InputFormat::Exr => "exr",
            InputFormat::Jpeg => "jpeg",
            InputFormat::Tiff => "tiff",
            InputFormat::Tga => "tga",
            InputFormat::Bmp => "bmp",
            InputFormat::WebP => "webp",
            InputFormat::Other(name) => name,
        })
    }
}

/// How the samples were stored in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SampleType {
    /// Unsigned integers of `bits` bits per channel, as decoded (a 1-, 2- or
    /// 4-bit gray PNG arrives expanded to 8 bits, scaled so that the top
    /// value stays 1.0); read as value / (2^bits − 1) ∈ [0, 1].
    Int {
        /// Bits per channel.
        bits: u8,
    },
    /// Signed (two's complement) integers of `bits` bits per channel, from
    /// a gray TIFF. Read as value / (2^bits − 1), the unsigned rule with the
    /// same step per stored unit, so h ∈ [−0.5, 0.5]: a signed map and the
    /// same map stored unsigned with an offset give the same normals.
    SignedInt {
        /// Bits per channel.
        bits: u8,
    },
    /// Floating point (half, float, double, or EXR's u32, all taken as
    /// numbers).
    Float,
}

impl SampleType {
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

/// One channel of an image: row-major, `width * height` values in contract
/// units.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    /// The channel's name: "Y" (gray), "R", "G", "B", "A" for the formats
    /// `image` and `tiff` read; the file's own channel names for EXR
    /// ("height", "diffuse.R", …).
    pub name: String,
    /// The values, row 0 first.
    pub data: Vec<f32>,
}

/// A decoded image, one plane per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Raster {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The format the content was decoded as.
    pub format: InputFormat,
    /// How the samples were stored.
    pub sample: SampleType,
    /// The channels, in the file's order.
    pub planes: Vec<Plane>,
}

/// Limits for a read of untrusted bytes, and which part of a file to read.
#[derive(Clone, Debug, PartialEq, Eq)]
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
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions { max_texels: 1 << 30, layer: None }
    }
}

impl ReadOptions {
    /// The same options with another texel limit.
    #[must_use]
    pub fn with_max_texels(mut self, max_texels: u64) -> Self {
        self.max_texels = max_texels;
        self
    }

    /// The same options reading the OpenEXR layer `name`.
    #[must_use]
    pub fn with_layer(mut self, name: impl Into<String>) -> Self {
        self.layer = Some(name.into());
        self
    }
}

/// The four bytes every OpenEXR file starts with.
pub(crate) const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// The four bytes a TIFF starts with: classic and BigTIFF, little- and
/// big-endian.
const TIFF_MAGIC: [[u8; 4]; 4] = [*b"II*\0", *b"MM\0*", *b"II+\0", *b"MM\0+"];

/// Rec. 709 luma weights of R, G and B (SPEC §1).
pub(crate) const LUMA: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// The luma of one texel, computed in f64 and rounded to f32 once, so it
/// does not depend on summation order (and every reader gets the same bits).
#[inline]
pub(crate) fn luma(r: f32, g: f32, b: f32) -> f32 {
    (LUMA[0] * f64::from(r) + LUMA[1] * f64::from(g) + LUMA[2] * f64::from(b)) as f32
}

/// Decodes an image from its bytes, choosing the decoder from the content.
///
/// Errors: [`Error::Decode`] for empty, unknown, corrupt, truncated or
/// zero-size data; [`Error::Limits`] when the header claims more than
/// `opts.max_texels` texels; [`Error::Unsupported`] for a layout normalfit
/// does not read, or a layer asked for in a format that has none.
pub fn decode(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    if bytes.is_empty() {
        return Err(Error::Decode("file is empty".into()));
    }
    if bytes.starts_with(&EXR_MAGIC) {
        return decode_exr(bytes, opts);
    }
    if let Some(layer) = &opts.layer {
        let format = if is_tiff(bytes) { InputFormat::Tiff } else { input_format(guess_format(bytes)?) };
        return Err(no_layers(&format, layer));
    }
    if bytes.starts_with(&PNG_SIGNATURE) {
        check_png_header(bytes, opts)?;
        return decode_png(bytes, opts);
    }
    if is_tiff(bytes) {
        if let Some(raster) = decode_tiff_gray(bytes, opts)? {
            return Ok(raster);
        }
    }
    decode_with_image(bytes, opts)
}

/// Reads the file at `path` and [`decode`]s it. Failing to read the file is
/// [`Error::Io`].
pub fn read_path(path: &Path, opts: &ReadOptions) -> Result<Raster> {
    let bytes = std::fs::read(path)?;
    decode(&bytes, opts)
}

impl Raster {
    /// The heights in contract units, row-major, chosen by `channel` as
    /// SPEC §1 says (`None` is the default rule).
    ///
    /// * A gray image (a "Y" plane, or an EXR's only channel) gives its gray
    ///   channel for `None`, `Luma`, `R`, `G` and `B`.
    /// * A colour image gives luma of R, G, B for `None` and `Luma`, else
    ///   the channel asked for.
    /// * An EXR prefers "Y", then its only channel, then luma of R, G, B.
    ///   Channel names match case-insensitively, also by their last
    ///   dot-separated part ("diffuse.R" is R).
    /// * `A` gives alpha, an error when there is none.
    ///
    /// Errors: [`Error::Unsupported`] when the channel is missing,
    /// [`Error::NonFiniteHeight`] naming the first NaN or infinite height in
    /// row order.
    pub fn heights(&self, channel: Option<Channel>) -> Result<Vec<f32>> {
        let heights = match self.select(channel)? {
            Source::Plane(i) => copy_plane(&self.planes[i].data)?,
            Source::Luma(rgb) => self.luma(rgb)?,
        };
        self.check_finite(&heights)?;
        Ok(heights)
    }

    /// Like [`Raster::heights`], but moves the chosen plane out instead of
    /// copying it when the heights are one stored channel.
    pub fn into_heights(mut self, channel: Option<Channel>) -> Result<Vec<f32>> {
        let heights = match self.select(channel)? {
            Source::Plane(i) => self.planes.swap_remove(i).data,
            Source::Luma(rgb) => self.luma(rgb)?,
        };
        self.check_finite(&heights)?;
        Ok(heights)
    }

    /// The plane with exactly this name, if any.
    #[must_use]
    pub fn plane(&self, name: &str) -> Option<&Plane> {
        self.planes.iter().find(|p| p.name == name)
    }

    /// Applies SPEC §1's channel rule to this raster's plane names.
    fn select(&self, channel: Option<Channel>) -> Result<Source> {
        let names: Vec<&str> = self.planes.iter().map(|p| p.name.as_str()).collect();
        select_channel(&names, channel)
    }

    /// Luma of three planes, each texel computed in f64 and rounded to f32
    /// once, so the result does not depend on f32 summation order.
    fn luma(&self, [r, g, b]: [usize; 3]) -> Result<Vec<f32>> {
        let (r, g, b) = (&self.planes[r].data, &self.planes[g].data, &self.planes[b].data);
        let mut out = try_vec(r.len())?;
        out.par_extend(r.par_iter().zip(g.par_iter()).zip(b.par_iter()).map(|((&r, &g), &b)| luma(r, g, b)));
        Ok(out)
    }

    /// SPEC §1: a NaN or infinite height is an error naming the first such
    /// texel in row order.
    fn check_finite(&self, heights: &[f32]) -> Result<()> {
        match heights.par_iter().position_first(|h| !h.is_finite()) {
            None => Ok(()),
            Some(i) => Err(Error::NonFiniteHeight { x: i % self.width.max(1), y: i / self.width.max(1) }),
        }
    }
}

/// Where the heights come from.
pub(crate) enum Source {
    /// One stored plane, by index.
    Plane(usize),
    /// Luma of the R, G, B planes at these indices.
    Luma([usize; 3]),
}

/// SPEC §1's channel rule (see [`Raster::heights`]) over a list of channel
/// names: which channel, or which three for luma, hold the height.
pub(crate) fn select_channel(names: &[&str], channel: Option<Channel>) -> Result<Source> {
    let names = Names(names);
    let wanted = match channel {
        None | Some(Channel::Luma) => None,
        Some(Channel::R) => Some("r"),
        Some(Channel::G) => Some("g"),
        Some(Channel::B) => Some("b"),
        Some(Channel::A) => {
            return names
                .find("a")?
                .map(Source::Plane)
                .ok_or_else(|| Error::Unsupported("image has no alpha channel".into()));
        }
    };
    // An explicit R, G or B names a stored channel when there is one,
    // overriding an EXR's "Y"; a gray image has none and gives gray.
    if let Some(name) = wanted {
        if let Some(i) = names.find(name)? {
            return Ok(Source::Plane(i));
        }
    }
    match (names.gray_plane()?, wanted) {
        (Some(i), _) => Ok(Source::Plane(i)),
        (None, Some(name)) => {
            Err(Error::Unsupported(format!("image has no {name} channel (channels: {})", names.channel_list())))
        }
        (None, None) => names.rgb().map(Source::Luma),
    }
}

/// Channel names, for the channel rule.
struct Names<'a>(&'a [&'a str]);

impl Names<'_> {
    /// The gray channel: "Y" if present, else the only channel there is.
    fn gray_plane(&self) -> Result<Option<usize>> {
        if let Some(i) = self.find("y")? {
            return Ok(Some(i));
        }
        Ok((self.0.len() == 1).then_some(0))
    }

    /// The R, G and B planes that luma is made of.
    fn rgb(&self) -> Result<[usize; 3]> {
        match (self.find("r")?, self.find("g")?, self.find("b")?) {
            (Some(r), Some(g), Some(b)) => Ok([r, g, b]),
            _ => Err(Error::Unsupported(format!(
                "no usable height channel: need y, a single channel, or r, g and b (channels: {})",
                self.channel_list()
            ))),
        }
    }

    /// Finds the plane for a channel letter (lower case): the name itself
    /// in any case, or a layer's channel whose last dot-separated part is
    /// the letter. An exact match wins; several layer matches are ambiguous,
    /// an error rather than a silent guess.
    fn find(&self, letter: &str) -> Result<Option<usize>> {
        let matches: Vec<usize> = (0..self.0.len())
            .filter(|&i| {
                let name = self.0[i];
                let last = name.rsplit('.').next().unwrap_or(name);
                last.eq_ignore_ascii_case(letter)
            })
            .collect();
        let exact = matches.iter().copied().find(|&i| self.0[i].eq_ignore_ascii_case(letter));
        match (exact, matches.as_slice()) {
            (Some(i), _) => Ok(Some(i)),
            (None, []) => Ok(None),
            (None, [i]) => Ok(Some(*i)),
            (None, _) => Err(Error::Unsupported(format!(
                "channel {letter} is ambiguous: {}",
                matches.iter().map(|&i| self.0[i]).collect::<Vec<_>>().join(", ")
            ))),
        }
    }

    /// The channel names, for messages.
    fn channel_list(&self) -> String {
        if self.0.is_empty() {
            return "none".into();
        }
        self.0.join(", ")
    }
}

/// A vector with room for `len` values, or [`Error::Limits`] if the memory
/// is not there (instead of the abort a plain allocation would give).
fn try_vec<T>(len: usize) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len)
        .map_err(|_| Error::Limits(format!("cannot allocate {len} values of {} bytes", size_of::<T>())))?;
    Ok(v)
}

/// A copy of a plane, allocated fallibly.
fn copy_plane(data: &[f32]) -> Result<Vec<f32>> {
    let mut out = try_vec(data.len())?;
    out.extend_from_slice(data);
    Ok(out)
}

/// The error for a layer asked for in a format without layers.
pub(crate) fn no_layers(format: &InputFormat, layer: &str) -> Error {
    Error::Unsupported(format!("layer {layer} asked for, but {format} files have no layers (only OpenEXR has)"))
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

// ---------------------------------------------------------------------------
// Formats `image` reads.

/// Decodes with the `image` crate: header first, size check, then pixels.
fn decode_with_image(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let format = guess_format(bytes)?;
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
        format: input_format(format),
        sample,
        planes,
    })
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
            return Err(Error::Unsupported(format!("png of {color:?} at {} bits is not supported", depth as u8)));
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
    })
}

/// Refuses a PNG palette that is not a whole number of RGB entries, which
/// the PNG spec makes an error. `png` 0.18.1 does not check it, and panics
/// (a slice index out of range) expanding such a palette into the first
/// row, whole-image and streamed alike. Found by fuzzing
/// (tests/fuzz_regressions.rs); the `png` crate's header has the palette
/// before any row is decoded.
pub(crate) fn check_png_palette(info: &png::Info) -> Result<()> {
    match info.palette.as_deref() {
        Some(p) if p.len() % 3 != 0 => {
            Err(Error::Decode(format!("png palette of {} bytes is not a whole number of 3-byte RGB entries", p.len())))
        }
        _ => Ok(()),
    }
}

/// The format from the magic bytes. TGA has none, so bytes no signature
/// matches are tried as TGA, and accepted only if its header parses (its
/// header has enough fixed fields, image type and pixel depth, that text
/// and most other data fail it).
fn guess_format(bytes: &[u8]) -> Result<ImageFormat> {
    if is_tiff(bytes) {
        // `image` knows only classic TIFF's signature; its decoder reads
        // BigTIFF too.
        return Ok(ImageFormat::Tiff);
    }
    let reader = ImageReader::new(Cursor::new(bytes)).with_guessed_format()?;
    if let Some(format) = reader.format() {
        return Ok(format);
    }
    let tga = ImageReader::with_format(Cursor::new(bytes), ImageFormat::Tga);
    if tga.into_decoder().is_ok() {
        return Ok(ImageFormat::Tga);
    }
    let start: String = bytes.iter().take(8).map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" ");
    Err(Error::Decode(format!("not a recognised image format (starts with bytes {start})")))
}

/// Limits handed to `image`, so its own allocations (PNG chunks, decoder
/// state) are bounded too: per side no more than `max_texels`, and memory
/// for the largest pixel (RGBA f32, 16 bytes) of every texel plus slack.
fn image_limits(opts: &ReadOptions) -> Limits {
    let side = u32::try_from(opts.max_texels).unwrap_or(u32::MAX);
    let mut limits = Limits::default();
    limits.max_image_width = Some(side);
    limits.max_image_height = Some(side);
    limits.max_alloc = Some(opts.max_texels.saturating_mul(16).saturating_add(64 << 20));
    limits
}

/// Plane names and sample type of a decoded colour type.
fn layout(color: ColorType) -> Result<(&'static [&'static str], SampleType)> {
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
            return Err(Error::Unsupported(format!("pixel layout {other:?} is not supported")));
        }
    })
}

/// Splits interleaved native-endian samples into planes in contract units.
fn deinterleave(buf: &[u8], names: &[&str], sample: SampleType, texels: usize) -> Result<Vec<Plane>> {
    let bytes = match sample {
        SampleType::Int { bits: 8 } => 1,
        SampleType::Int { bits: 16 } => 2,
        SampleType::Float => 4,
        other => return Err(Error::Unsupported(format!("{other:?} samples are not read from interleaved pixels"))),
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
            let mut data = try_vec(texels)?;
            let px = buf.par_chunks_exact(stride);
            match bytes {
                1 => data.par_extend(px.map(|p| f32::from(p[o]) / 255.0)),
                2 => data.par_extend(px.map(|p| f32::from(u16::from_ne_bytes([p[o], p[o + 1]])) / 65535.0)),
                _ => data.par_extend(px.map(|p| f32::from_ne_bytes([p[o], p[o + 1], p[o + 2], p[o + 3]]))),
            }
            Ok(Plane { name: (*name).to_string(), data })
        })
        .collect()
}

/// Our name for one of `image`'s formats.
fn input_format(format: ImageFormat) -> InputFormat {
    match format {
        ImageFormat::Png => InputFormat::Png,
        ImageFormat::Jpeg => InputFormat::Jpeg,
        ImageFormat::Tiff => InputFormat::Tiff,
        ImageFormat::Tga => InputFormat::Tga,
        ImageFormat::Bmp => InputFormat::Bmp,
        ImageFormat::WebP => InputFormat::WebP,
        ImageFormat::OpenExr => InputFormat::Exr,
        other => InputFormat::Other(format!("{other:?}").to_lowercase()),
    }
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

/// A size from a header as `usize`, or [`Error::Limits`] on a platform
/// where it does not fit.
fn to_usize(n: u64) -> Result<usize> {
    usize::try_from(n).map_err(|_| Error::Limits(format!("{n} does not fit in memory")))
}

// ---------------------------------------------------------------------------
// Gray TIFF that `image` refuses, read with the `tiff` crate: 32- and 64-bit
// float (what terrain generators and GIS tools export), half float, 32- and
// 64-bit unsigned and 8- to 64-bit signed integers. Every other TIFF (8- and
// 16-bit gray, RGB, float RGB, …) stays with `image`, which reads it.

/// Whether the bytes start with a TIFF signature.
fn is_tiff(bytes: &[u8]) -> bool {
    TIFF_MAGIC.iter().any(|magic| bytes.starts_with(magic))
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

/// Native-endian samples (as `tiff` leaves them) to heights in contract
/// units.
fn tiff_samples(buf: &[u8], kind: TiffGray, texels: usize) -> Result<Vec<f32>> {
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
    let mut data = try_vec(texels)?;
    let px = buf.par_chunks_exact(size);
    match kind {
        TiffGray::F16 => data.par_extend(px.map(|p| exr::prelude::f16::from_bits(u16::from_ne_bytes(ne(p))).to_f32())),
        TiffGray::F32 => data.par_extend(px.map(|p| f32::from_ne_bytes(ne(p)))),
        TiffGray::F64 => data.par_extend(px.map(|p| f64::from_ne_bytes(ne(p)) as f32)),
        TiffGray::U32 => data.par_extend(px.map(|p| (f64::from(u32::from_ne_bytes(ne(p))) / U32_TOP) as f32)),
        TiffGray::U64 => data.par_extend(px.map(|p| (u64::from_ne_bytes(ne(p)) as f64 / U64_TOP) as f32)),
        TiffGray::I8 => data.par_extend(px.map(|p| f32::from(i8::from_ne_bytes(ne(p))) / 255.0)),
        TiffGray::I16 => data.par_extend(px.map(|p| f32::from(i16::from_ne_bytes(ne(p))) / 65535.0)),
        TiffGray::I32 => data.par_extend(px.map(|p| (f64::from(i32::from_ne_bytes(ne(p))) / U32_TOP) as f32)),
        TiffGray::I64 => data.par_extend(px.map(|p| (i64::from_ne_bytes(ne(p)) as f64 / U64_TOP) as f32)),
    }
    Ok(data)
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

// ---------------------------------------------------------------------------
// OpenEXR, read with the `exr` crate: `image`'s EXR path only gives RGB(A)
// and rejects single-channel files, the common height map layout.

/// Decodes an EXR: meta data first (windows and sizes checked), then the
/// layer asked for ([`choose_exr_layer`]) at its largest resolution level,
/// all its channels.
fn decode_exr(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    check_exr_windows(Cursor::new(bytes))?;
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false).map_err(from_exr_error)?;
    check_exr_meta(&meta, bytes.len() as u64, opts)?;
    let choice = choose_exr_layer(&meta.headers, opts.layer.as_deref())?;
    // `exr` allocates the image itself, and aborts if that fails.
    memory::check_memory("decoding", memory::exr_decode_bytes(&meta.headers[choice.part]))?;
    use exr::prelude::ReadLayers;
    let channels = exr::prelude::read().no_deep_data().largest_resolution_level().all_channels();
    let image = OnePart { part: choice.part, channels }
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(from_exr_error)?;
    let (size, channels) = image.layer_data;
    let (width, height) = (size.0, size.1);
    check_size(width as u64, height as u64, opts)?;
    let texels = to_usize((width as u64).saturating_mul(height as u64))?;
    let planes = channels
        .list
        .into_iter()
        .filter(|channel| choice.holds(&channel.name.to_string()))
        .map(|channel| exr_plane(channel, texels))
        .collect::<Result<Vec<_>>>()?;
    Ok(Raster { width, height, format: InputFormat::Exr, sample: SampleType::Float, planes })
}

/// Which part of an OpenEXR file, and which of its channels, make the
/// image read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct ExrLayer {
    /// The part (header) index.
    pub part: usize,
    /// Only the channels named `prefix.…`, or all the part's channels.
    pub prefix: Option<String>,
}

impl ExrLayer {
    /// Whether the channel of this name belongs to the layer.
    pub fn holds(&self, channel: &str) -> bool {
        match &self.prefix {
            None => true,
            Some(p) => channel.strip_prefix(p.as_str()).is_some_and(|rest| rest.starts_with('.')),
        }
    }
}

/// Finds the layer `name` among an OpenEXR file's headers (see
/// [`ReadOptions::layer`]): a part of that name, else the first part with
/// channels named `name.…`; `None` is the first part of flat samples.
///
/// Errors: [`Error::Unsupported`] naming the layers there are when none
/// matches, or when every part holds deep data.
pub(crate) fn choose_exr_layer(headers: &[exr::meta::header::Header], name: Option<&str>) -> Result<ExrLayer> {
    let Some(name) = name else {
        return headers
            .iter()
            .position(|h| !h.deep)
            .map(|part| ExrLayer { part, prefix: None })
            .ok_or_else(|| Error::Unsupported("exr file holds only deep data".into()));
    };
    let part_name = |h: &exr::meta::header::Header| h.own_attributes.layer_name.as_ref().map(|n| n.to_string());
    if let Some(part) = headers.iter().position(|h| part_name(h).as_deref() == Some(name)) {
        return Ok(ExrLayer { part, prefix: None });
    }
    let group = ExrLayer { part: 0, prefix: Some(name.to_string()) };
    if let Some(part) =
        headers.iter().position(|h| !h.deep && h.channels.list.iter().any(|c| group.holds(&c.name.to_string())))
    {
        return Ok(ExrLayer { part, ..group });
    }
    // The names there are: parts, and the channel groups of each part.
    let mut layers: Vec<String> = Vec::new();
    for header in headers {
        layers.extend(part_name(header));
        for channel in &header.channels.list {
            let channel = channel.name.to_string();
            if let Some((group, _)) = channel.rsplit_once('.') {
                if !layers.iter().any(|l| l == group) {
                    layers.push(group.to_string());
                }
            }
        }
    }
    let there = if layers.is_empty() {
        "it has none: no part names, no channels named LAYER.X".into()
    } else {
        format!("layers: {}", layers.join(", "))
    };
    Err(Error::Unsupported(format!("exr file has no layer {name} ({there})")))
}

/// The `exr` reader of one part of a file, by index (the crate itself
/// reads the first valid part or all of them).
struct OnePart<C> {
    part: usize,
    channels: C,
}

/// Gathers the blocks of one part.
struct OnePartReader<R> {
    part: usize,
    size: exr::math::Vec2<usize>,
    channels: R,
}

impl<'s, C: exr::image::read::layers::ReadChannels<'s>> exr::image::read::image::ReadLayers<'s> for OnePart<C> {
    type Layers = (exr::math::Vec2<usize>, <C::Reader as exr::image::read::layers::ChannelsReader>::Channels);
    type Reader = OnePartReader<C::Reader>;

    fn create_layers_reader(&'s self, headers: &[exr::meta::header::Header]) -> exr::error::Result<Self::Reader> {
        let header = headers.get(self.part).ok_or_else(|| exr::error::Error::Invalid("layer index".into()))?;
        let channels = self.channels.create_channels_reader(header)?;
        Ok(OnePartReader { part: self.part, size: header.layer_size, channels })
    }
}

impl<R: exr::image::read::layers::ChannelsReader> exr::image::read::image::LayersReader for OnePartReader<R> {
    type Layers = (exr::math::Vec2<usize>, R::Channels);

    fn filter_block(
        &self,
        _: &exr::meta::MetaData,
        tile: exr::block::chunk::TileCoordinates,
        block: exr::block::BlockIndex,
    ) -> bool {
        block.layer == self.part && self.channels.filter_block(tile)
    }

    fn read_block(
        &mut self,
        headers: &[exr::meta::header::Header],
        block: exr::block::UncompressedBlock,
    ) -> exr::error::UnitResult {
        let header = headers.get(self.part).ok_or_else(|| exr::error::Error::Invalid("layer index".into()))?;
        // Only the full-resolution level is read (its blocks alone pass the
        // filter, by the offset table); a block whose own data names
        // another level is corrupt, and `exr` would only notice it in a
        // debug assertion (a panic in debug builds, found by fuzzing).
        if block.index.level != exr::math::Vec2(0, 0) {
            return Err(exr::error::Error::Invalid("block of a resolution level that was not asked for".into()));
        }
        self.channels.read_block(header, block)
    }

    fn into_layers(self) -> Self::Layers {
        (self.size, self.channels.into_channels())
    }
}

/// Checks the data and display windows of every header as stored: each
/// max at least its min. The `exr` crate swaps an inverted window's
/// corners, which would read a broken or forged header as some other
/// image; OpenEXR rejects it, and so does normalfit. Anything else wrong
/// with the header (bytes missing, a name too long) is left to `exr`,
/// which reports it.
pub(crate) fn check_exr_windows(mut read: impl BufRead) -> Result<()> {
    /// Attribute and type names are at most 255 bytes (with long names).
    const NAME_MAX: usize = 256;
    fn name(read: &mut impl BufRead) -> Option<Vec<u8>> {
        let mut out = Vec::new();
        for byte in read.bytes() {
            match byte.ok()? {
                0 => return Some(out),
                b if out.len() < NAME_MAX => out.push(b),
                _ => return None,
            }
        }
        None
    }
    fn i32_le(read: &mut impl Read) -> Option<i32> {
        let mut b = [0u8; 4];
        read.read_exact(&mut b).ok()?;
        Some(i32::from_le_bytes(b))
    }
    let mut start = [0u8; 8];
    if read.read_exact(&mut start).is_err() {
        return Ok(());
    }
    // Version field flags: bit 12 (byte 5, 0x10) is "multi-part".
    let multipart = start[5] & 0x10 != 0;
    loop {
        let mut attributes = 0;
        loop {
            let Some(attribute) = name(&mut read) else { return Ok(()) };
            if attribute.is_empty() {
                break;
            }
            attributes += 1;
            let (Some(kind), Some(size)) = (name(&mut read), i32_le(&mut read)) else { return Ok(()) };
            let window = attribute == b"dataWindow" || attribute == b"displayWindow";
            if window && kind == b"box2i" && size == 16 {
                let corners: Option<Vec<i32>> = (0..4).map(|_| i32_le(&mut read)).collect();
                let Some(&[x_min, y_min, x_max, y_max]) = corners.as_deref() else { return Ok(()) };
                if x_max < x_min || y_max < y_min {
                    let which = if attribute == b"dataWindow" { "data" } else { "display" };
                    return Err(Error::Decode(format!(
                        "exr {which} window is inverted: min ({x_min}, {y_min}), max ({x_max}, {y_max})"
                    )));
                }
            } else {
                let Ok(size) = u64::try_from(size) else { return Ok(()) };
                let skipped = std::io::copy(&mut (&mut read).take(size), &mut std::io::sink()).unwrap_or(0);
                if skipped != size {
                    return Ok(());
                }
            }
        }
        // A multi-part file ends its list of headers with an empty one.
        if !multipart || attributes == 0 {
            return Ok(());
        }
    }
}

/// Checks every layer's data window against the limit, from the header of
/// a file of `file_len` bytes. Every layer, not just the first: `exr`
/// reads all offset tables, whose length follows from each layer's size.
/// The offset tables are stored in the file, so an honest file holds 8
/// bytes per chunk; a header claiming more chunks than that is forged.
pub(crate) fn check_exr_meta(meta: &exr::meta::MetaData, file_len: u64, opts: &ReadOptions) -> Result<()> {
    if meta.headers.is_empty() {
        return Err(Error::Decode("exr file has no layers".into()));
    }
    let mut chunks: u64 = 0;
    for header in &meta.headers {
        let size = header.layer_size;
        check_size(size.0 as u64, size.1 as u64, opts)?;
        chunks = chunks.saturating_add(header.chunk_count as u64);
    }
    if chunks.saturating_mul(8) > file_len {
        return Err(Error::Decode(format!(
            "truncated or corrupt: header claims {chunks} chunks, more than the file holds"
        )));
    }
    Ok(())
}

/// One EXR channel as a plane: half and float as stored, u32 as its number.
fn exr_plane(channel: exr::prelude::AnyChannel<exr::prelude::FlatSamples>, texels: usize) -> Result<Plane> {
    use exr::prelude::FlatSamples;
    let name = channel.name.to_string();
    let data = match channel.sample_data {
        FlatSamples::F32(v) => v,
        FlatSamples::F16(v) => {
            let mut out = try_vec(v.len())?;
            out.par_extend(v.par_iter().map(|h| h.to_f32()));
            out
        }
        FlatSamples::U32(v) => {
            let mut out = try_vec(v.len())?;
            // u32 → f32 rounds above 2^24; SPEC treats EXR as a float image.
            out.par_extend(v.par_iter().map(|&n| n as f32));
            out
        }
    };
    if data.len() != texels {
        return Err(Error::Unsupported(format!(
            "channel {name} is subsampled ({} samples for {texels} texels)",
            data.len()
        )));
    }
    Ok(Plane { name, data })
}

/// Maps `exr`'s errors onto ours; reading from memory cannot fail at the
/// operating system, so its I/O errors mean the data ended early.
pub(crate) fn from_exr_error(e: exr::error::Error) -> Error {
    use exr::error::Error as E;
    match e {
        E::NotSupported(m) => Error::Unsupported(format!("exr: {}", message(&m))),
        // `exr` reports every read past the end of the data so.
        E::Invalid(m) if m == "reference to missing bytes" => {
            Error::Decode("truncated or corrupt: the file ends before the data its header refers to".into())
        }
        E::Invalid(m) => Error::Decode(format!("invalid exr: {}", message(&m))),
        E::Io(e) => Error::Decode(format!("truncated or corrupt: {}", message(&e.to_string()))),
        E::Aborted => Error::Decode("reading was aborted".into()),
    }
}
