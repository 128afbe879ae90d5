//! The engine: every command's one path from a source, through a stage,
//! to a sink.
//!
//! * **Source** ([`Source`]): a file found by the input registry, or bytes;
//!   its rows streamed wherever the format allows (PNG, scan-line EXR,
//!   striped or tiled TIFF bands: GeoTIFF elevation, in texel or map
//!   units, with or without nodata), else decoded whole. The choice is
//!   made here, once, for every command: a source streams unless the stage
//!   needs the whole image ([`Source::open`]'s `may_stream`).
//! * **Stage**: what is computed from the heights band by band:
//!   the normal map (its residual from the whole image), or the lit view
//!   (tiled 2×2 from the whole image). The inverse (normal map → heights,
//!   [`crate::height`]) needs the whole image and says so: it reads a
//!   whole source and writes through the same sink.
//! * **Sink** ([`Output`]): a file, written atomically (whole or not at all,
//!   never over the input, its georeferencing sidecars beside it), or any
//!   writer; the format and its options from the output registry
//!   ([`crate::io::encoding`]), streamed where the format's writer can.
//!
//! Between source and sink a streamed run holds a few bands of rows
//! ([`crate::pipeline`]: decode, fit and encode on three threads); a whole
//! run holds the image. Both give the same bytes.
//!
//! [`crate::convert`] (the normal map), [`crate::shade`] (the lit view) and
//! [`crate::height`] (the inverse) map their options onto the engine; the
//! command line and the Python package call those.

mod job;
pub(crate) mod sink;
pub(crate) mod source;
mod stage;

use std::fmt;
use std::path::PathBuf;

use crate::borders::{BorderChoices, Warning};
use crate::error::Error;
use crate::io::read::georef::holes_value;
use crate::io::{self, Channel, Encoding, InputFormat, OutputFormat, ReadOptions, SampleType};
use crate::light::Lighting;
use crate::tiling::TilingReport;
use crate::units::MapSpacing;
use crate::{Borders, Options};

pub(crate) use self::sink::chain_files;
pub(crate) use self::sink::write_to;
pub use self::sink::{Output, chain_stem, level_path, roughness_path};
pub(crate) use self::source::decode_whole;
pub use self::source::{Input, Source, read_all};
pub(crate) use self::stage::{Depth, Texels, write_normals};

/// Which file an error concerns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Place {
    /// The height map read (for a blend, the base normal map).
    Input,
    /// The detail normal map read (a blend).
    Detail,
    /// The normal map written.
    Output,
    /// The residual map written.
    Residual,
    /// The base roughness read (`roughness_base`).
    RoughnessBase,
    /// The roughness chain written.
    Roughness,
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
    pub(crate) fn at(place: Place) -> impl Fn(Error) -> ConvertError {
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
    /// alpha of validity ([`crate::io::Layout::RgbValid`]).
    pub nodata: Option<f64>,
    /// Missing texels (holes, and texels whose valid points do not
    /// determine a plane): alpha 0 in the map. 0 without a nodata value.
    pub missing: usize,
}

/// A mip chain's stage: how the chain is made, whether all of it is
/// written, in which encoding, and whether a roughness chain goes beside.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MipStage {
    /// Fit, average, or as the input says.
    pub choice: crate::mips::MipChoice,
    /// Every level; else level 0 alone (a texture asked for without mips),
    /// fitted from the heights.
    pub all: bool,
    /// A texture holding the chain, or an image a level.
    pub encoding: Encoding,
    /// A roughness chain beside, at [`roughness_path`].
    pub roughness: bool,
}

/// What is computed from the heights.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Stage {
    /// A mip chain of normals (the whole image), its roughness beside.
    Mips(MipStage),
    /// The normal map in this encoding (an alpha of validity where there
    /// are holes), and its residual when a residual output is given (the
    /// whole image).
    Normals(Encoding),
    /// The curvature map ([`crate::fit::curvature`]): one channel in this
    /// encoding, float as it is, 8 or 16 bits mapped so that `range` is
    /// white ([`crate::fit::quadratic::encode`]); streamed band by band
    /// into an EXR or PNG file, else from the whole image.
    Curvature {
        /// The output's format and depth (its layout not used).
        encoding: Encoding,
        /// The curvature that maps to white.
        range: f64,
    },
    /// A slope or an aspect map ([`crate::units::Measure`]): one float32
    /// channel in this encoding (a TIFF with gdaldem's nodata, −9999, or
    /// an EXR); streamed into a TIFF file, else from the whole image.
    Terrain {
        /// What each texel holds.
        measure: crate::units::Measure,
        /// The output's format (float32: checked by the entry point).
        encoding: Encoding,
    },
    /// The lit view, 8-bit grey (PNG, or TIFF with GDAL's nodata 0), lit
    /// as `lighting` says; tiled 2×2 from the whole image.
    Lit {
        /// The light or the sun.
        lighting: Lighting,
        /// Tiled 2×2.
        tile: bool,
        /// A TIFF, else a PNG.
        tiff: bool,
    },
}

impl Stage {
    /// Whether this stage can take rows as they stream into `output`
    /// (`None`: no file, the pixels kept): the lit view only whole when
    /// tiled, and streamed only into a file (its PNG takes its top rows
    /// last, in room kept after the header), not a device, FIFO or socket
    /// named as one (`-o /dev/null`), which is written as a writer; the
    /// curvature streamed into an EXR or PNG file alone (EXR's offsets and
    /// PNG's top rows are written last), a slope or aspect map into a TIFF
    /// file alone.
    pub(crate) fn streams_into(&self, output: Option<&Output<'_>>) -> bool {
        let into_file = match output {
            Some(Output::File { path, .. }) => !matches!(io::output_target(path), Ok(io::OutputTarget::Stream(_))),
            _ => false,
        };
        match self {
            Stage::Normals(_) => true,
            Stage::Mips(_) => false,
            Stage::Curvature { encoding, .. } => into_file && matches!(encoding, Encoding::Exr(_) | Encoding::Png(_)),
            // The TIFF writer's rows go into a file, which it seeks back
            // into; an EXR or a stream is written from the whole image.
            Stage::Terrain { encoding, .. } => into_file && matches!(encoding, Encoding::Tiff(_)),
            Stage::Lit { tile, .. } => !tile && into_file,
        }
    }
}

/// What a run takes of the fit and the source besides the stage.
#[derive(Clone, Debug)]
pub(crate) struct Settings<'a> {
    /// The fit; its borders are replaced by `borders`', its nodata value
    /// (else the GeoTIFF's) says where the holes are.
    pub fit: Options,
    /// The border modes, fixed or `auto`.
    pub borders: BorderChoices,
    /// The reading options (a first pass, a tail, read again alike).
    pub read: &'a ReadOptions,
    /// The channel that holds the height.
    pub channel: Option<Channel>,
    /// Real-world units: the heights as stored, the spacing from the file
    /// or given.
    pub map_units: Option<MapSpacing>,
    /// Which existing files the outputs (and their sidecars) may replace.
    pub replace: io::Replace,
    /// A mip chain's base roughness: a gray image of the input's size.
    pub roughness_base: Option<&'a std::path::Path>,
    /// Files no output may replace besides the input: a batch's other
    /// inputs.
    pub inputs: std::sync::Arc<io::Inputs>,
}

/// Where a run's results go: the main output (none: a lit view's pixels
/// are kept, [`run`] returns them), and the residual map beside a normal
/// map.
pub(crate) struct Sink<'a, 'b> {
    pub main: Option<Output<'a>>,
    pub residual: Option<(Output<'b>, OutputFormat)>,
}

/// Runs `stage` from `source` into `sink`: the one path of every
/// conversion. Returns what was done, and a lit view's pixels when the
/// sink keeps them.
///
/// Errors: [`Place::Input`] for reading, decoding and the fit;
/// [`Place::Output`] or [`Place::Residual`] for memory checks, encoding and
/// writing ([`Error::InvalidOption`] for a file output that is the input).
pub(crate) fn run(
    source: Source,
    stage: Stage,
    sink: Sink<'_, '_>,
    mut settings: Settings<'_>,
    observer: &dyn Observer,
) -> Result<(Summary, Option<Vec<u8>>), ConvertError> {
    let Source { path, rows, format, sample } = source;
    let georef = rows.georef().cloned();
    // Holes: the nodata value given, else the GeoTIFF's own; a normal map
    // then says which texels are missing in its alpha, a lit view greys
    // them 0.
    let nodata = holes_value(settings.fit.nodata, georef.as_ref());
    settings.fit.nodata = nodata;
    let stage = match (stage, nodata) {
        (Stage::Normals(encoding), Some(_)) => Stage::Normals(encoding.with_layout(encoding.layout().with_holes())),
        (stage, _) => stage,
    };
    let encoding = stage.encoding();
    // A file output that leads to a device, FIFO or socket is a stream,
    // written as a writer is.
    let input = path.as_deref();
    let mut main_stream =
        self::sink::open_stream(sink.main.as_ref(), input).map_err(ConvertError::at(Place::Output))?;
    let mut residual_stream = self::sink::open_stream(sink.residual.as_ref().map(|(output, _)| output), input)
        .map_err(ConvertError::at(Place::Residual))?;
    let sink = Sink {
        main: sink.main.map(|output| self::sink::or_stream(output, &mut main_stream)),
        residual: sink.residual.map(|(output, format)| (self::sink::or_stream(output, &mut residual_stream), format)),
    };
    // Beside a PNG file: GDAL reads no EXR here, a TIFF holds its own
    // tags, a writer has no name, and a tiled view is not the place.
    let sidecar_of = match (&sink.main, encoding, stage) {
        (_, _, Stage::Lit { tile: true, .. }) => None,
        (Some(Output::File { path, .. }), Encoding::Png(_), _) => georef.as_ref().map(|g| (path.to_path_buf(), g)),
        _ => None,
    };
    let mut job = job::Job {
        settings: &settings,
        stage,
        input: path.as_deref(),
        encoding,
        georef: georef.as_ref(),
        observer,
        pixels: None,
        summary: Summary {
            width: 0,
            height: 0,
            input_format: format,
            sample,
            encoding,
            borders: settings.fit.borders,
            streamed: false,
            tiling: None,
            warnings: Vec::new(),
            sidecars: Vec::new(),
            nodata,
            missing: 0,
        },
        files: io::FileSet::new(settings.replace).keeping(settings.inputs.clone()),
    };
    // The sidecars first: they are known from the georeferencing, and one
    // that is an input or that the policy keeps stops the run before any
    // image byte is written. All the files are named together at the end.
    if let Some((path, georef)) = sidecar_of {
        job.summary.sidecars = io::sidecar::write_sidecars(&path, georef, input, &mut job.files)
            .map_err(ConvertError::at(Place::Output))?;
    }
    job.run(rows, sink)?;
    std::mem::take(&mut job.files).commit().map_err(ConvertError::at(Place::Output))?;
    Ok((job.summary, job.pixels))
}

impl Stage {
    /// The encoding of the main output.
    fn encoding(&self) -> Encoding {
        match *self {
            Stage::Normals(encoding) => encoding,
            Stage::Mips(mips) => mips.encoding,
            Stage::Curvature { encoding, .. } => encoding,
            Stage::Terrain { encoding, .. } => encoding,
            Stage::Lit { tiff: true, .. } => io::encoding::TiffOptions::new(io::encoding::TiffDepth::Eight).into(),
            Stage::Lit { tiff: false, .. } => {
                io::PngOptions::new(io::PngDepth::Eight).with_compression(io::PngCompression::Default).into()
            }
        }
    }
}
