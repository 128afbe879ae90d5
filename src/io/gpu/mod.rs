//! GPU textures: a mip chain ([`crate::mips`]) in a DDS or KTX2 file,
//! block-compressed or not, in one call ([`write_chain`], or
//! [`write_chain_file`] for a path, written atomically).
//!
//! What each [`Compression`] stores (a normal's components n in [−1, 1]
//! stored as the 8-bit encoding stores them, c = (n + 1) · 127.5, except
//! the half-float layouts, which store n itself):
//!
//! | compression | normals | one channel (values in [0, 1]) |
//! |---|---|---|
//! | `bc5` | x, y (the shader rebuilds z = √(1 − x² − y²)) | — |
//! | `bc7` | x, y, z, alpha 1 or the alpha given (feature `bc7`) | — |
//! | `bc4` | — | the value |
//! | `rgba8` | x, y, z, alpha 255 or round(255 a) | — |
//! | `rg8` | x, y | — |
//! | `r8` | — | the value, round(255 v) |
//! | `rgba16f` | n, alpha 1 or a, half floats | — |
//! | `rg16f` | n's x, y, half floats | — |
//! | `r16f` | — | the value, a half float |
//!
//! Normals with an alpha ([`Chain::NormalsAlpha`]: a height a texel, for
//! parallax mapping) go in the formats that have one: BC7, RGBA8 and
//! RGBA16F; BC5 and the red-green layouts refuse them.
//!
//! A combination the table leaves empty is [`Error::InvalidOption`]; both
//! containers hold every format of the table ([`TextureFormat`] has the
//! numbers each names them by).
//!
//! **BC4 and BC5 are encoded from the floats** (`bc4.rs`): the endpoints
//! and indices of each block are fitted to the unrounded values, not to
//! 8-bit codes. A BC4 block interpolates between its endpoints in sevenths,
//! finer than 8 bits, and the float normals let the encoder use that: on
//! the samples and the shared real textures, BC5 from floats has a sixth
//! to a half of the mean angular error of BC5 from the rounded 8-bit
//! normals, and less than 8-bit RG without any blocks (docs/mips.md, "GPU
//! containers", has the figures). No crate
//! encodes BC4/BC5 from floats (`intel_tex_2`, `block_compression` and
//! `texpresso` take 8-bit texels), so the encoder is normalfit's own.
//! **BC7** is `block_compression`'s (`bc7.rs`), behind the `bc7` feature.
//!
//! Sides that are not multiples of 4 (300 × 7, 2 × 2, 1 × 1) fill their
//! last blocks by repeating the edge texels, as texconv does.
//!
//! ```
//! use normalfit::io::gpu::{Chain, Compression, Container, write_chain};
//! use normalfit::mips::average_chain;
//!
//! let flat = vec![[0.0f32, 0.0, 1.0]; 8 * 4];
//! let chain = average_chain(&flat, (8, 4))?;
//! let mut dds = Vec::new();
//! write_chain(&mut dds, Chain::Normals(&chain), Container::Dds, Compression::Bc5)?;
//! // The header, then the levels: 8 × 4 (2 blocks), 4 × 2, 2 × 1, 1 × 1 (a block each).
//! assert_eq!(dds.len(), 148 + 16 * (2 + 1 + 1 + 1));
//! # Ok::<(), normalfit::Error>(())
//! ```

mod bc4;
#[cfg(feature = "bc7")]
mod bc7;
mod blocks;
mod levels;

use std::io::Write;
use std::path::Path;

use half::f16;

use blocks::BlockGrid;

use super::atomic::write_atomically;
use super::dds::write::write_dds;
use super::from_normal::FromNormal;
use super::ktx2::write::write_ktx2;
use crate::error::{Error, Result};
use crate::options::named_values;
use crate::par::prelude::*;
use crate::samples::try_vec;

pub use super::texture::TextureFormat;
pub use levels::{MipLevel, level_sizes};

/// The file a chain is written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Container {
    /// DirectDraw Surface with the DX10 header (`.dds`): Direct3D's.
    Dds,
    /// KTX 2.0 (`.ktx2`): Khronos's, for Vulkan, OpenGL and glTF.
    Ktx2,
}

named_values!(Container, "container", { Dds => "dds", Ktx2 => "ktx2" });

impl Container {
    /// The container a file name's extension names (`.dds`, `.ktx2`, any
    /// case).
    ///
    /// Errors: [`Error::Unsupported`] for a name without either.
    pub fn from_path(path: &Path) -> Result<Container> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("dds") => Ok(Container::Dds),
            Some("ktx2") => Ok(Container::Ktx2),
            Some(other) => Err(Error::Unsupported(format!(
                "cannot write a GPU texture as .{other}: name the output .dds or .ktx2"
            ))),
            None => Err(Error::Unsupported("a GPU texture's name needs an extension: .dds or .ktx2".into())),
        }
    }

    /// The file name extension, without the dot.
    #[must_use]
    pub fn extension(self) -> &'static str {
        self.name()
    }
}

/// The layouts of [`Compression::None`]: texels stored as they are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Uncompressed {
    /// Normals: x, y, z and an alpha of 255, a byte each.
    Rgba8,
    /// Normals: x and y, a byte each.
    Rg8,
    /// One channel: a byte.
    R8,
    /// Normals: x, y, z and an alpha of 1, half floats.
    Rgba16f,
    /// Normals: x and y, half floats.
    Rg16f,
    /// One channel: a half float.
    R16f,
}

named_values!(Uncompressed, "layout", {
    Rgba8 => "rgba8", Rg8 => "rg8", R8 => "r8", Rgba16f => "rgba16f", Rg16f => "rg16f", R16f => "r16f"
});

/// How a chain's texels are stored: a block compression, or none and the
/// layout of the texels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Compression {
    /// Normals' x and y in BC5 blocks (1 byte a texel).
    Bc5,
    /// Normals' x, y and z in BC7 blocks (1 byte a texel); feature `bc7`.
    Bc7,
    /// One channel in BC4 blocks (half a byte a texel).
    Bc4,
    /// No blocks: the texels in this layout.
    None(Uncompressed),
}

impl Compression {
    /// Every compression, in the order the docs list them.
    pub const ALL: &'static [Compression] = &[
        Compression::Bc5,
        Compression::Bc7,
        Compression::Bc4,
        Compression::None(Uncompressed::Rgba8),
        Compression::None(Uncompressed::Rg8),
        Compression::None(Uncompressed::R8),
        Compression::None(Uncompressed::Rgba16f),
        Compression::None(Uncompressed::Rg16f),
        Compression::None(Uncompressed::R16f),
    ];

    /// The name the command line and the Python package spell it with:
    /// `bc5`, `bc7`, `bc4`, or the layout's (`rgba8`, `rg16f`, …).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Compression::Bc5 => "bc5",
            Compression::Bc7 => "bc7",
            Compression::Bc4 => "bc4",
            Compression::None(layout) => layout.name(),
        }
    }

    /// The format a chain of `channels` (3: normals; 1: values) is stored
    /// in with this compression.
    ///
    /// Errors: [`Error::InvalidOption`] for a compression the chain's
    /// channels do not go in (BC5 of one channel, BC4 of normals, …);
    /// [`Error::Unsupported`] for BC7 in a build without the `bc7` feature.
    pub fn format(self, chain: &Chain<'_>) -> Result<TextureFormat> {
        let format = match self {
            Compression::Bc5 => TextureFormat::Bc5,
            Compression::Bc7 => TextureFormat::Bc7,
            Compression::Bc4 => TextureFormat::Bc4,
            Compression::None(Uncompressed::Rgba8) => TextureFormat::Rgba8,
            Compression::None(Uncompressed::Rg8) => TextureFormat::Rg8,
            Compression::None(Uncompressed::R8) => TextureFormat::R8,
            Compression::None(Uncompressed::Rgba16f) => TextureFormat::Rgba16f,
            Compression::None(Uncompressed::Rg16f) => TextureFormat::Rg16f,
            Compression::None(Uncompressed::R16f) => TextureFormat::R16f,
        };
        let normals = matches!(chain, Chain::Normals(_) | Chain::NormalsAlpha(..));
        if matches!(chain, Chain::NormalsAlpha(..)) && format.channels() < 4 {
            return Err(Error::InvalidOption(format!(
                "{self} has no alpha: normals with an alpha of heights take bc7, rgba8 or rgba16f"
            )));
        }
        if normals && format.channels() == 1 {
            return Err(Error::InvalidOption(format!(
                "{self} stores one channel: a chain of normals takes bc5, bc7, rgba8, rg8, rgba16f or rg16f"
            )));
        }
        if !normals && format.channels() > 1 {
            let what =
                if format.channels() == 2 { "two channels (a normal's x and y)" } else { "a normal's x, y and z" };
            return Err(Error::InvalidOption(format!(
                "{self} stores {what}: a chain of one channel takes bc4, r8 or r16f"
            )));
        }
        if format == TextureFormat::Bc7 && !cfg!(feature = "bc7") {
            return Err(Error::Unsupported("bc7 needs normalfit built with the `bc7` feature".into()));
        }
        Ok(format)
    }
}

impl std::fmt::Display for Compression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Compression {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        let s = s.trim();
        Compression::ALL.iter().copied().find(|c| s.eq_ignore_ascii_case(c.name())).ok_or_else(|| {
            let names: Vec<&str> = Compression::ALL.iter().map(|c| c.name()).collect();
            Error::InvalidOption(format!("unknown compression '{s}': use {}", crate::options::one_of(&names)))
        })
    }
}

/// A mip chain to store, the finest level first: each level's sizes as
/// [`level_sizes`] gives them (the first levels of a chain, or all).
#[derive(Clone, Copy, Debug)]
pub enum Chain<'a> {
    /// Unit normals (x, y, z in [−1, 1], tangent space, y up as OpenGL
    /// has it): [`crate::mips::fit_chain`], [`crate::mips::average_chain`].
    Normals(&'a [MipLevel<[f32; 3]>]),
    /// Unit normals, as [`Chain::Normals`], and an alpha a texel, the
    /// levels of the same sizes: a height in [0, 1] for the UNORM layouts
    /// (clamped, round(255 a)), as it is in half floats (the chain of a
    /// height map's heights: [`crate::mips::box_levels`]).
    NormalsAlpha(&'a [MipLevel<[f32; 3]>], &'a [MipLevel<f32>]),
    /// One value a texel, in [0, 1] for the UNORM layouts (clamped): a
    /// roughness made from [`crate::mips::mean_lengths`], a height.
    Values(&'a [MipLevel<f32>]),
}

impl<'a> From<&'a [MipLevel<[f32; 3]>]> for Chain<'a> {
    fn from(levels: &'a [MipLevel<[f32; 3]>]) -> Self {
        Chain::Normals(levels)
    }
}

impl<'a> From<&'a [MipLevel<f32>]> for Chain<'a> {
    fn from(levels: &'a [MipLevel<f32>]) -> Self {
        Chain::Values(levels)
    }
}

impl Chain<'_> {
    /// The levels' sizes, the finest first.
    fn sizes(&self) -> Vec<(usize, usize)> {
        match self {
            Chain::Normals(levels) | Chain::NormalsAlpha(levels, _) => {
                levels.iter().map(|l| (l.width, l.height)).collect()
            }
            Chain::Values(levels) => levels.iter().map(|l| (l.width, l.height)).collect(),
        }
    }

    /// Errors of a chain that is not one: no levels, a size of zero, a
    /// level whose size is not the chain's, texels that do not fill their
    /// level, a texel that is NaN or infinite.
    fn check(&self) -> Result<()> {
        let sizes = self.sizes();
        let Some(&(width, height)) = sizes.first() else {
            return Err(Error::InvalidOption("a chain of no levels has nothing to write".into()));
        };
        if width == 0 || height == 0 {
            return Err(Error::InvalidOption(format!("a chain's finest level is {width} × {height} texels")));
        }
        let expected = level_sizes(width, height);
        if sizes.len() > expected.len() {
            return Err(Error::InvalidOption(format!(
                "a chain of a {width} × {height} texture has {} levels, not {}",
                expected.len(),
                sizes.len()
            )));
        }
        for (k, (got, want)) in sizes.iter().zip(&expected).enumerate() {
            if got != want {
                return Err(Error::InvalidOption(format!(
                    "level {k} is {} × {}, but level {k} of a {width} × {height} texture is {} × {}",
                    got.0, got.1, want.0, want.1
                )));
            }
        }
        let not_finite = |k: usize, at: usize, w: usize| (k, at % w, at / w);
        match self {
            Chain::Normals(levels) | Chain::NormalsAlpha(levels, _) => {
                for level in *levels {
                    check_len(level)?;
                }
                for level in *levels {
                    if let Some(at) = level.texels.iter().position(|n| !n.iter().all(|c| c.is_finite())) {
                        let (_, x, y) = not_finite(0, at, level.width);
                        return Err(Error::NonFiniteNormal { x, y });
                    }
                }
                if let Chain::NormalsAlpha(_, alpha) = self {
                    let alpha_sizes: Vec<(usize, usize)> = alpha.iter().map(|l| (l.width, l.height)).collect();
                    if alpha_sizes != sizes {
                        return Err(Error::InvalidOption(format!(
                            "the alpha's levels ({} of them) are not the normals' ({}) sizes",
                            alpha.len(),
                            sizes.len()
                        )));
                    }
                    Chain::Values(alpha).check()?;
                }
            }
            Chain::Values(levels) => {
                for level in *levels {
                    check_len(level)?;
                }
                for (k, level) in levels.iter().enumerate() {
                    if let Some(at) = level.texels.iter().position(|v| !v.is_finite()) {
                        let (k, x, y) = not_finite(k, at, level.width);
                        return Err(Error::InvalidOption(format!(
                            "the value at texel (x {x}, y {y}) of level {k} is NaN or infinite"
                        )));
                    }
                }
            }
        }
        Ok(())
    }
}

/// [`Error::BufferSize`] unless the level's texels fill it.
fn check_len<T>(level: &MipLevel<T>) -> Result<()> {
    let expected = level.width * level.height;
    if level.texels.len() == expected {
        Ok(())
    } else {
        Err(Error::BufferSize { expected, actual: level.texels.len() })
    }
}

/// A chain encoded: its format and each level's bytes, the finest first,
/// as the containers store them (rows of blocks, or of texels, top to
/// bottom; multi-byte values little-endian).
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct EncodedChain {
    /// The format of every level.
    pub format: TextureFormat,
    /// The levels' sizes in texels, the finest first.
    pub sizes: Vec<(usize, usize)>,
    /// The levels' bytes ([`TextureFormat::level_bytes`] each).
    pub levels: Vec<Vec<u8>>,
}

/// `chain` encoded as `compression` says (the module's table), for a
/// container or an upload.
///
/// Errors: [`Error::InvalidOption`] for a chain that is not one (no
/// levels, sizes other than [`level_sizes`]') or a compression its
/// channels do not go in ([`Compression::format`]); [`Error::BufferSize`]
/// for a level whose texels do not fill it; [`Error::NonFiniteNormal`]
/// for a normal with a NaN or infinite component (its texel in the first
/// level that has one); [`Error::Unsupported`] for BC7 without the `bc7`
/// feature; [`Error::Limits`] when the memory is not there.
pub fn encode_chain(chain: Chain<'_>, compression: Compression) -> Result<EncodedChain> {
    let format = compression.format(&chain)?;
    chain.check()?;
    let levels = match chain {
        Chain::Normals(levels) => levels.iter().map(|l| encode_normals(l, None, format)).collect::<Result<Vec<_>>>()?,
        Chain::NormalsAlpha(levels, alpha) => levels
            .iter()
            .zip(alpha)
            .map(|(l, a)| encode_normals(l, Some(&a.texels), format))
            .collect::<Result<Vec<_>>>()?,
        Chain::Values(levels) => levels.iter().map(|l| encode_values(l, format)).collect::<Result<Vec<_>>>()?,
    };
    Ok(EncodedChain { format, sizes: chain.sizes(), levels })
}

/// Writes `chain` into `out` as a `container` file, its texels stored as
/// `compression` says: the one call the command line and the Python
/// package make.
///
/// Errors: those of [`encode_chain`]; [`Error::Limits`] for a size a
/// container's 32-bit fields cannot hold; [`Error::Io`] from `out`.
pub fn write_chain<W: Write>(
    mut out: W,
    chain: Chain<'_>,
    container: Container,
    compression: Compression,
) -> Result<()> {
    let encoded = encode_chain(chain, compression)?;
    write_encoded(&mut out, &encoded, container)
}

/// Writes an encoded chain into `out` as a `container` file.
///
/// Errors: [`Error::Limits`] for a size a container's 32-bit fields
/// cannot hold; [`Error::Io`] from `out`.
pub fn write_encoded<W: Write + ?Sized>(out: &mut W, encoded: &EncodedChain, container: Container) -> Result<()> {
    let size = encoded.sizes.first().copied().unwrap_or((0, 0));
    match container {
        Container::Dds => write_dds(out, encoded.format, size, &encoded.levels),
        Container::Ktx2 => write_ktx2(out, encoded.format, size, &encoded.levels),
    }
}

/// [`write_chain`] into the file at `path`, its container named by the
/// extension (`.dds`, `.ktx2`), written atomically: the file appears
/// whole or not at all ([`write_atomically`]).
///
/// Errors: those of [`Container::from_path`] and [`write_chain`].
pub fn write_chain_file(path: &Path, chain: Chain<'_>, compression: Compression) -> Result<()> {
    let container = Container::from_path(path)?;
    let encoded = encode_chain(chain, compression)?;
    write_atomically(path, |out| write_encoded(out, &encoded, container))
}

/// The code of a normal's component c: (c + 1) · 127.5, in [0, 255].
#[inline]
fn code(c: f32) -> f32 {
    ((c + 1.0) * 127.5).clamp(0.0, 255.0)
}

/// A normal's 8-bit texel as the 8-bit encoding rounds it ([`FromNormal`]).
#[inline]
fn rgb8(n: [f32; 3]) -> [u8; 3] {
    <[u8; 3] as FromNormal>::from_normal(n.map(|c| f64::from(c.clamp(-1.0, 1.0))))
}

/// Half float bytes, little-endian.
#[inline]
fn half(v: f32) -> [u8; 2] {
    f16::from_f32(v).to_le_bytes()
}

/// The blocks of a level, each from `block(bx, by)`, rows of blocks in
/// parallel.
fn encode_blocks(
    grid: BlockGrid,
    block_bytes: usize,
    block: impl Fn(usize, usize, &mut [u8]) + Sync,
) -> Result<Vec<u8>> {
    let row_bytes = grid.across * block_bytes;
    let mut out: Vec<u8> = try_vec(row_bytes * grid.down)?;
    out.resize(row_bytes * grid.down, 0);
    out.par_chunks_mut(row_bytes).enumerate().for_each(|(by, row)| {
        for (bx, bytes) in row.chunks_exact_mut(block_bytes).enumerate() {
            block(bx, by, bytes);
        }
    });
    Ok(out)
}

/// Texels laid out one after the other, `per` bytes each.
fn encode_texels<T: Copy>(texels: &[T], per: usize, bytes: impl Fn(T, &mut [u8])) -> Result<Vec<u8>> {
    encode_indexed(texels, per, |_, t, b| bytes(t, b))
}

/// [`encode_texels`], `bytes` told each texel's index too.
fn encode_indexed<T: Copy>(texels: &[T], per: usize, bytes: impl Fn(usize, T, &mut [u8])) -> Result<Vec<u8>> {
    let mut out: Vec<u8> = try_vec(texels.len() * per)?;
    out.resize(texels.len() * per, 0);
    for (i, (&t, b)) in texels.iter().zip(out.chunks_exact_mut(per)).enumerate() {
        bytes(i, t, b);
    }
    Ok(out)
}

/// An alpha's byte: round(255 a) of a clamped to [0, 1], as an 8-bit
/// PNG's alpha of heights stores it.
#[inline]
fn alpha8(a: f32) -> u8 {
    (f64::from(a.clamp(0.0, 1.0)) * 255.0).round() as u8
}

/// A level of normals in `format`, with `alpha` (one a texel) in the
/// alpha channel, else an opaque one.
fn encode_normals(level: &MipLevel<[f32; 3]>, alpha: Option<&[f32]>, format: TextureFormat) -> Result<Vec<u8>> {
    let grid = BlockGrid::new(level.width, level.height);
    let texels = &level.texels;
    let a8 = |i: usize| alpha.map_or(255, |a| alpha8(a[i]));
    let a16 = |i: usize| alpha.map_or(1.0, |a| a[i]);
    match format {
        TextureFormat::Bc5 => encode_blocks(grid, 16, |bx, by, out| {
            for c in 0..2 {
                let values: [f32; 16] = std::array::from_fn(|i| code(texels[grid.texel(bx, by, i)][c]));
                out[8 * c..8 * c + 8].copy_from_slice(&bc4::encode_block(&values));
            }
        }),
        #[cfg(feature = "bc7")]
        TextureFormat::Bc7 => bc7::encode(grid, alpha.is_some(), |x, y| {
            let i = y * grid.width + x;
            let [r, g, b] = rgb8(texels[i]);
            [r, g, b, a8(i)]
        }),
        TextureFormat::Rgba8 => encode_indexed(texels, 4, |i, n, b| {
            b[..3].copy_from_slice(&rgb8(n));
            b[3] = a8(i);
        }),
        TextureFormat::Rg8 => encode_texels(texels, 2, |n, b| b.copy_from_slice(&rgb8(n)[..2])),
        TextureFormat::Rgba16f => encode_indexed(texels, 8, |i, n, b| {
            for (c, v) in [n[0], n[1], n[2], a16(i)].into_iter().enumerate() {
                b[2 * c..2 * c + 2].copy_from_slice(&half(v));
            }
        }),
        TextureFormat::Rg16f => encode_texels(texels, 4, |n, b| {
            b[..2].copy_from_slice(&half(n[0]));
            b[2..].copy_from_slice(&half(n[1]));
        }),
        other => Err(Error::InvalidOption(format!("normals cannot be stored as {}", other.name()))),
    }
}

/// A level of one channel in `format`.
fn encode_values(level: &MipLevel<f32>, format: TextureFormat) -> Result<Vec<u8>> {
    let grid = BlockGrid::new(level.width, level.height);
    let texels = &level.texels;
    match format {
        TextureFormat::Bc4 => encode_blocks(grid, 8, |bx, by, out| {
            let values: [f32; 16] = std::array::from_fn(|i| texels[grid.texel(bx, by, i)].clamp(0.0, 1.0) * 255.0);
            out.copy_from_slice(&bc4::encode_block(&values));
        }),
        TextureFormat::R8 => encode_texels(texels, 1, |v, b| b[0] = (v.clamp(0.0, 1.0) * 255.0).round() as u8),
        TextureFormat::R16f => encode_texels(texels, 2, |v, b| b.copy_from_slice(&half(v))),
        other => Err(Error::InvalidOption(format!("one channel cannot be stored as {}", other.name()))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mips::average_chain;

    fn tilted(width: usize, height: usize) -> Vec<[f32; 3]> {
        (0..width * height)
            .map(|k| {
                let (x, y) = ((k % width) as f32 / width as f32 - 0.5, (k / width) as f32 / height as f32 - 0.5);
                let n = [x, -0.6 * y, 1.0];
                let len = (n[0] * n[0] + n[1] * n[1] + 1.0f32).sqrt();
                n.map(|c| c / len)
            })
            .collect()
    }

    #[test]
    fn bc5_of_a_level_decodes_within_the_block_bound() {
        let (w, h) = (13, 6);
        let normals = tilted(w, h);
        let chain = average_chain(&normals, (w, h)).unwrap();
        let encoded = encode_chain(Chain::Normals(&chain), Compression::Bc5).unwrap();
        assert_eq!(encoded.levels.len(), 4);
        let grid = BlockGrid::new(w, h);
        let level = &encoded.levels[0];
        assert_eq!(level.len(), grid.across * grid.down * 16);
        for (b, block) in level.chunks_exact(16).enumerate() {
            let (bx, by) = (b % grid.across, b / grid.across);
            for c in 0..2 {
                let decoded = bc4::decode_block(block[8 * c..8 * c + 8].try_into().unwrap());
                let values: Vec<f32> = (0..16).map(|i| code(normals[grid.texel(bx, by, i)][c])).collect();
                let (lo, hi) = values.iter().fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
                // Half a step of the ramp spanning the block, and the
                // endpoints' rounding.
                let bound = (hi - lo) / 14.0 + 1.0;
                for (i, (t, d)) in values.iter().zip(decoded).enumerate() {
                    assert!((t - d).abs() <= bound, "block {b} texel {i} channel {c}: {t} decoded {d}, bound {bound}");
                }
            }
        }
    }

    #[test]
    fn uncompressed_layouts_follow_the_8_bit_and_half_encodings() {
        let n = [0.6f32, -0.8, 0.0];
        let chain = [MipLevel { width: 1, height: 1, texels: vec![n] }];
        let rgba8 = encode_chain(Chain::Normals(&chain), Compression::None(Uncompressed::Rgba8)).unwrap();
        // f32 −0.8 is −0.800000012: (n + 1) · 127.5 = 25.4999985, rounded to 25.
        assert_eq!(rgba8.levels[0], [204, 25, 128, 255]);
        let rg16f = encode_chain(Chain::Normals(&chain), Compression::None(Uncompressed::Rg16f)).unwrap();
        assert_eq!(rg16f.levels[0], [f16::from_f32(0.6).to_le_bytes(), f16::from_f32(-0.8).to_le_bytes()].concat());
        let values = [MipLevel { width: 2, height: 1, texels: vec![0.5f32, 2.0] }];
        let r8 = encode_chain(Chain::Values(&values), Compression::None(Uncompressed::R8)).unwrap();
        assert_eq!(r8.levels[0], [128, 255]);
    }

    #[test]
    fn names_parse_back() {
        for &c in Compression::ALL {
            assert_eq!(c.name().parse::<Compression>().unwrap(), c);
        }
        assert!(matches!("bc6".parse::<Compression>(), Err(Error::InvalidOption(m)) if m.contains("bc5, bc7")));
    }
}
