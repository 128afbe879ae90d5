//! A scan-line OpenEXR file's rows, decoded block by block ahead of the
//! rows asked for ([`ExrRows`]), for the streaming pipeline
//! ([`crate::pipeline`]).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Seek, SeekFrom};
use std::path::Path;

use exr::block::UncompressedBlock;
use exr::block::reader::ChunksReader;
use exr::meta::BlockDescription;
use exr::meta::attribute::{ChannelList, SampleType as ExrSample};
use exr::prelude::{Vec2, f16};

use super::subsampled::{self as exr_subsampled, Headers, ScanLines};
use super::{EXR_MAGIC, check_exr_meta, check_exr_windows, choose_exr_layer, exr_parts, from_exr_error};
use crate::error::{Error, Result};
use crate::io::read::{Channel, Source, select_channel};
use crate::io::rows::RowSource;
use crate::io::{InputFormat, ReadOptions};
use crate::samples::luma;

/// The decompressed blocks of a file, in the order they finish.
type Blocks = Box<dyn Iterator<Item = exr::error::Result<UncompressedBlock>> + Send>;

/// The rows of a scan-line OpenEXR file, top to bottom, as heights.
///
/// Blocks (1 to 32 rows, by compression) are decompressed on a few
/// threads ahead of the rows asked for; a block that arrives before its
/// turn waits. Files written top to bottom (line order "increasing", what
/// writers use) then hold a few blocks in memory, whatever their height.
/// Files with subsampled channels, which the `exr` crate refuses, are read
/// block by block through their offset table instead.
pub struct ExrRows {
    decoder: Decoder,
    source: Source,
    width: usize,
    height: usize,
    lines_per_block: usize,
    /// The heights of the block being handed out, from row `current_y0`.
    current: Vec<f64>,
    current_y0: usize,
    /// The wanted channels' planes of the block being read, and one line's
    /// samples as stored: kept from block to block, so that a block's
    /// buffers are not new pages each time (under glibc's
    /// `MALLOC_TRIM_THRESHOLD_`, which Dask sets, freed blocks went back to
    /// the system and every block's buffers came back as fresh pages:
    /// twice the processor time of a 16384² EXR conversion).
    planes: Vec<Vec<f64>>,
    line: LineSamples,
    /// The next row handed out.
    next: usize,
}

/// Where the blocks come from.
enum Decoder {
    /// The `exr` crate's decompressors, over the blocks of one part.
    Exr {
        blocks: Blocks,
        channels: ChannelList,
        part: usize,
        /// Blocks that arrived before their turn, by first row.
        early: BTreeMap<usize, UncompressedBlock>,
    },
    /// A file with subsampled channels ([`ScanLines`]).
    Subsampled { file: BufReader<File>, part: ScanLines },
}

impl ExrRows {
    /// Opens `path` for streaming if it is an OpenEXR file that can stream:
    /// a part of scan lines (the first, or the one `opts.layer` names),
    /// one resolution level, no deep data. `Ok(None)` otherwise (not EXR,
    /// tiled, …), and the caller reads the image whole. Reads only the
    /// headers. `opts.layer` may also pick a group of the part's channels
    /// ([`ReadOptions::layer`]). Subsampled channels (luminance/chroma
    /// files) are skipped, as the whole-image reader skips them.
    ///
    /// Errors: [`Error::Io`](crate::Error::Io) if the file cannot be opened, [`Error::Decode`](crate::Error::Decode)
    /// for a corrupt header (an inverted window among them),
    /// [`Error::Limits`](crate::Error::Limits) for a size above `opts.max_texels`,
    /// [`Error::Unsupported`](crate::Error::Unsupported) for a missing channel or layer.
    pub fn open(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<ExrRows>> {
        Self::open_from(path, opts, channel.as_ref(), 0)
    }

    /// The last `rows` rows of `path` (fewer if the image is shorter),
    /// decoding only the blocks that hold them: the tail a wrap in y needs
    /// for the top rows ([`convert_exr`](crate::pipeline::convert_exr), [`convert_png`](crate::pipeline::convert_png)).
    ///
    /// Errors: as [`ExrRows::open`], and [`Error::Unsupported`](crate::Error::Unsupported) if the file
    /// cannot stream.
    pub fn last_rows(path: &Path, opts: &ReadOptions, channel: Option<Channel>, rows: usize) -> Result<Vec<f64>> {
        let channel = channel.as_ref();
        let probe = Self::open_from(path, opts, channel, 0)?.ok_or_else(not_streamable)?;
        let (w, h) = (probe.width, probe.height);
        drop(probe);
        let keep = rows.min(h);
        let mut source = Self::open_from(path, opts, channel, h - keep)?.ok_or_else(not_streamable)?;
        let mut tail = crate::io::rows::zeroed(keep * w)?;
        tail.chunks_exact_mut(w.max(1)).try_for_each(|row| source.next_row(row))?;
        Ok(tail)
    }

    /// Opens the file to hand out rows from `first_row` on; only the blocks
    /// that hold them are read.
    fn open_from(
        path: &Path,
        opts: &ReadOptions,
        channel: Option<&Channel>,
        first_row: usize,
    ) -> Result<Option<ExrRows>> {
        // A band, a packing or a RAW layout is the whole-image reader's to
        // apply (and to refuse for an EXR, with its message).
        if !opts.may_stream(path) {
            return Ok(None);
        }
        crate::io::read::formats::check_extension(path)?;
        let file = File::open(path)?;
        let file_len = file.metadata()?.len();
        let mut file = BufReader::with_capacity(1 << 16, file);
        if !std::io::BufRead::fill_buf(&mut file)?.starts_with(&EXR_MAGIC) {
            return Ok(None);
        }
        check_exr_windows(&mut file)?;
        file.seek(SeekFrom::Start(0))?;
        if let Some(headers) = exr_subsampled::read_headers(&mut file).filter(Headers::subsampled) {
            let part = ScanLines::open(headers, &mut file, file_len, opts)?;
            let (indices, names): (Vec<usize>, Vec<&str>) = part.channels().unzip();
            let source = channel_source(&indices, &names, channel)?;
            let (width, height, lines_per_block) = (part.width(), part.height(), part.lines_per_block());
            let decoder = Decoder::Subsampled { file, part };
            return Ok(Some(ExrRows::new(decoder, source, (width, height), lines_per_block, first_row)));
        }
        file.seek(SeekFrom::Start(0))?;
        let reader = exr::block::read(file, false).map_err(from_exr_error)?;
        check_exr_meta(reader.meta_data(), file_len, opts)?;
        let layer = choose_exr_layer(&exr_parts(reader.headers()), opts.layer.as_deref())?;
        let part = layer.part;
        let Some(header) = reader.headers().get(part) else { return Ok(None) };
        if header.deep || header.blocks != BlockDescription::ScanLines {
            return Ok(None);
        }
        // The channel rule runs on the layer's channels; `source` indexes
        // the part's whole channel list.
        let (indices, names): (Vec<usize>, Vec<String>) = (header.channels.list.iter().enumerate())
            .map(|(i, c)| (i, c.name.to_string()))
            .filter(|(_, name)| layer.holds(name))
            .unzip();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let source = channel_source(&indices, &names, channel)?;
        let size = (header.layer_size.0, header.layer_size.1);
        let channels = header.channels.clone();
        let lines_per_block = header.compression.scan_lines_per_block();
        let first_block = first_row - first_row % lines_per_block;

        let chunks = reader
            .filter_chunks(false, |_, _, block| {
                block.layer == part && block.pixel_position.y() + block.pixel_size.y() > first_block
            })
            .map_err(from_exr_error)?;
        // exr decompresses blocks on threads only with its `rayon` feature,
        // which normalfit's `parallel` turns on.
        #[cfg(feature = "parallel")]
        let blocks: Blocks = match chunks.parallel_decompressor(false) {
            Ok(parallel) => Box::new(parallel),
            Err(chunks) => Box::new(chunks.sequential_decompressor(false)),
        };
        #[cfg(not(feature = "parallel"))]
        let blocks: Blocks = Box::new(chunks.sequential_decompressor(false));
        let decoder = Decoder::Exr { blocks, channels, part, early: BTreeMap::new() };
        Ok(Some(ExrRows::new(decoder, source, size, lines_per_block, first_row)))
    }

    fn new(decoder: Decoder, source: Source, size: (usize, usize), lines_per_block: usize, first_row: usize) -> Self {
        ExrRows {
            decoder,
            source,
            width: size.0,
            height: size.1,
            lines_per_block,
            current: Vec::new(),
            current_y0: first_row - first_row % lines_per_block,
            planes: Vec::new(),
            line: LineSamples::default(),
            next: first_row,
        }
    }

    /// Makes the block that starts at row `y0` the current one.
    fn load_block(&mut self, y0: usize) -> Result<()> {
        let rows = self.lines_per_block.min(self.height - y0);
        let wanted: Vec<usize> = match self.source {
            Source::Plane(c) => vec![c],
            Source::Luma(rgb) => rgb.to_vec(),
        };
        match &mut self.decoder {
            Decoder::Exr { blocks, channels, part, early } => {
                let block = next_block(blocks, early, *part, y0, self.lines_per_block, self.height)?;
                let index = block.index;
                if index.pixel_position.x() != 0
                    || index.pixel_size != Vec2(self.width, rows)
                    || index.level != Vec2(0, 0)
                {
                    return Err(Error::Decode(format!("block for row {y0} has the wrong size")));
                }
                let into = (&mut self.planes, &mut self.line);
                block_planes(&block, channels, &wanted, (self.width, y0, rows), into)?;
            }
            Decoder::Subsampled { file, part } => self.planes = part.read_block(file, y0, &wanted)?,
        }
        match self.planes.as_mut_slice() {
            [r, g, b] => {
                self.current.clear();
                self.current.extend(r.iter().zip(&*g).zip(&*b).map(|((&r, &g), &b)| luma(r, g, b)));
            }
            // The plane becomes the current block, and the current block's
            // buffer the plane's for the next.
            [plane, ..] => std::mem::swap(&mut self.current, plane),
            [] => unreachable!("one or three channels are wanted"),
        }
        self.current_y0 = y0;
        Ok(())
    }
}

/// SPEC §1's channel rule over a layer's channels, `names`, whose indices
/// in the part's channel list are `indices`: the source, by the latter.
fn channel_source(indices: &[usize], names: &[&str], channel: Option<&Channel>) -> Result<Source> {
    Ok(match select_channel(names, channel, &InputFormat::Exr)? {
        Source::Plane(i) => Source::Plane(indices[i]),
        Source::Luma(rgb) => Source::Luma(rgb.map(|i| indices[i])),
    })
}

/// The decompressed block of `part` that starts at row `y0`, from those
/// that arrived early or the next ones to finish.
fn next_block(
    blocks: &mut Blocks,
    early: &mut BTreeMap<usize, UncompressedBlock>,
    part: usize,
    y0: usize,
    lines_per_block: usize,
    height: usize,
) -> Result<UncompressedBlock> {
    loop {
        if let Some(block) = early.remove(&y0) {
            return Ok(block);
        }
        let block = match blocks.next() {
            Some(block) => block.map_err(from_exr_error)?,
            None => return Err(Error::Decode(format!("image data ends after {y0} of {height} rows"))),
        };
        if block.index.layer != part {
            return Err(Error::Decode(format!("a block of part {} is among those of part {part}", block.index.layer)));
        }
        let at = block.index.pixel_position.y();
        if at == y0 {
            return Ok(block);
        }
        if at < y0 || at % lines_per_block != 0 || early.insert(at, block).is_some() {
            return Err(Error::Decode(format!("block for row {at} is misplaced or repeated")));
        }
    }
}

/// One line's samples as a block stores them, for [`block_planes`].
#[derive(Default)]
struct LineSamples {
    floats: Vec<f32>,
    halves: Vec<f16>,
    ints: Vec<u32>,
}

/// The rows of the `wanted` channels of a block (`rows` rows of `w` from
/// row `y0`), widened to f64, into `planes` (one a wanted channel, 0 where
/// the block has no line), with `line` for the samples as stored.
fn block_planes(
    block: &UncompressedBlock,
    channels: &ChannelList,
    wanted: &[usize],
    (w, y0, rows): (usize, usize, usize),
    (planes, line_samples): (&mut Vec<Vec<f64>>, &mut LineSamples),
) -> Result<()> {
    planes.resize_with(wanted.len(), Vec::new);
    for plane in planes.iter_mut() {
        plane.clear();
        plane.resize(rows * w, 0.0);
    }
    let LineSamples { floats, halves, ints } = line_samples;
    for line in block.lines(channels) {
        let Some(k) = wanted.iter().position(|&c| c == line.location.channel) else { continue };
        let row = line.location.position.y() - y0;
        let out = &mut planes[k][row * w..][..w];
        // Every sample type widened to f64, exactly (the whole-image
        // reader keeps u32 in f64 too).
        let read = match channels.list[line.location.channel].sample_type {
            ExrSample::F32 => {
                floats.resize(w, 0.0);
                line.read_samples_into_slice(floats).map(|()| {
                    out.iter_mut().zip(&*floats).for_each(|(o, &v)| *o = f64::from(v));
                })
            }
            ExrSample::F16 => {
                halves.resize(w, f16::ZERO);
                line.read_samples_into_slice(halves).map(|()| {
                    out.iter_mut().zip(&*halves).for_each(|(o, h)| *o = f64::from(h.to_f32()));
                })
            }
            ExrSample::U32 => {
                ints.resize(w, 0);
                line.read_samples_into_slice(ints).map(|()| {
                    out.iter_mut().zip(&*ints).for_each(|(o, &n)| *o = f64::from(n));
                })
            }
        };
        read.map_err(from_exr_error)?;
    }
    Ok(())
}

impl RowSource for ExrRows {
    fn width(&self) -> usize {
        self.width
    }

    fn height(&self) -> usize {
        self.height
    }

    fn unit(&self) -> f64 {
        1.0
    }

    fn next_row(&mut self, out: &mut [f64]) -> Result<()> {
        let (w, y) = (self.width, self.next);
        if y >= self.height {
            return Err(Error::Decode(format!("all {} rows have been read", self.height)));
        }
        if out.len() != w {
            return Err(Error::BufferSize { expected: w, actual: out.len() });
        }
        if y >= self.current_y0 + self.current.len() / w.max(1) || self.current.is_empty() {
            self.load_block(y - y % self.lines_per_block)?;
        }
        out.copy_from_slice(&self.current[(y - self.current_y0) * w..][..w]);
        self.next += 1;
        Ok(())
    }

    /// One channel of half or float samples; not luma, not u32.
    fn exact_in_f32(&self) -> bool {
        match (&self.source, &self.decoder) {
            (Source::Plane(c), Decoder::Exr { channels, .. }) => {
                channels.list.get(*c).is_some_and(|ch| ch.sample_type != ExrSample::U32)
            }
            (Source::Plane(c), Decoder::Subsampled { part, .. }) => !part.is_int(*c),
            (Source::Luma(_), _) => false,
        }
    }

    // `next_row_f32`: the trait's, from the f64 rows (exact when
    // `exact_in_f32`).
}

fn not_streamable() -> Error {
    Error::Unsupported("only scan-line EXR parts can be read by rows".into())
}
