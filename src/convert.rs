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
//!   ([`io::check_memory`]): running out is an error, never an abort;
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

use std::fmt;
use std::io::{Cursor, Read, Seek, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::encoding::{TiffDepth, TiffOptions};
use crate::io::read::georef::holes_value;
use crate::io::write::TiffTags;
use crate::io::{
    self, Channel, Encoding, ExrDepth, ExrOptions, Georef, InputFormat, Layout, OutputFormat, PngCompression, PngDepth,
    PngOptions, Raster, ReadOptions, SampleType,
};
#[cfg(feature = "tiff")]
use crate::pipeline::TiffRows;
use crate::pipeline::{self, ExrRows, PngRows, RowSource};
use crate::samples::try_vec;
use crate::tiling::{HeightSeams, KindChoice, TilingOptions, TilingReport};
use crate::units::MapSpacing;
use crate::{Border, Borders, FromNormal, Options, Samples};

/// One axis's border mode: as given, or chosen by the tiling check.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BorderChoice {
    /// This mode, whatever the image.
    Fixed(Border),
    /// Wrap if the image tiles along the axis, else mirror.
    Auto,
}

/// The border choice of each axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BorderChoices {
    /// Left and right.
    pub x: BorderChoice,
    /// Top and bottom.
    pub y: BorderChoice,
}

impl BorderChoices {
    /// The same choice on both axes.
    #[must_use]
    pub fn both(choice: BorderChoice) -> BorderChoices {
        BorderChoices { x: choice, y: choice }
    }

    /// The modes themselves, for what was made with known borders (a
    /// normal map going back to heights): `auto` names no mode.
    ///
    /// Errors: [`Error::InvalidOption`] when an axis is `auto`.
    pub fn fixed(&self) -> Result<Borders> {
        match (self.x, self.y) {
            (BorderChoice::Fixed(x), BorderChoice::Fixed(y)) => Ok(Borders { x, y }),
            _ => Err(Error::InvalidOption(
                "border of a normal map names the modes it was made with (wrap, clamp, mirror), not auto".into(),
            )),
        }
    }

    /// Whether an axis is [`BorderChoice::Auto`].
    #[must_use]
    pub fn any_auto(&self) -> bool {
        self.x == BorderChoice::Auto || self.y == BorderChoice::Auto
    }

    /// Whether these borders need the tiling check: a wrap (to warn when
    /// it draws a seam) or `auto`.
    #[must_use]
    pub fn needs_check(&self) -> bool {
        let check = |c: BorderChoice| matches!(c, BorderChoice::Auto | BorderChoice::Fixed(Border::Wrap));
        check(self.x) || check(self.y)
    }

    /// The border modes for one image: `auto` becomes wrap where the image
    /// tiles and mirror where it does not (`report`: the tiling check;
    /// without it, `auto` is mirror).
    #[must_use]
    pub fn resolve(&self, report: Option<&TilingReport>) -> Borders {
        let suggested = report.map_or(Borders::both(Border::Mirror), TilingReport::suggested_borders);
        let resolve = |asked: BorderChoice, auto: Border| match asked {
            BorderChoice::Fixed(b) => b,
            BorderChoice::Auto => auto,
        };
        Borders { x: resolve(self.x, suggested.x), y: resolve(self.y, suggested.y) }
    }

    /// The border modes for heights held in memory (`width` × `height`,
    /// row-major, any [`Sample`](crate::Sample) type): `auto` settled by
    /// the tiling check of a height map, as a conversion settles it;
    /// fixed modes as they are, without a check.
    ///
    /// Errors: those of [`HeightSeams`] (the memory for the check, heights
    /// that are not `width` × `height`).
    pub fn settle<H: crate::Sample>(&self, heights: &[H], width: usize, height: usize) -> Result<Borders> {
        if !self.any_auto() {
            return Ok(self.resolve(None));
        }
        if Some(heights.len()) != width.checked_mul(height) {
            return Err(Error::BufferSize { expected: width.saturating_mul(height), actual: heights.len() });
        }
        let mut seams = HeightSeams::new(width, height)?;
        seams.push_heights(heights)?;
        Ok(self.resolve(Some(&seams.finish(&TilingOptions::new().with_kind(KindChoice::Height))?)))
    }

    /// The warning about a wrap asked for on an axis that does not tile
    /// (it draws a seam there), if there is one.
    #[must_use]
    pub fn seams(&self, report: &TilingReport) -> Option<Warning> {
        let wrap = BorderChoice::Fixed(Border::Wrap);
        let seam = |asked: BorderChoice, axis: crate::tiling::AxisReport| {
            (asked == wrap && !axis.seamless).then_some(axis.score)
        };
        let (x, y) = (seam(self.x, report.x), seam(self.y, report.y));
        (x.is_some() || y.is_some()).then_some(Warning::Seams { x, y })
    }
}

impl std::str::FromStr for BorderChoice {
    type Err = Error;

    /// A [`Border`]'s name, or `auto`.
    fn from_str(s: &str) -> Result<Self> {
        if s.trim().eq_ignore_ascii_case("auto") {
            return Ok(BorderChoice::Auto);
        }
        s.parse::<Border>().map(BorderChoice::Fixed).map_err(|_| {
            let names: Vec<&str> = Border::ALL.iter().map(|b| b.name()).chain(["auto"]).collect();
            Error::InvalidOption(format!("unknown border mode '{}': use {}", s.trim(), crate::options::one_of(&names)))
        })
    }
}

impl std::str::FromStr for BorderChoices {
    type Err = Error;

    /// One choice for both axes (`mirror`), or x then y (`wrap,auto`).
    fn from_str(s: &str) -> Result<Self> {
        match s.split_once(',') {
            None => Ok(BorderChoices::both(s.parse()?)),
            Some((x, y)) => Ok(BorderChoices { x: x.parse()?, y: y.parse()? }),
        }
    }
}

impl From<Borders> for BorderChoices {
    fn from(b: Borders) -> Self {
        BorderChoices { x: BorderChoice::Fixed(b.x), y: BorderChoice::Fixed(b.y) }
    }
}

/// Something the caller may want to tell its user; the work went on.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Warning {
    /// A wrap was asked for along an axis that does not tile, so the
    /// normal map shows a seam there: the seam scores of those axes.
    Seams {
        /// The seam score along x, if x wraps and does not tile.
        x: Option<f64>,
        /// The seam score along y, if y wraps and does not tile.
        y: Option<f64>,
    },
    /// The tiling check, which only warns here, was skipped: its memory
    /// was not there (a conversion of an image 2^24 texels wide can fit
    /// where its check does not).
    SeamCheckSkipped(String),
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Warning::Seams { x, y } => {
                let axes: Vec<String> = [("x", x), ("y", y)]
                    .iter()
                    .filter_map(|(name, score)| score.map(|s| format!("{name} (seam score {s:.2})")))
                    .collect();
                write!(f, "does not tile along {}: wrap borders will show a seam there", axes.join(" and "))
            }
            Warning::SeamCheckSkipped(why) => write!(f, "seam check skipped: {why}"),
        }
    }
}

/// Which file an error concerns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Place {
    /// The height map read.
    Input,
    /// The normal map written.
    Output,
    /// The residual map written.
    Residual,
}

/// An error of a conversion, and which file it concerns.
#[derive(Debug)]
pub struct ConvertError {
    /// The file at fault.
    pub place: Place,
    /// What went wrong.
    pub error: Error,
}

impl ConvertError {
    fn at(place: Place) -> impl Fn(Error) -> ConvertError {
        move |error| ConvertError { place, error }
    }
}

impl fmt::Display for ConvertError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.error.fmt(f)
    }
}

impl std::error::Error for ConvertError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.error)
    }
}

impl From<ConvertError> for Error {
    fn from(e: ConvertError) -> Self {
        e.error
    }
}

/// Hears about a conversion as it goes (a progress bar, a log). Every
/// method does nothing unless overridden; `()` is the observer that
/// listens to nothing.
pub trait Observer: Sync {
    /// A streamed conversion of a `width` × `height` image starts.
    fn size(&self, _width: usize, _height: usize) {}
    /// A streamed conversion decoded one more row (called from another
    /// thread than the caller's).
    fn row(&self) {}
    /// A warning, when it arises (also in the [`Summary`]).
    fn warning(&self, _warning: &Warning) {}
}

impl Observer for () {}

/// A height map to convert.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub enum Input<'a> {
    /// A file, read by content. PNG and scan-line EXR files stream.
    Path(&'a Path),
    /// An encoded image in memory (see [`read_all`] for a reader).
    Bytes(&'a [u8]),
}

/// Where a map goes.
#[non_exhaustive]
pub enum Output<'a> {
    /// A file, written atomically: a new file beside it, given its name
    /// once complete. Never the input file.
    File {
        /// The file.
        path: &'a Path,
        /// Create its folder (and those above) if missing.
        create_folder: bool,
    },
    /// Any writer (a pipe, a socket, a buffer): formats that must seek
    /// (EXR) are assembled in memory first, checked against the memory
    /// limits.
    Writer(&'a mut dyn Write),
}

impl<'a> Output<'a> {
    /// The file at `path`, in a folder that exists.
    #[must_use]
    pub fn file(path: &'a Path) -> Output<'a> {
        Output::File { path, create_folder: false }
    }

    fn path(&self) -> Option<&'a Path> {
        match self {
            Output::File { path, .. } => Some(path),
            Output::Writer(_) => None,
        }
    }
}

/// What a conversion did.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct Summary {
    /// Columns of the image.
    pub width: usize,
    /// Rows of the image.
    pub height: usize,
    /// The format read.
    pub input_format: InputFormat,
    /// The input's samples.
    pub sample: SampleType,
    /// How the normal map was encoded.
    pub encoding: Encoding,
    /// The border modes the fit used (`auto` settled).
    pub borders: Borders,
    /// Whether the rows streamed (else the image was read whole).
    pub streamed: bool,
    /// The tiling check, when the borders needed it and it ran.
    pub tiling: Option<TilingReport>,
    /// The warnings, in order.
    pub warnings: Vec<Warning>,
    /// The georeferencing files written beside a PNG normal map of a
    /// GeoTIFF ([`io::sidecar`]): its world file, and its `.aux.xml` when
    /// the GeoTIFF names an EPSG code.
    pub sidecars: Vec<PathBuf>,
    /// The nodata value the conversion used (the fit's, else the
    /// GeoTIFF's GDAL_NODATA tag), if any: the map then has holes, and an
    /// alpha of validity ([`Layout::RgbValid`]).
    pub nodata: Option<f64>,
    /// Missing texels (holes, and texels whose valid points do not
    /// determine a plane): alpha 0 in the map. 0 without a nodata value.
    pub missing: usize,
}

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
    /// the file or given; `None`: the contract's units. The image is then
    /// read whole, and its heights taken as stored
    /// ([`Raster::into_stored_heights`]). The fit's own
    /// [`Options::units`] are replaced by what this gives.
    pub map_units: Option<MapSpacing>,
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
    /// ([`io::read_path`], [`io::decode`]).
    pub fn open(&self, input: Input<'_>) -> Result<Opened, ConvertError> {
        let fail = ConvertError::at(Place::Input);
        // Map units read the image whole: its georeferencing and stored
        // values come with the raster.
        if let (Input::Path(path), false, None) = (input, self.residual, self.map_units) {
            if let Some(rows) = PngRows::open(path, &self.read, self.channel.clone()).map_err(&fail)? {
                let bits = if rows.more_than_8_bits() { 16 } else { 8 };
                return Ok(self.opened(
                    Some(path),
                    Source::Png(Box::new(rows), path.to_path_buf()),
                    InputFormat::Png,
                    SampleType::Int { bits },
                ));
            }
            if let Some(rows) = ExrRows::open(path, &self.read, self.channel.clone()).map_err(&fail)? {
                return Ok(self.opened(
                    Some(path),
                    Source::Exr(Box::new(rows), path.to_path_buf()),
                    InputFormat::Exr,
                    SampleType::Float,
                ));
            }
            #[cfg(feature = "tiff")]
            if let Some(rows) = TiffRows::open(path, &self.read, self.channel.clone()).map_err(&fail)? {
                let sample = rows.sample();
                return Ok(self.opened(
                    Some(path),
                    Source::Tiff(Box::new(rows), path.to_path_buf()),
                    InputFormat::Tiff,
                    sample,
                ));
            }
        }
        let (path, raster) = match input {
            Input::Path(path) => (Some(path), io::read_path(path, &self.read).map_err(&fail)?),
            Input::Bytes(bytes) => (None, io::decode(bytes, &self.read).map_err(&fail)?),
        };
        let (format, sample) = (raster.format.clone(), raster.sample);
        Ok(self.opened(path, Source::Whole(Box::new(raster)), format, sample))
    }

    fn opened(&self, path: Option<&Path>, source: Source, format: InputFormat, sample: SampleType) -> Opened {
        Opened { conversion: self.clone(), path: path.map(Path::to_path_buf), source, format, sample }
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

/// Reads `reader` to its end, growing the buffer fallibly: an input too
/// large for the memory the process may take is an error, not an abort.
/// The bytes are for [`Input::Bytes`].
///
/// Errors: [`Error::Limits`] when the memory runs out, [`Error::Io`].
pub fn read_all(mut reader: impl Read) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes).map_err(|e| match e.kind() {
        std::io::ErrorKind::OutOfMemory => Error::Limits(format!(
            "the input is read whole, and {} MiB of it already fill the memory the process may take",
            bytes.len() >> 20
        )),
        _ => e.into(),
    })?;
    Ok(bytes)
}

/// Where an opened input's heights come from.
enum Source {
    /// A PNG file that streams, and its path. The decoders are boxed:
    /// their state is large beside a raster's.
    Png(Box<PngRows>, PathBuf),
    /// A scan-line EXR file that streams, and its path.
    Exr(Box<ExrRows>, PathBuf),
    /// A TIFF band that streams, and its path.
    #[cfg(feature = "tiff")]
    Tiff(Box<TiffRows>, PathBuf),
    /// A decoded image, boxed for the same reason in reverse: a GeoTIFF's
    /// georeferencing makes a raster several times a decoder's box.
    Whole(Box<Raster>),
}

/// An input opened for conversion: its format and samples are known, its
/// rows not yet read (streaming) or decoded whole.
pub struct Opened {
    /// The choices, a copy of the conversion's (a few small values).
    conversion: Conversion,
    path: Option<PathBuf>,
    source: Source,
    format: InputFormat,
    sample: SampleType,
}

impl Opened {
    /// The format read.
    #[must_use]
    pub fn input_format(&self) -> &InputFormat {
        &self.format
    }

    /// The input's samples.
    #[must_use]
    pub fn sample(&self) -> SampleType {
        self.sample
    }

    /// Whether the conversion streams.
    #[must_use]
    pub fn streams(&self) -> bool {
        !matches!(self.source, Source::Whole(_))
    }

    /// The normal map's encoding for an output named `path` (`None`: a
    /// writer), by the conversion's options and this input.
    ///
    /// Errors ([`Place::Output`]): those of [`OutputFormat::choose`] and
    /// [`Encoding::choose`].
    pub fn encoding(&self, path: Option<&Path>) -> Result<Encoding, ConvertError> {
        let c = &self.conversion;
        OutputFormat::choose(path, c.format, (&self.format, self.sample))
            .and_then(|format| Encoding::choose(format, c.bits, c.signed, c.layout, c.compression, self.sample))
            .map_err(ConvertError::at(Place::Output))
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
        let Opened { mut conversion, path, source, format, sample } = self;
        let georef = match &source {
            Source::Whole(raster) => raster.georef.clone(),
            #[cfg(feature = "tiff")]
            Source::Tiff(rows, _) => rows.georef().cloned(),
            _ => None,
        };
        // Holes: the nodata value given, else the GeoTIFF's own; the map
        // then says which texels are missing in its alpha.
        let nodata = holes_value(conversion.fit.nodata, georef.as_ref());
        conversion.fit.nodata = nodata;
        let encoding = &match nodata {
            Some(_) => encoding.with_layout(encoding.layout().with_holes()),
            None => *encoding,
        };
        let mut job = Job {
            conversion: &conversion,
            input: path.as_deref(),
            encoding: *encoding,
            georef: georef.as_ref(),
            observer,
            summary: Summary {
                width: 0,
                height: 0,
                input_format: format,
                sample,
                encoding: *encoding,
                borders: conversion.fit.borders,
                streamed: false,
                tiling: None,
                warnings: Vec::new(),
                sidecars: Vec::new(),
                nodata,
                missing: 0,
            },
        };
        // Beside a PNG file: GDAL reads no EXR here, a TIFF holds its own
        // tags, and a writer has no name.
        let sidecar_of = match (&normals, encoding) {
            (Some(Output::File { path, .. }), Encoding::Png(_)) => georef.as_ref().map(|g| (path.to_path_buf(), g)),
            _ => None,
        };
        match (source, normals) {
            (Source::Whole(raster), normals) => job.whole(*raster, normals, residual)?,
            (_, None) => {
                let problem = "nothing to write: no output given";
                return Err(ConvertError { place: Place::Output, error: Error::InvalidOption(problem.into()) });
            }
            (Source::Png(rows, input), Some(out)) => job.streaming(*rows, &input, out)?,
            (Source::Exr(rows, input), Some(out)) => job.streaming(*rows, &input, out)?,
            #[cfg(feature = "tiff")]
            (Source::Tiff(rows, input), Some(out)) => job.streaming(*rows, &input, out)?,
        }
        if let Some((path, georef)) = sidecar_of {
            job.summary.sidecars =
                io::sidecar::write_sidecars(&path, georef).map_err(ConvertError::at(Place::Output))?;
        }
        Ok(job.summary)
    }
}

/// One conversion under way.
struct Job<'a> {
    conversion: &'a Conversion,
    /// The input file, which no output may replace.
    input: Option<&'a Path>,
    encoding: Encoding,
    /// The input's georeferencing, which a TIFF output keeps.
    georef: Option<&'a Georef>,
    observer: &'a dyn Observer,
    summary: Summary,
}

impl Job<'_> {
    /// What a TIFF output holds besides its samples: the input's
    /// georeferencing.
    fn tiff_tags(&self) -> TiffTags<'_> {
        TiffTags { georef: self.georef, nodata: None }
    }

    fn warn(&mut self, warning: Warning) {
        self.observer.warning(&warning);
        self.summary.warnings.push(warning);
    }

    /// The streamed tiling check of a `width` × `height` image, or `None`
    /// with a warning when its memory is not there: the check only warns
    /// about a wrap that draws a seam. `auto` borders need its verdict, so
    /// there the lack of memory is an error.
    fn seam_check(&mut self, width: usize, height: usize) -> Result<Option<HeightSeams>, ConvertError> {
        match HeightSeams::new(width, height) {
            Ok(seams) => Ok(Some(seams)),
            Err(e) if self.conversion.borders.any_auto() => Err(ConvertError { place: Place::Input, error: e }),
            Err(e) => {
                self.warn(Warning::SeamCheckSkipped(e.to_string()));
                Ok(None)
            }
        }
    }

    /// Records the tiling check and warns about a wrap that draws a seam.
    fn judge(&mut self, report: TilingReport) {
        if let Some(warning) = self.conversion.borders.seams(&report) {
            self.warn(warning);
        }
        self.summary.tiling = Some(report);
    }

    /// Settles the borders (`auto` by the tiling check) and gives the
    /// fit's options.
    fn fit_options(&mut self) -> Options {
        let borders = self.conversion.borders.resolve(self.summary.tiling.as_ref());
        self.summary.borders = borders;
        self.conversion.fit.clone().with_borders(borders)
    }

    /// Refuses a file output that is the input file (or a link to it), and
    /// makes its folder if asked to.
    fn prepare(&self, output: &Output<'_>, place: Place) -> Result<(), ConvertError> {
        let Output::File { path, create_folder } = *output else { return Ok(()) };
        let fail = ConvertError::at(place);
        if let Some(input) = self.input
            && same_file(input, path)
        {
            return Err(fail(Error::InvalidOption(
                "the output is the input (or a link to it): normalfit never writes over an input".into(),
            )));
        }
        if let (true, Some(parent)) = (create_folder, path.parent())
            && !parent.as_os_str().is_empty()
        {
            std::fs::create_dir_all(parent).map_err(|e| {
                fail(Error::Io(std::io::Error::new(e.kind(), format!("cannot create the output folder: {e}"))))
            })?;
        }
        Ok(())
    }

    /// The whole-image conversion: the heights in memory, fitted straight
    /// into the output's texel type.
    fn whole(
        &mut self,
        raster: Raster,
        normals: Option<Output<'_>>,
        residual: Option<(Output<'_>, OutputFormat)>,
    ) -> Result<(), ConvertError> {
        let (width, height) = (raster.width, raster.height);
        (self.summary.width, self.summary.height) = (width, height);
        let conversion = self.conversion;
        let in_failure = ConvertError::at(Place::Input);
        let units = match &conversion.map_units {
            Some(map) => Some(map.units(raster.georef.as_ref(), height).map_err(&in_failure)?),
            None => None,
        };
        let mut fit_nodata = conversion.fit.nodata;
        let heights = match (units.is_some(), conversion.fit.nodata) {
            (stored, Some(nodata)) => {
                let channel = conversion.channel.clone();
                let (heights, nodata) = raster.into_heights_with_holes(channel, stored, nodata).map_err(&in_failure)?;
                fit_nodata = Some(nodata);
                heights
            }
            (true, None) => raster.into_stored_heights(conversion.channel.clone()).map_err(&in_failure)?,
            (false, None) => raster.into_heights(conversion.channel.clone()).map_err(&in_failure)?,
        };
        let report = match conversion.borders.needs_check() {
            true => match self.seam_check(width, height)? {
                Some(mut seams) => {
                    seams.push_samples(&heights).map_err(&in_failure)?;
                    Some(seams.finish(&TilingOptions::new().with_kind(KindChoice::Height)).map_err(&in_failure)?)
                }
                None => None,
            },
            false => None,
        };
        if let Some(report) = report {
            self.judge(report);
        }
        let mut fit = self.fit_options().with_nodata(fit_nodata);
        if let Some(units) = units {
            fit = fit.with_units(units);
        }
        // Named by the first output to be written.
        let first = if normals.is_some() { Place::Output } else { Place::Residual };
        let to_writer = matches!(normals, Some(Output::Writer(_)));
        check_encode_memory(&self.encoding, to_writer, normals.is_some(), residual.is_some(), width, height)
            .map_err(ConvertError::at(first))?;
        let mut distances = residual.as_ref().map(|_| zeroed::<f32>(heights.len())).transpose().map_err(&in_failure)?;
        let mut valid = match fit.nodata {
            Some(_) => Some(zeroed::<bool>(heights.len()).map_err(&in_failure)?),
            None => None,
        };
        let texels =
            Texels::fit(&heights, width, height, &fit, &self.encoding, distances.as_deref_mut(), valid.as_deref_mut())
                .map_err(&in_failure)?;
        self.summary.missing = valid.as_ref().map_or(0, |v| v.iter().filter(|&&v| !v).count());
        // An alpha of heights takes them in contract units, as f32; an
        // alpha of validity, 1 and 0.
        let heights = match (self.encoding.layout(), &valid) {
            (Layout::RgbValid, Some(valid)) => valid.iter().map(|&v| if v { 1.0 } else { 0.0 }).collect(),
            (Layout::RgbValid, None) => vec![1.0; width * height],
            (layout, _) if layout.needs_heights() => heights.into_f32().map_err(&in_failure)?,
            _ => Vec::new(),
        };
        let (encoding, tags) = (self.encoding, self.tiff_tags());
        if let Some(out) = normals {
            self.prepare(&out, Place::Output)?;
            write_to(out, |w| texels.encode(&heights, (width, height), &encoding, tags, w))
                .map_err(ConvertError::at(Place::Output))?;
        }
        if let (Some((out, format)), Some(distances)) = (residual, &distances) {
            self.prepare(&out, Place::Residual)?;
            let scale = fit.scale_for_width(width);
            write_to(out, |w| encode_residual(distances, (width, height), scale, (format, tags), w))
                .map_err(ConvertError::at(Place::Residual))?;
        }
        Ok(())
    }

    /// A PNG or scan-line EXR file converted without holding the image:
    /// rows stream from the decoder through the fit to the encoder. One
    /// pass over the input, but for a wrap in y into an output written in
    /// order (EXR, or PNG into a writer), which needs the image's last rows
    /// first: an EXR gives them from its last blocks, a PNG by a first
    /// pass; and for `auto` borders, whose borders depend on the tiling
    /// check, which then comes from a first pass too.
    fn streaming<S: Reopen>(&mut self, rows: S, input: &Path, out: Output<'_>) -> Result<(), ConvertError> {
        self.prepare(&out, Place::Output)?;
        self.summary.streamed = true;
        let conversion = self.conversion;
        let (read, channel) = (&conversion.read, || conversion.channel.clone());
        let in_failure = ConvertError::at(Place::Input);
        let (width, height, r) = (rows.width(), rows.height(), conversion.fit.patch / 2);
        (self.summary.width, self.summary.height) = (width, height);
        let borders = conversion.borders;
        let auto = borders.any_auto();
        let may_wrap_y = matches!(borders.y, BorderChoice::Auto | BorderChoice::Fixed(Border::Wrap));
        // A PNG file takes its top rows last, in room kept after the header.
        let png_file = matches!(out, Output::File { .. }) && matches!(self.encoding, Encoding::Png(_));
        let needs_tail = may_wrap_y && !png_file;
        let check_opts = TilingOptions::new().with_kind(KindChoice::Height);
        let cheap_tail = if needs_tail && !auto { S::last_rows(input, read, channel(), r) } else { None };
        let (report, tail) = match cheap_tail {
            Some(tail) => (None, Some(tail.map_err(&in_failure)?)),
            None if auto || needs_tail => {
                let first = S::reopen(input, read, channel()).map_err(&in_failure)?;
                let first =
                    first.ok_or_else(|| in_failure(std::io::Error::other("changed while being read").into()))?;
                let mut seams = self.seam_check(width, height)?;
                let tail = first
                    .read_tail(r, |row| {
                        // Whole rows from the decoder, at most `height` of
                        // them: the check takes every one.
                        if let Some(s) = seams.as_mut() {
                            let _ = s.push_row(row);
                        }
                    })
                    .map_err(&in_failure)?;
                (seams.map(|s| s.finish(&check_opts)).transpose().map_err(&in_failure)?, Some(tail))
            }
            None => (None, None),
        };
        // Without a first pass, the check runs on the rows as they stream
        // and the warning comes after the output.
        if let Some(report) = report {
            self.judge(report);
        }
        let fit = self.fit_options();
        // The nodata value as the rows hold it.
        let fit = fit.clone().with_nodata(fit.nodata.map(|v| rows.row_value(v)));
        let tail = if fit.borders.y == Border::Wrap { tail.as_deref() } else { None };
        let mut seams = match self.summary.tiling.is_none() && borders.needs_check() {
            true => self.seam_check(width, height)?,
            false => None,
        };
        let observer = self.observer;
        observer.size(width, height);
        let visit = |row: &[f32]| {
            observer.row();
            // Whole rows from the decoder, at most `height` of them: the
            // check takes every one.
            if let Some(s) = seams.as_mut() {
                let _ = s.push_row(row);
            }
        };
        // Decoding and fitting fail on the input; writing, on the output.
        let mut input_failed = false;
        let mut on_input = |e: &Error| {
            if !matches!(e, Error::Io(_) | Error::Encode(_)) {
                input_failed = true;
            }
        };
        let (w, h) = (width, height);
        let mut missing = 0;
        #[cfg(feature = "tiff")]
        let tags = self.tiff_tags();
        let result = match (out, self.encoding) {
            (Output::File { path, .. }, Encoding::Exr(options)) => io::write_file_atomically(path, |file| {
                missing = pipeline::convert_exr_counting(rows, tail, &fit, options, visit, file)
                    .inspect_err(&mut on_input)?;
                Ok(())
            }),
            (Output::Writer(writer), Encoding::Exr(options)) => {
                // EXR seeks back to its offset table: the file is assembled
                // first, and must leave the stream room to work.
                let mut bytes = InMemory::default();
                check_assembly_memory(&self.encoding, w, h)
                    .and_then(|()| pipeline::convert_exr_counting(rows, tail, &fit, options, visit, &mut bytes))
                    .inspect_err(&mut on_input)
                    .and_then(|m| {
                        missing = m;
                        write_all(writer, bytes.0.get_ref())
                    })
            }
            (Output::File { path, .. }, Encoding::Png(options)) => io::write_file_atomically(path, |file| {
                missing = pipeline::convert_png_seekable_counting(rows, &fit, options, visit, file)
                    .inspect_err(&mut on_input)?;
                Ok(())
            }),
            (Output::Writer(writer), Encoding::Png(options)) => {
                pipeline::convert_png_counting(rows, tail, &fit, options, visit, writer)
                    .inspect_err(&mut on_input)
                    .map(|m| missing = m)
            }
            #[cfg(feature = "tiff")]
            (Output::File { path, .. }, Encoding::Tiff(options)) => io::write_file_atomically(path, |file| {
                missing = pipeline::convert_tiff_counting(rows, tail, &fit, options, tags, visit, file)
                    .inspect_err(&mut on_input)?;
                Ok(())
            }),
            #[cfg(feature = "tiff")]
            (Output::Writer(writer), Encoding::Tiff(options)) => {
                // TIFF seeks back to its directory's offset: the file is
                // assembled first, as an EXR is.
                let mut bytes = InMemory::default();
                check_assembly_memory(&self.encoding, w, h)
                    .and_then(|()| pipeline::convert_tiff_counting(rows, tail, &fit, options, tags, visit, &mut bytes))
                    .inspect_err(&mut on_input)
                    .and_then(|m| {
                        missing = m;
                        write_all(writer, bytes.0.get_ref())
                    })
            }
            #[cfg(not(feature = "tiff"))]
            (_, Encoding::Tiff(_)) => Err(io::write::no_tiff()),
        };
        self.summary.missing = missing;
        let place = if input_failed { Place::Input } else { Place::Output };
        result.map_err(ConvertError::at(place))?;
        // A failed write stopped the rows part way: no seams to judge.
        if let Some(seams) = seams {
            self.judge(seams.finish(&check_opts).map_err(ConvertError::at(Place::Input))?);
        }
        Ok(())
    }
}

/// Writes to a file atomically, or assembles the bytes in memory (EXR
/// seeks while writing) and gives them to a writer.
pub(crate) fn write_to(out: Output<'_>, encode: impl FnOnce(&mut dyn WriteSeek) -> Result<()>) -> Result<()> {
    match out {
        // Into the file itself, which seeks as EXR needs: no copy of the
        // encoded image in memory.
        Output::File { path, .. } => io::write_file_atomically(path, |file| encode(file)),
        Output::Writer(writer) => {
            let mut bytes = InMemory::default();
            encode(&mut bytes)?;
            write_all(writer, bytes.0.get_ref())
        }
    }
}

/// A writer that seeks, as a trait object.
pub(crate) trait WriteSeek: Write + Seek {}
impl<T: Write + Seek> WriteSeek for T {}

/// Writes `bytes` and flushes.
fn write_all(writer: &mut dyn Write, bytes: &[u8]) -> Result<()> {
    writer.write_all(bytes)?;
    writer.flush()?;
    Ok(())
}

pub(crate) use crate::io::same_file;

/// A normal map fitted straight into the output's texel type.
enum Texels {
    Eight(Vec<[u8; 3]>),
    Sixteen(Vec<[u16; 3]>),
    /// The normals n, stored as the EXR options say when encoded.
    Float(Vec<[f32; 3]>),
}

impl Texels {
    /// Fits the normals for `encoding`; with `residual`, the fit's RMS
    /// distances too (in surface units).
    fn fit(
        heights: &Samples,
        w: usize,
        h: usize,
        opts: &Options,
        encoding: &Encoding,
        residual: Option<&mut [f32]>,
        valid: Option<&mut [bool]>,
    ) -> Result<Texels> {
        fn fitted<T: FromNormal + Default + Clone>(
            heights: &Samples,
            w: usize,
            h: usize,
            opts: &Options,
            residual: Option<&mut [f32]>,
            valid: Option<&mut [bool]>,
        ) -> Result<Vec<T>> {
            let mut texels = zeroed::<T>(heights.len())?;
            match (residual, valid) {
                (residual, Some(valid)) => {
                    heights.normals_masked_into((w, h), opts, &mut texels, residual, valid)?;
                }
                (Some(r), None) => heights.normals_and_residual_into(w, h, opts, &mut texels, r)?,
                (None, None) => heights.normals_into(w, h, opts, &mut texels)?,
            }
            Ok(texels)
        }
        Ok(match encoding {
            Encoding::Png(PngOptions { depth: PngDepth::Eight, .. }) => {
                Texels::Eight(fitted(heights, w, h, opts, residual, valid)?)
            }
            Encoding::Png(PngOptions { depth: PngDepth::Sixteen, .. }) => {
                Texels::Sixteen(fitted(heights, w, h, opts, residual, valid)?)
            }
            Encoding::Exr(_) | Encoding::Tiff(TiffOptions { depth: TiffDepth::Float, .. }) => {
                Texels::Float(fitted(heights, w, h, opts, residual, valid)?)
            }
            Encoding::Tiff(TiffOptions { depth: TiffDepth::Eight, .. }) => {
                Texels::Eight(fitted(heights, w, h, opts, residual, valid)?)
            }
            Encoding::Tiff(TiffOptions { depth: TiffDepth::Sixteen, .. }) => {
                Texels::Sixteen(fitted(heights, w, h, opts, residual, valid)?)
            }
        })
    }

    /// Encodes the map (`heights` for an alpha of heights; a TIFF with
    /// `tags`).
    fn encode(
        &self,
        heights: &[f32],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: &mut dyn WriteSeek,
    ) -> Result<()> {
        match self {
            Texels::Eight(t) => io::write::encode_normals_tagged(t, Some(heights), size, encoding, tags, out),
            Texels::Sixteen(t) => io::write::encode_normals_tagged(t, Some(heights), size, encoding, tags, out),
            Texels::Float(t) => io::write::encode_normals_tagged(t, Some(heights), size, encoding, tags, out),
        }
    }
}

/// Writes the residual map: the RMS distances (surface units) divided by
/// the gain |S|, so in height units; 0 where S = 0 (a flat surface). PNG:
/// 16-bit gray, 65535 · value clamped to [0, 1]; EXR: 32-bit float,
/// channel Y, the value as it is; TIFF: 32-bit float, the value as it is,
/// with `tags`.
fn encode_residual(
    distances: &[f32],
    (w, h): (usize, usize),
    scale: f64,
    (format, tags): (OutputFormat, TiffTags<'_>),
    out: &mut dyn WriteSeek,
) -> Result<()> {
    let per_height = if scale == 0.0 { 0.0 } else { 1.0 / scale.abs() };
    let values = distances.iter().map(|&d| f64::from(d) * per_height);
    match format {
        OutputFormat::Png => {
            let mut stored = zeroed::<u16>(distances.len())?;
            stored.iter_mut().zip(values).for_each(|(s, v)| *s = (v.clamp(0.0, 1.0) * 65535.0).round() as u16);
            io::encode_gray(&stored, w, h, &PngOptions::new(PngDepth::Sixteen).into(), out)
        }
        OutputFormat::Exr | OutputFormat::Tiff => {
            let mut stored = zeroed::<f32>(distances.len())?;
            stored.iter_mut().zip(values).for_each(|(s, v)| *s = v as f32);
            let encoding = match format {
                OutputFormat::Tiff => TiffOptions::new(TiffDepth::Float).into(),
                _ => ExrOptions::new(ExrDepth::Float).into(),
            };
            io::write::encode_gray_tagged(&stored, (w, h), &encoding, tags, out)
        }
    }
}

/// Refuses an encode that the memory limits leave no room for, before it
/// starts: past our own buffers the encoders allocate as they go, and a
/// failure there would abort the process. Bytes held per texel, from what
/// the encoders do:
/// * the normal map: 3, 6 or 12 (8-bit, 16-bit, float);
/// * PNG (c samples of s bytes a texel): the samples laid out, unless RGB
///   (c·s); for 16 bits, the native-endian and `image`'s big-endian
///   copies (2·c·s); the whole zlib stream, which `png` assembles in
///   memory, and its stored fallback when deflate does not pay (2·c·s);
/// * EXR: only a few blocks at a time;
/// * the residual: its distances (4), and for its one-channel encode no
///   more than 10;
/// * for a writer, the encoded file: at most about its raw size.
fn check_encode_memory(
    encoding: &Encoding,
    to_writer: bool,
    normals: bool,
    residual: bool,
    w: usize,
    h: usize,
) -> Result<()> {
    let layout = encoding.layout();
    let c: u64 = match layout {
        Layout::Rgb | Layout::Rg => 3,
        _ => 4,
    };
    let (map, encode, raw) = match encoding {
        Encoding::Png(PngOptions { depth: PngDepth::Eight, .. }) => {
            (3, if layout == Layout::Rgb { 0 } else { c } + 2 * c, c)
        }
        Encoding::Png(PngOptions { depth: PngDepth::Sixteen, .. }) => {
            (6, if layout == Layout::Rgb { 0 } else { 2 * c } + 4 * c + 4 * c, 2 * c)
        }
        Encoding::Exr(_) => (12, 0, 4 * c),
        // Laid out a few hundred rows at a time, unless RGB.
        Encoding::Tiff(TiffOptions { depth: TiffDepth::Eight, .. }) => (3, 0, c),
        Encoding::Tiff(TiffOptions { depth: TiffDepth::Sixteen, .. }) => (6, 0, 2 * c),
        Encoding::Tiff(TiffOptions { depth: TiffDepth::Float, .. }) => (12, 0, 4 * c),
    };
    let assembled = if to_writer { raw } else { 0 };
    let per_texel = map + if normals { encode + assembled } else { 0 } + if residual { 4 + 10 } else { 0 };
    let texels = (w as u64).saturating_mul(h as u64);
    io::check_memory("encoding the normal map", texels.saturating_mul(per_texel))
}

/// Refuses to assemble an EXR for a writer in memory when the memory
/// limits leave no room for it (its raw size, which ZIP does not exceed)
/// beside the stream's own buffers.
fn check_assembly_memory(encoding: &Encoding, w: usize, h: usize) -> Result<()> {
    let channels: u64 = match (encoding.layout(), encoding) {
        (Layout::Rg, Encoding::Exr(_)) => 2,
        (Layout::Rg | Layout::Rgb, _) => 3,
        _ => 4,
    };
    let sample = match encoding {
        Encoding::Exr(ExrOptions { depth: ExrDepth::Half, .. }) => 2,
        Encoding::Tiff(TiffOptions { depth: TiffDepth::Eight, .. }) => 1,
        Encoding::Tiff(TiffOptions { depth: TiffDepth::Sixteen, .. }) => 2,
        _ => 4,
    };
    let texels = (w as u64).saturating_mul(h as u64);
    io::check_memory("assembling the output in memory", texels.saturating_mul(channels * sample))
}

/// A buffer of `len` values, or an error when the memory is not there:
/// `vec!` would abort the process instead (under `ulimit -v`).
fn zeroed<T: Clone + Default>(len: usize) -> Result<Vec<T>> {
    let mut values = try_vec(len).map_err(|_| {
        let mib = len.saturating_mul(size_of::<T>()) >> 20;
        Error::Limits(format!("not enough memory for the output ({mib} MiB more)"))
    })?;
    values.resize(len, T::default());
    Ok(values)
}

/// An encoded file assembled in memory, like `Cursor<Vec<u8>>`, but whose
/// growth is reserved fallibly: running out of memory is an error, where a
/// growing `Vec` would abort the process (under `ulimit -v`).
#[derive(Default)]
struct InMemory(Cursor<Vec<u8>>);

impl Write for InMemory {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let end = usize::try_from(self.0.position()).unwrap_or(usize::MAX).saturating_add(buf.len());
        let bytes = self.0.get_mut();
        if end > bytes.capacity() {
            // Amortised growth, as `Vec` itself would.
            bytes.try_reserve(end - bytes.len()).map_err(|_| {
                let mib = end >> 20;
                std::io::Error::new(
                    std::io::ErrorKind::OutOfMemory,
                    format!("not enough memory to assemble the output ({mib} MiB)"),
                )
            })?;
        }
        self.0.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for InMemory {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        self.0.seek(to)
    }
}

/// An input format whose rows stream, opened by path.
trait Reopen: RowSource + Sized {
    /// Opens `path` if it is this format and can stream (`Ok(None)`: read
    /// it whole).
    fn reopen(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<Self>>;

    /// The image's last `rows` rows, if the format can give them without
    /// reading the whole file (`None`: it cannot).
    fn last_rows(path: &Path, opts: &ReadOptions, channel: Option<Channel>, rows: usize) -> Option<Result<Vec<f64>>>;
}

impl Reopen for PngRows {
    fn reopen(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<Self>> {
        PngRows::open(path, opts, channel)
    }

    fn last_rows(_: &Path, _: &ReadOptions, _: Option<Channel>, _: usize) -> Option<Result<Vec<f64>>> {
        // PNG cannot seek: its last rows come from a pass over the file.
        None
    }
}

#[cfg(feature = "tiff")]
impl Reopen for TiffRows {
    fn reopen(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<Self>> {
        TiffRows::open(path, opts, channel)
    }

    fn last_rows(path: &Path, opts: &ReadOptions, channel: Option<Channel>, rows: usize) -> Option<Result<Vec<f64>>> {
        Some(TiffRows::last_rows(path, opts, channel, rows))
    }
}

impl Reopen for ExrRows {
    fn reopen(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<Self>> {
        ExrRows::open(path, opts, channel)
    }

    fn last_rows(path: &Path, opts: &ReadOptions, channel: Option<Channel>, rows: usize) -> Option<Result<Vec<f64>>> {
        Some(ExrRows::last_rows(path, opts, channel, rows))
    }
}
