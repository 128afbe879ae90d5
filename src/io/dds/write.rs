//! The DDS writer: the magic, the 124-byte `DDS_HEADER`, the 20-byte
//! `DDS_HEADER_DXT10`, then every level's bytes, the finest first, each
//! level's rows of blocks (or texels) top to bottom with no padding.
//!
//! As Microsoft's "DDS file layout" documents it, and texconv writes it:
//! `dwFlags` holds CAPS, HEIGHT, WIDTH and PIXELFORMAT, with MIPMAPCOUNT
//! when there is more than one level, and LINEARSIZE (block-compressed:
//! `dwPitchOrLinearSize` is the finest level's bytes) or PITCH (else: the
//! bytes of one of its rows); the pixel format is a FourCC of `DX10`;
//! `dwCaps` holds TEXTURE, with COMPLEX and MIPMAP for a chain; the DX10
//! header names the `DXGI_FORMAT`, a 2D texture, an array of one.

use std::io::Write;

use crate::error::Result;
use crate::io::texture::{TextureFormat, word};

/// Bytes before the first level: the magic, `DDS_HEADER`, `DDS_HEADER_DXT10`.
pub(crate) const HEADER_BYTES: usize = 4 + 124 + 20;

const DDSD_CAPS: u32 = 0x1;
const DDSD_HEIGHT: u32 = 0x2;
const DDSD_WIDTH: u32 = 0x4;
const DDSD_PITCH: u32 = 0x8;
const DDSD_PIXELFORMAT: u32 = 0x1000;
const DDSD_MIPMAPCOUNT: u32 = 0x2_0000;
const DDSD_LINEARSIZE: u32 = 0x8_0000;
const DDPF_FOURCC: u32 = 0x4;
const DDSCAPS_COMPLEX: u32 = 0x8;
const DDSCAPS_TEXTURE: u32 = 0x1000;
const DDSCAPS_MIPMAP: u32 = 0x40_0000;
const D3D10_RESOURCE_DIMENSION_TEXTURE2D: u32 = 3;

/// Writes the DDS file of a chain whose finest level is `size`, its
/// levels' bytes (`levels`, the finest first, each as
/// [`TextureFormat::level_bytes`] says) in `format`.
pub(crate) fn write_dds<W: Write + ?Sized>(
    out: &mut W,
    format: TextureFormat,
    (width, height): (usize, usize),
    levels: &[Vec<u8>],
) -> Result<()> {
    let count = word(levels.len(), "a level count of")?;
    let chain = levels.len() > 1;
    let (size_flag, pitch) = if format.is_block_compressed() {
        (DDSD_LINEARSIZE, format.level_bytes((width, height)))
    } else {
        (DDSD_PITCH, format.row_bytes(width))
    };
    let flags =
        DDSD_CAPS | DDSD_HEIGHT | DDSD_WIDTH | DDSD_PIXELFORMAT | size_flag | if chain { DDSD_MIPMAPCOUNT } else { 0 };
    let caps = DDSCAPS_TEXTURE | if chain { DDSCAPS_COMPLEX | DDSCAPS_MIPMAP } else { 0 };
    let mut header: Vec<u32> = Vec::with_capacity(HEADER_BYTES / 4);
    header.push(u32::from_le_bytes(*b"DDS "));
    // DDS_HEADER
    header.extend([124, flags, word(height, "a height of")?, word(width, "a width of")?, word(pitch, "a level of")?]);
    header.extend([0, count]); // dwDepth, dwMipMapCount
    header.extend([0; 11]); // dwReserved1
    // DDS_PIXELFORMAT: size, flags, FourCC, then bit count and masks unused.
    header.extend([32, DDPF_FOURCC, u32::from_le_bytes(*b"DX10"), 0, 0, 0, 0, 0]);
    header.extend([caps, 0, 0, 0, 0]); // dwCaps, dwCaps2..4, dwReserved2
    // DDS_HEADER_DXT10: format, dimension, misc flag, array size, misc flags 2.
    header.extend([format.dxgi_format(), D3D10_RESOURCE_DIMENSION_TEXTURE2D, 0, 1, 0]);
    debug_assert_eq!(header.len() * 4, HEADER_BYTES);
    let bytes: Vec<u8> = header.iter().flat_map(|w| w.to_le_bytes()).collect();
    out.write_all(&bytes)?;
    for level in levels {
        out.write_all(level)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(bytes: &[u8]) -> Vec<u32> {
        bytes.chunks_exact(4).map(|w| u32::from_le_bytes(w.try_into().unwrap())).collect()
    }

    #[test]
    fn header_of_a_bc5_chain() {
        let levels = vec![vec![1; 32], vec![2; 16], vec![3; 16]];
        let mut out = Vec::new();
        write_dds(&mut out, TextureFormat::Bc5, (8, 4), &levels).unwrap();
        assert_eq!(out.len(), HEADER_BYTES + 64);
        let w = words(&out[..HEADER_BYTES]);
        assert_eq!(&out[..4], b"DDS ");
        assert_eq!(w[1], 124);
        assert_eq!(w[2], 0x1 | 0x2 | 0x4 | 0x1000 | 0x2_0000 | 0x8_0000);
        assert_eq!((w[3], w[4], w[5], w[7]), (4, 8, 32, 3));
        assert_eq!(&out[84..88], b"DX10");
        assert_eq!(w[27], 0x1000 | 0x8 | 0x40_0000);
        assert_eq!(&w[32..37], &[83, 3, 0, 1, 0]);
        assert_eq!(&out[HEADER_BYTES..HEADER_BYTES + 32], &[1; 32]);
    }

    #[test]
    fn an_uncompressed_level_has_a_pitch() {
        let mut out = Vec::new();
        write_dds(&mut out, TextureFormat::Rg8, (3, 1), &[vec![0; 6]]).unwrap();
        let w = words(&out[..HEADER_BYTES]);
        assert_eq!(w[2], 0x1 | 0x2 | 0x4 | 0x1000 | 0x8);
        assert_eq!((w[5], w[7]), (6, 1));
        assert_eq!(w[27], 0x1000);
        assert_eq!(w[32], 49);
    }
}
