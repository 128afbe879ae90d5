//! Writing normal maps: PNG (8/16-bit RGB), OpenEXR (half/float RGB), and
//! files that appear whole or not at all.
//!
//! The encoders take texels as the fit produces them (`[u8; 3]`,
//! `[u16; 3]`, `[f32; 3]`, see [`crate::FromNormal`]), so no float copy of
//! the image is made between the fit and the file.

use std::io::{Seek, Write};

pub use super::atomic::{write_atomically, write_file_atomically};

use exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use exr::block::writer::{ChunkWriter, ChunksWriter};
use exr::compression::Compression;
use exr::meta::BlockDescription;
use exr::meta::attribute::{ChannelDescription, LineOrder, SampleType as ExrSample, Text};
use exr::meta::header::Header;
use exr::prelude::{LayerAttributes, SmallVec, f16};
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder, ImageError};
use rayon::prelude::*;

use crate::error::{Error, Result, one_line};

/// How hard the PNG encoder compresses.
///
/// The default is [`PngCompression::Fast`]: normal maps (16-bit ones most
/// of all) are noisy in their low bits and gain little from slow deflate,
/// while deflate runs on one thread and would otherwise take longer than
/// the whole parallel fit. It is also `image`'s own default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
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
    /// The `image` setting this stands for.
    fn to_image(self) -> CompressionType {
        match self {
            PngCompression::Fast => CompressionType::Fast,
            PngCompression::Default => CompressionType::Default,
            PngCompression::Best => CompressionType::Best,
        }
    }
}

/// Sample type of an EXR output (SPEC §3: `--bits 16` or `--bits 32`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ExrDepth {
    /// 16-bit half floats.
    Half,
    /// 32-bit floats, the EXR default.
    #[default]
    Float,
}

/// Writes an 8-bit RGB PNG of `width` × `height` texels, row-major.
///
/// Errors: [`Error::BufferSize`] if `texels` does not hold
/// `width * height`, [`Error::Encode`] for sizes PNG cannot hold,
/// [`Error::Io`] if `out` fails.
pub fn encode_png_rgb8(
    texels: &[[u8; 3]],
    width: usize,
    height: usize,
    compression: PngCompression,
    out: impl Write,
) -> Result<()> {
    let (w, h) = png_size(texels.len(), width, height)?;
    png_encoder(out, compression)
        .write_image(texels.as_flattened(), w, h, ExtendedColorType::Rgb8)
        .map_err(from_image_error)
}

/// Writes an 8-bit gray PNG of `width` × `height` texels, row-major: a
/// picture such as [`shade`](crate::shade::shade) makes, a third the size
/// of the same picture as RGB.
///
/// Errors: as [`encode_png_rgb8`].
pub fn encode_png_gray8(
    texels: &[u8],
    width: usize,
    height: usize,
    compression: PngCompression,
    out: impl Write,
) -> Result<()> {
    let (w, h) = png_size(texels.len(), width, height)?;
    png_encoder(out, compression).write_image(texels, w, h, ExtendedColorType::L8).map_err(from_image_error)
}

/// Writes a 16-bit RGB PNG of `width` × `height` texels, row-major.
///
/// `image`'s `PngEncoder::write_image` takes 16-bit samples as
/// native-endian bytes and swaps them to PNG's big-endian order itself.
///
/// Errors: as [`encode_png_rgb8`].
pub fn encode_png_rgb16(
    texels: &[[u16; 3]],
    width: usize,
    height: usize,
    compression: PngCompression,
    out: impl Write,
) -> Result<()> {
    let (w, h) = png_size(texels.len(), width, height)?;
    let mut bytes = Vec::new();
    bytes.try_reserve_exact(texels.len() * 6).map_err(|_| Error::Encode("out of memory for the png rows".into()))?;
    bytes.extend(texels.as_flattened().iter().flat_map(|v| v.to_ne_bytes()));
    png_encoder(out, compression).write_image(&bytes, w, h, ExtendedColorType::Rgb16).map_err(from_image_error)
}

/// Writes an OpenEXR file with channels R, G, B of `width` × `height`
/// texels, values as given (`Half` rounds them to half floats).
///
/// ZIP compression in blocks of 16 rows, what most tools write by default:
/// lossless, small, and read by every EXR reader. The EXR layout puts an
/// offset table before the pixel data, filled in at the end, so `out` must
/// seek; to write to a pipe, encode into a `Cursor<Vec<u8>>` first.
///
/// Errors: [`Error::BufferSize`] if `texels` does not hold
/// `width * height`, [`Error::Encode`] for a zero size or an encoder
/// failure, [`Error::Io`] if `out` fails.
pub fn encode_exr(
    texels: &[[f32; 3]],
    width: usize,
    height: usize,
    depth: ExrDepth,
    out: impl Write + Seek,
) -> Result<()> {
    check_buffer(texels.len(), width, height)?;
    write_exr_rows(out, width, height, depth, |push| {
        // A few hundred rows at a time: the blocks being compressed stay few.
        texels.chunks(width.saturating_mul(256).max(1)).try_for_each(push)
    })
}

/// Rows per EXR block with ZIP compression, what [`write_exr_rows`] writes.
const EXR_BLOCK_ROWS: usize = 16;

/// Writes an OpenEXR file with channels R, G, B (half or float by `depth`),
/// ZIP compression in blocks of 16 rows, whose texels `fill` pushes in
/// order, any number of whole rows at a time. Blocks are compressed in
/// parallel as soon as their rows are in, so memory holds a few blocks,
/// not the image.
///
/// Errors: [`Error::Encode`] for a zero size, rows pushed that do not fit
/// or are missing at the end, or an encoder failure; [`Error::Io`] if
/// `out` fails; any error of `fill`, which stops the writing.
pub(crate) fn write_exr_rows<W: Write + Seek>(
    out: W,
    width: usize,
    height: usize,
    depth: ExrDepth,
    fill: impl FnOnce(&mut dyn FnMut(&[[f32; 3]]) -> Result<()>) -> Result<()>,
) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::Encode("image has zero size".into()));
    }
    let sample = match depth {
        ExrDepth::Half => ExrSample::F16,
        ExrDepth::Float => ExrSample::F32,
    };
    // Channels in the file's order, which is by name: B, G, R.
    let channels = ["B", "G", "R"].map(|name| ChannelDescription::named(name, sample));
    let header = Header::new(Text::from(""), (width, height), SmallVec::from_iter(channels))
        .with_encoding(Compression::ZIP16, BlockDescription::ScanLines, LineOrder::Increasing)
        .with_attributes(LayerAttributes::default());
    let mut outcome = Ok(());
    let written = exr::block::write(out, SmallVec::from_elem(header, 1), true, |_, chunks| {
        let mut blocks = ExrBlocks { chunks, width, height, depth, pending: Vec::new(), done: 0 };
        outcome = fill(&mut |rows| blocks.push(rows)).and_then(|()| blocks.finish());
        // Our own error is kept in `outcome`; this only stops the writer.
        if outcome.is_err() { Err(exr::error::Error::Aborted) } else { Ok(()) }
    });
    outcome?;
    written.map_err(from_exr_error)
}

/// The rows of an EXR file being written, cut into blocks.
struct ExrBlocks<'a, W> {
    chunks: &'a mut ChunkWriter<W>,
    width: usize,
    height: usize,
    depth: ExrDepth,
    /// Texels of the rows not yet written, from row `done`.
    pending: Vec<[f32; 3]>,
    done: usize,
}

impl<W: Write + Seek> ExrBlocks<'_, W> {
    /// Takes more rows; writes every block they complete.
    fn push(&mut self, rows: &[[f32; 3]]) -> Result<()> {
        let w = self.width;
        if rows.len() % w != 0 || self.done + (self.pending.len() + rows.len()) / w > self.height {
            return Err(Error::Encode(format!("{} texels are not whole rows of the image", rows.len())));
        }
        self.pending.extend_from_slice(rows);
        let block = EXR_BLOCK_ROWS * w;
        let last = self.done + self.pending.len() / w == self.height;
        let ready = if last { self.pending.len() } else { self.pending.len() - self.pending.len() % block };
        if ready == 0 {
            return Ok(());
        }
        let (first_row, depth) = (self.done, self.depth);
        let compressed: Vec<_> = self.pending[..ready]
            .par_chunks(block)
            .enumerate()
            .map(|(k, texels)| zip_chunk(texels, w, first_row + k * EXR_BLOCK_ROWS, depth))
            .collect();
        for (k, chunk) in compressed.into_iter().enumerate() {
            let index = first_row / EXR_BLOCK_ROWS + k;
            self.chunks.write_chunk(index, chunk?).map_err(from_exr_error)?;
        }
        self.pending.drain(..ready);
        self.done += ready / w;
        Ok(())
    }

    /// Checks that every row came.
    fn finish(&self) -> Result<()> {
        if self.done == self.height {
            Ok(())
        } else {
            Err(Error::Encode(format!("only {} of {} rows were written", self.done, self.height)))
        }
    }
}

/// zlib level of EXR blocks.
const EXR_ZLIB_LEVEL: u8 = 1;

/// One block of rows `y0 …` as an EXR ZIP chunk.
///
/// EXR's ZIP is zlib over the block's little-endian bytes after two steps
/// that make them compress: the even bytes first, then the odd ones, and
/// each byte replaced by its difference from the one before, plus 128.
/// `exr` does this itself but deflates with miniz_oxide at level 4, which
/// took 85 % of an EXR conversion's time; fdeflate is several times
/// faster on these bytes and about as small. A block that does not shrink
/// is stored as it is, which is how EXR readers tell the two apart.
fn zip_chunk(texels: &[[f32; 3]], width: usize, y0: usize, depth: ExrDepth) -> Result<Chunk> {
    let raw = exr_block_bytes(texels, width, depth);
    let mut split = vec![0u8; raw.len()];
    let (even, odd) = split.split_at_mut(raw.len().div_ceil(2));
    for ((e, o), pair) in even.iter_mut().zip(odd.iter_mut()).zip(raw.chunks_exact(2)) {
        (*e, *o) = (pair[0], pair[1]);
    }
    if raw.len() % 2 == 1 {
        even[even.len() - 1] = raw[raw.len() - 1];
    }
    let mut deltas = Vec::with_capacity(split.len());
    deltas.extend(split.first());
    deltas.extend(
        split.iter().zip(&split[1.min(split.len())..]).map(|(&before, &b)| b.wrapping_sub(before).wrapping_add(128)),
    );
    let compressed = miniz_oxide::deflate::compress_to_vec_zlib(&deltas, EXR_ZLIB_LEVEL);
    let y_coordinate =
        i32::try_from(y0).map_err(|_| Error::Encode(format!("row {y0} is beyond what EXR can index")))?;
    let compressed_pixels_le = if compressed.len() < raw.len() { compressed } else { raw };
    Ok(Chunk {
        layer_index: 0,
        compressed_block: CompressedBlock::ScanLine(CompressedScanLineBlock { y_coordinate, compressed_pixels_le }),
    })
}

/// One block's bytes as EXR stores them before compression: row by row,
/// each row's B samples, then G, then R, little-endian.
fn exr_block_bytes(texels: &[[f32; 3]], width: usize, depth: ExrDepth) -> Vec<u8> {
    let size = match depth {
        ExrDepth::Half => 2,
        ExrDepth::Float => 4,
    };
    let mut data = Vec::with_capacity(texels.len() * 3 * size);
    for row in texels.chunks_exact(width) {
        for c in [2, 1, 0] {
            match depth {
                ExrDepth::Half => data.extend(row.iter().flat_map(|t| f16::from_f32(t[c]).to_le_bytes())),
                ExrDepth::Float => data.extend(row.iter().flat_map(|t| t[c].to_le_bytes())),
            }
        }
    }
    data
}

/// A PNG encoder with the adaptive filter, which suits smooth gradients.
fn png_encoder<W: Write>(out: W, compression: PngCompression) -> PngEncoder<W> {
    PngEncoder::new_with_quality(out, compression.to_image(), FilterType::Adaptive)
}

/// Checks the buffer and the PNG size limits before `image`, which panics
/// on a buffer of the wrong length.
fn png_size(len: usize, width: usize, height: usize) -> Result<(u32, u32)> {
    check_buffer(len, width, height)?;
    let side = |n: usize| u32::try_from(n).ok().filter(|&n| n > 0 && n <= i32::MAX as u32);
    match (side(width), side(height)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(Error::Encode(format!("png cannot hold {width} × {height} texels"))),
    }
}

/// Checks that a buffer holds `width * height` texels.
fn check_buffer(len: usize, width: usize, height: usize) -> Result<()> {
    let expected = width
        .checked_mul(height)
        .ok_or_else(|| Error::Encode(format!("{width} × {height} texels do not fit in memory")))?;
    if len != expected {
        return Err(Error::BufferSize { expected, actual: len });
    }
    Ok(())
}

/// Maps `image`'s errors: I/O stays I/O (the caller's writer failed),
/// everything else is an encoding failure.
fn from_image_error(e: ImageError) -> Error {
    match e {
        ImageError::IoError(e) => Error::Io(e),
        other => Error::Encode(one_line(&other.to_string()).to_lowercase()),
    }
}

/// Maps `exr`'s errors like [`from_image_error`].
fn from_exr_error(e: exr::error::Error) -> Error {
    match e {
        exr::error::Error::Io(e) => Error::Io(e),
        other => Error::Encode(one_line(&other.to_string()).to_lowercase()),
    }
}
