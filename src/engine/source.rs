//! The engine's sources: a height map opened by path or from bytes, its
//! rows streamed where the format allows, else decoded whole.

use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::{self, Channel, Georef, InputFormat, Raster, ReadOptions, SampleType};
#[cfg(feature = "tiff")]
use crate::pipeline::TiffRows;
use crate::pipeline::{ExrRows, PngRows, RowSource, StoredRows};

/// A height map to convert.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub enum Input<'a> {
    /// A file, read by content. PNG and scan-line EXR files stream.
    Path(&'a Path),
    /// An encoded image in memory (see [`read_all`] for a reader).
    Bytes(&'a [u8]),
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

/// A height map opened: its format and samples known, its rows not yet
/// read (streaming) or decoded whole.
pub struct Source {
    /// The file, which no output may replace.
    pub(crate) path: Option<PathBuf>,
    pub(crate) rows: Rows,
    pub(crate) format: InputFormat,
    pub(crate) sample: SampleType,
}

/// Where a source's heights come from.
pub(crate) enum Rows {
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

impl Rows {
    /// The georeferencing of the file, if it has any.
    pub(crate) fn georef(&self) -> Option<&Georef> {
        match self {
            Rows::Whole(raster) => raster.georef.as_ref(),
            #[cfg(feature = "tiff")]
            Rows::Tiff(rows, _) => rows.georef(),
            _ => None,
        }
    }
}

impl Source {
    /// Opens `input`: with `may_stream`, a file whose format streams by its
    /// header alone (PNG, scan-line EXR, a TIFF band the `tiff` crate reads);
    /// anything else read and decoded whole. The one rule of every command:
    /// a source streams unless its stage needs the whole image.
    ///
    /// Errors: those of reading and decoding ([`io::read_path`],
    /// [`io::decode`]).
    pub fn open(input: Input<'_>, read: &ReadOptions, channel: Option<Channel>, may_stream: bool) -> Result<Source> {
        if let (Input::Path(path), true) = (input, may_stream) {
            let file = || path.to_path_buf();
            if let Some(rows) = PngRows::open(path, read, channel.clone())? {
                let bits = if rows.more_than_8_bits() { 16 } else { 8 };
                let sample = SampleType::Int { bits };
                return Ok(Source::of(path, Rows::Png(Box::new(rows), file()), InputFormat::Png, sample));
            }
            if let Some(rows) = ExrRows::open(path, read, channel.clone())? {
                return Ok(Source::of(path, Rows::Exr(Box::new(rows), file()), InputFormat::Exr, SampleType::Float));
            }
            #[cfg(feature = "tiff")]
            if let Some(rows) = TiffRows::open(path, read, channel.clone())? {
                let sample = rows.sample();
                return Ok(Source::of(path, Rows::Tiff(Box::new(rows), file()), InputFormat::Tiff, sample));
            }
        }
        let path = match input {
            Input::Path(path) => Some(path),
            Input::Bytes(_) => None,
        };
        Ok(Source::whole(decode_whole(input, read)?, path))
    }

    /// A decoded image (read from `path`, if from a file).
    pub fn whole(raster: Raster, path: Option<&Path>) -> Source {
        let (format, sample) = (raster.format.clone(), raster.sample);
        Source { path: path.map(Path::to_path_buf), rows: Rows::Whole(Box::new(raster)), format, sample }
    }

    fn of(path: &Path, rows: Rows, format: InputFormat, sample: SampleType) -> Source {
        Source { path: Some(path.to_path_buf()), rows, format, sample }
    }

    /// The format read.
    #[must_use]
    pub fn format(&self) -> &InputFormat {
        &self.format
    }

    /// The samples stored.
    #[must_use]
    pub fn sample(&self) -> SampleType {
        self.sample
    }

    /// The image's columns and rows.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        match &self.rows {
            Rows::Whole(raster) => (raster.width, raster.height),
            Rows::Png(rows, _) => (rows.width(), rows.height()),
            Rows::Exr(rows, _) => (rows.width(), rows.height()),
            #[cfg(feature = "tiff")]
            Rows::Tiff(rows, _) => (rows.width(), rows.height()),
        }
    }

    /// Whether its rows stream (else it is decoded whole).
    #[must_use]
    pub fn streams(&self) -> bool {
        !matches!(self.rows, Rows::Whole(_))
    }

    /// Whether it is a TIFF band that streams: GeoTIFF elevation, taken for
    /// heights without a look at the whole image.
    pub(crate) fn is_tiff_band(&self) -> bool {
        #[cfg(feature = "tiff")]
        if let Rows::Tiff(..) = self.rows {
            return true;
        }
        false
    }

    /// The source decoded whole: as it is, or read again from its file.
    ///
    /// Errors: those of [`io::read_path`].
    pub(crate) fn into_whole(self, read: &ReadOptions) -> Result<Source> {
        match (&self.rows, &self.path) {
            (Rows::Whole(_), _) => Ok(self),
            (_, Some(path)) => Ok(Source::whole(io::read_path(path, read)?, Some(path))),
            (_, None) => Err(Error::Io(std::io::Error::other("a streamed source without a file"))),
        }
    }

    /// The decoded image, if the source is one, given up.
    pub(crate) fn into_raster(self) -> Option<Raster> {
        match self.rows {
            Rows::Whole(raster) => Some(*raster),
            _ => None,
        }
    }

    /// The decoded image, if the source is one.
    pub(crate) fn raster(&self) -> Option<&Raster> {
        match &self.rows {
            Rows::Whole(raster) => Some(raster),
            _ => None,
        }
    }
}

/// `input` decoded whole: what a source that may not stream reads, and
/// what a stage that needs the whole image (the inverse) reads.
///
/// Errors: those of [`io::read_path`] and [`io::decode`].
pub(crate) fn decode_whole(input: Input<'_>, read: &ReadOptions) -> Result<Raster> {
    match input {
        Input::Path(path) => io::read_path(path, read),
        Input::Bytes(bytes) => io::decode(bytes, read),
    }
}

/// An input format whose rows stream, opened by path.
pub(crate) trait Reopen: RowSource + Sized {
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

impl<R: Reopen> Reopen for StoredRows<R> {
    fn reopen(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<Self>> {
        Ok(R::reopen(path, opts, channel)?.map(StoredRows::new))
    }

    fn last_rows(path: &Path, opts: &ReadOptions, channel: Option<Channel>, rows: usize) -> Option<Result<Vec<f64>>> {
        let tail = R::last_rows(path, opts, channel.clone(), rows)?;
        // The scale is the source's: a new one, opened for its header.
        Some(tail.and_then(|mut tail| {
            let source = R::reopen(path, opts, channel)?
                .ok_or_else(|| Error::Io(std::io::Error::other("changed while being read")))?;
            StoredRows::new(source).restore(&mut tail);
            Ok(tail)
        }))
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
