//! OpenEXR files with subsampled channels, read without the `exr` crate.
//!
//! A luminance/chroma file (OpenEXR's "YC" or `RgbaYca` layout) stores Y,
//! and A if any, at full resolution, and RY and BY subsampled (x and y
//! sampling 2). The `exr` crate refuses every header with a sampling other
//! than 1 × 1 ("channel subsampling not supported yet"; its issue 15), its
//! metadata included, so such a file would never reach the channel rule,
//! although its height, Y, is not subsampled. This module reads the
//! scan-line parts of such files itself: their full-resolution channels
//! (the subsampled ones are skipped, never heights), for the compressions
//! whose decompressed block is the plain line layout below: none, RLE,
//! ZIPS and ZIP. PIZ, PXR24, B44, B44A and DWA transform each channel as a
//! 2-D array of its own (subsampled) size; those files are refused by
//! name. Files without a subsampled channel never come here: the `exr`
//! crate reads them.
//!
//! The layout (OpenEXR's "file layout" document): the magic number and
//! version, the header (attributes until an empty name; in a multi-part
//! file, headers until an empty one), one offset table per part (a u64
//! file position per chunk, blocks top to bottom whatever the line order),
//! then the chunks. A scan-line chunk is: the part number (multi-part
//! files only), the block's first y, the data's size, the data. The data,
//! decompressed, holds for each line y of the block, and in it for each
//! channel in the header's (alphabetical) order, the line's samples
//! little-endian if y is a multiple of the channel's y sampling — width /
//! x sampling of them — and nothing otherwise. A block whose compressed
//! data would not be smaller than that is stored as it is.

use std::io::{BufRead, Read, Seek, SeekFrom};

use exr::prelude::f16;

use super::{EXR_MAGIC, ExrPart, choose_exr_layer};
use crate::error::{Error, Result};
use crate::io::{ReadOptions, check_size};

/// One channel of a header.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Channel {
    pub name: String,
    /// Bytes per sample: 2 (half) or 4 (float, or u32 when `int`).
    bytes: usize,
    int: bool,
    /// x and y sampling, at least 1.
    sampling: (usize, usize),
}

impl Channel {
    /// Whether the channel has a sample for every texel.
    pub fn full_resolution(&self) -> bool {
        self.sampling == (1, 1)
    }
}

/// The attributes of one part that this reader needs.
#[derive(Clone, Debug, Default)]
pub(crate) struct Header {
    pub name: Option<String>,
    pub channels: Vec<Channel>,
    compression: Option<u8>,
    /// x min, y min, x max, y max.
    data_window: Option<[i32; 4]>,
    tiled: bool,
    deep: bool,
    chunk_count: Option<u64>,
}

/// The headers of a file, read up to its offset tables.
#[derive(Clone, Debug)]
pub(crate) struct Headers {
    pub parts: Vec<Header>,
    multipart: bool,
}

impl Headers {
    /// Whether some channel of some part is subsampled: the files the
    /// `exr` crate refuses, which this module reads.
    pub fn subsampled(&self) -> bool {
        self.parts.iter().flat_map(|p| &p.channels).any(|c| !c.full_resolution())
    }

    /// The parts as the layer choice sees them.
    pub fn summary(&self) -> Vec<ExrPart> {
        let part = |h: &Header| ExrPart {
            name: h.name.clone(),
            deep: h.deep,
            channels: h.channels.iter().map(|c| c.name.clone()).collect(),
        };
        self.parts.iter().map(part).collect()
    }
}

/// Attribute values longer than this are not read into memory (a channel
/// list of 64 KiB holds hundreds of channels with the longest names).
const VALUE_MAX: u64 = 1 << 16;

/// Reads the headers of an OpenEXR file from its first byte, leaving
/// `read` at the offset tables. `None` for anything it does not follow
/// (a truncated or malformed header among them): the `exr` crate then
/// reads the file, and reports its errors as it always has.
pub(crate) fn read_headers(read: &mut impl BufRead) -> Option<Headers> {
    let mut start = [0u8; 8];
    read.read_exact(&mut start).ok()?;
    if start[..4] != EXR_MAGIC || start[4] != 2 {
        return None;
    }
    // Version flags: 0x200 single-part tiled, 0x800 deep ("non-image"),
    // 0x1000 multi-part.
    let flags = u32::from_le_bytes([start[4], start[5], start[6], start[7]]);
    let multipart = flags & 0x1000 != 0;
    let mut parts = Vec::new();
    loop {
        let mut header =
            Header { tiled: !multipart && flags & 0x200 != 0, deep: flags & 0x800 != 0, ..Header::default() };
        let mut attributes = 0;
        loop {
            let name = c_string(read)?;
            if name.is_empty() {
                break;
            }
            attributes += 1;
            let kind = c_string(read)?;
            let size = u64::try_from(i32_le(read)?).ok()?;
            let wanted = matches!(
                name.as_slice(),
                b"channels" | b"compression" | b"dataWindow" | b"type" | b"name" | b"chunkCount" | b"tiles"
            );
            if !wanted {
                let skipped = std::io::copy(&mut read.by_ref().take(size), &mut std::io::sink()).ok()?;
                (skipped == size).then_some(())?;
                continue;
            }
            if size > VALUE_MAX {
                return None;
            }
            let mut value = Vec::new();
            read.by_ref().take(size).read_to_end(&mut value).ok()?;
            (value.len() as u64 == size).then_some(())?;
            match (name.as_slice(), kind.as_slice()) {
                (b"channels", b"chlist") => header.channels = channel_list(&value)?,
                (b"compression", b"compression") => header.compression = value.first().copied(),
                (b"dataWindow", b"box2i") => {
                    let v: Vec<i32> =
                        value.chunks_exact(4).map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
                    header.data_window = Some(v.try_into().ok()?);
                }
                (b"type", b"string") => {
                    header.tiled = value.ends_with(b"tile");
                    header.deep = value.starts_with(b"deep");
                }
                (b"name", b"string") => header.name = Some(String::from_utf8_lossy(&value).into_owned()),
                (b"chunkCount", b"int") => {
                    header.chunk_count = Some(u64::try_from(i32::from_le_bytes(value.try_into().ok()?)).ok()?);
                }
                (b"tiles", _) => header.tiled = true,
                _ => return None,
            }
        }
        if attributes == 0 {
            // The empty header that ends a multi-part file's list.
            break;
        }
        parts.push(header);
        if !multipart {
            break;
        }
    }
    (!parts.is_empty()).then_some(Headers { parts, multipart })
}

/// A null-terminated name of at most 255 bytes.
fn c_string(read: &mut impl BufRead) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    read.by_ref().take(256).read_until(0, &mut out).ok()?;
    (out.pop()? == 0).then_some(out)
}

fn i32_le(read: &mut impl Read) -> Option<i32> {
    let mut b = [0u8; 4];
    read.read_exact(&mut b).ok()?;
    Some(i32::from_le_bytes(b))
}

/// A `chlist` value: per channel its name, pixel type (0 u32, 1 half, 2
/// float), linearity and three reserved bytes, x and y sampling; an empty
/// name ends it.
fn channel_list(mut value: &[u8]) -> Option<Vec<Channel>> {
    let mut channels = Vec::new();
    loop {
        let end = value.iter().position(|&b| b == 0)?;
        let name = String::from_utf8_lossy(&value[..end]).into_owned();
        value = &value[end + 1..];
        if name.is_empty() {
            return Some(channels);
        }
        let fields = value.get(..16)?;
        value = &value[16..];
        let int = |at: usize| i32::from_le_bytes([fields[at], fields[at + 1], fields[at + 2], fields[at + 3]]);
        let (bytes, int_type) = match int(0) {
            0 => (4, true),
            1 => (2, false),
            2 => (4, false),
            _ => return None,
        };
        let sampling = (usize::try_from(int(8)).ok()?, usize::try_from(int(12)).ok()?);
        channels.push(Channel { name, bytes, int: int_type, sampling });
    }
}

/// The compressions by number, for messages, and the scan lines per block
/// of each.
const COMPRESSIONS: [(&str, usize); 10] = [
    ("none", 1),
    ("RLE", 1),
    ("ZIPS", 1),
    ("ZIP", 16),
    ("PIZ", 32),
    ("PXR24", 16),
    ("B44", 32),
    ("B44A", 32),
    ("DWAA", 32),
    ("DWAB", 256),
];

/// One scan-line part of a file with subsampled channels, ready to decode
/// block by block.
pub(crate) struct ScanLines {
    header: Header,
    /// The part's index, written before each chunk of a multi-part file.
    part: Option<i32>,
    compression: u8,
    /// Where each block's chunk starts, top block first.
    offsets: Vec<u64>,
    /// The file's length, which no chunk may pass.
    file_len: u64,
    width: usize,
    height: usize,
    y_min: i64,
    lines_per_block: usize,
    /// The full-resolution channels of the layer asked for, as indices
    /// into the header's channels.
    layer_channels: Vec<usize>,
}

impl ScanLines {
    /// The part that `opts.layer` chooses, from `headers` read by
    /// [`read_headers`] with `read` left at the offset tables, which are
    /// read here. `file_len` bounds what the header may claim.
    ///
    /// Errors: [`Error::Unsupported`] for a layer that is not there, a
    /// tiled or deep part, or a compression this module does not decode;
    /// [`Error::Decode`] for sampling or windows OpenEXR forbids, or offset
    /// tables that do not fit the file; [`Error::Limits`] for a size above
    /// `opts.max_texels`.
    pub fn open(headers: Headers, read: &mut impl Read, file_len: u64, opts: &ReadOptions) -> Result<ScanLines> {
        let layer = choose_exr_layer(&headers.summary(), opts.layer.as_deref())?;
        // The offset tables of every part come first, in the parts' order.
        let mut counts = Vec::with_capacity(headers.parts.len());
        for header in &headers.parts {
            let [x0, y0, x1, y1] = header.data_window.ok_or_else(|| corrupt("a header has no data window"))?;
            let (w, h) = (i64::from(x1) - i64::from(x0) + 1, i64::from(y1) - i64::from(y0) + 1);
            check_size(w.max(0) as u64, h.max(0) as u64, opts)?;
            let lines = header.compression.and_then(|c| COMPRESSIONS.get(usize::from(c))).map_or(1, |c| c.1);
            let count = match header.chunk_count {
                Some(count) => count,
                None if !header.tiled && !header.deep => (h as u64).div_ceil(lines as u64),
                None => return Err(corrupt("a tiled part has no chunkCount")),
            };
            counts.push(count);
        }
        let chunks = counts.iter().fold(0u64, |a, &c| a.saturating_add(c));
        if chunks.saturating_mul(8) > file_len {
            return Err(corrupt(&format!("header claims {chunks} chunks, more than the file holds")));
        }
        let part = layer.part;
        let mut offsets = Vec::new();
        for (k, &count) in counts.iter().enumerate() {
            let mut table = vec![0u8; count as usize * 8];
            read.read_exact(&mut table).map_err(|_| corrupt("the file ends in its offset tables"))?;
            if k == part {
                offsets = table.chunks_exact(8).map(|b| u64::from_le_bytes(b.try_into().unwrap_or_default())).collect();
            }
        }
        let multipart = headers.multipart;
        let header = headers.parts.into_iter().nth(part).ok_or_else(|| corrupt("no such part"))?;
        if header.tiled || header.deep {
            let what = if header.deep { "deep" } else { "tiled" };
            return Err(Error::Unsupported(format!(
                "exr part of subsampled channels is {what}: only scan-line parts are read with subsampled channels"
            )));
        }
        let compression = header.compression.ok_or_else(|| corrupt("a header has no compression"))?;
        let name = COMPRESSIONS.get(usize::from(compression)).map_or("unknown", |c| c.0);
        if compression > 3 {
            return Err(Error::Unsupported(format!(
                "exr file has subsampled channels and {name} compression: with subsampling (luminance/chroma files), \
                 only none, RLE, ZIPS and ZIP are read (the exr crate reads no subsampled file)"
            )));
        }
        let [x0, y0, x1, y1] = header.data_window.unwrap_or_default();
        let (width, height) =
            ((i64::from(x1) - i64::from(x0) + 1) as usize, (i64::from(y1) - i64::from(y0) + 1) as usize);
        for c in &header.channels {
            let (sx, sy) = c.sampling;
            // OpenEXR's own rule: the window's corner and size are multiples
            // of every sampling, so every channel's lines are whole.
            let fits = sx >= 1
                && sy >= 1
                && i64::from(x0) % sx as i64 == 0
                && i64::from(y0) % sy as i64 == 0
                && width % sx == 0
                && height % sy == 0;
            if !fits {
                return Err(corrupt(&format!(
                    "channel {} has sampling {sx} × {sy}, which does not divide the data window",
                    c.name
                )));
            }
        }
        let layer_channels = (0..header.channels.len())
            .filter(|&i| header.channels[i].full_resolution() && layer.holds(&header.channels[i].name))
            .collect();
        Ok(ScanLines {
            part: multipart.then_some(part as i32),
            compression,
            offsets,
            file_len,
            width,
            height,
            y_min: i64::from(y0),
            lines_per_block: COMPRESSIONS[usize::from(compression)].1,
            layer_channels,
            header,
        })
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    pub fn lines_per_block(&self) -> usize {
        self.lines_per_block
    }

    /// Whether channel `i` of the part holds 32-bit integers.
    pub fn is_int(&self, i: usize) -> bool {
        self.header.channels.get(i).is_some_and(|c| c.int)
    }

    /// The full-resolution channels of the layer: index into the part's
    /// channels, and name. The subsampled ones are not among them.
    pub fn channels(&self) -> impl Iterator<Item = (usize, &str)> {
        self.layer_channels.iter().map(|&i| (i, self.header.channels[i].name.as_str()))
    }

    /// Decodes the block that starts at row `y0` (a multiple of
    /// [`ScanLines::lines_per_block`]): for each of the part's channels in
    /// `wanted` (full resolution), its rows as `f64`, row-major.
    ///
    /// Errors: [`Error::Decode`] for a chunk that is not where the offset
    /// table says, is of another part or block, or does not decompress to
    /// the block's size.
    pub fn read_block(&self, read: &mut (impl Read + Seek), y0: usize, wanted: &[usize]) -> Result<Vec<Vec<f64>>> {
        let block = y0 / self.lines_per_block;
        let rows = self.lines_per_block.min(self.height - y0);
        let offset = *self.offsets.get(block).ok_or_else(|| corrupt("a block past the offset table"))?;
        read.seek(SeekFrom::Start(offset)).map_err(|_| missing(y0))?;
        let mut int = || {
            let mut b = [0u8; 4];
            read.read_exact(&mut b).map(|()| i32::from_le_bytes(b)).map_err(|_| missing(y0))
        };
        if let Some(part) = self.part
            && int()? != part
        {
            return Err(corrupt(&format!("the chunk for row {y0} belongs to another part")));
        }
        let y = int()?;
        if i64::from(y) != self.y_min + y0 as i64 {
            return Err(corrupt(&format!("the chunk for row {y0} says it starts at y = {y}")));
        }
        let size =
            usize::try_from(int()?).map_err(|_| corrupt(&format!("the chunk for row {y0} has a negative size")))?;
        let raw_size = self.raw_size(y0, rows);
        if size > raw_size {
            return Err(corrupt(&format!(
                "the chunk for row {y0} holds {size} bytes, more than its {raw_size} raw bytes"
            )));
        }
        // The chunk's header: y and size, after the part number if any.
        let header = if self.part.is_some() { 12 } else { 8 };
        if offset.saturating_add(header).saturating_add(size as u64) > self.file_len {
            return Err(missing(y0));
        }
        let mut data = vec![0u8; size];
        read.read_exact(&mut data).map_err(|_| missing(y0))?;
        let raw = if size == raw_size { data } else { self.decompress(&data, raw_size, y0)? };
        Ok(self.samples(&raw, y0, rows, wanted))
    }

    /// The bytes of the block's lines, uncompressed.
    fn raw_size(&self, y0: usize, rows: usize) -> usize {
        let mut size = 0;
        for y in self.y_min + y0 as i64..self.y_min + (y0 + rows) as i64 {
            for c in &self.header.channels {
                if y.rem_euclid(c.sampling.1 as i64) == 0 {
                    size += self.width / c.sampling.0 * c.bytes;
                }
            }
        }
        size
    }

    /// RLE, ZIPS or ZIP data back to the raw lines: the stream
    /// decompressed, then OpenEXR's predictor undone (each byte is stored
    /// as its difference to the one before, plus 128) and its two halves
    /// interleaved again (even bytes were stored first, odd bytes after).
    fn decompress(&self, data: &[u8], raw_size: usize, y0: usize) -> Result<Vec<u8>> {
        let bytes = match self.compression {
            1 => unpack_rle(data, raw_size),
            _ => miniz_oxide::inflate::decompress_to_vec_zlib_with_limit(data, raw_size).ok(),
        };
        let Some(mut bytes) = bytes.filter(|b| b.len() == raw_size) else {
            return Err(corrupt(&format!("the chunk for row {y0} does not decompress to its {raw_size} bytes")));
        };
        for i in 1..bytes.len() {
            bytes[i] = bytes[i - 1].wrapping_add(bytes[i]).wrapping_sub(128);
        }
        let (first, second) = bytes.split_at(raw_size.div_ceil(2));
        let mut out = Vec::with_capacity(raw_size);
        for (i, &b) in first.iter().enumerate() {
            out.push(b);
            if let Some(&odd) = second.get(i) {
                out.push(odd);
            }
        }
        Ok(out)
    }

    /// The rows of the `wanted` channels out of a block's raw lines.
    fn samples(&self, raw: &[u8], y0: usize, rows: usize, wanted: &[usize]) -> Vec<Vec<f64>> {
        let w = self.width;
        let mut planes = vec![vec![0.0f64; w * rows]; wanted.len()];
        let mut at = 0;
        for row in 0..rows {
            let y = self.y_min + (y0 + row) as i64;
            for (c, channel) in self.header.channels.iter().enumerate() {
                if y.rem_euclid(channel.sampling.1 as i64) != 0 {
                    continue;
                }
                let len = w / channel.sampling.0 * channel.bytes;
                let line = &raw[at..at + len];
                at += len;
                let Some(k) = wanted.iter().position(|&i| i == c) else { continue };
                let out = &mut planes[k][row * w..][..w];
                match (channel.bytes, channel.int) {
                    (2, _) => out
                        .iter_mut()
                        .zip(line.chunks_exact(2))
                        .for_each(|(o, b)| *o = f64::from(f16::from_bits(u16::from_le_bytes([b[0], b[1]])).to_f32())),
                    // Every type widened to f64 exactly, as the `exr` path does.
                    (_, true) => out
                        .iter_mut()
                        .zip(line.chunks_exact(4))
                        .for_each(|(o, b)| *o = f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))),
                    (_, false) => out
                        .iter_mut()
                        .zip(line.chunks_exact(4))
                        .for_each(|(o, b)| *o = f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))),
                }
            }
        }
        planes
    }
}

/// OpenEXR's run-length code: a signed count byte, then either −count
/// bytes as they are, or one byte repeated count + 1 times. `None` when
/// the data ends inside a run or unpacks to more than `limit` bytes.
fn unpack_rle(mut data: &[u8], limit: usize) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(limit);
    while let Some((&count, rest)) = data.split_first() {
        let count = count as i8;
        if count < 0 {
            let n = usize::from(count.unsigned_abs());
            out.extend_from_slice(rest.get(..n)?);
            data = &rest[n..];
        } else {
            let (&value, rest) = rest.split_first()?;
            out.resize(out.len() + count as usize + 1, value);
            data = rest;
        }
        if out.len() > limit {
            return None;
        }
    }
    Some(out)
}

fn corrupt(what: &str) -> Error {
    Error::Decode(format!("invalid exr: {what}"))
}

fn missing(y0: usize) -> Error {
    Error::Decode(format!("truncated or corrupt: the file ends before the chunk for row {y0}"))
}
