//! OpenEXR files written block by block: ZIP blocks of 16 rows compressed
//! in parallel as their rows come in ([`ExrBlocks`]), and the file put
//! together around them ([`write_exr_blocks`]); whole normal maps and
//! one-channel maps are written the same way.

use std::cell::RefCell;
use std::io::{Seek, SeekFrom, Write};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

use exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use exr::compression::Compression;
use exr::meta::attribute::{ChannelDescription, LineOrder, SampleType as ExrSample, Text};
use exr::meta::header::Header;
use exr::meta::{BlockDescription, MetaData, magic_number};
use exr::prelude::{LayerAttributes, SmallVec, f16};
use miniz_oxide::DataFormat;
use miniz_oxide::deflate::core::{CompressorOxide, TDEFLFlush, TDEFLStatus, compress};

use crate::error::{Error, Result, one_line};
use crate::io::encoding::{ExrDepth, ExrOptions};
use crate::io::texels::{Container, lay_out};
use crate::par::prelude::*;

/// An OpenEXR normal map of the normals n: each band of rows stored as
/// `options` says ([`ExrOptions::stored`]) and laid out as it is written.
pub(crate) fn exr_normals(
    texels: &[[f32; 3]],
    heights: &[f32],
    (width, height): (usize, usize),
    options: ExrOptions,
    out: impl Write + Seek,
) -> Result<()> {
    let layout = options.layout;
    // A few hundred rows at a time: the blocks being compressed stay few.
    let rows = width.saturating_mul(256).max(1);
    write_exr_rows(out, width, height, options.depth, layout.exr_channels(), |push| {
        let mut samples = Vec::new();
        // The normals' samples (R, G, B or R, G: the first of a texel's)
        // are stored once laid out, in place: no copy of the normals.
        let channels = layout.exr_channels().len();
        let normal_samples = channels.min(3);
        texels.chunks(rows).enumerate().try_for_each(|(k, chunk)| {
            let band_heights = if heights.is_empty() { heights } else { &heights[k * rows..][..chunk.len()] };
            samples.clear();
            lay_out(chunk, band_heights, layout, Container::Exr, &mut samples);
            if !options.signed {
                for texel in samples.chunks_exact_mut(channels) {
                    texel[..normal_samples].iter_mut().for_each(|c| *c = options.stored(*c));
                }
            }
            push(&samples)
        })
    })
}

/// Rows per EXR block with ZIP compression, what [`write_exr_rows`] writes.
const EXR_BLOCK_ROWS: usize = 16;

/// Writes an OpenEXR file with the named `channels` (half or float by
/// `depth`), ZIP compression in blocks of 16 rows, whose samples `fill`
/// pushes, texel after texel (each texel's samples in the order
/// `channels` names them), any number of whole rows at a time.
/// Blocks are compressed in parallel as soon as their rows are in, so
/// memory holds a few blocks, not the image.
///
/// Errors: [`Error::Encode`] for a zero size, rows pushed that do not fit
/// or are missing at the end, or an encoder failure; [`Error::Io`] if
/// `out` fails; any error of `fill`, which stops the writing.
pub(crate) fn write_exr_rows<W: Write + Seek>(
    out: W,
    width: usize,
    height: usize,
    depth: ExrDepth,
    channels: &[&str],
    fill: impl FnOnce(&mut dyn FnMut(&[f32]) -> Result<()>) -> Result<()>,
) -> Result<()> {
    let mut blocks = ExrBlocks::new(width, height, depth, channels)?;
    let spares = blocks.spares();
    write_exr_blocks(out, &blocks.header(), &spares, |write| {
        fill(&mut |rows| write(blocks.push(rows)?))?;
        blocks.finish()
    })
}

/// Writes an OpenEXR file of `header` ([`ExrBlocks::header`]) whose
/// blocks `fill` hands over, compressed ([`ExrBlocks::push`]), in any
/// order; each block's buffer goes back to `spares` once written. Blocks
/// made on other threads, as the streamed conversion makes them, only
/// need writing here.
///
/// The file is what `exr::block::write` makes of the same header and
/// blocks, byte for byte (a test checks it): the header, the offset
/// table, filled in at the end, and the blocks. It is written here
/// because that writer takes each block's buffer and frees it: a new
/// buffer per block, 786 KB for 16 rows of a 4096-wide float map, cost a
/// page fault per 4 KiB (35 000 at 4096², 14 % of that conversion's
/// processor time).
///
/// Errors: [`Error::Io`] if `out` fails, [`Error::Encode`] for an invalid
/// header, a block the file has no room for, one written twice or one
/// missing at the end; any error of `fill`, which stops the writing.
pub(crate) fn write_exr_blocks<W: Write + Seek>(
    mut out: W,
    header: &Header,
    spares: &ExrSpares,
    fill: impl FnOnce(&mut dyn FnMut(Vec<IndexedChunk>) -> Result<()>) -> Result<()>,
) -> Result<()> {
    let headers = [header.clone()];
    let requirements = MetaData::validate(&headers, true).map_err(from_exr_error)?;
    let start = out.stream_position()?;
    let mut file = Counting { out: &mut out, written: 0 };
    magic_number::write(&mut file).map_err(from_exr_error)?;
    requirements.write(&mut file).map_err(from_exr_error)?;
    Header::write_all(&headers, &mut file, requirements.has_multiple_layers).map_err(from_exr_error)?;
    // The offset table, zeros until every block's place is known.
    let table_at = file.written;
    let mut offsets = vec![0u64; header.chunk_count];
    file.write_all(&vec![0u8; offsets.len() * 8])?;
    fill(&mut |chunks| {
        for (index, chunk) in chunks {
            let slot = offsets.get_mut(index).ok_or_else(|| Error::Encode(format!("the file has no block {index}")))?;
            if *slot != 0 {
                return Err(Error::Encode(format!("block {index} is written twice")));
            }
            *slot = file.written;
            chunk.write(&mut file, 1).map_err(from_exr_error)?;
            if let CompressedBlock::ScanLine(block) = chunk.compressed_block {
                spares.give(block.compressed_pixels_le);
            }
        }
        Ok(())
    })?;
    if let Some(missing) = offsets.iter().position(|&at| at == 0) {
        return Err(Error::Encode(format!("block {missing} of {} was not written", offsets.len())));
    }
    out.seek(SeekFrom::Start(start + table_at))?;
    out.write_all(&offsets.iter().flat_map(|at| at.to_le_bytes()).collect::<Vec<u8>>())?;
    out.flush()?;
    Ok(())
}

/// A writer that counts the bytes it passes on: the places of an EXR
/// file's blocks, for its offset table.
struct Counting<'a, W> {
    out: &'a mut W,
    written: u64,
}

impl<W: Write> Write for Counting<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.out.write(buf)?;
        self.written += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// Where the buffers of written EXR blocks go back to their
/// [`ExrBlocks`], to hold the next blocks: their pages stay mapped (see
/// [`write_exr_blocks`]). A few are kept; the rest are freed.
#[derive(Clone)]
pub(crate) struct ExrSpares(SyncSender<Vec<u8>>);

impl ExrSpares {
    /// Gives a written block's buffer back (or frees it, if enough are
    /// waiting already).
    fn give(&self, buffer: Vec<u8>) {
        let _ = self.0.try_send(buffer);
    }
}

/// A compressed block of an EXR file and its index in the file's blocks.
pub(crate) type IndexedChunk = (usize, Chunk);

/// The rows of an EXR file being written, cut into compressed blocks.
pub(crate) struct ExrBlocks {
    width: usize,
    height: usize,
    depth: ExrDepth,
    /// The channels' names, as a texel's samples come.
    channels: Vec<String>,
    /// The index in a texel's samples of each channel, in the file's order
    /// (sorted by name: B, G, R).
    order: Vec<usize>,
    /// Samples of the rows after row `done` that do not fill a block yet.
    pending: Vec<f32>,
    done: usize,
    /// Buffers of written blocks, to fill again, and where they come from.
    spare: Receiver<Vec<u8>>,
    spares: ExrSpares,
}

impl ExrBlocks {
    /// The blocks of a `width` × `height` image with `channels` (named as
    /// a texel's samples come), each `depth`.
    ///
    /// Errors: [`Error::Encode`] for a zero size, or more rows than EXR
    /// can index.
    pub(crate) fn new(width: usize, height: usize, depth: ExrDepth, channels: &[&str]) -> Result<ExrBlocks> {
        if width == 0 || height == 0 {
            return Err(Error::Encode("image has zero size".into()));
        }
        if i32::try_from(height).is_err() || i32::try_from(width).is_err() {
            return Err(Error::Encode(format!("{width} × {height} texels are beyond what EXR can index")));
        }
        let mut order: Vec<usize> = (0..channels.len()).collect();
        order.sort_by_key(|&k| channels[k]);
        let channels = channels.iter().map(|&c| c.to_owned()).collect();
        // Enough for the blocks of a band or two (a band is 64 rows or
        // more, 4 blocks); more would only hold memory.
        let (give, spare) = sync_channel(32);
        let spares = ExrSpares(give);
        Ok(ExrBlocks { width, height, depth, channels, order, pending: Vec::new(), done: 0, spare, spares })
    }

    /// Where the writer gives written blocks' buffers back.
    pub(crate) fn spares(&self) -> ExrSpares {
        self.spares.clone()
    }

    /// The file's header.
    pub(crate) fn header(&self) -> Header {
        let sample = match self.depth {
            ExrDepth::Half => ExrSample::F16,
            ExrDepth::Float => ExrSample::F32,
        };
        let descriptions = self.order.iter().map(|&k| ChannelDescription::named(self.channels[k].as_str(), sample));
        Header::new(Text::from(""), (self.width, self.height), SmallVec::from_iter(descriptions))
            .with_encoding(Compression::ZIP16, BlockDescription::ScanLines, LineOrder::Increasing)
            .with_attributes(LayerAttributes::default())
    }

    /// Takes more rows; returns the blocks they complete, compressed in
    /// parallel. Whole blocks are read from `rows` where they lie; only
    /// the rows of a block not yet complete are kept.
    ///
    /// Errors: [`Error::Encode`] for samples that are not whole rows, or
    /// rows past the last.
    pub(crate) fn push(&mut self, mut rows: &[f32]) -> Result<Vec<IndexedChunk>> {
        let row_len = self.width * self.order.len();
        let pending_rows = self.pending.len() / row_len;
        if !rows.len().is_multiple_of(row_len) || self.done + pending_rows + rows.len() / row_len > self.height {
            return Err(Error::Encode(format!("{} samples are not whole rows of the image", rows.len())));
        }
        let block = EXR_BLOCK_ROWS * row_len;
        let last = self.done + pending_rows + rows.len() / row_len == self.height;
        // The rows kept from before make a block first, if these complete it.
        let take = if self.pending.is_empty() { 0 } else { (block - self.pending.len()).min(rows.len()) };
        self.pending.extend_from_slice(&rows[..take]);
        rows = &rows[take..];
        let pending_ready = !self.pending.is_empty() && (self.pending.len() == block || (last && rows.is_empty()));
        if !self.pending.is_empty() && !pending_ready {
            return Ok(Vec::new());
        }
        let ready = if last { rows.len() } else { rows.len() - rows.len() % block };
        let first_row = self.done;
        let blocks: Vec<&[f32]> =
            (pending_ready.then_some(&self.pending[..])).into_iter().chain(rows[..ready].chunks(block)).collect();
        let (depth, order) = (self.depth, &self.order[..]);
        let buffers: Vec<Vec<u8>> = blocks.iter().map(|_| self.spare.try_recv().unwrap_or_default()).collect();
        let chunks = blocks
            .par_iter()
            .zip(buffers)
            .enumerate()
            .map(|(k, (samples, buffer))| {
                let y0 = first_row + k * EXR_BLOCK_ROWS;
                (y0 / EXR_BLOCK_ROWS, zip_chunk(samples, row_len, order, y0, depth, buffer))
            })
            .collect::<Vec<_>>();
        self.done += blocks.iter().map(|b| b.len() / row_len).sum::<usize>();
        self.pending.clear();
        self.pending.extend_from_slice(&rows[ready..]);
        Ok(chunks)
    }

    /// Checks that every row came.
    pub(crate) fn finish(&self) -> Result<()> {
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
/// took 85 % of an EXR conversion's time; level 1 is several times
/// faster. On a 4096² map of float heights in these blocks, level 1 took
/// 0.38 s to 86 % of the size; libdeflate's level 1 0.41 s to 71 %,
/// zlib-rs's 0.44 s to 86 %, and fdeflate (made for PNG's filtered bytes)
/// 0.07 s to 137 %. A block that does not shrink is stored as it is,
/// which is how EXR readers tell the two apart. The raw bytes are laid
/// out in `raw` (a written block's buffer, or a new one).
fn zip_chunk(samples: &[f32], row_len: usize, order: &[usize], y0: usize, depth: ExrDepth, mut raw: Vec<u8>) -> Chunk {
    exr_block_bytes(samples, row_len, order, depth, &mut raw);
    // `ExrBlocks::new` checked that every row is an i32.
    let y_coordinate = y0 as i32;
    // Float normals do not deflate: judged by the first bytes alone, such
    // a block is stored without its whole split and differences made.
    let compressed_pixels_le = if incompressible(&zip_predicted(&raw, EXR_PROBE_BYTES)) {
        raw
    } else {
        match zlib(&zip_predicted(&raw, raw.len())) {
            Some(compressed) if compressed.len() < raw.len() => compressed,
            _ => raw,
        }
    };
    Chunk {
        layer_index: 0,
        compressed_block: CompressedBlock::ScanLine(CompressedScanLineBlock { y_coordinate, compressed_pixels_le }),
    }
}

/// The first `len` bytes (at most all) of what EXR's ZIP deflates for the
/// block `raw`: its even bytes, then its odd ones, each byte replaced by
/// its difference from the one before, plus 128.
fn zip_predicted(raw: &[u8], len: usize) -> Vec<u8> {
    let len = len.min(raw.len());
    let half = raw.len().div_ceil(2);
    let mut split = vec![0u8; len];
    let (even, odd) = split.split_at_mut(half.min(len));
    for (e, pair) in even.iter_mut().zip(raw.chunks(2)) {
        *e = pair[0];
    }
    for (o, pair) in odd.iter_mut().zip(raw.chunks_exact(2)) {
        *o = pair[1];
    }
    let mut deltas = Vec::with_capacity(len);
    deltas.extend(split.first());
    deltas.extend(split.iter().zip(&split[1.min(len)..]).map(|(&before, &b)| b.wrapping_sub(before).wrapping_add(128)));
    deltas
}

/// Bytes of a block deflated first, to judge whether the rest is worth it.
const EXR_PROBE_BYTES: usize = 16 << 10;

/// Whether a block's bytes (after EXR's split and deltas) are not worth
/// deflating: their first [`EXR_PROBE_BYTES`] shrink by less than 3 %.
/// Float normals are such blocks: their low mantissa bits are noise, and
/// a 4096² float EXR shrank by 0.75 % in all, for 60 % of its
/// conversion's processor time (1.5 s of 2.5 s on 2 cores). Such a block
/// is stored as it is (what a block that does not shrink always was);
/// half floats and smooth maps deflate as before. The verdict depends on
/// the block's bytes only, so every writer of the same samples writes the
/// same file.
fn incompressible(deltas: &[u8]) -> bool {
    let probe = &deltas[..deltas.len().min(EXR_PROBE_BYTES)];
    probe.len() == EXR_PROBE_BYTES && zlib(probe).is_none_or(|deflated| deflated.len() * 100 > probe.len() * 97)
}

/// `data` as zlib at [`EXR_ZLIB_LEVEL`], what miniz_oxide's
/// `compress_to_vec_zlib` makes of it, by a compressor kept per thread:
/// that function makes a new one per call, whose tables were allocated
/// and zeroed for every block's probe: a float EXR's conversion had 17 000
/// page faults with it, 7 600 without (4096², 10 % of its processor
/// time). `None` if miniz_oxide fails (which that function would panic
/// on): the block is stored.
fn zlib(mut data: &[u8]) -> Option<Vec<u8>> {
    thread_local! {
        static COMPRESSOR: RefCell<Box<CompressorOxide>> = RefCell::new(Box::default());
    }
    COMPRESSOR.with_borrow_mut(|compressor| {
        compressor.reset();
        compressor.set_format_and_level(DataFormat::Zlib, EXR_ZLIB_LEVEL);
        let mut out = vec![0; (data.len() / 2).max(2)];
        let mut len = 0;
        loop {
            let (status, read, written) = compress(compressor, data, &mut out[len..], TDEFLFlush::Finish);
            len += written;
            data = &data[read.min(data.len())..];
            match status {
                TDEFLStatus::Done => break,
                TDEFLStatus::Okay if out.len() - len < 30 => out.resize(out.len() * 2, 0),
                TDEFLStatus::Okay => {}
                // Only for a wrong argument, which this is not.
                TDEFLStatus::BadParam | TDEFLStatus::PutBufFailed => return None,
            }
        }
        out.truncate(len);
        Some(out)
    })
}

/// One block's bytes as EXR stores them before compression, in `out`:
/// row by row, each channel's samples in the file's order (`order`: the
/// index of each in a texel's samples), little-endian.
fn exr_block_bytes(samples: &[f32], row_len: usize, order: &[usize], depth: ExrDepth, out: &mut Vec<u8>) {
    match depth {
        ExrDepth::Half => channel_major(samples, row_len, order, |v| f16::from_f32(v).to_le_bytes(), out),
        ExrDepth::Float => channel_major(samples, row_len, order, f32::to_le_bytes, out),
    }
}

/// The samples of each row channel by channel (`order`), each as `bytes`
/// gives it, in `out`. `out` is resized, not cleared: a written block's
/// buffer has the length already, so its bytes are overwritten without
/// first being zeroed. Plain loops over fixed-size chunks: an iterator
/// chain here (`step_by`, `flat_map`) was once left out of line by the
/// compiler and took 7 % of an EXR conversion.
fn channel_major<const N: usize>(
    samples: &[f32],
    row_len: usize,
    order: &[usize],
    bytes: impl Fn(f32) -> [u8; N],
    out: &mut Vec<u8>,
) {
    let stride = order.len().max(1);
    let plane = row_len / stride * N;
    out.resize(samples.len() * N, 0);
    for (row, out_row) in samples.chunks_exact(row_len).zip(out.chunks_exact_mut(row_len * N)) {
        for (&c, out_plane) in order.iter().zip(out_row.chunks_exact_mut(plane.max(1))) {
            for (o, texel) in out_plane.chunks_exact_mut(N).zip(row.chunks_exact(stride)) {
                o.copy_from_slice(&bytes(texel[c]));
            }
        }
    }
}

/// Maps `exr`'s errors like [`from_image_error`].
fn from_exr_error(e: exr::error::Error) -> Error {
    match e {
        exr::error::Error::Io(e) => Error::Io(e),
        other => Error::Encode(one_line(&other.to_string()).to_lowercase()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use exr::block::writer::ChunksWriter;

    /// The blocks' bytes, in the file's order.
    fn blocks_of(chunks: Vec<IndexedChunk>) -> Vec<(usize, i32, Vec<u8>)> {
        chunks
            .into_iter()
            .map(|(index, chunk)| match chunk.compressed_block {
                CompressedBlock::ScanLine(b) => (index, b.y_coordinate, b.compressed_pixels_le),
                other => panic!("not a scan-line block: {other:?}"),
            })
            .collect()
    }

    /// However the rows come (one at a time, in bands that straddle
    /// blocks, all at once), the blocks are the same, and whole.
    #[test]
    fn blocks_do_not_depend_on_how_rows_are_pushed() {
        let (w, h) = (37, 53); // 3 whole blocks and a last one of 5 rows
        for depth in [ExrDepth::Half, ExrDepth::Float] {
            // Smooth samples (that deflate) and noisy ones (that do not).
            let samples: Vec<f32> = (0..w * h * 3)
                .map(|i| if i % 7 == 0 { (i as f32 * 0.618).fract() } else { (i / 3 % w) as f32 * 0.01 })
                .collect();
            let row_len = w * 3;
            let mut expected = None;
            for band in [1, 5, 16, 17, 40, h] {
                let mut blocks = ExrBlocks::new(w, h, depth, &["R", "G", "B"]).unwrap();
                let mut chunks = Vec::new();
                for rows in samples.chunks(band * row_len) {
                    chunks.extend(blocks.push(rows).unwrap());
                }
                blocks.finish().unwrap();
                let got = blocks_of(chunks);
                let indices: Vec<usize> = got.iter().map(|b| b.0).collect();
                assert_eq!(indices, [0, 1, 2, 3], "bands of {band}");
                let ys: Vec<i32> = got.iter().map(|b| b.1).collect();
                assert_eq!(ys, [0, 16, 32, 48], "bands of {band}");
                match &expected {
                    None => expected = Some(got),
                    Some(e) => assert!(*e == got, "bands of {band} give other blocks"),
                }
            }
        }
    }

    /// Rows past the last, rows that are not whole, and rows missing at
    /// the end are errors.
    #[test]
    fn blocks_refuse_rows_that_do_not_fit() {
        let mut blocks = ExrBlocks::new(4, 3, ExrDepth::Float, &["Y"]).unwrap();
        assert!(blocks.push(&[0.0; 5]).is_err());
        assert!(blocks.push(&[0.0; 8]).unwrap().is_empty());
        assert!(blocks.finish().is_err());
        assert!(blocks.push(&[0.0; 8]).is_err());
        assert_eq!(blocks.push(&[0.0; 4]).unwrap().len(), 1);
        blocks.finish().unwrap();
        assert!(ExrBlocks::new(0, 3, ExrDepth::Float, &["Y"]).is_err());
    }

    /// Samples of `w` × `h` RGB texels whose blocks differ: smooth rows
    /// (that deflate) and noisy ones (that do not), by block.
    fn mixed_samples(w: usize, h: usize) -> Vec<f32> {
        (0..w * h * 3)
            .map(|i| {
                let y = i / (3 * w);
                if y / 16 % 2 == 1 { (i as f32 * 0.618_034).fract() } else { (i / 3 % w) as f32 * 0.01 }
            })
            .collect()
    }

    /// The file is `exr`'s own writer's, byte for byte, for the same
    /// header and blocks, whichever order they come in; buffers given
    /// back and filled again (by a shorter last block, by a deflated
    /// block's smaller one) leave nothing of their old bytes.
    #[test]
    fn exr_files_are_exrs_own_byte_for_byte() {
        let (w, h) = (29, 16 * 7 + 3);
        for depth in [ExrDepth::Half, ExrDepth::Float] {
            let samples = mixed_samples(w, h);
            let fresh = || {
                let mut blocks = ExrBlocks::new(w, h, depth, &["R", "G", "B"]).unwrap();
                let chunks = blocks.push(&samples).unwrap();
                (blocks.header(), chunks)
            };
            for reversed in [false, true] {
                let (header, mut chunks) = fresh();
                if reversed {
                    chunks.reverse();
                }
                let mut expected = std::io::Cursor::new(Vec::new());
                exr::block::write(&mut expected, SmallVec::from_elem(header, 1), true, |_, writer| {
                    chunks.into_iter().try_for_each(|(index, chunk)| writer.write_chunk(index, chunk))
                })
                .unwrap();
                let mut blocks = ExrBlocks::new(w, h, depth, &["R", "G", "B"]).unwrap();
                let (header, spares) = (blocks.header(), blocks.spares());
                let mut got = std::io::Cursor::new(Vec::new());
                write_exr_blocks(&mut got, &header, &spares, |write| {
                    let mut all = Vec::new();
                    // Two rows at a time: blocks are written (and their
                    // buffers given back) while later ones are made.
                    for rows in samples.chunks(2 * w * 3) {
                        let made = blocks.push(rows)?;
                        if reversed { all.extend(made) } else { write(made)? }
                    }
                    all.reverse();
                    write(all)?;
                    blocks.finish()
                })
                .unwrap();
                assert!(got.into_inner() == expected.into_inner(), "{depth:?}, reversed: {reversed}");
            }
        }
    }

    /// A block written twice, one the file has no room for, and one
    /// missing at the end are errors, not a file.
    #[test]
    fn exr_files_refuse_blocks_that_do_not_fit() {
        let (w, h) = (5, 40);
        let samples = mixed_samples(w, h);
        let attempt = |edit: &dyn Fn(&mut Vec<IndexedChunk>)| {
            let mut blocks = ExrBlocks::new(w, h, ExrDepth::Float, &["R", "G", "B"]).unwrap();
            let (header, spares) = (blocks.header(), blocks.spares());
            let mut chunks = blocks.push(&samples).unwrap();
            edit(&mut chunks);
            write_exr_blocks(std::io::Cursor::new(Vec::new()), &header, &spares, |write| write(chunks))
        };
        assert!(attempt(&|_| {}).is_ok());
        let twice = attempt(&|c| {
            let copy = (c[0].0, c[0].1.clone());
            c.push(copy);
        });
        assert!(matches!(twice, Err(Error::Encode(m)) if m.contains("twice")));
        let beyond = attempt(&|c| c[2].0 = 3);
        assert!(matches!(beyond, Err(Error::Encode(m)) if m.contains("no block 3")));
        let missing = attempt(&|c| {
            c.pop();
        });
        assert!(matches!(missing, Err(Error::Encode(m)) if m.contains("block 2 of 3 was not written")));
    }

    /// The compressor kept per thread deflates as a new one does, call
    /// after call.
    #[test]
    fn zlib_is_miniz_oxides_own() {
        let inputs: Vec<Vec<u8>> = vec![
            Vec::new(),
            vec![7],
            (0..100_000u32).map(|i| (i % 251) as u8).collect(),
            (0..70_000u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8).collect(),
            vec![0; 50_000],
        ];
        for data in inputs.iter().chain(inputs.iter().rev()) {
            let expected = miniz_oxide::deflate::compress_to_vec_zlib(data, EXR_ZLIB_LEVEL);
            assert_eq!(zlib(data).unwrap(), expected, "{} bytes", data.len());
        }
    }

    /// The predicted bytes are EXR's: even bytes, then odd ones, each the
    /// difference from the one before plus 128; a prefix is the prefix.
    #[test]
    fn zip_prediction_is_exrs() {
        let raw = [10u8, 20, 13, 25, 7];
        // Split: 10 13 7 | 20 25; differences + 128.
        let whole = [10u8, 131, 122, 141, 133];
        assert_eq!(zip_predicted(&raw, raw.len()), whole);
        assert_eq!(zip_predicted(&raw, 3), whole[..3]);
        assert_eq!(zip_predicted(&raw, 99), whole);
        assert!(zip_predicted(&[], 4).is_empty());
    }
}
