//! Streaming conversion of PNG files: rows go from the decoder through the
//! fit to the encoder, so memory grows with the width and the patch size,
//! not with the image's height.
//!
//! Three stages run at once: a thread decodes rows into bands of heights;
//! a thread fits each band (its row tiles in parallel on rayon's pool) and
//! PNG-filters it (in parallel too); the caller's thread deflates the
//! filtered rows into the output. The pixels are the same, bit for bit, as
//! decoding the whole image and calling [`normals_into`](crate::normals_into):
//! the fit is cut into the same tiles either way ([`BandFit`]).
//!
//! A wrap across the top and bottom needs the image's last rows for the top
//! N/2 output rows. Into an output that seeks ([`convert_png_seekable`]),
//! those rows are fitted last and written into room kept for them after
//! the header, stored uncompressed, so the input is read once. Into a pipe
//! ([`convert_png`]), the caller reads the file once more for the last rows
//! first ([`PngRows::read_tail`]); PNG cannot seek, so that pass decodes the
//! whole file.

use std::borrow::Cow;
use std::fs::File;
use std::io::{BufReader, Read, Seek, Write};

use rayon::prelude::*;
use std::path::Path;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

use super::read::{Channel, LUMA, ReadOptions, check_png_palette, check_size};
use crate::error::{Error, Result};
use crate::fit::{BandFit, FromNormal};
use crate::options::{Border, Options};

/// The rows of a PNG file, top to bottom, as heights in contract units.
pub struct PngRows {
    reader: png::Reader<BufReader<File>>,
    width: usize,
    height: usize,
    layout: RowLayout,
    /// Rows handed out so far.
    next: usize,
}

/// How one decoded row turns into heights.
#[derive(Clone, Copy)]
struct RowLayout {
    /// Samples per texel.
    channels: usize,
    /// Bytes per sample (1 or 2).
    bytes: usize,
    pick: Pick,
}

#[derive(Clone, Copy)]
enum Pick {
    /// One stored channel, by index.
    Channel(usize),
    /// Luma of channels 0, 1, 2.
    Luma,
}

impl PngRows {
    /// Opens `path` for streaming if it is a PNG that can stream (not
    /// interlaced: Adam7 rows arrive in seven passes); `Ok(None)` otherwise,
    /// and the caller reads the image whole. Reads only the header.
    ///
    /// Errors: [`Error::Io`] if the file cannot be opened, [`Error::Decode`]
    /// for a corrupt header, [`Error::Limits`] for a size above
    /// `opts.max_texels`, [`Error::Unsupported`] for a missing channel.
    pub fn open(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<PngRows>> {
        let mut file = BufReader::with_capacity(1 << 16, File::open(path)?);
        let magic = std::io::BufRead::fill_buf(&mut file)?;
        if !magic.starts_with(b"\x89PNG\r\n\x1a\n") {
            return Ok(None);
        }
        // The decoder's own buffers are a few rows; the limit guards them.
        let mut decoder = png::Decoder::new_with_limits(file, png::Limits { bytes: 1 << 28 });
        decoder.set_transformations(png::Transformations::EXPAND);
        let reader = decoder.read_info().map_err(png_error)?;
        let info = reader.info();
        check_png_palette(info)?;
        let (width, height) = (info.width, info.height);
        check_size(u64::from(width), u64::from(height), opts)?;
        if info.interlaced {
            return Ok(None);
        }
        let (color, depth) = reader.output_color_type();
        let bytes = match depth {
            png::BitDepth::Eight => 1,
            png::BitDepth::Sixteen => 2,
            _ => return Ok(None),
        };
        let channels = color.samples();
        let gray = channels <= 2;
        let alpha = matches!(channels, 2 | 4).then_some(channels - 1);
        let pick = match channel {
            Some(Channel::A) => {
                Pick::Channel(alpha.ok_or_else(|| Error::Unsupported("image has no alpha channel".into()))?)
            }
            _ if gray => Pick::Channel(0),
            None | Some(Channel::Luma) => Pick::Luma,
            Some(Channel::R) => Pick::Channel(0),
            Some(Channel::G) => Pick::Channel(1),
            Some(Channel::B) => Pick::Channel(2),
        };
        Ok(Some(PngRows {
            reader,
            width: width as usize,
            height: height as usize,
            layout: RowLayout { channels, bytes, pick },
            next: 0,
        }))
    }

    /// Columns.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Whether the file stores more than 8 bits per sample.
    #[must_use]
    pub fn more_than_8_bits(&self) -> bool {
        self.layout.bytes == 2
    }

    /// Decodes the next row into `out` (`width` heights).
    ///
    /// Errors: [`Error::Decode`] for corrupt or truncated data, or when all
    /// rows have been read.
    pub fn next_row(&mut self, out: &mut [f32]) -> Result<()> {
        let layout = self.layout;
        let row = self.reader.next_row().map_err(png_error)?;
        let row =
            row.ok_or_else(|| Error::Decode(format!("image data ends after {} of {} rows", self.next, self.height)))?;
        let data = row.data();
        let stride = layout.channels * layout.bytes;
        if data.len() != stride * out.len() {
            return Err(Error::Decode(format!("row of {} bytes for {} texels", data.len(), out.len())));
        }
        let sample = |px: &[u8], c: usize| -> f32 {
            if layout.bytes == 1 {
                f32::from(px[c]) / 255.0
            } else {
                f32::from(u16::from_be_bytes([px[2 * c], px[2 * c + 1]])) / 65535.0
            }
        };
        let texels = data.chunks_exact(stride);
        match layout.pick {
            Pick::Channel(c) => out.iter_mut().zip(texels).for_each(|(o, px)| *o = sample(px, c)),
            Pick::Luma => out.iter_mut().zip(texels).for_each(|(o, px)| {
                let [r, g, b] = [0, 1, 2].map(|c| f64::from(sample(px, c)));
                *o = (LUMA[0] * r + LUMA[1] * g + LUMA[2] * b) as f32;
            }),
        }
        self.next += 1;
        Ok(())
    }

    /// Reads every row, giving each to `visit`, and returns the last
    /// `rows` rows (fewer if the image is shorter): the first pass of a
    /// conversion that wraps across the top and bottom.
    pub fn read_tail(mut self, rows: usize, mut visit: impl FnMut(&[f32])) -> Result<Vec<f32>> {
        let (w, h) = (self.width, self.height);
        let keep = rows.min(h);
        let mut tail = vec![0.0f32; keep * w];
        let mut row = vec![0.0f32; w];
        for y in 0..h {
            self.next_row(&mut row)?;
            visit(&row);
            if y + keep >= h {
                let slot = y + keep - h;
                tail[slot * w..][..w].copy_from_slice(&row);
            }
        }
        Ok(tail)
    }
}

/// How the streamed normal map is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PngDepth {
    /// 8-bit RGB.
    Eight,
    /// 16-bit RGB.
    Sixteen,
}

/// Converts the rows of `rows` to a PNG normal map written in order to
/// `out`, which need not seek (a pipe).
///
/// `tail` holds the image's last N/2 rows ([`PngRows::read_tail`] of a
/// first pass) and is needed when `opts` wraps in y; other borders find
/// their rows in the stream. Every decoded row is also given to `visit`
/// (a tiling check, say).
///
/// Errors: those of decoding, [`Error::InvalidOption`] for bad options or
/// a wrap in y without `tail`, [`Error::Io`] if writing fails.
pub fn convert_png(
    rows: PngRows,
    tail: Option<&[f32]>,
    opts: &Options,
    depth: PngDepth,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut dyn Write,
) -> Result<()> {
    let (w, h, r) = (rows.width, rows.height, opts.patch / 2);
    let tail = match tail {
        Some(t) if t.len() == r.min(h) * w => Some(t),
        Some(t) => return Err(Error::BufferSize { expected: r.min(h) * w, actual: t.len() }),
        None if opts.borders.y == Border::Wrap => {
            return Err(Error::InvalidOption("a wrap in y needs the image's last rows from a first pass".into()));
        }
        None => None,
    };
    match depth {
        PngDepth::Eight => convert_as::<[u8; 3], _>(rows, tail, opts, visit, out, false),
        PngDepth::Sixteen => convert_as::<[u16; 3], _>(rows, tail, opts, visit, out, false),
    }?;
    out.flush()?;
    Ok(())
}

/// Like [`convert_png`], in one pass over the input whatever the borders,
/// into an output that can seek (a file).
///
/// The top N/2 rows, the only ones that need the image's last rows with a
/// wrap in y, are fitted last: the file keeps room for them after the
/// header, stored uncompressed (N/2 rows, a small part of the file), and
/// they are written there once the last rows have been read.
pub fn convert_png_seekable<W: Write + Seek>(
    rows: PngRows,
    opts: &Options,
    depth: PngDepth,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut W,
) -> Result<()> {
    let start = out.stream_position()?;
    let first_idat = match depth {
        PngDepth::Eight => convert_as::<[u8; 3], _>(rows, None, opts, visit, out, true),
        PngDepth::Sixteen => convert_as::<[u16; 3], _>(rows, None, opts, visit, out, true),
    }?;
    // The room kept for the first IDAT chunk follows the signature and IHDR.
    let end = out.stream_position()?;
    out.seek(std::io::SeekFrom::Start(start + HEADER_BYTES))?;
    write_chunk(out, b"IDAT", &first_idat)?;
    out.seek(std::io::SeekFrom::Start(end))?;
    out.flush()?;
    Ok(())
}

/// A texel type the streamed PNG can hold, with its big-endian bytes.
trait PngTexel: FromNormal + Default {
    /// Bits per sample.
    const BITS: u8;
    /// Bytes per texel (three samples).
    const BYTES: usize = 3 * (Self::BITS as usize / 8);
    /// The samples of `texels`, big-endian (8-bit ones as they are).
    fn bytes(texels: &[Self]) -> Cow<'_, [u8]>;
}

impl PngTexel for [u8; 3] {
    const BITS: u8 = 8;
    fn bytes(texels: &[Self]) -> Cow<'_, [u8]> {
        Cow::Borrowed(texels.as_flattened())
    }
}

impl PngTexel for [u16; 3] {
    const BITS: u8 = 16;
    fn bytes(texels: &[Self]) -> Cow<'_, [u8]> {
        Cow::Owned(texels.as_flattened().iter().flat_map(|v| v.to_be_bytes()).collect())
    }
}

/// Bytes of the PNG signature (8) and the IHDR chunk (25), after which the
/// first IDAT chunk starts.
const HEADER_BYTES: u64 = 8 + 25;

/// A band of rows between stages: its first row and its values (heights;
/// or the PNG rows, each with its filter byte).
type Band<T> = Result<(usize, Vec<T>)>;

/// Streams the PNG into `out`. With `deferred`, the top N/2 rows are
/// fitted last: `out` gets room for the first IDAT chunk after the header,
/// and the chunk's data (zlib header and the top rows, stored) is returned
/// for the caller to write there; otherwise everything is written in order
/// and nothing is returned.
fn convert_as<T: PngTexel, W: Write + ?Sized>(
    mut rows: PngRows,
    tail: Option<&[f32]>,
    opts: &Options,
    mut visit: impl FnMut(&[f32]) + Send,
    out: &mut W,
    deferred: bool,
) -> Result<Vec<u8>> {
    let (w, h) = (rows.width, rows.height);
    let fit = BandFit::new(w, h, opts)?;
    let top_len = fit.radius().min(h) * (T::BYTES * w + 1);

    write_signature_and_header(out, w, h, T::BITS)?;
    if deferred {
        // Room for the first IDAT chunk: zlib header and the top rows as
        // stored blocks, filled in at the end.
        let room = 12 + 2 + stored_len(top_len);
        std::io::copy(&mut std::io::repeat(0).take(room as u64), out)?;
    }
    let mut idat = Idat { out: &mut *out, buf: Vec::new(), skip: if deferred { 2 } else { 0 } };
    let mut compressor = fdeflate::Compressor::new(&mut idat)?;
    let mut fed = 0u64;
    let mut top = Vec::new();

    // Two bands in flight between stages keep every stage busy without
    // holding more than a few bands.
    let (heights_tx, heights_rx) = sync_channel::<Band<f32>>(2);
    let (png_tx, png_rx) = sync_channel::<Band<u8>>(2);
    let band = fit.band_rows();
    std::thread::scope(|scope| -> Result<()> {
        scope.spawn(move || decode_stage(&mut rows, band, &heights_tx));
        let fit = &fit;
        scope.spawn(move || fit_stage::<T>(fit, tail, deferred, &mut visit, heights_rx, &png_tx));
        for message in png_rx {
            let (y0, bytes) = message?;
            if deferred && y0 == 0 {
                top = bytes;
            } else {
                compressor.write_data(&bytes)?;
                fed += bytes.len() as u64;
            }
        }
        Ok(())
    })?;
    compressor.finish()?;
    let mut trailer = idat.take_trailer()?;
    let mut first_idat = Vec::new();
    if deferred {
        if top.len() != top_len {
            return Err(Error::Encode("the top rows were not fitted".into()));
        }
        trailer = adler32_combine(adler32(&top), trailer, fed);
        first_idat.extend_from_slice(&[0x78, 0x01]);
        put_stored(&top, &mut first_idat);
    }
    idat.buf.extend_from_slice(&trailer.to_be_bytes());
    idat.flush_chunk()?;
    write_chunk(out, b"IEND", &[])?;
    Ok(first_idat)
}

/// Decodes bands of `band` rows and sends them on; stops at the first
/// error (sent on) or when the receiver is gone. Decoding is the one stage
/// that cannot be split, so it does nothing else.
fn decode_stage(rows: &mut PngRows, band: usize, tx: &SyncSender<Band<f32>>) {
    let (w, h) = (rows.width, rows.height);
    for y0 in (0..h).step_by(band) {
        let n = band.min(h - y0);
        let mut heights = vec![0.0f32; n * w];
        let result = heights.chunks_exact_mut(w).try_for_each(|row| rows.next_row(row));
        let failed = result.is_err();
        if tx.send(result.map(|()| (y0, heights))).is_err() || failed {
            return;
        }
    }
}

/// Fits each band once the rows it reads are in, turns it into filtered
/// PNG rows and sends it on; gives every row that comes in to `visit`.
/// `deferred`: the top band is fitted last, when the image's last rows are
/// in, and sent unfiltered.
fn fit_stage<T: PngTexel>(
    fit: &BandFit,
    tail: Option<&[f32]>,
    deferred: bool,
    visit: &mut dyn FnMut(&[f32]),
    rx: Receiver<Band<f32>>,
    tx: &SyncSender<Band<u8>>,
) {
    let (w, h, r) = (fit.width(), fit.height(), fit.radius());
    // The decoded bands that later bands still read, as they came (first
    // row, heights), and a copy of the image's first 2r rows, which the top
    // band and a wrap at the bottom read after they have left.
    let mut window: std::collections::VecDeque<(usize, Vec<f32>)> = std::collections::VecDeque::new();
    let mut decoded = 0;
    let head_rows = (2 * r).min(h);
    let mut head: Vec<f32> = Vec::new();
    let mut incoming = rx.into_iter();
    let mut prior: Option<Vec<u8>> = None;
    let mut bands: Vec<_> = fit.bands().collect();
    if deferred {
        bands.rotate_left(1);
    }
    for rows in bands {
        let (y0, y1) = (rows.start, rows.end);
        let top_last = deferred && y0 == 0;
        let needed = if top_last { h } else { (y1 + r).min(h) };
        while decoded < needed {
            match incoming.next() {
                Some(Ok((first, rows))) => {
                    rows.chunks_exact(w).for_each(&mut *visit);
                    let wanted = (head_rows * w).saturating_sub(head.len()).min(rows.len());
                    head.extend_from_slice(&rows[..wanted]);
                    decoded = first + rows.len() / w;
                    window.push_back((first, rows));
                }
                Some(Err(e)) => {
                    let _ = tx.send(Err(e));
                    return;
                }
                None => {
                    let _ = tx.send(Err(Error::Decode("image data ends early".into())));
                    return;
                }
            }
        }
        let in_window = &window;
        let row = |y: usize| -> &[f32] {
            if let Some((first, rows)) =
                in_window.iter().find(|(first, rows)| (*first..first + rows.len() / w).contains(&y))
            {
                &rows[(y - first) * w..][..w]
            } else if y < head_rows {
                &head[y * w..][..w]
            } else {
                // Only a wrap at the top, fitted first, reads below the window.
                let t = tail.expect("a wrap in y comes with the tail");
                &t[(y + r.min(h) - h) * w..][..w]
            }
        };
        let mut normals = vec![T::default(); (y1 - y0) * w];
        let result = fit.fit_band(rows, &row, &mut normals).map(|()| {
            let raw = T::bytes(&normals);
            let stride = T::BYTES * w;
            if top_last {
                // Stored as they are: filter type 0 before each row.
                raw.chunks_exact(stride).flat_map(|row| std::iter::once(0).chain(row.iter().copied())).collect()
            } else {
                let filtered = filter_rows(&raw, stride, T::BYTES, prior.as_deref());
                prior = Some(raw[raw.len() - stride..].to_vec());
                filtered
            }
        });
        let failed = result.is_err();
        if tx.send(result.map(|bytes| (y0, bytes))).is_err() || failed {
            return;
        }
        // The next band reads from r rows above its start (with the top
        // band last, the last r rows stay for it): older bands can go.
        let keep_from = y1.saturating_sub(r);
        while window.front().is_some_and(|(first, rows)| first + rows.len() / w <= keep_from) {
            window.pop_front();
        }
    }
}

/// PNG-filters rows of `stride` bytes (texels of `bpp` bytes), in
/// parallel: Avg (the mean of the left and upper bytes predicts each byte)
/// for every row with a row above, Sub (the left byte) for the first row
/// written. Avg is cheap and, on smooth normal maps, nearly as small as
/// trying every filter per row (measured: 22.6 against 19.9 MiB for a
/// 4096² map, at half the time).
fn filter_rows(raw: &[u8], stride: usize, bpp: usize, prior: Option<&[u8]>) -> Vec<u8> {
    let rows = raw.len() / stride;
    let mut out = vec![0u8; rows * (stride + 1)];
    out.par_chunks_mut(stride + 1).enumerate().for_each(|(k, dst)| {
        let cur = &raw[k * stride..][..stride];
        let above = if k == 0 { prior } else { Some(&raw[(k - 1) * stride..][..stride]) };
        let (kind, body) = dst.split_first_mut().expect("a filter byte");
        // Written as zips over slices, with no indexing, so the loops
        // vectorise (indexed, they ran one byte at a time).
        match above {
            None => {
                *kind = 1;
                body[..bpp].copy_from_slice(&cur[..bpp]);
                for ((d, &c), &left) in body[bpp..].iter_mut().zip(&cur[bpp..]).zip(cur) {
                    *d = c.wrapping_sub(left);
                }
            }
            Some(up) => {
                *kind = 3;
                for ((d, &c), &u) in body[..bpp].iter_mut().zip(cur).zip(up) {
                    *d = c.wrapping_sub(u >> 1);
                }
                let rest = body[bpp..].iter_mut().zip(&cur[bpp..]).zip(cur).zip(&up[bpp..]);
                for (((d, &c), &left), &u) in rest {
                    let mean = ((u16::from(left) + u16::from(u)) >> 1) as u8;
                    *d = c.wrapping_sub(mean);
                }
            }
        }
    });
    out
}

/// The PNG signature and the IHDR of a `bits`-bit RGB image.
fn write_signature_and_header<W: Write + ?Sized>(out: &mut W, w: usize, h: usize, bits: u8) -> Result<()> {
    let side = |n: usize| u32::try_from(n).ok().filter(|&n| n <= i32::MAX as u32);
    let (Some(w), Some(h)) = (side(w), side(h)) else {
        return Err(Error::Encode(format!("{w} × {h} is too large for PNG")));
    };
    out.write_all(b"\x89PNG\r\n\x1a\n")?;
    let mut ihdr = Vec::with_capacity(13);
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    // Bit depth, colour type 2 (RGB), deflate, adaptive filtering, no interlace.
    ihdr.extend_from_slice(&[bits, 2, 0, 0, 0]);
    write_chunk(out, b"IHDR", &ihdr)
}

/// One PNG chunk: length, type, data, CRC of type and data.
fn write_chunk<W: Write + ?Sized>(out: &mut W, kind: &[u8; 4], data: &[u8]) -> Result<()> {
    let len = u32::try_from(data.len()).map_err(|_| Error::Encode("chunk too large".into()))?;
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    out.write_all(&len.to_be_bytes())?;
    out.write_all(kind)?;
    out.write_all(data)?;
    out.write_all(&crc.finalize().to_be_bytes())?;
    Ok(())
}

/// IDAT chunks of the compressor's output: drops its first `skip` bytes
/// (its zlib header, when ours comes first) and holds back its last four
/// (the checksum, which may need replacing).
struct Idat<'a, W: ?Sized> {
    out: &'a mut W,
    buf: Vec<u8>,
    skip: usize,
}

/// IDAT chunks of about this many bytes.
const IDAT_BYTES: usize = 1 << 20;

impl<W: Write + ?Sized> Write for &mut Idat<'_, W> {
    fn write(&mut self, data: &[u8]) -> std::io::Result<usize> {
        let dropped = self.skip.min(data.len());
        self.skip -= dropped;
        self.buf.extend_from_slice(&data[dropped..]);
        if self.buf.len() >= IDAT_BYTES + 4 {
            let cut = self.buf.len() - 4;
            write_chunk(self.out, b"IDAT", &self.buf[..cut]).map_err(std::io::Error::other)?;
            self.buf.drain(..cut);
        }
        Ok(data.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl<W: Write + ?Sized> Idat<'_, W> {
    /// Takes the checksum the compressor wrote last.
    fn take_trailer(&mut self) -> Result<u32> {
        let n = self.buf.len();
        if n < 4 {
            return Err(Error::Encode("deflate stream without its checksum".into()));
        }
        let t = u32::from_be_bytes([self.buf[n - 4], self.buf[n - 3], self.buf[n - 2], self.buf[n - 1]]);
        self.buf.truncate(n - 4);
        Ok(t)
    }

    /// Writes what is buffered as the last IDAT chunk.
    fn flush_chunk(&mut self) -> Result<()> {
        write_chunk(self.out, b"IDAT", &self.buf)?;
        self.buf.clear();
        Ok(())
    }
}

/// Bytes of `len` bytes of data as deflate stored blocks.
fn stored_len(len: usize) -> usize {
    len + 5 * len.div_ceil(STORED_MAX).max(1)
}

const STORED_MAX: usize = 65535;

/// Appends `data` as non-final deflate stored blocks, starting on a byte
/// boundary (after the zlib header).
fn put_stored(data: &[u8], out: &mut Vec<u8>) {
    let mut blocks = data.chunks(STORED_MAX).peekable();
    if blocks.peek().is_none() {
        out.extend_from_slice(&[0, 0, 0, 0xff, 0xff]);
    }
    for block in blocks {
        let len = block.len() as u16;
        out.push(0); // BFINAL 0, BTYPE 00 (stored), then padding to the byte
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(&(!len).to_le_bytes());
        out.extend_from_slice(block);
    }
}

/// Adler-32 of `data`, as zlib computes it.
fn adler32(data: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    // 5552 bytes is the most that can be summed before b overflows.
    for chunk in data.chunks(5552) {
        for &x in chunk {
            a += u32::from(x);
            b += a;
        }
        a %= 65521;
        b %= 65521;
    }
    (b << 16) | a
}

/// The Adler-32 of two byte strings one after the other, from theirs and
/// the second one's length (zlib's adler32_combine).
fn adler32_combine(first: u32, second: u32, second_len: u64) -> u32 {
    const BASE: u64 = 65521;
    let rem = second_len % BASE;
    let (a1, b1) = (u64::from(first & 0xffff), u64::from(first >> 16));
    let (a2, b2) = (u64::from(second & 0xffff), u64::from(second >> 16));
    let a = (a1 + a2 + BASE - 1) % BASE;
    let b = (rem * a1 % BASE + b1 + b2 + BASE - rem) % BASE;
    ((b << 16) | a) as u32
}

fn png_error(e: png::DecodingError) -> Error {
    match e {
        png::DecodingError::IoError(e) if e.kind() != std::io::ErrorKind::UnexpectedEof => Error::Io(e),
        png::DecodingError::LimitsExceeded => Error::Limits("the png decoder needs more memory than allowed".into()),
        other => Error::Decode(crate::error::one_line(&other.to_string())),
    }
}
