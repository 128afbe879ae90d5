//! How a normal map is stored: one vocabulary for the whole-image writers
//! ([`encode_normals`](super::encode_normals)) and the streaming pipeline
//! ([`crate::pipeline`]), and the rules that choose it from a file name,
//! a bit depth and the input (SPEC §3).

use std::path::Path;

use super::gpu::{Compression, Container, Uncompressed};
use super::{InputFormat, SampleType};
use crate::error::{Error, Result};
use crate::options::named_values;

/// The file formats normal maps are written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum OutputFormat {
    /// PNG: 8 or 16 bits a sample, c = round(max · (n + 1)/2).
    Png,
    /// OpenEXR: half or float samples, (n + 1)/2 or n itself.
    Exr,
    /// TIFF: 8- or 16-bit samples as PNG stores them, or float samples as
    /// EXR does; a GeoTIFF when the input is one (its georeferencing tags
    /// copied), so the map overlays its source in GIS tools.
    Tiff,
    /// DirectDraw Surface (DX10 header): a GPU texture holding a mip chain
    /// ([`crate::io::gpu`]), block-compressed or not.
    Dds,
    /// KTX 2.0: a GPU texture holding a mip chain, as DDS does.
    Ktx2,
}

named_values!(OutputFormat, "format", {
    Png => "png", Exr => "exr", Tiff => "tiff" | "tif", Dds => "dds", Ktx2 => "ktx2"
});

impl OutputFormat {
    /// The format a file name's extension names (`.png`, `.exr`, in any
    /// case); `Ok(None)` for a name without an extension, which leaves the
    /// choice to the input ([`OutputFormat::for_input`]).
    ///
    /// Errors: [`Error::Unsupported`] for any other extension.
    pub fn from_path(path: &Path) -> Result<Option<OutputFormat>> {
        let Some(ext) = path.extension() else { return Ok(None) };
        match ext.to_string_lossy().to_ascii_lowercase().as_str() {
            "png" => Ok(Some(OutputFormat::Png)),
            "exr" => Ok(Some(OutputFormat::Exr)),
            "tif" | "tiff" => Ok(Some(OutputFormat::Tiff)),
            "dds" => Ok(Some(OutputFormat::Dds)),
            "ktx2" => Ok(Some(OutputFormat::Ktx2)),
            other => Err(Error::Unsupported(format!(
                "cannot write .{other} files: name the output .png, .exr, .tif, .dds or .ktx2"
            ))),
        }
    }

    /// The format of an output whose name and options do not say: the
    /// input's own if it is PNG or EXR, else EXR for float samples and PNG
    /// for integers.
    #[must_use]
    pub fn for_input(format: &InputFormat, sample: SampleType) -> OutputFormat {
        match (format, sample) {
            (InputFormat::Exr, _) => OutputFormat::Exr,
            (InputFormat::Png, _) => OutputFormat::Png,
            (_, SampleType::Float) => OutputFormat::Exr,
            _ => OutputFormat::Png,
        }
    }

    /// The format of an output named `path` (if it is a file), `asked`
    /// (if the caller says), else the input's: the first that speaks.
    ///
    /// Errors: those of [`OutputFormat::from_path`], and
    /// [`Error::InvalidOption`] when the name and `asked` disagree.
    pub fn choose(
        path: Option<&Path>,
        asked: Option<OutputFormat>,
        input: (&InputFormat, SampleType),
    ) -> Result<OutputFormat> {
        let named = path.map(OutputFormat::from_path).transpose()?.flatten();
        if let (Some(asked), Some(named)) = (asked, named)
            && asked != named
        {
            let (named, asked) = (named.extension(), asked.extension());
            return Err(Error::InvalidOption(format!("extension says {named} but the format asked is {asked}")));
        }
        Ok(asked.or(named).unwrap_or_else(|| OutputFormat::for_input(input.0, input.1)))
    }

    /// The file name extension, lower case, without the dot.
    #[must_use]
    pub fn extension(self) -> &'static str {
        match self {
            OutputFormat::Png => "png",
            OutputFormat::Exr => "exr",
            OutputFormat::Tiff => "tif",
            OutputFormat::Dds => "dds",
            OutputFormat::Ktx2 => "ktx2",
        }
    }

    /// The GPU container this format is, if it is one (DDS, KTX2).
    #[must_use]
    pub fn container(self) -> Option<Container> {
        match self {
            OutputFormat::Dds => Some(Container::Dds),
            OutputFormat::Ktx2 => Some(Container::Ktx2),
            _ => None,
        }
    }
}

/// How a GPU texture's normals are stored, as callers ask for them
/// (`--compress`, `compress=`): BC5 blocks (x and y; the default), BC7
/// blocks (x, y and z; the `bc7` feature), or none (8-bit RGBA, or RG with
/// red-green channels; half floats with 16 bits).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum TextureCompression {
    /// BC5: x and y, a byte a texel. The default.
    #[default]
    Bc5,
    /// BC7: x, y, z, a byte a texel.
    Bc7,
    /// No blocks.
    None,
}

named_values!(TextureCompression, "compression", { Bc5 => "bc5", Bc7 => "bc7", None => "none" });

/// A GPU texture's container and how its texels are stored: the normal
/// map's, and its one-channel companions' (a roughness chain:
/// [`TextureOptions::values`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub struct TextureOptions {
    /// DDS or KTX2.
    pub container: Container,
    /// The normals' storage.
    pub compression: Compression,
    /// The alpha holds each level's heights ([`Layout::RgbHeight`]: BC7,
    /// RGBA8 or RGBA16F), else it is opaque (or absent).
    pub heights: bool,
}

impl TextureOptions {
    /// The texture for these options: `compression` (default BC5);
    /// without blocks, RGBA8 (RG8 with [`Layout::Rg`]), or half floats with
    /// 16 `bits`.
    ///
    /// With [`Layout::RgbHeight`] the alpha holds the heights: BC7, RGBA8
    /// or RGBA16F (BC5 and red-green have no alpha).
    ///
    /// Errors: [`Error::InvalidOption`] for `bits` beside blocks, or other
    /// than 8 and 16; an alpha of heights in BC5 (the default), or an
    /// alpha of validity; `signed` (half floats store n itself already, 8
    /// bits (n + 1)/2).
    pub fn choose(
        container: Container,
        compression: Option<TextureCompression>,
        bits: Option<u8>,
        signed: bool,
        layout: Layout,
    ) -> Result<TextureOptions> {
        let ext = container.extension();
        if signed {
            return Err(Error::InvalidOption(format!(
                "a .{ext} texture has no signed option: its half floats store n itself, its bytes (n + 1)/2"
            )));
        }
        let heights = layout == Layout::RgbHeight;
        if layout == Layout::RgbValid {
            return Err(Error::InvalidOption(format!("a .{ext} texture holds no alpha of validity")));
        }
        if heights && compression.unwrap_or_default() == TextureCompression::Bc5 {
            return Err(Error::InvalidOption(format!(
                "a .{ext} texture in BC5 (the default) holds x and y alone, no alpha: an alpha of heights takes compression bc7 or none"
            )));
        }
        let rg = layout == Layout::Rg;
        let compression = match (compression.unwrap_or_default(), bits) {
            (TextureCompression::Bc5, None) => Compression::Bc5,
            (TextureCompression::Bc7, None) => Compression::Bc7,
            (TextureCompression::None, None | Some(8)) if rg => Compression::None(Uncompressed::Rg8),
            (TextureCompression::None, None | Some(8)) => Compression::None(Uncompressed::Rgba8),
            (TextureCompression::None, Some(16)) if rg => Compression::None(Uncompressed::Rg16f),
            (TextureCompression::None, Some(16)) => Compression::None(Uncompressed::Rgba16f),
            (TextureCompression::None, Some(b)) => {
                return Err(Error::InvalidOption(format!(
                    "a .{ext} texture without blocks holds 8 bits (RGBA8) or 16 (half floats), not {b}"
                )));
            }
            (c, Some(b)) => {
                return Err(Error::InvalidOption(format!(
                    "{b} bits with compression {c}: bits are for a texture without blocks (compression none)"
                )));
            }
        };
        Ok(TextureOptions { container, compression, heights })
    }

    /// How a one-channel chain beside the normals is stored: BC4 beside
    /// blocks, one byte beside 8-bit texels, a half float beside half
    /// floats.
    #[must_use]
    pub fn values(self) -> Compression {
        match self.compression {
            Compression::Bc5 | Compression::Bc7 | Compression::Bc4 => Compression::Bc4,
            Compression::None(Uncompressed::Rgba16f | Uncompressed::Rg16f | Uncompressed::R16f) => {
                Compression::None(Uncompressed::R16f)
            }
            Compression::None(_) => Compression::None(Uncompressed::R8),
        }
    }
}

/// Bits per sample of a PNG normal map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PngDepth {
    /// 8 bits a sample.
    Eight,
    /// 16 bits a sample.
    Sixteen,
}

/// A PNG normal map's depth, compression and channels.
///
/// Streamed ([`crate::pipeline`]), [`PngCompression::Fast`] filters every
/// row with Avg (22.6 MiB for a 4096² map) and stores the rows that
/// deflate would shrink by less than a tenth (16-bit maps, whose low bytes
/// are noise: 4 % larger, in 28 % less processor time); `Default` and
/// `Best` choose each row's filter (19.9 MiB, the filtering taking twice
/// as long) and deflate every row, unless that makes it larger.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub struct PngOptions {
    /// Bits per sample.
    pub depth: PngDepth,
    /// How hard the rows are deflated. Default: fast.
    pub compression: PngCompression,
    /// Which channels: RGB, RGBA with an alpha of heights or of 1, or
    /// red-green (B = 0). Default: RGB.
    pub layout: Layout,
}

impl PngOptions {
    /// `depth`, fast compression, RGB.
    #[must_use]
    pub fn new(depth: PngDepth) -> PngOptions {
        PngOptions { depth, compression: PngCompression::Fast, layout: Layout::Rgb }
    }

    /// With this compression.
    #[must_use]
    pub fn with_compression(self, compression: PngCompression) -> PngOptions {
        PngOptions { compression, ..self }
    }

    /// With these channels.
    #[must_use]
    pub fn with_layout(self, layout: Layout) -> PngOptions {
        PngOptions { layout, ..self }
    }
}

impl From<PngDepth> for PngOptions {
    fn from(depth: PngDepth) -> Self {
        PngOptions::new(depth)
    }
}

/// An OpenEXR normal map's sample type, encoding and channels (ZIP
/// compression in blocks of 16 rows, always).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub struct ExrOptions {
    /// Half or float samples. Default: float.
    pub depth: ExrDepth,
    /// Store n itself, in [−1, 1], instead of (n + 1)/2. Default: off.
    pub signed: bool,
    /// Which channels. Default: R, G, B.
    pub layout: Layout,
}

impl ExrOptions {
    /// `depth`, (n + 1)/2, R, G, B.
    #[must_use]
    pub fn new(depth: ExrDepth) -> ExrOptions {
        ExrOptions { depth, signed: false, layout: Layout::Rgb }
    }

    /// Storing n itself (`true`) or (n + 1)/2.
    #[must_use]
    pub fn with_signed(self, signed: bool) -> ExrOptions {
        ExrOptions { signed, ..self }
    }

    /// With these channels.
    #[must_use]
    pub fn with_layout(self, layout: Layout) -> ExrOptions {
        ExrOptions { layout, ..self }
    }

    /// The value stored for a normal's component `c` (in [−1, 1]): the one
    /// rule of whole-image and streamed EXR outputs.
    #[inline]
    #[must_use]
    pub fn stored(self, c: f32) -> f32 {
        if self.signed { c } else { (c + 1.0) * 0.5 }
    }

    /// [`ExrOptions::stored`] of every component of `normals`, in place.
    pub(crate) fn store_all(self, normals: &mut [[f32; 3]]) {
        if !self.signed {
            normals.iter_mut().for_each(|t| *t = t.map(|c| self.stored(c)));
        }
    }
}

impl From<ExrDepth> for ExrOptions {
    fn from(depth: ExrDepth) -> Self {
        ExrOptions::new(depth)
    }
}

/// A TIFF normal map's sample type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TiffDepth {
    /// 8-bit unsigned integers, as an 8-bit PNG stores them.
    Eight,
    /// 16-bit unsigned integers, as a 16-bit PNG stores them.
    Sixteen,
    /// 32-bit floats, as a float EXR stores them.
    Float,
}

/// A TIFF normal map's sample type, encoding and channels: uncompressed,
/// a row a strip (GDAL's own default for striped files), so it is
/// written at the speed of the disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub struct TiffOptions {
    /// Bits and type of a sample.
    pub depth: TiffDepth,
    /// Float samples only: store n itself, in [−1, 1], instead of
    /// (n + 1)/2. Default: off.
    pub signed: bool,
    /// Which channels: RGB, RGBA (an unassociated alpha of heights, of 1,
    /// or of validity), or red-green (B = 0, as in PNG). Default: RGB.
    pub layout: Layout,
}

impl TiffOptions {
    /// `depth`, (n + 1)/2, RGB.
    #[must_use]
    pub fn new(depth: TiffDepth) -> TiffOptions {
        TiffOptions { depth, signed: false, layout: Layout::Rgb }
    }

    /// Storing n itself (`true`) or (n + 1)/2; float samples only.
    #[must_use]
    pub fn with_signed(self, signed: bool) -> TiffOptions {
        TiffOptions { signed, ..self }
    }

    /// With these channels.
    #[must_use]
    pub fn with_layout(self, layout: Layout) -> TiffOptions {
        TiffOptions { layout, ..self }
    }
}

impl From<TiffDepth> for TiffOptions {
    fn from(depth: TiffDepth) -> Self {
        TiffOptions::new(depth)
    }
}

/// How a normal map (or a one-channel map) is encoded: the format and its
/// options.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Encoding {
    /// PNG.
    Png(PngOptions),
    /// OpenEXR.
    Exr(ExrOptions),
    /// TIFF.
    Tiff(TiffOptions),
    /// A GPU texture (DDS, KTX2): a mip chain, written whole
    /// ([`crate::io::gpu`]).
    Texture(TextureOptions),
}

impl Encoding {
    /// An 8-bit RGB PNG, fast compression.
    #[must_use]
    pub fn png8() -> Encoding {
        Encoding::Png(PngOptions::new(PngDepth::Eight))
    }

    /// A 16-bit RGB PNG, fast compression.
    #[must_use]
    pub fn png16() -> Encoding {
        Encoding::Png(PngOptions::new(PngDepth::Sixteen))
    }

    /// A float RGB OpenEXR holding (n + 1)/2.
    #[must_use]
    pub fn exr() -> Encoding {
        Encoding::Exr(ExrOptions::new(ExrDepth::Float))
    }

    /// The encoding of `format` for these options (SPEC §3): `bits` 8 or
    /// 16 for PNG (none: 16 if the input has more than 8 bits a sample,
    /// else 8), 16 (half) or 32 (float, and none) for EXR, 8, 16 (none:
    /// as PNG) or 32 (float) for TIFF; `signed` (n itself) for float
    /// samples alone.
    ///
    /// Errors: [`Error::Unsupported`] for a depth or `signed` the format
    /// cannot hold.
    pub fn choose(
        format: OutputFormat,
        bits: Option<u8>,
        signed: bool,
        layout: Layout,
        compression: PngCompression,
        input: SampleType,
    ) -> Result<Encoding> {
        let png = |depth| Encoding::Png(PngOptions { depth, compression, layout });
        let exr = |depth| Encoding::Exr(ExrOptions { depth, signed, layout });
        let tiff = |depth| Encoding::Tiff(TiffOptions { depth, signed, layout });
        let encoding = match (format, bits) {
            (OutputFormat::Png, None) if input.more_than_8_bits() => png(PngDepth::Sixteen),
            (OutputFormat::Png, None | Some(8)) => png(PngDepth::Eight),
            (OutputFormat::Png, Some(16)) => png(PngDepth::Sixteen),
            (OutputFormat::Png, Some(b)) => {
                return Err(Error::Unsupported(format!("PNG holds 8 or 16 bits: {b} bits need EXR output")));
            }
            (OutputFormat::Exr, None | Some(32)) => exr(ExrDepth::Float),
            (OutputFormat::Exr, Some(16)) => exr(ExrDepth::Half),
            (OutputFormat::Exr, Some(b)) => {
                return Err(Error::Unsupported(format!("EXR holds 16- or 32-bit floats: {b} bits need PNG output")));
            }
            (OutputFormat::Tiff, None) if input.more_than_8_bits() => tiff(TiffDepth::Sixteen),
            (OutputFormat::Tiff, None | Some(8)) => tiff(TiffDepth::Eight),
            (OutputFormat::Tiff, Some(16)) => tiff(TiffDepth::Sixteen),
            (OutputFormat::Tiff, Some(32)) => tiff(TiffDepth::Float),
            (OutputFormat::Tiff, Some(b)) => {
                return Err(Error::Unsupported(format!("TIFF output holds 8, 16 or 32 (float) bits, not {b}")));
            }
            (OutputFormat::Dds | OutputFormat::Ktx2, bits) => {
                let container = format.container().expect("a GPU format");
                Encoding::Texture(TextureOptions::choose(container, None, bits, signed, layout)?)
            }
        };
        match encoding {
            Encoding::Png(_) if signed => {
                return Err(Error::Unsupported(
                    "signed normals need a float output (EXR): PNG stores only [0, 1]".into(),
                ));
            }
            Encoding::Tiff(o) if signed && o.depth != TiffDepth::Float => {
                return Err(Error::Unsupported(
                    "signed normals need float samples (--bits 32): integer TIFF stores only [0, 1]".into(),
                ));
            }
            _ => {}
        }
        Ok(encoding)
    }

    /// The file format.
    #[must_use]
    pub fn format(&self) -> OutputFormat {
        match self {
            Encoding::Png(_) => OutputFormat::Png,
            Encoding::Exr(_) => OutputFormat::Exr,
            Encoding::Tiff(_) => OutputFormat::Tiff,
            Encoding::Texture(o) => match o.container {
                Container::Dds => OutputFormat::Dds,
                Container::Ktx2 => OutputFormat::Ktx2,
            },
        }
    }

    /// The channels.
    #[must_use]
    pub fn layout(&self) -> Layout {
        match self {
            Encoding::Png(o) => o.layout,
            Encoding::Exr(o) => o.layout,
            Encoding::Tiff(o) => o.layout,
            Encoding::Texture(o) => match o.compression {
                Compression::None(Uncompressed::Rg8 | Uncompressed::Rg16f) => Layout::Rg,
                _ if o.heights => Layout::RgbHeight,
                _ => Layout::Rgb,
            },
        }
    }

    /// Whether the samples are floats, which hold any height as it is (an
    /// alpha of heights in map units: a DEM's metres); integer samples
    /// and GPU textures hold [0, 1].
    #[must_use]
    pub fn has_float_samples(&self) -> bool {
        match self {
            Encoding::Exr(_) => true,
            Encoding::Tiff(o) => o.depth == TiffDepth::Float,
            Encoding::Png(_) | Encoding::Texture(_) => false,
        }
    }

    /// The same encoding with other channels.
    #[must_use]
    pub fn with_layout(self, layout: Layout) -> Encoding {
        match self {
            Encoding::Png(o) => Encoding::Png(o.with_layout(layout)),
            Encoding::Exr(o) => Encoding::Exr(o.with_layout(layout)),
            Encoding::Tiff(o) => Encoding::Tiff(o.with_layout(layout)),
            // A texture's channels are its compression's.
            Encoding::Texture(o) => Encoding::Texture(o),
        }
    }
}

impl From<PngOptions> for Encoding {
    fn from(options: PngOptions) -> Self {
        Encoding::Png(options)
    }
}

impl From<ExrOptions> for Encoding {
    fn from(options: ExrOptions) -> Self {
        Encoding::Exr(options)
    }
}

impl From<TiffOptions> for Encoding {
    fn from(options: TiffOptions) -> Self {
        Encoding::Tiff(options)
    }
}

/// How hard the PNG encoder compresses.
///
/// The default is [`PngCompression::Fast`]: normal maps (16-bit ones most
/// of all) are noisy in their low bits and gain little from slow deflate,
/// while deflate runs on one thread and would otherwise take longer than
/// the whole parallel fit. It is also `image`'s own default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum PngCompression {
    /// Fast deflate; somewhat larger files.
    #[default]
    Fast,
    /// Balanced speed and size.
    Default,
    /// Smallest files, slowest.
    Best,
}

impl PngCompression {
    /// The settings callers choose by name (`--compression`,
    /// `compression=`): fast and small. [`Best`](Self::Best) is for library
    /// callers of the whole-image writer alone: the streamed writer makes
    /// the same file at `Default` and `Best`.
    pub const NAMED: &'static [PngCompression] = &[PngCompression::Fast, PngCompression::Default];

    /// The setting's name: `fast`, `small` (for `Default`) or `best`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            PngCompression::Fast => "fast",
            PngCompression::Default => "small",
            PngCompression::Best => "best",
        }
    }

    /// Other spellings that parse as this setting.
    #[must_use]
    pub fn aliases(self) -> &'static [&'static str] {
        &[]
    }
}

impl std::fmt::Display for PngCompression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for PngCompression {
    type Err = Error;

    /// One of [`NAMED`](Self::NAMED)'s names, ASCII case ignored.
    fn from_str(s: &str) -> Result<Self> {
        let s = s.trim();
        let names: Vec<&str> = PngCompression::NAMED.iter().map(|c| c.name()).collect();
        PngCompression::NAMED.iter().copied().find(|c| s.eq_ignore_ascii_case(c.name())).ok_or_else(|| {
            Error::InvalidOption(format!("unknown compression '{s}': use {}", crate::options::one_of(&names)))
        })
    }
}

/// Sample type of an EXR output (SPEC §3: `--bits 16` or `--bits 32`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ExrDepth {
    /// 16-bit half floats.
    Half,
    /// 32-bit floats, the EXR default.
    #[default]
    Float,
}

/// Which channels a normal map file holds. R, G and B are the normal's
/// x, y and z, encoded as the contract says (SPEC §3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Layout {
    /// R, G, B. The default.
    #[default]
    Rgb,
    /// R, G, B and an alpha channel holding each texel's height, for
    /// parallax mapping: the height as the fit read it (SPEC §1 units, not
    /// scaled by the gain; in map units, as stored: a DEM's metres, which
    /// only float samples hold), clamped to [0, 1] in a PNG, as it is in
    /// an EXR; 0 where the texel has no normal (a hole).
    RgbHeight,
    /// R, G, B and an opaque alpha (1), for pipelines that want four
    /// channels.
    RgbOpaque,
    /// R, G, B and an alpha that says which texels have a normal: 1 (the
    /// sample's largest value) where the texel has one, 0 where it is
    /// missing, a hole (docs/terrain.md, "Holes"; a missing texel's RGB is
    /// the flat normal). What a conversion with a nodata value writes in
    /// place of RGB or an opaque alpha.
    RgbValid,
    /// The normal's x and y alone, for two-channel (BC5) pipelines whose
    /// shaders rebuild z = √(1 − x² − y²). An EXR holds channels R and G; a
    /// PNG, which has no red-green type, stays RGB with B = 0, which BC5
    /// encoders ignore and deflate stores almost for free.
    Rg,
}

/// What a normal map's alpha channel holds, as callers ask for it: with
/// [`OutputChannels`], [`Layout::from_parts`] makes the [`Layout`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Alpha {
    /// No alpha channel. The default.
    #[default]
    None,
    /// The texel's height (for parallax mapping).
    Height,
    /// An opaque alpha, 1.
    One,
}

/// Which components of the normal a map holds, as callers ask for them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum OutputChannels {
    /// x, y and z as R, G and B. The default.
    #[default]
    Rgb,
    /// x and y alone, for two-channel (BC5) textures.
    Rg,
}

named_values!(Alpha, "alpha", { None => "none", Height => "height", One => "one" });
named_values!(OutputChannels, "channels", { Rgb => "rgb", Rg => "rg" });

impl Layout {
    /// The layout of a map with these channels and this alpha: what the
    /// command line's `--channels` and `--alpha`, and the Python package's
    /// `channels=` and `alpha=`, ask for together.
    ///
    /// Errors: [`Error::InvalidOption`] for an alpha beside red-green
    /// alone, which has none.
    pub fn from_parts(channels: OutputChannels, alpha: Alpha) -> Result<Layout> {
        match (channels, alpha) {
            (OutputChannels::Rgb, Alpha::None) => Ok(Layout::Rgb),
            (OutputChannels::Rgb, Alpha::Height) => Ok(Layout::RgbHeight),
            (OutputChannels::Rgb, Alpha::One) => Ok(Layout::RgbOpaque),
            (OutputChannels::Rg, Alpha::None) => Ok(Layout::Rg),
            (OutputChannels::Rg, _) => Err(Error::InvalidOption(format!(
                "channels rg has no alpha (asked for alpha {alpha}): it is for two-channel (BC5) textures"
            ))),
        }
    }

    /// Samples per texel in a PNG.
    pub(crate) fn png_samples(self) -> usize {
        match self {
            Layout::Rgb | Layout::Rg => 3,
            Layout::RgbHeight | Layout::RgbOpaque | Layout::RgbValid => 4,
        }
    }

    /// The EXR channels, in the order [`lay_out`] gives their samples.
    pub(crate) fn exr_channels(self) -> &'static [&'static str] {
        match self {
            Layout::Rgb => &["R", "G", "B"],
            Layout::RgbHeight | Layout::RgbOpaque | Layout::RgbValid => &["R", "G", "B", "A"],
            Layout::Rg => &["R", "G"],
        }
    }

    /// Whether the texels' heights are needed (for [`Layout::RgbValid`],
    /// the texels' validity in their place: 1 or 0).
    #[must_use]
    pub fn needs_heights(self) -> bool {
        matches!(self, Layout::RgbHeight | Layout::RgbValid)
    }

    /// The layout of a map with holes: an alpha of validity in place of
    /// none or an opaque one; an alpha of heights, and red-green alone,
    /// stay as asked.
    #[must_use]
    pub fn with_holes(self) -> Layout {
        match self {
            Layout::Rgb | Layout::RgbOpaque => Layout::RgbValid,
            other => other,
        }
    }
}

/// What a TIFF output holds besides its samples (nothing for PNG or EXR).
/// Public only as an argument of the sealed traits' hidden methods.
#[doc(hidden)]
#[derive(Clone, Copy, Debug, Default)]
#[cfg_attr(not(feature = "tiff"), allow(dead_code))]
pub struct TiffTags<'a> {
    /// The source's georeferencing, copied as stored.
    pub(crate) georef: Option<&'a super::read::Georef>,
    /// GDAL's nodata value (the GDAL_NODATA tag): the value of a missing
    /// texel, for maps whose values say it (a lit view's 0).
    pub(crate) nodata: Option<f64>,
}
