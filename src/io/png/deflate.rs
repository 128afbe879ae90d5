//! The PNG encoder's zlib stream (RFC 1950, 1951), deflated in pieces on
//! every core.
//!
//! A zlib stream is one deflate stream, whose blocks follow each other bit
//! by bit, and one checksum of all the data. Deflated on its own, a piece
//! ends its stream: its last block is marked final, its bits stop in the
//! middle of a byte, and its Adler-32 is its data's only. A [`Piece`] is
//! made to join others: its block is not final, it ends on a byte boundary
//! (an empty stored block, as zlib's sync flush writes), and it keeps its
//! Adler-32, which [`adler32_combine`] joins with the others'. Pieces are
//! then written one after the other, between [`ZLIB_HEADER`] and
//! [`FINAL_BLOCK`] and the checksum, and inflate as one stream.
//!
//! Deflate is fdeflate's: one block with a fixed Huffman table tuned for
//! filtered images, and runs of zeros. Its stream's shape, which a piece
//! relies on, is checked on every piece (one that is not as expected is
//! stored instead, never wrong) and pinned by this module's tests.
//!
//! Why: deflate was the one part of a streamed PNG on a single thread, and
//! pieces let a piece that deflate barely shrinks be stored. Measured on
//! the 4096² GeoTIFF of `bench/terrain.sh` to a 16-bit PNG, 2 cores: 0.21
//! s with deflate on the writing thread, 0.11 s without deflate at all (an
//! invalid file, for the measure); with pieces, 0.13–0.14 s (see
//! docs/speed.md).

use crate::par::prelude::*;

/// The zlib header: deflate, 32 KiB window, no dictionary, fastest level.
pub(crate) const ZLIB_HEADER: [u8; 2] = [0x78, 0x01];

/// A final, empty block after the last piece: BFINAL 1, BTYPE 01 (fixed
/// Huffman), end-of-block (seven 0 bits), from a byte boundary.
pub(crate) const FINAL_BLOCK: [u8; 2] = [0x03, 0x00];

/// The Adler-32 and the length of some data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Checksum {
    pub adler: u32,
    pub len: u64,
}

impl Checksum {
    /// No data.
    pub const EMPTY: Checksum = Checksum { adler: 1, len: 0 };

    pub fn of(data: &[u8]) -> Checksum {
        Checksum { adler: adler32(data), len: data.len() as u64 }
    }

    /// The checksum of this data followed by `next`'s.
    #[must_use]
    pub fn then(self, next: Checksum) -> Checksum {
        Checksum { adler: adler32_combine(self.adler, next.adler, next.len), len: self.len + next.len }
    }
}

/// Raw deflate that does not end the stream and ends on a byte boundary,
/// and the checksum of the data it holds.
#[derive(Debug)]
pub(crate) struct Piece {
    pub bytes: Vec<u8>,
    pub sum: Checksum,
}

impl Piece {
    /// `data` as stored blocks (no compression), in `bytes` (its contents
    /// replaced): for rows written as they are, and for fdeflate output
    /// that is not as expected.
    pub fn stored(data: &[u8], mut bytes: Vec<u8>) -> Piece {
        bytes.clear();
        put_stored(data, &mut bytes);
        Piece { bytes, sum: Checksum::of(data) }
    }
}

/// A zlib stream's data given part after part (the rows of a band),
/// deflated in pieces of [`PIECE`] bytes at fixed places from its start,
/// the last one shorter: the bytes written do not depend on where the
/// parts end (a band's rows depend on the number of threads). The pieces
/// a part completes are deflated in parallel on rayon's pool.
pub(crate) struct Pieces {
    /// The data of the piece not yet complete.
    pending: Vec<u8>,
    /// Whether a piece whose first [`PROBE`] bytes deflate shrinks by
    /// less than a tenth is stored instead: deflating it would cost more
    /// time than it saves bytes (16-bit normal maps, whose low bytes are
    /// noise).
    probe: bool,
}

/// Bytes of data in a piece. Each costs fdeflate's 54-byte table and 4
/// to 5 bytes of stored block.
const PIECE: usize = 1 << 18;

impl Pieces {
    pub fn new(probe: bool) -> Pieces {
        Pieces { pending: Vec::new(), probe }
    }

    /// The pieces that `data`, the next part, completes, in order; with
    /// `last`, every piece left. Each piece's bytes go into a buffer from
    /// `spare` (one written already, say, whose pages are mapped), or a
    /// new one.
    pub fn push(&mut self, mut data: &[u8], last: bool, mut spare: impl FnMut() -> Option<Vec<u8>>) -> Vec<Piece> {
        if !self.pending.is_empty() {
            let take = (PIECE - self.pending.len()).min(data.len());
            self.pending.extend_from_slice(&data[..take]);
            data = &data[take..];
            if self.pending.len() < PIECE && !last {
                return Vec::new();
            }
        }
        let whole = if last { data.len() } else { data.len() - data.len() % PIECE };
        let (now, rest) = data.split_at(whole);
        let first = (!self.pending.is_empty()).then_some(&self.pending[..]);
        let parts: Vec<&[u8]> = first.into_iter().chain(now.chunks(PIECE)).collect();
        let buffers: Vec<Vec<u8>> = parts.iter().map(|_| spare().unwrap_or_default()).collect();
        let probe = self.probe;
        let pieces = parts
            .into_par_iter()
            .zip(buffers.into_par_iter())
            .map(|(part, buffer)| {
                if probe && !worth_deflating(part) { Piece::stored(part, buffer) } else { deflate_piece(part, buffer) }
            })
            .collect();
        self.pending.clear();
        self.pending.extend_from_slice(rest);
        pieces
    }
}

/// Bytes of a piece that [`Pieces`] deflates first, to see whether the
/// rest is worth it.
const PROBE: usize = 1 << 12;

/// Whether deflate shrinks the start of `data` by a tenth or more.
fn worth_deflating(data: &[u8]) -> bool {
    let probe = &data[..data.len().min(PROBE)];
    10 * fdeflate::compress_to_vec(probe).len() <= 9 * probe.len()
}

/// `data` deflated by fdeflate as a piece, in `buffer` (its contents
/// replaced); stored instead if that is smaller (deflate can grow noise by
/// half, its table being made for filtered rows) or if fdeflate's stream
/// is not as expected.
fn deflate_piece(data: &[u8], buffer: Vec<u8>) -> Piece {
    match fdeflated(data, buffer) {
        Ok(piece) if piece.bytes.len() <= stored_len(data.len()) => piece,
        Ok(Piece { bytes, .. }) | Err(bytes) => Piece::stored(data, bytes),
    }
}

/// `data` deflated by fdeflate as a piece, in `buffer` (its contents
/// replaced); the buffer back if fdeflate's stream is not as expected.
fn fdeflated(data: &[u8], mut buffer: Vec<u8>) -> Result<Piece, Vec<u8>> {
    buffer.clear();
    let body = Body { out: buffer, header: Vec::new() };
    let mut compressor = fdeflate::Compressor::new(body).expect("writing to memory");
    compressor.write_data(data).expect("writing to memory");
    let body = compressor.finish().expect("writing to memory");
    as_piece(body, data.len() as u64)
}

/// A zlib stream written to memory without its 2-byte header (kept apart,
/// to be checked): a piece's bytes start where they are to stay.
struct Body {
    out: Vec<u8>,
    header: Vec<u8>,
}

impl std::io::Write for Body {
    fn write(&mut self, data: &[u8]) -> std::io::Result<usize> {
        let to_header = (ZLIB_HEADER.len() - self.header.len()).min(data.len());
        self.header.extend_from_slice(&data[..to_header]);
        self.out.extend_from_slice(&data[to_header..]);
        Ok(data.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// fdeflate's zlib stream of `len` bytes as a piece, in place; its buffer
/// back if it is not the shape this relies on.
///
/// The shape: the zlib header (2 bytes); one block, final, with its own
/// Huffman table (BFINAL 1 and BTYPE 10 in the low 3 bits of its first
/// byte), whose end-of-block code (111111110001, sent in that order) ends
/// in a 1 bit, followed by 0 bits up to the byte boundary; the Adler-32
/// (4 bytes, big-endian).
fn as_piece(Body { out: mut stream, header }: Body, len: u64) -> Result<Piece, Vec<u8>> {
    let n = stream.len();
    if header != ZLIB_HEADER || n < 2 + 4 || stream[0] & 0b111 != 0b101 || stream[n - 5] == 0 {
        return Err(stream);
    }
    let adler = u32::from_be_bytes([stream[n - 4], stream[n - 3], stream[n - 2], stream[n - 1]]);
    let last = stream[n - 5];
    stream.truncate(n - 4);
    // Not the last block.
    stream[0] &= !1;
    // An empty stored block: its 3 header bits (BFINAL 0, BTYPE 00) are
    // the last byte's free bits above the end-of-block code if there are 3
    // of them, else the next byte's; then LEN 0 and NLEN 0xffff.
    if last.leading_zeros() < 3 {
        stream.push(0);
    }
    stream.extend_from_slice(&[0, 0, 0xff, 0xff]);
    Ok(Piece { bytes: stream, sum: Checksum { adler, len } })
}

/// Bytes of `len` bytes of data as deflate stored blocks.
pub(crate) fn stored_len(len: usize) -> usize {
    len + 5 * len.div_ceil(STORED_MAX).max(1)
}

const STORED_MAX: usize = 65535;

/// Appends `data` as non-final deflate stored blocks, starting on a byte
/// boundary.
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

/// Adler-32 of `data`, as zlib computes it (`simd-adler32`'s, which
/// fdeflate uses too: a loop of a byte at a time here took 7 % of a
/// 16-bit PNG's processor time).
fn adler32(data: &[u8]) -> u32 {
    simd_adler32::adler32(&data)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// No spare buffers.
    fn none() -> Option<Vec<u8>> {
        None
    }

    /// A zlib stream of `pieces`, one after the other.
    fn stream_of(pieces: &[&Piece]) -> Vec<u8> {
        let mut stream = ZLIB_HEADER.to_vec();
        let mut sum = Checksum::EMPTY;
        for piece in pieces {
            stream.extend_from_slice(&piece.bytes);
            sum = sum.then(piece.sum);
        }
        stream.extend_from_slice(&FINAL_BLOCK);
        stream.extend_from_slice(&sum.adler.to_be_bytes());
        stream
    }

    /// Bytes like a filtered image's: small differences, runs of zeros,
    /// and now and then noise.
    fn filtered_like(len: usize, seed: u64) -> Vec<u8> {
        let mut state = seed | 1;
        (0..len)
            .map(|k| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                match (k / 700) % 3 {
                    0 => 0,
                    1 => (state % 5) as u8,
                    _ => state as u8,
                }
            })
            .collect()
    }

    #[test]
    fn adler32_and_its_combination_match_the_definition() {
        // Adler-32 of "Wikipedia", the usual worked example.
        assert_eq!(adler32(b"Wikipedia"), 0x11e6_0398);
        assert_eq!(adler32(b""), 1);
        let data: Vec<u8> = (0..20000u32).map(|k| (k * 7 % 251) as u8).collect();
        for cut in [0, 1, 5552, 11111, 20000] {
            let (a, b) = data.split_at(cut);
            assert_eq!(adler32_combine(adler32(a), adler32(b), b.len() as u64), adler32(&data), "cut {cut}");
            assert_eq!(Checksum::of(a).then(Checksum::of(b)), Checksum::of(&data), "cut {cut}");
        }
    }

    #[test]
    fn stored_blocks_inflate_to_their_data() {
        for len in [0, 1, STORED_MAX, STORED_MAX + 1, 3 * STORED_MAX + 17] {
            let data: Vec<u8> = (0..len).map(|k| (k % 253) as u8).collect();
            let piece = Piece::stored(&data, Vec::new());
            assert_eq!(piece.bytes.len(), stored_len(len), "len {len}");
            assert_eq!(fdeflate::decompress_to_vec(&stream_of(&[&piece])).unwrap(), data, "len {len}");
        }
    }

    #[test]
    fn fdeflate_streams_have_the_shape_a_piece_relies_on() {
        // Every length up to 2 bytes past a word, so the end-of-block code
        // ends at every bit of a byte; each is a piece, not stored.
        for len in 0..200 {
            let data = filtered_like(len, len as u64 + 7);
            let piece = fdeflated(&data, vec![9; 3]).expect("fdeflate's stream as expected");
            assert_eq!(piece.sum, Checksum::of(&data), "len {len}");
            assert_eq!(fdeflate::decompress_to_vec(&stream_of(&[&piece])).unwrap(), data, "len {len}");
        }
    }

    #[test]
    fn pieces_joined_inflate_as_one_stream_and_as_the_png_crate_reads_them() {
        let data = filtered_like(3 * PIECE + 12345, 42);
        // Pieces of every kind, cut anywhere, in order.
        let cuts = [0, 1, 9, 700, 70_000, 70_003, 200_000, data.len()];
        let pieces: Vec<Piece> = cuts
            .windows(2)
            .enumerate()
            .map(|(k, c)| {
                let part = &data[c[0]..c[1]];
                if k % 3 == 2 { Piece::stored(part, Vec::new()) } else { deflate_piece(part, Vec::new()) }
            })
            .collect();
        let stream = stream_of(&pieces.iter().collect::<Vec<_>>());
        assert_eq!(fdeflate::decompress_to_vec(&stream).unwrap(), data);
        // A second inflater.
        let inflated = miniz_oxide::inflate::decompress_to_vec_zlib(&stream).unwrap();
        assert_eq!(inflated, data);
        // Given in parts cut anywhere: the same pieces as given whole,
        // several of them, smaller than the data.
        let whole = Pieces::new(false).push(&data, true, none);
        assert!(whole.len() > 1, "{} pieces", whole.len());
        let mut pieces = Pieces::new(false);
        let mut parted = Vec::new();
        for c in [0, 5, 70_000, 70_001, 600_000, data.len()].windows(2) {
            parted.extend(pieces.push(&data[c[0]..c[1]], c[1] == data.len(), || Some(vec![7; 100])));
        }
        let bytes = |ps: &[Piece]| ps.iter().map(|p| p.bytes.clone()).collect::<Vec<_>>();
        assert_eq!(bytes(&parted), bytes(&whole));
        let sum = whole.iter().fold(Checksum::EMPTY, |sum, p| sum.then(p.sum));
        assert_eq!(sum, Checksum::of(&data));
        let size: usize = whole.iter().map(|p| p.bytes.len()).sum();
        assert!(size < data.len(), "{size} bytes");
        assert_eq!(fdeflate::decompress_to_vec(&stream_of(&whole.iter().collect::<Vec<_>>())).unwrap(), data);
        assert!(Pieces::new(false).push(&[], true, none).is_empty());
    }

    #[test]
    fn the_probe_stores_what_deflate_barely_shrinks() {
        // Noise: stored with the probe without deflating it, and stored
        // without the probe too, deflate making it larger.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let noise: Vec<u8> = (0..PIECE + 100)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        let stored: Vec<Vec<u8>> = noise.chunks(PIECE).map(|part| Piece::stored(part, Vec::new()).bytes).collect();
        let probed = Pieces::new(true).push(&noise, true, none);
        assert_eq!(probed.iter().map(|p| p.bytes.clone()).collect::<Vec<_>>(), stored);
        assert!(!worth_deflating(&noise));
        let deflated = Pieces::new(false).push(&noise, true, none);
        assert_eq!(deflated.iter().map(|p| p.bytes.clone()).collect::<Vec<_>>(), stored);
        assert!(fdeflated(&noise[..PIECE], Vec::new()).unwrap().bytes.len() > stored[0].len());
        // Filtered rows: deflated either way, smaller.
        let rows = filtered_like(PIECE, 3);
        assert!(worth_deflating(&rows));
        let piece = Pieces::new(true).push(&rows, true, none).remove(0);
        assert_eq!(piece.bytes, fdeflated(&rows, Vec::new()).unwrap().bytes);
        assert!(piece.bytes.len() < rows.len());
        for pieces in [probed, deflated] {
            let stream = stream_of(&pieces.iter().collect::<Vec<_>>());
            assert_eq!(fdeflate::decompress_to_vec(&stream).unwrap(), noise);
        }
    }
}
