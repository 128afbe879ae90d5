//! Reading height maps: bytes in, planes of `f32` in contract units out.
//!
//! Rules this module keeps, and why:
//! * The decoder is chosen from the content, never the file name: a `.png`
//!   that is really a JPEG still reads, and a renamed file cannot pick a
//!   decoder that then misreads it. OpenEXR goes to the `exr` crate (a
//!   file with subsampled channels, which it refuses, to
//!   `io/exr_subsampled.rs`), gray TIFF with samples `image` refuses
//!   (float, half, 32/64-bit and signed integers) to the `tiff` crate,
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
//! * Values are kept as they were stored ([`Samples`]): 8- and 16-bit
//!   integers as integers, whose height is value / (2^bits − 1) (SPEC §1),
//!   floats as floats. Dividing first and rounding to `f32` would move
//!   normals at high gains (see [`crate::samples`]). NaN and infinities are
//!   kept in the planes; only [`Raster::heights`] rejects them, because only
//!   the channel that becomes the height matters.

use std::fmt;
use std::io::{BufRead, Cursor, Read};
use std::path::Path;

use image::{ColorType, ImageDecoder, ImageError, ImageFormat, ImageReader, Limits};
use rayon::prelude::*;
use tiff::tags::{SampleFormat, Tag};

use super::png_zlib::{self, IdatWatch, finish_checked, png_error};
use super::{exr_subsampled, memory};
use crate::error::{Error, Result, one_line};
use crate::samples::{Samples, luma, try_vec};

/// Which channel of the image gives the height (SPEC §1, `--channel`).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
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
    /// A channel by name, as `--channel` passes it: an OpenEXR channel of
    /// exactly this name ("Z", "height", "disparityL.x"; with a layer
    /// chosen, also the name within it), else one of the keywords above
    /// in any case ("luma", "R"), else the one OpenEXR channel whose name
    /// matches in any case. Formats other than OpenEXR take the keywords
    /// only.
    Named(String),
}

impl Channel {
    /// The keyword this channel is: itself, or for [`Channel::Named`] the
    /// keyword its name spells in any case.
    fn keyword(&self) -> Option<Channel> {
        let Channel::Named(name) = self else { return Some(self.clone()) };
        Some(match name.to_ascii_lowercase().as_str() {
            "luma" => Channel::Luma,
            "r" => Channel::R,
            "g" => Channel::G,
            "b" => Channel::B,
            "a" => Channel::A,
            _ => return None,
        })
    }
}

impl fmt::Display for Channel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Channel::Luma => "luma",
            Channel::R => "r",
            Channel::G => "g",
            Channel::B => "b",
            Channel::A => "a",
            Channel::Named(name) => name,
        })
    }
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

/// One channel of an image: row-major, `width * height` samples as stored
/// (see [`Samples`] for their heights in contract units).
#[derive(Clone, Debug, PartialEq)]
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
    /// * An EXR applies the rule to its root channels, those whose names
    ///   have no dot: "Y", then its only root channel, then luma of R, G,
    ///   B, matching names in any case. A channel `layer.name` is a layer's
    ///   ("disparityL.y" is never the image's Y); the layers are read by
    ///   choosing one ([`ReadOptions::layer`]) or a channel by its full
    ///   name. When every channel shares one layer ("diffuse.R",
    ///   "diffuse.G", …), the names within it are the root; when they are
    ///   spread over several layers and none is at the root, the default
    ///   is an error naming the layers.
    /// * `A` gives alpha, an error when there is none.
    /// * [`Channel::Named`] picks an EXR channel by its exact name first
    ///   (see there).
    ///
    /// The heights are rounded to `f32`, for views and checks; the fit
    /// takes the samples themselves ([`Raster::into_heights`]).
    ///
    /// Errors: [`Error::Unsupported`] when the channel is missing,
    /// [`Error::NonFiniteHeight`] naming the first NaN or infinite height in
    /// row order.
    pub fn heights(&self, channel: Option<Channel>) -> Result<Vec<f32>> {
        let heights = match self.select(channel.as_ref())? {
            Source::Plane(i) => self.planes[i].data.to_f32()?,
            Source::Luma(rgb) => self.luma(rgb)?.into_f32()?,
        };
        // After the rounding: a double beyond f32's range is infinite here.
        match crate::fit::first_non_finite(&heights, self.width.max(1)) {
            None => Ok(heights),
            Some((x, y)) => Err(Error::NonFiniteHeight { x, y }),
        }
    }

    /// The samples the heights are made of, chosen as [`Raster::heights`]
    /// chooses them, as stored (one channel, moved out, not copied) or as
    /// luma in f64: what the fit reads, with no rounding between the file
    /// and the fit.
    ///
    /// Errors: as [`Raster::heights`].
    pub fn into_heights(mut self, channel: Option<Channel>) -> Result<Samples> {
        let heights = match self.select(channel.as_ref())? {
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
    fn select(&self, channel: Option<&Channel>) -> Result<Source> {
        let names: Vec<&str> = self.planes.iter().map(|p| p.name.as_str()).collect();
        select_channel(&names, channel, &self.format)
    }

    /// Luma of three planes in contract units, each texel in f64 by the one
    /// formula every reader uses ([`luma`]).
    fn luma(&self, [r, g, b]: [usize; 3]) -> Result<Samples> {
        let (r, g, b) = (&self.planes[r].data, &self.planes[g].data, &self.planes[b].data);
        let len = r.len().min(g.len()).min(b.len());
        let mut out = try_vec(len)?;
        // Every i < len is in all three planes: `height` gives Some.
        let at = |p: &Samples, i: usize| p.height(i).unwrap_or(0.0);
        out.par_extend((0..len).into_par_iter().map(|i| luma(at(r, i), at(g, i), at(b, i))));
        Ok(Samples::F64(out))
    }

    /// SPEC §1: a NaN or infinite height is an error naming the first such
    /// texel in row order.
    fn check_finite<'s>(&self, heights: &'s Samples) -> Result<&'s Samples> {
        match heights.first_non_finite(self.width.max(1)) {
            None => Ok(heights),
            Some((x, y)) => Err(Error::NonFiniteHeight { x, y }),
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
/// names: which channel, or which three for luma, hold the height. The
/// names are an OpenEXR file's own when `format` is [`InputFormat::Exr`];
/// the other formats' planes have fixed names ("Y", "R", …) that
/// [`Channel::Named`] cannot pick, only its keywords.
pub(crate) fn select_channel(names: &[&str], channel: Option<&Channel>, format: &InputFormat) -> Result<Source> {
    let names = Names::new(names);
    let exr = *format == InputFormat::Exr;
    let keyword = match channel {
        None => Channel::Luma,
        Some(Channel::Named(name)) => {
            if let Some(i) = names.exact(name).filter(|_| exr) {
                return Ok(Source::Plane(i));
            }
            match channel.and_then(Channel::keyword) {
                Some(keyword) => keyword,
                None if exr => {
                    return names.unique_ignoring_case(name).map(Source::Plane).ok_or_else(|| {
                        Error::Unsupported(format!("no channel {name} (channels: {})", names.channel_list()))
                    });
                }
                None => {
                    return Err(Error::Unsupported(format!(
                        "no channel {name}: {format} images take luma, r, g, b or a (only OpenEXR channels are \
                         chosen by name)"
                    )));
                }
            }
        }
        Some(keyword) => keyword.clone(),
    };
    let roots = names.roots()?;
    let wanted = match keyword {
        Channel::R => Some("r"),
        Channel::G => Some("g"),
        Channel::B => Some("b"),
        Channel::A => {
            return names
                .find(&roots, "a")
                .map(Source::Plane)
                .ok_or_else(|| Error::Unsupported("image has no alpha channel".into()));
        }
        Channel::Luma | Channel::Named(_) => None,
    };
    // An explicit R, G or B names a stored channel when there is one,
    // overriding an EXR's "Y"; a gray image has none and gives gray.
    if let Some(i) = wanted.and_then(|name| names.find(&roots, name)) {
        return Ok(Source::Plane(i));
    }
    match (names.gray_plane(&roots), wanted) {
        (Some(i), _) => Ok(Source::Plane(i)),
        (None, Some(name)) => {
            Err(Error::Unsupported(format!("image has no {name} channel (channels: {})", names.channel_list())))
        }
        (None, None) => names.rgb(&roots).map(Source::Luma),
    }
}

/// Channel names, for the channel rule.
///
/// OpenEXR names channels `layer.name` ("diffuse.R", "disparityL.x"); a
/// name without a dot is a root channel. The rule's keywords (the default,
/// luma, r, g, b, a) look at the root channels only, so a layer's "x" or
/// "R" is never mistaken for the image's own. When every name shares a
/// layer prefix (a file or `--layer` holding one layer only), the names
/// after that prefix are the root.
struct Names<'a> {
    all: &'a [&'a str],
    /// The length of the layer prefix every name shares ("diffuse."), or 0.
    shared: usize,
}

impl<'a> Names<'a> {
    fn new(all: &'a [&'a str]) -> Self {
        let mut shared = 0;
        if let Some(first) = all.first() {
            for (dot, _) in first.match_indices('.') {
                let prefix = &first[..=dot];
                if !all.iter().all(|name| name.starts_with(prefix)) {
                    break;
                }
                shared = dot + 1;
            }
        }
        Names { all, shared }
    }

    /// A name after the shared layer prefix.
    fn relative(&self, i: usize) -> &'a str {
        &self.all[i][self.shared..]
    }

    /// The root channels, by index: names (after the shared prefix) without
    /// a dot. An error when every channel is in a layer and the layers
    /// differ: which one holds the height is the user's choice.
    fn roots(&self) -> Result<Vec<usize>> {
        let roots: Vec<usize> = (0..self.all.len()).filter(|&i| !self.relative(i).contains('.')).collect();
        if roots.is_empty() && !self.all.is_empty() {
            let mut layers: Vec<&str> = Vec::new();
            for i in 0..self.all.len() {
                let layer = self.relative(i).split('.').next().unwrap_or_default();
                let layer = &self.all[i][..self.shared + layer.len()];
                if !layers.contains(&layer) {
                    layers.push(layer);
                }
            }
            return Err(Error::Unsupported(format!(
                "every channel is in a layer ({}) and none is at the root: choose a layer, or a channel by its \
                 full name",
                layers.join(", ")
            )));
        }
        Ok(roots)
    }

    /// The channel of exactly this name, or of this name after the shared
    /// layer prefix ("x" for "disparityL.x" when the layer was chosen).
    fn exact(&self, name: &str) -> Option<usize> {
        (self.all.iter().position(|n| *n == name)).or_else(|| (0..self.all.len()).find(|&i| self.relative(i) == name))
    }

    /// The one channel whose name, whole or after the shared prefix,
    /// matches in any case; none when no channel or several do.
    fn unique_ignoring_case(&self, name: &str) -> Option<usize> {
        let matches: Vec<usize> = (0..self.all.len())
            .filter(|&i| self.all[i].eq_ignore_ascii_case(name) || self.relative(i).eq_ignore_ascii_case(name))
            .collect();
        match matches.as_slice() {
            [i] => Some(*i),
            _ => None,
        }
    }

    /// The gray channel: "Y" if present, else the only root channel.
    fn gray_plane(&self, roots: &[usize]) -> Option<usize> {
        let only = match roots {
            [only] => Some(*only),
            _ => None,
        };
        self.find(roots, "y").or(only)
    }

    /// The R, G and B planes that luma is made of.
    fn rgb(&self, roots: &[usize]) -> Result<[usize; 3]> {
        match (self.find(roots, "r"), self.find(roots, "g"), self.find(roots, "b")) {
            (Some(r), Some(g), Some(b)) => Ok([r, g, b]),
            _ => Err(Error::Unsupported(format!(
                "no usable height channel: need y, a single channel, or r, g and b (channels: {})",
                self.channel_list()
            ))),
        }
    }

    /// The root channel for a letter (lower case), in any case; the upper
    /// case one, OpenEXR's spelling, when both are there.
    fn find(&self, roots: &[usize], letter: &str) -> Option<usize> {
        let upper = letter.to_ascii_uppercase();
        (roots.iter().copied().find(|&i| self.relative(i) == upper))
            .or_else(|| roots.iter().copied().find(|&i| self.relative(i).eq_ignore_ascii_case(letter)))
    }

    /// The channel names, for messages.
    fn channel_list(&self) -> String {
        if self.all.is_empty() {
            return "none".into();
        }
        self.all.join(", ")
    }
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

/// Splits interleaved native-endian samples into planes, as stored.
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

/// The values of a parallel iterator of `len` items in a vector allocated
/// fallibly.
fn par_collect<T: Send>(len: usize, values: impl ParallelIterator<Item = T>) -> Result<Vec<T>> {
    let mut data = try_vec(len)?;
    data.par_extend(values);
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
    let mut read = Cursor::new(bytes);
    if let Some(headers) = exr_subsampled::read_headers(&mut read).filter(exr_subsampled::Headers::subsampled) {
        return decode_exr_subsampled(read, headers, opts);
    }
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false).map_err(from_exr_error)?;
    check_exr_meta(&meta, bytes.len() as u64, opts)?;
    let choice = choose_exr_layer(&exr_parts(&meta.headers), opts.layer.as_deref())?;
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

/// Decodes an EXR with subsampled channels, which the `exr` crate refuses
/// (see [`exr_subsampled`]): the full-resolution channels of the layer
/// asked for, block by block. `read` is at the offset tables.
fn decode_exr_subsampled(
    mut read: Cursor<&[u8]>,
    headers: exr_subsampled::Headers,
    opts: &ReadOptions,
) -> Result<Raster> {
    let file_len = read.get_ref().len() as u64;
    let part = exr_subsampled::ScanLines::open(headers, &mut read, file_len, opts)?;
    let (width, height) = (part.width(), part.height());
    let texels = to_usize((width as u64).saturating_mul(height as u64))?;
    let (wanted, names): (Vec<usize>, Vec<String>) = part.channels().map(|(i, n)| (i, n.to_string())).unzip();
    memory::check_memory("decoding", (texels as u64).saturating_mul(8 * wanted.len() as u64))?;
    // The planes grow block by block, so a header that claims far more
    // texels than the file holds fails at its first missing chunk, before
    // the memory is taken. They are f64, as the streamed rows are: every
    // sample type (half, float, u32) exactly, and the same bits either way.
    let mut planes: Vec<(String, Vec<f64>)> = names.into_iter().map(|name| (name, Vec::new())).collect();
    for y0 in (0..height).step_by(part.lines_per_block()) {
        let block = part.read_block(&mut read, y0, &wanted)?;
        for ((name, data), rows) in planes.iter_mut().zip(block) {
            data.try_reserve(rows.len())
                .map_err(|_| Error::Limits(format!("cannot allocate {texels} values of 8 bytes for channel {name}")))?;
            data.extend_from_slice(&rows);
        }
    }
    let planes = planes.into_iter().map(|(name, data)| Plane { name, data: Samples::F64(data) }).collect();
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

/// What the layer choice needs of one part of an OpenEXR file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct ExrPart {
    /// Its `name` attribute.
    pub name: Option<String>,
    /// Whether it holds deep data.
    pub deep: bool,
    /// Its channels' names.
    pub channels: Vec<String>,
}

/// The parts of a file as the `exr` crate read its headers.
pub(crate) fn exr_parts(headers: &[exr::meta::header::Header]) -> Vec<ExrPart> {
    let part = |h: &exr::meta::header::Header| ExrPart {
        name: h.own_attributes.layer_name.as_ref().map(|n| n.to_string()),
        deep: h.deep,
        channels: h.channels.list.iter().map(|c| c.name.to_string()).collect(),
    };
    headers.iter().map(part).collect()
}

/// Finds the layer `name` among an OpenEXR file's parts (see
/// [`ReadOptions::layer`]): a part of that name, else the first part with
/// channels named `name.…`; `None` is the first part of flat samples.
///
/// Errors: [`Error::Unsupported`] naming the layers there are when none
/// matches, or when every part holds deep data.
pub(crate) fn choose_exr_layer(parts: &[ExrPart], name: Option<&str>) -> Result<ExrLayer> {
    let Some(name) = name else {
        return parts
            .iter()
            .position(|p| !p.deep)
            .map(|part| ExrLayer { part, prefix: None })
            .ok_or_else(|| Error::Unsupported("exr file holds only deep data".into()));
    };
    if let Some(part) = parts.iter().position(|p| p.name.as_deref() == Some(name)) {
        return Ok(ExrLayer { part, prefix: None });
    }
    let group = ExrLayer { part: 0, prefix: Some(name.to_string()) };
    if let Some(part) = parts.iter().position(|p| !p.deep && p.channels.iter().any(|c| group.holds(c))) {
        return Ok(ExrLayer { part, ..group });
    }
    // The names there are: parts, and the channel groups of each part.
    let mut layers: Vec<String> = Vec::new();
    for part in parts {
        layers.extend(part.name.clone());
        for channel in &part.channels {
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
        FlatSamples::F32(v) => Samples::F32(v),
        FlatSamples::F16(v) => {
            let mut out = try_vec(v.len())?;
            out.par_extend(v.par_iter().map(|h| h.to_f32()));
            Samples::F32(out)
        }
        FlatSamples::U32(v) => {
            // SPEC treats EXR as a float image: the value is the height.
            // f64 holds every u32 exactly (f32 would round above 2^24).
            let mut out = try_vec(v.len())?;
            out.par_extend(v.par_iter().map(|&n| f64::from(n)));
            Samples::F64(out)
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
