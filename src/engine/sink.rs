//! The engine's sinks: a file written atomically (whole or not at all,
//! never over the input), or any writer (formats that seek assembled in
//! memory first, within the memory limits); what an encode holds, checked
//! before it starts.

use std::io::{Cursor, Seek, Write};
use std::path::{Path, PathBuf};

use super::Place;
use crate::error::{Error, Result};
use crate::io::encoding::{TiffDepth, TiffOptions, TiffTags};
use crate::io::{self, Encoding, ExrDepth, ExrOptions, FileSet, Layout, OutputFormat, PngDepth, PngOptions};
use crate::samples::try_vec;

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

    pub(crate) fn path(&self) -> Option<&'a Path> {
        match self {
            Output::File { path, .. } => Some(path),
            Output::Writer(_) => None,
        }
    }
}

/// The device, FIFO or socket a file output leads to
/// ([`io::OutputTarget::Stream`]), opened after the output is checked
/// against the input ([`prepare`]); `None` for a file (or no output). The
/// engine writes a stream as it writes a writer: formats that seek are
/// assembled first, and nothing is written beside it.
///
/// Errors: [`Error::InvalidOption`] for the input; [`Error::Io`] when the
/// target cannot be opened, or a link not followed.
pub(crate) fn open_stream(output: Option<&Output<'_>>, input: Option<&Path>) -> Result<Option<std::fs::File>> {
    let Some(output @ Output::File { path, .. }) = output else { return Ok(None) };
    match io::output_target(path)? {
        io::OutputTarget::File(_) => Ok(None),
        io::OutputTarget::Stream(target) => {
            prepare(output, input)?;
            io::open_stream(&target).map(Some)
        }
    }
}

/// `output`, or a writer into `stream` when it was opened
/// ([`open_stream`]).
pub(crate) fn or_stream<'a: 's, 's>(output: Output<'a>, stream: &'s mut Option<std::fs::File>) -> Output<'s> {
    match (stream, output) {
        (Some(file), _) => Output::Writer(file),
        (None, Output::File { path, create_folder }) => Output::File { path, create_folder },
        (None, Output::Writer(writer)) => Output::Writer(writer),
    }
}

/// Where level `k` of a mip chain written as images goes: level 0 at
/// `path`, level k ≥ 1 at `<stem>_mip<k>.<ext>` beside it.
#[must_use]
pub fn level_path(path: &Path, k: usize) -> PathBuf {
    if k == 0 {
        return path.to_path_buf();
    }
    let stem = path.file_stem().map_or_else(|| "image".into(), |s| s.to_string_lossy().into_owned());
    let name = match path.extension() {
        Some(ext) => format!("{stem}_mip{k}.{}", ext.to_string_lossy()),
        None => format!("{stem}_mip{k}"),
    };
    path.with_file_name(name)
}

/// Where the roughness chain beside the normal map at `path` goes:
/// `<stem>_roughness.<ext>` (its levels named from it by [`level_path`]).
#[must_use]
pub fn roughness_path(path: &Path) -> PathBuf {
    let stem = path.file_stem().map_or_else(|| "image".into(), |s| s.to_string_lossy().into_owned());
    let name = match path.extension() {
        Some(ext) => format!("{stem}_roughness.{}", ext.to_string_lossy()),
        None => format!("{stem}_roughness"),
    };
    path.with_file_name(name)
}

/// The stem of the normal map whose chain a file of stem `stem` is part
/// of (`rock` of `rock_mip3`, `rock_roughness`, `rock_roughness_mip3`:
/// [`level_path`]'s and [`roughness_path`]'s names), or `None` for a stem
/// that is not named so. A folder's search skips a chain's files as it
/// skips normal maps.
///
/// ```
/// use normalfit::convert::chain_stem;
/// assert_eq!(chain_stem("rock_mip3"), Some("rock"));
/// assert_eq!(chain_stem("rock_roughness"), Some("rock"));
/// assert_eq!(chain_stem("rock_roughness_mip12"), Some("rock"));
/// assert_eq!(chain_stem("rock_mipmap"), None);
/// assert_eq!(chain_stem("rock"), None);
/// ```
#[must_use]
pub fn chain_stem(stem: &str) -> Option<&str> {
    let level = stem
        .rsplit_once("_mip")
        .and_then(|(base, k)| (!k.is_empty() && k.bytes().all(|b| b.is_ascii_digit()) && k != "0").then_some(base));
    let base = level.unwrap_or(stem);
    match base.strip_suffix("_roughness") {
        Some(base) => Some(base),
        None => level,
    }
}

/// Every file a mip chain of `count` levels written at `path` makes, in
/// the order it is written, and which output each is: a texture at
/// `path`, its roughness at [`roughness_path`]; images a level at
/// [`level_path`]s, then the roughness's levels. The one list the engine
/// checks before it starts and writes, and callers claim
/// ([`crate::convert::Opened::outputs`]).
pub(crate) fn chain_files(path: &Path, texture: bool, count: usize, roughness: bool) -> Vec<(PathBuf, Place)> {
    let levels = if texture { 1 } else { count };
    let normals = (0..levels).map(|k| (level_path(path, k), Place::Output));
    let rough = roughness_path(path);
    let rough = (0..if roughness { levels } else { 0 }).map(|k| (level_path(&rough, k), Place::Roughness));
    normals.chain(rough).collect()
}

/// Writes a file of the run's set `files` (named with the others at its
/// commit), or assembles the bytes in memory (EXR seeks while writing) and
/// gives them to a writer.
pub(crate) fn write_to(
    out: Output<'_>,
    files: &mut FileSet,
    encode: impl FnOnce(&mut dyn WriteSeek) -> Result<()>,
) -> Result<()> {
    match out {
        // Into the file itself, which seeks as EXR needs: no copy of the
        // encoded image in memory.
        Output::File { path, .. } => match io::output_target(path)? {
            io::OutputTarget::File(_) => files.write(path, |file| encode(file)),
            io::OutputTarget::Stream(target) => {
                let mut bytes = InMemory::default();
                encode(&mut bytes)?;
                write_all(&mut io::open_stream(&target)?, bytes.0.get_ref())
            }
        },
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
pub(crate) fn write_all(writer: &mut dyn Write, bytes: &[u8]) -> Result<()> {
    writer.write_all(bytes)?;
    writer.flush()?;
    Ok(())
}

/// Writes the residual map: the RMS distances (surface units) divided by
/// the gain |S|, so in height units; 0 where S = 0 (a flat surface). PNG:
/// 16-bit gray, 65535 · value clamped to [0, 1]; EXR: 32-bit float,
/// channel Y, the value as it is; TIFF: 32-bit float, the value as it is,
/// with `tags`.
pub(crate) fn encode_residual(
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
        OutputFormat::Dds | OutputFormat::Ktx2 => {
            Err(Error::Unsupported("a residual map is written as .png, .exr or .tif, not as a GPU texture".into()))
        }
    }
}

/// Refuses a whole-image conversion that the memory limits leave no room
/// for, in one line, before the fit allocates anything: a failure past our
/// own buffers (the encoders allocate as they go) would abort the process.
/// `fit_work` is what the fit allocates beyond its outputs
/// ([`crate::fit::work_bytes`]: its sums, which grow with N, on every
/// thread). Bytes held per texel, from what the fit and the encoders do:
/// * the normal map: 3, 6 or 12 (8-bit, 16-bit, float);
/// * with holes (`holes`), which texels have a normal (1);
/// * an alpha of heights or of validity: its f32 plane (4);
/// * PNG (c samples of s bytes a texel): the samples laid out, unless RGB
///   (c·s); for 16 bits, the native-endian and `image`'s big-endian
///   copies (2·c·s); the whole zlib stream, which `png` assembles in
///   memory, and its stored fallback when deflate does not pay (2·c·s);
/// * EXR: only a few blocks at a time;
/// * the residual: its distances (4), and for its one-channel encode no
///   more than 10;
/// * for a writer, the encoded file: at most about its raw size.
pub(crate) fn check_whole_memory(
    encoding: &Encoding,
    to_writer: bool,
    (normals, residual, holes): (bool, bool, bool),
    (w, h): (usize, usize),
    fit_work: u64,
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
        // The float normals, and the texture's bytes (at most 8 a texel).
        Encoding::Texture(_) => (12, 8, 8),
    };
    let assembled = if to_writer { raw } else { 0 };
    let alpha = if layout.needs_heights() { 4 } else { 0 };
    let per_texel = map
        + if normals { encode + assembled + alpha } else { 0 }
        + if residual { 4 + 10 } else { 0 }
        + u64::from(holes);
    let texels = (w as u64).saturating_mul(h as u64);
    io::check_memory("fitting and encoding the normal map", texels.saturating_mul(per_texel).saturating_add(fit_work))
}

/// Refuses to assemble an EXR for a writer in memory when the memory
/// limits leave no room for it (its raw size, which ZIP does not exceed)
/// beside the stream's own buffers.
pub(crate) fn check_assembly_memory(encoding: &Encoding, w: usize, h: usize) -> Result<()> {
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
pub(crate) fn zeroed<T: Clone + Default>(len: usize) -> Result<Vec<T>> {
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
pub(crate) struct InMemory(pub(crate) Cursor<Vec<u8>>);

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

/// Refuses a file output that is the input file (or a link to it), and
/// makes its folder if asked to.
///
/// Errors: [`Error::InvalidOption`] for the input; [`Error::Io`] when the
/// folder cannot be made.
pub(crate) fn prepare(output: &Output<'_>, input: Option<&Path>) -> Result<()> {
    let Output::File { path, create_folder } = *output else { return Ok(()) };
    refuse_input(path, input)?;
    if let (true, Some(parent)) = (create_folder, path.parent())
        && !parent.as_os_str().is_empty()
    {
        std::fs::create_dir_all(parent)
            .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("cannot create the output folder: {e}"))))?;
    }
    Ok(())
}

/// Refuses a file output at `path` that is `input` (or a link to it).
///
/// Errors: [`Error::InvalidOption`].
pub(crate) fn refuse_input(path: &Path, input: Option<&Path>) -> Result<()> {
    if let Some(input) = input
        && io::same_file(input, path)
    {
        return Err(Error::InvalidOption(
            "the output is the input (or a link to it): normalfit never writes over an input".into(),
        ));
    }
    Ok(())
}
