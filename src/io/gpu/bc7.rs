//! BC7 blocks by the `block_compression` crate's CPU encoder (a Rust port
//! of Intel's ISPC texture compressor's BC7 kernel), its `opaque_basic`
//! settings: every mode an opaque texture can use, a moderate search.
//! Chosen over `intel_tex_2` (the ISPC kernels themselves, prebuilt), which
//! gives the same blocks four times as fast but links C++ that the crate
//! does not declare (on Debian the link fails on `__gxx_personality_v0`
//! without an extra `-lstdc++`), ships prebuilt libraries for a fixed list
//! of targets and is called through `unsafe`; docs/mips.md has the
//! measurements.

use block_compression::{BC7Settings, CompressionVariant, encode::compress_rgba8};

use super::blocks::BlockGrid;
use crate::error::Result;
use crate::par::prelude::*;
use crate::samples::try_vec;

/// Bytes of a BC7 block.
const BC7_BYTES: usize = 16;

/// The BC7 blocks of a level of RGBA texels (`texel(x, y)`, edges repeated
/// past the level's size), a row of blocks at a time in parallel: with
/// `alpha`, by the `alpha_basic` settings (the modes that hold an alpha
/// too), else `opaque_basic`.
pub(crate) fn encode(grid: BlockGrid, alpha: bool, texel: impl Fn(usize, usize) -> [u8; 4] + Sync) -> Result<Vec<u8>> {
    let row_bytes = grid.across * BC7_BYTES;
    let mut out: Vec<u8> = try_vec(row_bytes * grid.down)?;
    out.resize(row_bytes * grid.down, 0);
    let settings =
        CompressionVariant::BC7(if alpha { BC7Settings::alpha_basic() } else { BC7Settings::opaque_basic() });
    let strip_width = grid.across * 4;
    out.par_chunks_mut(row_bytes).enumerate().for_each(|(by, blocks)| {
        // The strip of four rows this row of blocks covers, edges repeated.
        let mut strip = vec![0u8; strip_width * 4 * 4];
        for (i, px) in strip.chunks_exact_mut(4).enumerate() {
            let (x, y) = (i % strip_width, by * 4 + i / strip_width);
            px.copy_from_slice(&texel(grid.clamp_x(x), grid.clamp_y(y)));
        }
        compress_rgba8(settings, &strip, blocks, strip_width as u32, 4, strip_width as u32 * 4);
    });
    Ok(out)
}
