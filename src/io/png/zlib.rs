//! The checksum of a PNG's image data: zlib's Adler-32 of the inflated
//! bytes, verified whole-image and streamed alike, so a corrupt stream is
//! an error rather than an image.
//!
//! The `png` crate leaves the check off unless asked ([`decode_options`]
//! asks), and `image` builds its `png` decoder itself, with no way to ask:
//! so PNG is read with `png` in both paths. Even asked, `png` checks only
//! what its inflater reads while rows are decoded: once the last row is
//! out, `finish` steps over the rest of the image data unread. The
//! checksum is the stream's last four bytes, so it is missed when it comes
//! after the bytes the last row needed: in an IDAT chunk of its own, or
//! (streamed) past the end of what was buffered.
//!
//! [`IdatWatch`] counts the IDAT bytes the decoder reads, and
//! [`finish_checked`] compares the count at the last row with the count at
//! the end: when the decoder read image data after the last row, the
//! stream is inflated once more, from the start, with the check on
//! ([`verify_zlib`]: measured, 70 ms more processor time and 0.12 s more
//! wall time for a 4096² 16-bit map, whose conversion takes 0.46 s and
//! 0.9 s). That is the rare case: the checksum in a chunk of its own, or
//! across the edge of the streamed reader's 64 KiB buffer. Otherwise the
//! check is the decoder's, at no cost that could be measured (docs/bad-input.md,
//! "Checksums").
//!
//! What stays unchecked: a stream holding more data than the image (which
//! `png` and libpng accept), when its end is among the bytes read for the
//! last row. The inflater stops once the image is full, and the count
//! cannot tell that from a stream checked to its end. A stream with no
//! checksum at all has nothing to verify, and reads, as in `png`.

use std::io::{BufRead, ErrorKind, Read, Seek, SeekFrom};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crate::error::{Error, Result};
use crate::io::message;

/// The `png` decoder's options with zlib's checksum verified.
pub(crate) fn decode_options() -> png::DecodeOptions {
    let mut options = png::DecodeOptions::default();
    options.set_ignore_adler32(false);
    options
}

/// The error for image data whose checksum does not match.
pub(crate) fn checksum_mismatch() -> Error {
    Error::Decode("image data is corrupt: zlib checksum (Adler-32) does not match".into())
}

/// Maps `png`'s errors onto ours. Its error type is opaque: a checksum
/// that does not match is known by the name `fdeflate` gives it.
pub(crate) fn png_error(e: png::DecodingError) -> Error {
    match e {
        png::DecodingError::IoError(e) if e.kind() != ErrorKind::UnexpectedEof => Error::Io(e),
        png::DecodingError::IoError(e) => Error::Decode(format!("truncated or corrupt: {}", message(&e.to_string()))),
        png::DecodingError::LimitsExceeded => Error::Limits("the png decoder needs more memory than allowed".into()),
        other => {
            let text = other.to_string();
            if text.contains("WrongChecksum") {
                return checksum_mismatch();
            }
            Error::Decode(format!("png: {}", message(&text)))
        }
    }
}

/// How many bytes of IDAT data an [`IdatWatch`] has let through, read from
/// outside the decoder that owns the watch.
#[derive(Clone, Default)]
pub(crate) struct IdatCount(Arc<Count>);

#[derive(Default)]
struct Count {
    bytes: AtomicU64,
    /// The watch lost its place in the file (a seek), so the count means
    /// nothing and the stream is verified again.
    lost: AtomicBool,
}

impl IdatCount {
    /// IDAT bytes read so far, or `None` if the count was lost.
    pub(crate) fn get(&self) -> Option<u64> {
        (!self.0.lost.load(Ordering::Relaxed)).then(|| self.0.bytes.load(Ordering::Relaxed))
    }
}

/// A PNG byte stream on its way to the `png` decoder, counting the IDAT
/// data the decoder consumes ([`IdatCount`]). `png` reads only through
/// `fill_buf` and `consume`, in order.
pub(crate) struct IdatWatch<R> {
    inner: R,
    at: Place,
    count: IdatCount,
}

/// Where the bytes consumed so far end in the PNG's chunk structure.
#[derive(Clone, Copy)]
enum Place {
    /// In the signature, this many bytes before its end.
    Signature(u64),
    /// In a chunk's length and type, with this many of their 8 bytes read.
    Header { got: usize, bytes: [u8; 8] },
    /// In a chunk's data, this many bytes before its end.
    Data { left: u64, idat: bool },
    /// In a chunk's CRC, this many bytes before its end.
    Crc(u64),
}

impl<R: BufRead> IdatWatch<R> {
    /// Watches `inner`, read from the file's first byte.
    pub(crate) fn new(inner: R) -> (IdatWatch<R>, IdatCount) {
        let count = IdatCount::default();
        (IdatWatch { inner, at: Place::Signature(8), count: count.clone() }, count)
    }
}

impl Place {
    /// Moves over `bytes`, the next ones consumed; returns how many of
    /// them are IDAT data.
    fn follow(&mut self, mut bytes: &[u8]) -> u64 {
        let mut idat = 0;
        while !bytes.is_empty() {
            // The bytes of `left` still to go that `bytes` holds, taken off it.
            let mut take = |left: u64| {
                let n = left.min(bytes.len() as u64);
                bytes = &bytes[n as usize..];
                n
            };
            *self = match *self {
                Place::Signature(left) => match left - take(left) {
                    0 => Place::Header { got: 0, bytes: [0; 8] },
                    left => Place::Signature(left),
                },
                Place::Crc(left) => match left - take(left) {
                    0 => Place::Header { got: 0, bytes: [0; 8] },
                    left => Place::Crc(left),
                },
                Place::Data { left, idat: is_idat } => {
                    let n = take(left);
                    if is_idat {
                        idat += n;
                    }
                    match left - n {
                        0 => Place::Crc(4),
                        left => Place::Data { left, idat: is_idat },
                    }
                }
                Place::Header { got, bytes: mut header } => {
                    let n = (8 - got).min(bytes.len());
                    header[got..got + n].copy_from_slice(&bytes[..n]);
                    bytes = &bytes[n..];
                    match got + n {
                        8 => {
                            let len = u32::from_be_bytes([header[0], header[1], header[2], header[3]]);
                            Place::Data { left: u64::from(len), idat: &header[4..] == b"IDAT" }
                        }
                        got => Place::Header { got, bytes: header },
                    }
                }
            };
        }
        idat
    }
}

impl<R: BufRead> Read for IdatWatch<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        let buf = self.inner.fill_buf()?;
        let n = buf.len().min(out.len());
        out[..n].copy_from_slice(&buf[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for IdatWatch<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }

    fn consume(&mut self, amount: usize) {
        if amount > 0 {
            // A consume follows a `fill_buf` that gave at least `amount`
            // bytes: they are buffered, and asking again reads nothing.
            match self.inner.fill_buf() {
                Ok(buf) if buf.len() >= amount => {
                    let idat = self.at.follow(&buf[..amount]);
                    self.count.0.bytes.fetch_add(idat, Ordering::Relaxed);
                }
                _ => self.count.0.lost.store(true, Ordering::Relaxed),
            }
        }
        self.inner.consume(amount);
    }
}

impl<R: BufRead + Seek> Seek for IdatWatch<R> {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.count.0.lost.store(true, Ordering::Relaxed);
        self.inner.seek(to)
    }
}

/// Reads the rest of the file after the last row (`reader.finish`), and
/// verifies the image data's checksum again, from a fresh reader of the
/// file (`reopen`), when the decoder read image data after the last row
/// and so did not check it (see the module's documentation). `count` is
/// the watch's under `reader`, and `at_last_row` what it said when the
/// last row was out (asking `png` for a row past the last one reads on).
pub(crate) fn finish_checked<R, F>(
    reader: &mut png::Reader<IdatWatch<R>>,
    count: &IdatCount,
    at_last_row: Option<u64>,
    reopen: impl FnOnce() -> Result<F>,
) -> Result<()>
where
    R: BufRead + Seek,
    F: BufRead,
{
    reader.finish().map_err(png_error)?;
    match (at_last_row, count.get()) {
        (Some(rows), Some(all)) if rows == all => Ok(()),
        _ => verify_zlib(reopen()?),
    }
}

/// Inflates the image data of the PNG file `png` (read from its first
/// byte) with zlib's checksum verified, keeping only the 32 KiB deflate
/// may refer back to. The chunks' CRCs are not checked again (the decoder
/// did), nor anything past the image data.
///
/// Errors: [`checksum_mismatch`]; [`Error::Decode`] for a corrupt stream
/// or a file cut short; [`Error::Io`] if reading fails.
pub(crate) fn verify_zlib(mut png: impl BufRead) -> Result<()> {
    /// Deflate refers back at most this far.
    const WINDOW: usize = 1 << 15;
    let mut inflater = fdeflate::Decompressor::new();
    let mut out = vec![0u8; 4 * WINDOW];
    let mut filled = 0;
    let mut seen_idat = false;
    let eof = |e: std::io::Error| match e.kind() {
        ErrorKind::UnexpectedEof => Error::Decode("truncated or corrupt: the file ends in its image data".into()),
        _ => Error::Io(e),
    };
    let mut header = [0u8; 8];
    png.read_exact(&mut header).map_err(eof)?;
    loop {
        png.read_exact(&mut header).map_err(eof)?;
        let len = u64::from(u32::from_be_bytes([header[0], header[1], header[2], header[3]]));
        if &header[4..] != b"IDAT" {
            if seen_idat {
                // The image data ended without the stream's end: no
                // checksum to verify, which `png` accepts too.
                return Ok(());
            }
            std::io::copy(&mut (&mut png).take(len + 4), &mut std::io::sink()).map_err(eof)?;
            continue;
        }
        seen_idat = true;
        let mut left = len;
        while left > 0 {
            let input = png.fill_buf().map_err(eof)?;
            if input.is_empty() {
                return Err(eof(ErrorKind::UnexpectedEof.into()));
            }
            let input = &input[..input.len().min(left as usize)];
            let (used, made) = inflater.read(input, &mut out, filled, false).map_err(|e| match e {
                fdeflate::DecompressionError::WrongChecksum => checksum_mismatch(),
                e => Error::Decode(format!("png: corrupt deflate stream: {}", deflate_words(&e))),
            })?;
            png.consume(used);
            left -= used as u64;
            filled += made;
            if inflater.is_done() {
                return Ok(());
            }
            if filled == out.len() {
                out.copy_within(filled - WINDOW.., 0);
                filled = WINDOW;
            }
        }
        png.read_exact(&mut [0u8; 4]).map_err(eof)?;
    }
}

/// What an fdeflate error means, in words (its `Debug` is a Rust name and
/// it has no `Display`).
fn deflate_words(e: &fdeflate::DecompressionError) -> &'static str {
    use fdeflate::DecompressionError as D;
    match e {
        D::BadZlibHeader => "bad zlib header",
        D::InsufficientInput => "the stream ends early",
        D::InvalidBlockType => "invalid block type",
        D::InvalidUncompressedBlockLength => "invalid stored block length",
        D::InvalidHlit | D::InvalidHdist => "too many Huffman codes",
        D::InvalidCodeLengthRepeat | D::BadCodeLengthHuffmanTree => "invalid code lengths",
        D::BadLiteralLengthHuffmanTree | D::BadDistanceHuffmanTree => "invalid Huffman tree",
        D::InvalidLiteralLengthCode | D::InvalidDistanceCode => "invalid Huffman code",
        D::InputStartsWithRun | D::DistanceTooFarBack => "a back-reference before the start",
        D::WrongChecksum => "wrong checksum",
        D::ExtraInput => "data past the end of the stream",
    }
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;

    use super::*;

    fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
        let mut crc = crc32fast::Hasher::new();
        crc.update(kind);
        crc.update(data);
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        out.extend(kind);
        out.extend(data);
        out.extend(crc.finalize().to_be_bytes());
        out
    }

    /// A PNG-shaped file (no IHDR needed here) of these chunks, and the
    /// byte ranges of its IDAT data.
    fn file(chunks: &[(&[u8; 4], Vec<u8>)]) -> (Vec<u8>, Vec<std::ops::Range<usize>>) {
        let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
        let mut idat = Vec::new();
        for (kind, data) in chunks {
            if *kind == b"IDAT" {
                idat.push(out.len() + 8..out.len() + 8 + data.len());
            }
            out.extend(chunk(kind, data));
        }
        (out, idat)
    }

    /// Bytes that deflate compresses with references back across more
    /// than the inflater's buffer, so a window kept wrong shows.
    fn data(len: usize) -> Vec<u8> {
        let mut s = 0x2545_f491_4f6c_dd1d_u64;
        let noise: Vec<u8> = (0..20_000)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 56) as u8
            })
            .collect();
        noise.iter().cycle().take(len).copied().collect()
    }

    #[test]
    fn the_watch_counts_the_idat_data_consumed_at_every_step() {
        let (png, idat) = file(&[
            (b"IHDR", vec![7; 13]),
            (b"tEXt", b"IDAT inside a text chunk\0IDAT".to_vec()),
            (b"IDAT", vec![1; 5]),
            (b"IDAT", Vec::new()),
            (b"IDAT", vec![2; 300]),
            (b"tIME", vec![3; 7]),
            (b"IEND", Vec::new()),
        ]);
        let idat_before = |pos: usize| idat.iter().map(|r| r.end.min(pos).saturating_sub(r.start)).sum::<usize>();
        let (mut watch, count) = IdatWatch::new(Cursor::new(&png[..]));
        let mut pos = 0;
        for step in [1, 2, 3, 5, 7, 11, 13].iter().cycle() {
            let n = (*step).min(png.len() - pos);
            if n == 0 {
                break;
            }
            assert!(watch.fill_buf().unwrap().len() >= n);
            watch.consume(n);
            pos += n;
            assert_eq!(count.get(), Some(idat_before(pos) as u64), "after {pos} bytes");
        }
        assert_eq!(count.get(), Some(305));
        watch.seek(SeekFrom::Start(0)).unwrap();
        assert_eq!(count.get(), None, "a seek loses the count");
    }

    #[test]
    fn verify_zlib_checks_the_inflated_bytes_against_the_checksum() {
        let raw = data(1 << 20);
        // miniz, not fdeflate: fdeflate refers back only to the byte before.
        let zlib = miniz_oxide::deflate::compress_to_vec_zlib(&raw, 6);
        let (good, _) = file(&[
            (b"IHDR", vec![0; 13]),
            (b"IDAT", zlib[..1000].to_vec()),
            (b"IDAT", zlib[1000..zlib.len() - 4].to_vec()),
            (b"IDAT", zlib[zlib.len() - 4..].to_vec()),
            (b"IEND", Vec::new()),
        ]);
        verify_zlib(Cursor::new(&good)).expect("the stream as written");
        let mut flipped = zlib.clone();
        let end = flipped.len();
        flipped[end - 1] ^= 1;
        let (bad, _) = file(&[(b"IHDR", vec![0; 13]), (b"IDAT", flipped), (b"IEND", Vec::new())]);
        match verify_zlib(Cursor::new(&bad)) {
            Err(Error::Decode(m)) => assert_eq!(m, "image data is corrupt: zlib checksum (Adler-32) does not match"),
            other => panic!("want the checksum error, got {other:?}"),
        }
        // Without its checksum the stream has nothing to verify, which is
        // not an error (`png` reads such files too); bytes that are not
        // deflate are.
        let (no_checksum, _) =
            file(&[(b"IHDR", vec![0; 13]), (b"IDAT", zlib[..end - 4].to_vec()), (b"IEND", Vec::new())]);
        verify_zlib(Cursor::new(&no_checksum)).expect("no checksum to verify");
        let (garbage, _) =
            file(&[(b"IHDR", vec![0; 13]), (b"IDAT", vec![0x78, 0x01, 0xff, 0xff]), (b"IEND", Vec::new())]);
        assert!(matches!(verify_zlib(Cursor::new(&garbage)), Err(Error::Decode(m)) if m.contains("deflate")));
    }
}
