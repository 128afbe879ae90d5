//! The formats of GPU textures that the containers ([`super::dds`],
//! [`super::ktx2`]) hold and [`super::gpu`] encodes: each one's number in
//! Direct3D's `DXGI_FORMAT` and Vulkan's `VkFormat`, its texel block and
//! its bytes. The vocabulary the encoders and both containers share, kept
//! below them all.
//!
//! The numbers, as the Direct3D (`dxgiformat.h`) and Vulkan (`VkFormat`)
//! headers define them:
//!
//! | format | DXGI_FORMAT | VkFormat | block | bytes a block |
//! |---|---|---|---|---|
//! | BC4 | BC4_UNORM = 80 | BC4_UNORM_BLOCK = 139 | 4 × 4 | 8 |
//! | BC5 | BC5_UNORM = 83 | BC5_UNORM_BLOCK = 141 | 4 × 4 | 16 |
//! | BC7 | BC7_UNORM = 98 | BC7_UNORM_BLOCK = 145 | 4 × 4 | 16 |
//! | RGBA8 | R8G8B8A8_UNORM = 28 | R8G8B8A8_UNORM = 37 | 1 × 1 | 4 |
//! | RG8 | R8G8_UNORM = 49 | R8G8_UNORM = 16 | 1 × 1 | 2 |
//! | R8 | R8_UNORM = 61 | R8_UNORM = 9 | 1 × 1 | 1 |
//! | RGBA16F | R16G16B16A16_FLOAT = 10 | R16G16B16A16_SFLOAT = 97 | 1 × 1 | 8 |
//! | RG16F | R16G16_FLOAT = 34 | R16G16_SFLOAT = 83 | 1 × 1 | 4 |
//! | R16F | R16_FLOAT = 54 | R16_SFLOAT = 76 | 1 × 1 | 2 |

use crate::error::{Error, Result};

/// A size as a container's 32-bit header field, or [`Error::Limits`].
pub(crate) fn word(value: usize, what: &str) -> Result<u32> {
    u32::try_from(value).map_err(|_| Error::Limits(format!("{what} {value} does not fit a 32-bit header field")))
}

/// A GPU texture format a chain is stored in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TextureFormat {
    /// One channel in 4 × 4 blocks of 8 bytes (UNORM).
    Bc4,
    /// Two channels in 4 × 4 blocks of 16 bytes: two BC4 blocks, red then
    /// green (UNORM).
    Bc5,
    /// Four channels in 4 × 4 blocks of 16 bytes (UNORM).
    Bc7,
    /// Red, green, blue, alpha: a byte each (UNORM).
    Rgba8,
    /// Red, green: a byte each (UNORM).
    Rg8,
    /// Red: a byte (UNORM).
    R8,
    /// Red, green, blue, alpha: a half float each.
    Rgba16f,
    /// Red, green: a half float each.
    Rg16f,
    /// Red: a half float.
    R16f,
}

impl TextureFormat {
    /// The format as messages and docs name it: BC5, RGBA8, R16F…
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            TextureFormat::Bc4 => "BC4",
            TextureFormat::Bc5 => "BC5",
            TextureFormat::Bc7 => "BC7",
            TextureFormat::Rgba8 => "RGBA8",
            TextureFormat::Rg8 => "RG8",
            TextureFormat::R8 => "R8",
            TextureFormat::Rgba16f => "RGBA16F",
            TextureFormat::Rg16f => "RG16F",
            TextureFormat::R16f => "R16F",
        }
    }

    /// Direct3D's `DXGI_FORMAT` (a DDS file's DX10 header).
    #[must_use]
    pub fn dxgi_format(self) -> u32 {
        match self {
            TextureFormat::Bc4 => 80,
            TextureFormat::Bc5 => 83,
            TextureFormat::Bc7 => 98,
            TextureFormat::Rgba8 => 28,
            TextureFormat::Rg8 => 49,
            TextureFormat::R8 => 61,
            TextureFormat::Rgba16f => 10,
            TextureFormat::Rg16f => 34,
            TextureFormat::R16f => 54,
        }
    }

    /// Vulkan's `VkFormat` (a KTX2 file's `vkFormat`).
    #[must_use]
    pub fn vk_format(self) -> u32 {
        match self {
            TextureFormat::Bc4 => 139,
            TextureFormat::Bc5 => 141,
            TextureFormat::Bc7 => 145,
            TextureFormat::Rgba8 => 37,
            TextureFormat::Rg8 => 16,
            TextureFormat::R8 => 9,
            TextureFormat::Rgba16f => 97,
            TextureFormat::Rg16f => 83,
            TextureFormat::R16f => 76,
        }
    }

    /// Whether texels are stored in 4 × 4 blocks (else one at a time).
    #[must_use]
    pub fn is_block_compressed(self) -> bool {
        matches!(self, TextureFormat::Bc4 | TextureFormat::Bc5 | TextureFormat::Bc7)
    }

    /// Texels a block spans along each axis: 4 or 1.
    #[must_use]
    pub fn block_side(self) -> usize {
        if self.is_block_compressed() { 4 } else { 1 }
    }

    /// Bytes of one block (of one texel, for formats without blocks).
    #[must_use]
    pub fn block_bytes(self) -> usize {
        match self {
            TextureFormat::Bc4 | TextureFormat::Rgba16f => 8,
            TextureFormat::Bc5 | TextureFormat::Bc7 => 16,
            TextureFormat::Rgba8 | TextureFormat::Rg16f => 4,
            TextureFormat::Rg8 | TextureFormat::R16f => 2,
            TextureFormat::R8 => 1,
        }
    }

    /// Channels a texel holds (what the format decodes to).
    #[must_use]
    pub fn channels(self) -> usize {
        match self {
            TextureFormat::Bc4 | TextureFormat::R8 | TextureFormat::R16f => 1,
            TextureFormat::Bc5 | TextureFormat::Rg8 | TextureFormat::Rg16f => 2,
            TextureFormat::Bc7 | TextureFormat::Rgba8 | TextureFormat::Rgba16f => 4,
        }
    }

    /// Blocks across and down a `width × height` level: partial blocks
    /// at the right and bottom edges count whole.
    #[must_use]
    pub fn blocks(self, (width, height): (usize, usize)) -> (usize, usize) {
        let side = self.block_side();
        (width.div_ceil(side), height.div_ceil(side))
    }

    /// Bytes of a `width × height` level.
    #[must_use]
    pub fn level_bytes(self, size: (usize, usize)) -> usize {
        let (across, down) = self.blocks(size);
        across * down * self.block_bytes()
    }

    /// Bytes of one row of blocks (of texels) of a level `width` wide:
    /// DDS's pitch.
    #[must_use]
    pub fn row_bytes(self, width: usize) -> usize {
        width.div_ceil(self.block_side()) * self.block_bytes()
    }

    /// The size of the data type of a texel's components for an
    /// upload, as KTX2's `typeSize` states it: 2 for half floats, 1 for
    /// bytes and for block-compressed formats.
    #[must_use]
    pub fn type_size(self) -> u32 {
        match self {
            TextureFormat::Rgba16f | TextureFormat::Rg16f | TextureFormat::R16f => 2,
            _ => 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_bytes_count_partial_blocks_whole() {
        assert_eq!(TextureFormat::Bc5.level_bytes((300, 7)), 75 * 2 * 16);
        assert_eq!(TextureFormat::Bc4.level_bytes((1, 1)), 8);
        assert_eq!(TextureFormat::Bc7.level_bytes((2, 2)), 16);
        assert_eq!(TextureFormat::Rg8.level_bytes((3, 5)), 30);
        assert_eq!(TextureFormat::Rgba16f.row_bytes(3), 24);
    }
}
