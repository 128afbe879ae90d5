//! The KTX 2.0 writer, as the Khronos KTX 2.0 specification lays a file
//! out:
//!
//! 1. the identifier `«KTX 20»\r\n\x1A\n` (12 bytes);
//! 2. the header, nine little-endian words: `vkFormat`, `typeSize`,
//!    `pixelWidth`, `pixelHeight`, `pixelDepth` (0: 2D), `layerCount` (0:
//!    no array), `faceCount` (1), `levelCount`, `supercompressionScheme`
//!    (0: none);
//! 3. the index: the Data Format Descriptor's offset and length, the
//!    key/value data's, the supercompression global data's (none: 0, 0);
//! 4. the level index, one entry per level, the finest first:
//!    `byteOffset`, `byteLength`, `uncompressedByteLength` (equal to the
//!    length without supercompression), 64-bit each;
//! 5. the Data Format Descriptor (below);
//! 6. the key/value data: `KTXwriter`, this library and its version;
//! 7. the levels, **the smallest first**, each at an offset that is a
//!    multiple of lcm(texel block bytes, 4) (`mipPadding` of zeros before
//!    each).
//!
//! The Data Format Descriptor is one basic descriptor block (Khronos Data
//! Format Specification, "Basic descriptor block"): vendor 0 (Khronos),
//! type 0, version 2, its size 24 + 16 × samples; the colour model
//! (RGBSDA = 1, or BC4 = 131, BC5 = 132, BC7 = 134 for block formats),
//! BT.709 primaries (1), the linear transfer function (1), straight alpha;
//! the texel block's dimensions less one (3, 3 for blocks, else 0); its
//! bytes; then a sample per channel: bit offset and length less one, the
//! channel (R 0, G 1, B 2, A 15; a BC5 block's two halves R and G; a BC4
//! or BC7 block one sample of channel 0), qualifiers (half floats: signed
//! and float, 0xC0), and the range the values map to (UNORM bytes 0 to
//! 255, block formats 0 to 2³² − 1, half floats −1.0 to 1.0 as float bits).
//! These are the descriptors the Khronos tools (`ktx create`) write for
//! the same `vkFormat`s.

use std::io::Write;

use crate::error::Result;
use crate::io::texture::{TextureFormat, word};

/// The file identifier.
pub(crate) const IDENTIFIER: [u8; 12] = [0xAB, b'K', b'T', b'X', b' ', b'2', b'0', 0xBB, b'\r', b'\n', 0x1A, b'\n'];

/// Bytes of the identifier, the header and the index.
const FIXED_BYTES: usize = 12 + 9 * 4 + 4 * 4 + 2 * 8;

/// Bytes of one level index entry.
const LEVEL_ENTRY_BYTES: usize = 3 * 8;

/// Channel ids (RGBSDA model; BC5's red and green; BC4's and BC7's data).
const CHANNEL_R: u8 = 0;
const CHANNEL_G: u8 = 1;
const CHANNEL_B: u8 = 2;
const CHANNEL_A: u8 = 15;
/// Qualifiers of a half float sample: signed, float.
const SIGNED_FLOAT: u8 = 0x40 | 0x80;

/// One sample of a basic descriptor block.
struct DfdSample {
    bit_offset: u16,
    bit_length: u16,
    channel: u8,
    lower: u32,
    upper: u32,
}

/// The Data Format Descriptor of `format`: its total size, then the basic
/// descriptor block, as the module's docs lay it out.
pub(crate) fn data_format_descriptor(format: TextureFormat) -> Vec<u8> {
    let unorm8 = |i: u16, channel| DfdSample { bit_offset: 8 * i, bit_length: 8, channel, lower: 0, upper: 255 };
    let half = |i: u16, channel| DfdSample {
        bit_offset: 16 * i,
        bit_length: 16,
        channel: channel | SIGNED_FLOAT,
        lower: (-1.0f32).to_bits(),
        upper: 1.0f32.to_bits(),
    };
    let block =
        |bit_offset, bit_length, channel| DfdSample { bit_offset, bit_length, channel, lower: 0, upper: u32::MAX };
    let (model, samples): (u8, Vec<DfdSample>) = match format {
        TextureFormat::Bc4 => (131, vec![block(0, 64, 0)]),
        TextureFormat::Bc5 => (132, vec![block(0, 64, CHANNEL_R), block(64, 64, CHANNEL_G)]),
        TextureFormat::Bc7 => (134, vec![block(0, 128, 0)]),
        TextureFormat::Rgba8 => {
            (1, vec![unorm8(0, CHANNEL_R), unorm8(1, CHANNEL_G), unorm8(2, CHANNEL_B), unorm8(3, CHANNEL_A)])
        }
        TextureFormat::Rg8 => (1, vec![unorm8(0, CHANNEL_R), unorm8(1, CHANNEL_G)]),
        TextureFormat::R8 => (1, vec![unorm8(0, CHANNEL_R)]),
        TextureFormat::Rgba16f => {
            (1, vec![half(0, CHANNEL_R), half(1, CHANNEL_G), half(2, CHANNEL_B), half(3, CHANNEL_A)])
        }
        TextureFormat::Rg16f => (1, vec![half(0, CHANNEL_R), half(1, CHANNEL_G)]),
        TextureFormat::R16f => (1, vec![half(0, CHANNEL_R)]),
    };
    let block_size = 24 + 16 * samples.len();
    let side = (format.block_side() - 1) as u8;
    let mut words: Vec<u32> = vec![
        (4 + block_size) as u32,       // dfdTotalSize
        0,                             // vendorId 0 (17 bits), descriptorType 0 (15 bits)
        2 | (block_size as u32) << 16, // versionNumber, descriptorBlockSize
        // colorModel, colorPrimaries BT.709, transferFunction linear, flags 0
        u32::from_le_bytes([model, 1, 1, 0]),
        u32::from_le_bytes([side, side, 0, 0]), // texelBlockDimension0..3
        u32::from_le_bytes([format.block_bytes() as u8, 0, 0, 0]), // bytesPlane0..3
        0,                                      // bytesPlane4..7
    ];
    for s in samples {
        words.push(u32::from(s.bit_offset) | u32::from(s.bit_length - 1) << 16 | u32::from(s.channel) << 24);
        words.push(0); // samplePosition0..3
        words.push(s.lower);
        words.push(s.upper);
    }
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// The key/value data: `KTXwriter` naming this library, its length and
/// padding to a multiple of 4 included.
fn key_values() -> Vec<u8> {
    let mut entry = b"KTXwriter\0normalfit ".to_vec();
    entry.extend_from_slice(env!("CARGO_PKG_VERSION").as_bytes());
    entry.push(0);
    let mut out = (entry.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(&entry);
    out.resize(out.len().next_multiple_of(4), 0);
    out
}

/// Least common multiple of `a` and 4.
fn lcm4(a: usize) -> usize {
    match a % 4 {
        0 => a,
        2 => a * 2,
        _ => a * 4,
    }
}

/// Writes the KTX2 file of a chain whose finest level is `size`, its
/// levels' bytes (`levels`, the finest first, each as
/// [`TextureFormat::level_bytes`] says) in `format`.
pub(crate) fn write_ktx2<W: Write + ?Sized>(
    out: &mut W,
    format: TextureFormat,
    (width, height): (usize, usize),
    levels: &[Vec<u8>],
) -> Result<()> {
    let dfd = data_format_descriptor(format);
    let kvd = key_values();
    let dfd_offset = FIXED_BYTES + LEVEL_ENTRY_BYTES * levels.len();
    let kvd_offset = dfd_offset + dfd.len();
    let align = lcm4(format.block_bytes());
    // Offsets of the levels, the smallest (last) placed first.
    let mut offsets = vec![0usize; levels.len()];
    let mut at = kvd_offset + kvd.len();
    for (k, level) in levels.iter().enumerate().rev() {
        at = at.next_multiple_of(align);
        offsets[k] = at;
        at += level.len();
    }
    let mut head: Vec<u8> = Vec::with_capacity(kvd_offset + kvd.len());
    head.extend_from_slice(&IDENTIFIER);
    for w in [
        format.vk_format(),
        format.type_size(),
        word(width, "a width of")?,
        word(height, "a height of")?,
        0, // pixelDepth
        0, // layerCount
        1, // faceCount
        word(levels.len(), "a level count of")?,
        0, // supercompressionScheme
        word(dfd_offset, "an offset of")?,
        word(dfd.len(), "a length of")?,
        word(kvd_offset, "an offset of")?,
        word(kvd.len(), "a length of")?,
    ] {
        head.extend_from_slice(&w.to_le_bytes());
    }
    head.extend_from_slice(&[0; 16]); // sgdByteOffset, sgdByteLength
    for (level, offset) in levels.iter().zip(&offsets) {
        for v in [*offset as u64, level.len() as u64, level.len() as u64] {
            head.extend_from_slice(&v.to_le_bytes());
        }
    }
    head.extend_from_slice(&dfd);
    head.extend_from_slice(&kvd);
    out.write_all(&head)?;
    let mut written = head.len();
    for (level, offset) in levels.iter().zip(&offsets).rev() {
        out.write_all(&vec![0; offset - written])?;
        out.write_all(level)?;
        written = offset + level.len();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lcm_with_four() {
        assert_eq!([1, 2, 4, 8, 16].map(lcm4), [4, 4, 4, 8, 16]);
    }

    #[test]
    fn levels_smallest_first_and_aligned() {
        // R8 levels of odd lengths: each placed at a multiple of 4.
        let levels = vec![vec![1; 15], vec![2; 3], vec![3; 1]];
        let mut out = Vec::new();
        write_ktx2(&mut out, TextureFormat::R8, (5, 3), &levels).unwrap();
        let entry = |k: usize| {
            let at = FIXED_BYTES + LEVEL_ENTRY_BYTES * k;
            let v = |i: usize| u64::from_le_bytes(out[at + 8 * i..at + 8 * i + 8].try_into().unwrap()) as usize;
            (v(0), v(1), v(2))
        };
        let (o0, o1, o2) = (entry(0).0, entry(1).0, entry(2).0);
        assert!(o2 < o1 && o1 < o0, "{o2} {o1} {o0}");
        for (k, level) in levels.iter().enumerate() {
            let (offset, length, uncompressed) = entry(k);
            assert_eq!(offset % 4, 0);
            assert_eq!((length, uncompressed), (level.len(), level.len()));
            assert_eq!(&out[offset..offset + length], &level[..]);
        }
        assert_eq!(out.len(), o0 + 15);
    }

    #[test]
    fn descriptor_sizes() {
        for (format, samples) in [(TextureFormat::Bc5, 2), (TextureFormat::Rgba16f, 4), (TextureFormat::Bc7, 1)] {
            let dfd = data_format_descriptor(format);
            assert_eq!(dfd.len(), 4 + 24 + 16 * samples);
            assert_eq!(u32::from_le_bytes(dfd[..4].try_into().unwrap()) as usize, dfd.len());
        }
    }
}
