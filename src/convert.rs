//! Conversion: a height map in (a file, or bytes), a normal map out (a
//! file written atomically, or any writer), with every rule the command
//! line follows, so that other programs and bindings get them by one call.
//!
//! A [`Conversion`] holds the choices: the fit ([`Options`]), the borders
//! (fixed, or [`BorderChoice::Auto`]: wrap where the image tiles, mirror
//! where it does not), the output's format, depth, encoding and channels,
//! and whether the fit's residual is written too. It decides the rest:
//!
//! * the output's [`Encoding`], from the output's name, the options and the
//!   input ([`OutputFormat::choose`], [`Encoding::choose`]);
//! * streaming or whole: PNG, scan-line EXR and the TIFF bands the `tiff`
//!   crate reads (GeoTIFF elevation) stream through
//!   [`crate::pipeline`] (memory grows with the width, not the height),
//!   unless a residual is asked for, which is made from the whole image;
//!   both give the same bytes;
//! * the memory checks, before any large buffer or encoder runs
//!   ([`crate::io::check_memory`]): running out is an error, never an abort;
//! * the tiling check that `auto` borders need, and that warns about a
//!   wrap drawing a seam;
//! * the promise that a file output appears whole or not at all and never
//!   replaces the input file.
//!
//! Nothing here prints: warnings are data ([`Warning`], in the
//! [`Summary`] and given to an [`Observer`] as they happen), and errors say
//! which file they concern ([`ConvertError::place`]).
//!
//! One call, file to file:
//!
//! ```no_run
//! use normalfit::convert::{BorderChoice, BorderChoices, Conversion};
//! use normalfit::{Options, Strength};
//!
//! let conversion = Conversion::new()
//!     .with_fit(Options::new().with_patch(5).with_strength(Strength::Scale(4.0)))
//!     .with_borders(BorderChoices::both(BorderChoice::Auto))
//!     .with_bits(16);
//! let summary = conversion.convert_file("rock_height.png".as_ref(), "rock_normal.png".as_ref())?;
//! println!("{} × {}, borders {:?}, streamed: {}", summary.width, summary.height, summary.borders, summary.streamed);
//! # Ok::<(), normalfit::convert::ConvertError>(())
//! ```
//!
//! Two steps when the output's name depends on the input (its format):
//! [`Conversion::open`] reads the header (or the whole image), then
//! [`Opened::encoding`] gives the encoding for a name, and
//! [`Opened::write`] converts.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::Options;
pub use crate::borders::{BorderChoice, BorderChoices, Warning};
use crate::engine::{self, MipStage, Settings, Sink, Stage};
pub use crate::engine::{
    ConvertError, Input, Observer, Output, Place, Summary, chain_stem, level_path, read_all, roughness_path,
};
use crate::error::Error;
use crate::io::{
    Channel, Encoding, InputFormat, Inputs, Layout, OutputFormat, PngCompression, ReadOptions, Replace, SampleType,
    TextureCompression, TextureOptions,
};
pub use crate::light::Sun;
pub use crate::mips::MipChoice;
pub use crate::options::{Product, SlopeUnits};
use crate::units::{MapSpacing, Measure};

/// Every choice of a conversion. The defaults are the contract's: the
/// fit's defaults (3×3, wrap borders, OpenGL, scale 1), the output format
/// of its name (else the input's), 8 or 16 bits as the input has, (n + 1)/2,
/// RGB, fast PNG compression, no residual.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct Conversion {
    /// The fit; its borders are replaced by [`Conversion::borders`]'.
    pub fit: Options,
    /// The border modes, fixed or `auto`.
    pub borders: BorderChoices,
    /// The size limit and the EXR layer, for every read.
    pub read: ReadOptions,
    /// The channel that holds the height (SPEC §1's rule if none).
    pub channel: Option<Channel>,
    /// The output format, when the output's name does not say.
    pub format: Option<OutputFormat>,
    /// Bits per sample: 8 or 16 (PNG), 16 or 32 (EXR).
    pub bits: Option<u8>,
    /// EXR stores n itself instead of (n + 1)/2.
    pub signed: bool,
    /// PNG compression.
    pub compression: PngCompression,
    /// The normal map's channels.
    pub layout: Layout,
    /// Whether a residual map is made (the image is then read whole).
    pub residual: bool,
    /// Fit in real-world units ([`crate::Units::Map`]), the spacing from
    /// the file or given; `None`: the contract's units. The heights are
    /// then taken as stored ([`crate::io::Raster::into_stored_heights`]; streamed,
    /// the same values row by row). The fit's own [`Options::units`] are
    /// replaced by what this gives.
    pub map_units: Option<MapSpacing>,
    /// Which existing files the normal map, its residual and its
    /// georeferencing sidecars may replace (default: any). All of them are
    /// checked before any is written, and they appear together.
    pub replace: Replace,
    /// A mip chain ([`crate::mips`]): every level, fitted from the heights
    /// or averaged from a normal map's normals ([`MipChoice`]); `None`:
    /// the finest level alone. A `.dds` or `.ktx2` output holds the chain
    /// in one file; an image output takes level 0 at its name and level
    /// k ≥ 1 at `<stem>_mip<k>.<ext>` ([`level_path`]). The image is read
    /// whole. Default: none.
    pub mips: Option<MipChoice>,
    /// How a `.dds` or `.ktx2` output's normals are stored (default BC5);
    /// an error for other outputs.
    pub compress: Option<TextureCompression>,
    /// A roughness chain beside the normals, at `<stem>_roughness.<ext>`
    /// ([`roughness_path`]; [`crate::mips::roughness_chain`]: Toksvig's
    /// variance added to the base's α²). Default: off.
    pub roughness: bool,
    /// The base roughness of the roughness chain: a gray image of the
    /// input's size, perceptual roughness in [0, 1]. Default: none (0).
    pub roughness_base: Option<PathBuf>,
    /// Files no output may replace, besides the input itself (which none
    /// ever does): a batch's other inputs. Every file a conversion writes
    /// (a mip chain's levels and roughness included) is checked against
    /// them, and against [`Conversion::replace`], before the work starts.
    /// Default: none.
    pub inputs: Arc<Inputs>,
    /// What is made: the normal map, or the curvature map
    /// ([`crate::fit::curvature`]: streamed into an EXR file, else read
    /// whole). Default: normals.
    pub product: Product,
    /// The curvature that maps to white in an 8- or 16-bit curvature map
    /// ([`crate::fit::quadratic::encode`]), in the fit's units. Default:
    /// [`crate::fit::quadratic::DEFAULT_RANGE`].
    pub curvature_range: f64,
    /// A slope map's units ([`Product::Slope`]). Default: degrees.
    pub slope_units: SlopeUnits,
    /// An aspect map's value for a flat texel ([`Product::Aspect`]): 0,
    /// else [`crate::units::NODATA`] as gdaldem writes. Default: off.
    pub zero_for_flat: bool,
    /// The sun of a hillshade ([`Product::Hillshade`]). Default: gdaldem's,
    /// from 315° at 45°.
    pub sun: Sun,
}

impl Default for Conversion {
    fn default() -> Self {
        let fit = Options::new();
        Conversion {
            borders: fit.borders.into(),
            fit,
            read: ReadOptions::default(),
            channel: None,
            format: None,
            bits: None,
            signed: false,
            compression: PngCompression::Fast,
            layout: Layout::Rgb,
            residual: false,
            map_units: None,
            replace: Replace::Always,
            mips: None,
            compress: None,
            roughness: false,
            roughness_base: None,
            inputs: Arc::default(),
            product: Product::Normals,
            curvature_range: crate::fit::quadratic::DEFAULT_RANGE,
            slope_units: SlopeUnits::default(),
            zero_for_flat: false,
            sun: Sun::default(),
        }
    }
}

impl Conversion {
    /// The defaults.
    #[must_use]
    pub fn new() -> Conversion {
        Conversion::default()
    }

    /// With this fit, its borders fixed as they are.
    #[must_use]
    pub fn with_fit(mut self, fit: Options) -> Conversion {
        self.borders = fit.borders.into();
        self.fit = fit;
        self
    }

    /// With these border choices.
    #[must_use]
    pub fn with_borders(mut self, borders: BorderChoices) -> Conversion {
        self.borders = borders;
        self
    }

    /// With these read options.
    #[must_use]
    pub fn with_read(mut self, read: ReadOptions) -> Conversion {
        self.read = read;
        self
    }

    /// Reading the height from this channel.
    #[must_use]
    pub fn with_channel(mut self, channel: Option<Channel>) -> Conversion {
        self.channel = channel;
        self
    }

    /// Writing this format when the output's name does not say.
    #[must_use]
    pub fn with_format(mut self, format: Option<OutputFormat>) -> Conversion {
        self.format = format;
        self
    }

    /// With this many bits a sample.
    #[must_use]
    pub fn with_bits(mut self, bits: u8) -> Conversion {
        self.bits = Some(bits);
        self
    }

    /// Storing n itself in an EXR (`true`) or (n + 1)/2.
    #[must_use]
    pub fn with_signed(mut self, signed: bool) -> Conversion {
        self.signed = signed;
        self
    }

    /// With this PNG compression.
    #[must_use]
    pub fn with_compression(mut self, compression: PngCompression) -> Conversion {
        self.compression = compression;
        self
    }

    /// With these channels.
    #[must_use]
    pub fn with_layout(mut self, layout: Layout) -> Conversion {
        self.layout = layout;
        self
    }

    /// Fitting in map units, the spacing from the file
    /// ([`MapSpacing::FromFile`]) or given; `None` for the contract's.
    #[must_use]
    pub fn with_map_units(mut self, map_units: Option<MapSpacing>) -> Conversion {
        self.map_units = map_units;
        self
    }

    /// Which existing files the outputs may replace.
    #[must_use]
    pub fn with_replace(mut self, replace: Replace) -> Conversion {
        self.replace = replace;
        self
    }

    /// Making a mip chain (`Some`), fitted, averaged or as the input
    /// says; `None`: the finest level alone.
    #[must_use]
    pub fn with_mips(mut self, mips: Option<MipChoice>) -> Conversion {
        self.mips = mips;
        self
    }

    /// Storing a `.dds` or `.ktx2` output's normals so (`None`: BC5).
    #[must_use]
    pub fn with_compress(mut self, compress: Option<TextureCompression>) -> Conversion {
        self.compress = compress;
        self
    }

    /// Making the roughness chain too, from this base roughness (`None`:
    /// 0) if given.
    #[must_use]
    pub fn with_roughness(mut self, roughness: bool, base: Option<PathBuf>) -> Conversion {
        self.roughness = roughness;
        self.roughness_base = base;
        self
    }

    /// Never writing over any of `inputs` (a batch's inputs).
    #[must_use]
    pub fn with_inputs(mut self, inputs: Arc<Inputs>) -> Conversion {
        self.inputs = inputs;
        self
    }

    /// Making this product (the normal map, or the curvature map).
    #[must_use]
    pub fn with_product(mut self, product: Product) -> Conversion {
        self.product = product;
        self
    }

    /// The curvature that maps to white in an 8- or 16-bit curvature map
    /// (finite and positive: checked when the map is written).
    #[must_use]
    pub fn with_curvature_range(mut self, range: f64) -> Conversion {
        self.curvature_range = range;
        self
    }

    /// A slope map in these units.
    #[must_use]
    pub fn with_slope_units(mut self, units: SlopeUnits) -> Conversion {
        self.slope_units = units;
        self
    }

    /// An aspect map with 0 (`true`) or [`crate::units::NODATA`] where the
    /// surface is flat.
    #[must_use]
    pub fn with_zero_for_flat(mut self, zero: bool) -> Conversion {
        self.zero_for_flat = zero;
        self
    }

    /// A hillshade under this sun.
    #[must_use]
    pub fn with_sun(mut self, sun: Sun) -> Conversion {
        self.sun = sun;
        self
    }

    /// Making the residual map too (read whole).
    #[must_use]
    pub fn with_residual(mut self, residual: bool) -> Conversion {
        self.residual = residual;
        self
    }

    /// Opens `input`: a file that streams by its header alone, anything
    /// else read and decoded whole.
    ///
    /// Errors (all [`Place::Input`]): those of reading and decoding
    /// ([`crate::io::read_path`], [`crate::io::decode`]).
    pub fn open(&self, input: Input<'_>) -> Result<Opened, ConvertError> {
        // A residual map is made from the whole image (the engine reads
        // whole what else its stage needs whole).
        let may_stream = !self.residual && self.mips.is_none();
        let source = engine::Source::open(input, &self.read, self.channel.clone(), may_stream)
            .map_err(ConvertError::at(Place::Input))?;
        Ok(Opened { conversion: self.clone(), source })
    }

    /// Converts the file `input` to the file `output` (its format by its
    /// extension, else [`Conversion::format`], else the input's).
    ///
    /// Errors: those of [`Conversion::open`], [`Opened::encoding`] and
    /// [`Opened::write`].
    pub fn convert_file(&self, input: &Path, output: &Path) -> Result<Summary, ConvertError> {
        self.convert(Input::Path(input), Output::file(output))
    }

    /// Converts `input` to `output`; a residual map, if asked for, goes
    /// beside a file output as `<stem>_residual.<ext>` (an error for a
    /// writer: use [`Opened::write`]).
    ///
    /// Errors: as [`Conversion::convert_file`].
    pub fn convert(&self, input: Input<'_>, output: Output<'_>) -> Result<Summary, ConvertError> {
        let opened = self.open(input)?;
        let encoding = opened.encoding(output.path())?;
        let residual_path = match (self.residual, output.path()) {
            (false, _) => None,
            (true, Some(path)) => {
                let stem = path.file_stem().map_or_else(|| "image".into(), |s| s.to_string_lossy().into_owned());
                Some(path.with_file_name(format!("{stem}_residual.{}", encoding.format().extension())))
            }
            (true, None) => {
                return Err(ConvertError {
                    place: Place::Residual,
                    error: Error::InvalidOption("a residual map beside a writer needs its own output".into()),
                });
            }
        };
        let residual = residual_path.as_deref().map(|p| (Output::file(p), encoding.format()));
        opened.write(&encoding, Some(output), residual, &())
    }
}

/// An input opened for conversion: its format and samples are known, its
/// rows not yet read (streaming) or decoded whole.
pub struct Opened {
    /// The choices, a copy of the conversion's (a few small values).
    conversion: Conversion,
    source: engine::Source,
}

impl Opened {
    /// The format read.
    #[must_use]
    pub fn input_format(&self) -> &InputFormat {
        self.source.format()
    }

    /// The input's samples.
    #[must_use]
    pub fn sample(&self) -> SampleType {
        self.source.sample()
    }

    /// Whether the conversion streams.
    #[must_use]
    pub fn streams(&self) -> bool {
        self.source.streams()
    }

    /// The normal map's encoding for an output named `path` (`None`: a
    /// writer), by the conversion's options and this input.
    ///
    /// Errors ([`Place::Output`]): those of [`OutputFormat::choose`] and
    /// [`Encoding::choose`].
    pub fn encoding(&self, path: Option<&Path>) -> Result<Encoding, ConvertError> {
        let (c, sample) = (&self.conversion, self.sample());
        OutputFormat::choose(path, c.format, (self.input_format(), sample))
            .and_then(|format| product_bits(c, format).map(|bits| (format, bits)))
            .and_then(|(format, bits)| match (format.container(), c.compress) {
                (Some(container), compress) => {
                    TextureOptions::choose(container, compress, c.bits, c.signed, c.layout).map(Encoding::Texture)
                }
                (None, Some(compress)) => Err(Error::InvalidOption(format!(
                    "compression {compress} is for GPU textures: name the output .dds or .ktx2"
                ))),
                (None, None) => Encoding::choose(format, bits, c.signed, c.layout, c.compression, sample),
            })
            .and_then(|encoding| match (c.roughness || c.roughness_base.is_some(), c.mips, encoding) {
                (true, None, _) => {
                    Err(Error::InvalidOption("a roughness chain is made beside a mip chain: ask for mips".into()))
                }
                // In map units the alpha holds the heights as stored (a
                // DEM's metres): integer samples would clamp them all to 1.
                _ if c.map_units.is_some()
                    && encoding.layout() == Layout::RgbHeight
                    && !encoding.has_float_samples() =>
                {
                    Err(Error::Unsupported(format!(
                        "an alpha of heights in map units holds the heights as stored (a DEM's metres), which integer \
                         samples ({}) clamp to [0, 1]: write EXR or a float TIFF (--bits 32)",
                        encoding.format()
                    )))
                }
                _ => Ok(encoding),
            })
            .map_err(ConvertError::at(Place::Output))
    }

    /// Every file the normal map written at `path` with `encoding` makes,
    /// `path` first: a mip chain's levels written as images
    /// (`<stem>_mip<k>.<ext>`, [`level_path`]) and its roughness
    /// ([`roughness_path`], and its levels) too; the residual and
    /// georeferencing sidecars aside. What a caller claims before it
    /// writes (the command line: no two inputs of a batch write one file),
    /// and what [`Conversion::replace`] and [`Conversion::inputs`] are
    /// checked against.
    #[must_use]
    pub fn outputs(&self, encoding: &Encoding, path: &Path) -> Vec<PathBuf> {
        let c = &self.conversion;
        let texture = matches!(encoding, Encoding::Texture(_));
        if c.mips.is_none() && !texture {
            return vec![path.to_path_buf()];
        }
        let (width, height) = self.source.size();
        let count = if c.mips.is_some() { crate::mips::level_sizes(width, height).len() } else { 1 };
        let roughness = c.roughness || c.roughness_base.is_some();
        engine::chain_files(path, texture, count, roughness).into_iter().map(|(p, _)| p).collect()
    }

    /// Converts: the normal map to `normals` with `encoding` (see
    /// [`Opened::encoding`]), and the residual (if the conversion makes
    /// one) to `residual` in its format. Either may be left out (an output
    /// that is already there, say), not both. `observer` hears of progress
    /// and warnings.
    ///
    /// Errors: [`Place::Input`] for reading, decoding and the fit;
    /// [`Place::Output`] or [`Place::Residual`] for memory checks, encoding
    /// and writing ([`Error::InvalidOption`] for a file output that is the
    /// input, or a residual the conversion does not make).
    pub fn write(
        self,
        encoding: &Encoding,
        normals: Option<Output<'_>>,
        residual: Option<(Output<'_>, OutputFormat)>,
        observer: &dyn Observer,
    ) -> Result<Summary, ConvertError> {
        if residual.is_some() && !self.conversion.residual {
            let problem = "this conversion makes no residual map (Conversion::with_residual)";
            return Err(ConvertError { place: Place::Residual, error: Error::InvalidOption(problem.into()) });
        }
        let Opened { conversion: c, source } = self;
        let settings = Settings {
            fit: c.fit.clone(),
            borders: c.borders,
            read: &c.read,
            channel: c.channel.clone(),
            map_units: c.map_units,
            replace: c.replace,
            roughness_base: c.roughness_base.as_deref(),
            inputs: c.inputs.clone(),
        };
        let product = c.product;
        if c.residual && matches!(product, Product::Slope | Product::Aspect | Product::Hillshade) {
            let problem = format!("a residual map is made beside normals, not beside a {product} map");
            return Err(ConvertError { place: Place::Residual, error: Error::InvalidOption(problem) });
        }
        let stage = match (c.product, c.mips, encoding) {
            (Product::Slope | Product::Aspect | Product::Hillshade, Some(_), _) => {
                let problem = format!("a {product} map has no mip chain: leave out the mips");
                return Err(ConvertError { place: Place::Output, error: Error::InvalidOption(problem) });
            }
            (Product::Slope | Product::Aspect, None, encoding) => {
                let measure = match product {
                    Product::Slope => Measure::Slope(c.slope_units),
                    _ => Measure::Aspect { zero_for_flat: c.zero_for_flat },
                };
                let float32 = match encoding {
                    Encoding::Exr(o) => o.depth == crate::io::ExrDepth::Float,
                    Encoding::Tiff(o) => o.depth == crate::io::encoding::TiffDepth::Float,
                    Encoding::Png(_) | Encoding::Texture(_) => false,
                };
                if !float32 {
                    let problem = format!("a {product} map is float32: write .tif or .exr with 32 bits");
                    return Err(ConvertError { place: Place::Output, error: Error::Unsupported(problem) });
                }
                Stage::Terrain { measure, encoding: *encoding }
            }
            (Product::Hillshade, None, encoding) => {
                let tiff = match encoding {
                    Encoding::Tiff(o) if o.depth == crate::io::encoding::TiffDepth::Eight => true,
                    Encoding::Png(o) if o.depth == crate::io::PngDepth::Eight => false,
                    _ => {
                        let problem = "a hillshade is 8-bit grey, as gdaldem writes it: write .tif or .png with 8 bits";
                        return Err(ConvertError { place: Place::Output, error: Error::Unsupported(problem.into()) });
                    }
                };
                let lighting = crate::light::Lighting {
                    light: crate::light::Light::default(),
                    sun: crate::light::SunChoice::Always(c.sun),
                };
                Stage::Lit { lighting, tile: false, tiff }
            }
            (Product::Curvature, Some(_), _) => {
                let problem = "a curvature map has no mip chain: leave out the mips";
                return Err(ConvertError { place: Place::Output, error: Error::InvalidOption(problem.into()) });
            }
            (Product::Curvature, None, _) => {
                let range = crate::fit::quadratic::validate_range(c.curvature_range)
                    .map_err(ConvertError::at(Place::Output))?;
                Stage::Curvature { encoding: *encoding, range }
            }
            (_, None, Encoding::Texture(_)) | (_, Some(_), _) => Stage::Mips(MipStage {
                choice: c.mips.unwrap_or_default(),
                all: c.mips.is_some(),
                encoding: *encoding,
                roughness: c.roughness || c.roughness_base.is_some(),
            }),
            (_, None, _) => Stage::Normals(*encoding),
        };
        let sink = Sink { main: normals, residual };
        engine::run(source, stage, sink, settings, observer).map(|(summary, _)| summary)
    }
}

/// The bits a sample of `format` has for the conversion's product: the
/// caller's, else a slope's or an aspect's float32 and a hillshade's 8.
///
/// Errors ([`Error::Unsupported`]): a product's format that cannot hold
/// it (a slope in PNG, a hillshade in EXR), or channels other than one
/// asked of it.
fn product_bits(c: &Conversion, format: OutputFormat) -> Result<Option<u8>, Error> {
    let product = c.product;
    let (formats, bits) = match product {
        Product::Slope | Product::Aspect => ([OutputFormat::Tiff, OutputFormat::Exr], 32),
        Product::Hillshade => ([OutputFormat::Tiff, OutputFormat::Png], 8),
        _ => return Ok(c.bits),
    };
    if !formats.contains(&format) {
        return Err(Error::Unsupported(format!(
            "a {product} map is written as .{} or .{}, not .{}",
            formats[0].extension(),
            formats[1].extension(),
            format.extension()
        )));
    }
    if c.layout != Layout::Rgb {
        return Err(Error::InvalidOption(format!("a {product} map has one channel: leave out --alpha and --channels")));
    }
    Ok(Some(c.bits.unwrap_or(bits)))
}
