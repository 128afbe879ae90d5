//! Writing normal maps: PNG (8/16-bit RGB or RGBA), OpenEXR (half/float
//! RGB, RGBA or RG), one-channel maps (the fit's residual), and files that
//! appear whole or not at all.
//!
//! The encoders take texels as the fit produces them (`[u8; 3]`,
//! `[u16; 3]`, `[f32; 3]`, see [`FromNormal`]), so no float copy of
//! the image is made between the fit and the file. A [`Layout`] says which
//! channels the file holds; the streaming pipeline ([`crate::pipeline`])
//! lays texels out with the same code (`texels.rs`), so both give the same
//! samples. This file chooses the writer by the encoding and the texel
//! type; each format's writer is its own (`png/write.rs`,
//! `exr/write.rs`, `tiff/write.rs`).

use std::io::{Seek, Write};

pub use super::atomic::{FileSet, Replace, write_atomically, write_file_atomically};
pub use super::png::write::PngSample;
pub use super::texels::Sample;

use super::encoding::{Encoding, ExrDepth, ExrOptions, Layout, PngDepth, PngOptions, TiffDepth, TiffOptions, TiffTags};
use super::exr::write::{exr_normals, write_exr_rows};
use super::from_normal::FromNormal;
use super::png::write::{png_gray, png_normals};
use super::texels::{StoreInPlace, check_buffer};
#[cfg(feature = "tiff")]
use super::tiff::write::{tiff_gray, tiff_normals};
use crate::error::{Error, Result};

/// A texel of a normal map as the fit gives it ([`FromNormal`]),
/// which [`encode_normals`] writes: `[u8; 3]` and `[u16; 3]` are PNG's
/// stored samples already, c = round(max · (n + 1)/2) (an 8- or 16-bit
/// PNG); `[f32; 3]` is the normal n itself, stored as the encoding says
/// (EXR: (n + 1)/2 or n; PNG: quantised as the integer texels are).
pub trait NormalTexel: FromNormal + sealed::Sealed {
    /// Encodes `texels` (and `heights`, checked) as `encoding` says; a
    /// TIFF with `tags`.
    #[doc(hidden)]
    fn encode<W: Write + Seek>(
        texels: &[Self],
        heights: &[f32],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: W,
    ) -> Result<()>;
}

/// A value of a one-channel map ([`encode_gray`]): `u8` and `u16` are
/// stored as they are in a PNG of their depth, `f32` in an EXR's channel Y.
pub trait GrayValue: Copy + sealed::Sealed {
    /// Encodes `values` as `encoding` says; a TIFF with `tags`.
    #[doc(hidden)]
    fn encode<W: Write + Seek>(
        values: &[Self],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: W,
    ) -> Result<()>;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for [u8; 3] {}
    impl Sealed for [u16; 3] {}
    impl Sealed for [f32; 3] {}
    impl Sealed for u8 {}
    impl Sealed for u16 {}
    impl Sealed for f32 {}
}

/// The error of texels that the encoding does not store.
fn mismatch(texels: &str, encoding: &Encoding) -> Error {
    let wanted = match encoding {
        Encoding::Png(PngOptions { depth: PngDepth::Eight, .. }) => "an 8-bit PNG takes u8 samples",
        Encoding::Png(PngOptions { depth: PngDepth::Sixteen, .. }) => "a 16-bit PNG takes u16 samples",
        Encoding::Exr(_) => "an EXR takes f32 samples",
        Encoding::Tiff(TiffOptions { depth: TiffDepth::Eight, .. }) => "an 8-bit TIFF takes u8 samples",
        Encoding::Tiff(TiffOptions { depth: TiffDepth::Sixteen, .. }) => "a 16-bit TIFF takes u16 samples",
        Encoding::Tiff(TiffOptions { depth: TiffDepth::Float, .. }) => "a float TIFF takes f32 samples",
        Encoding::Texture(_) => "a GPU texture takes a mip chain (io::gpu)",
    };
    Error::InvalidOption(format!("{texels} samples for this encoding: {wanted}"))
}

impl NormalTexel for [u8; 3] {
    fn encode<W: Write + Seek>(
        texels: &[Self],
        heights: &[f32],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: W,
    ) -> Result<()> {
        match encoding {
            Encoding::Png(o) if o.depth == PngDepth::Eight => png_normals(texels, heights, size, o, out),
            Encoding::Tiff(o) if o.depth == TiffDepth::Eight => tiff_normals(texels, heights, size, o, None, tags, out),
            other => Err(mismatch("u8", other)),
        }
    }
}

impl NormalTexel for [u16; 3] {
    fn encode<W: Write + Seek>(
        texels: &[Self],
        heights: &[f32],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: W,
    ) -> Result<()> {
        match encoding {
            Encoding::Png(o) if o.depth == PngDepth::Sixteen => png_normals(texels, heights, size, o, out),
            Encoding::Tiff(o) if o.depth == TiffDepth::Sixteen => {
                tiff_normals(texels, heights, size, o, None, tags, out)
            }
            other => Err(mismatch("u16", other)),
        }
    }
}

impl NormalTexel for [f32; 3] {
    fn encode<W: Write + Seek>(
        texels: &[Self],
        heights: &[f32],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: W,
    ) -> Result<()> {
        fn quantised<T: FromNormal>(texels: &[[f32; 3]]) -> Result<Vec<T>> {
            let mut out = crate::samples::try_vec(texels.len())?;
            out.extend(texels.iter().map(|t| T::from_normal(t.map(f64::from))));
            Ok(out)
        }
        match encoding {
            Encoding::Texture(_) => Err(not_a_chain()),
            Encoding::Exr(o) => exr_normals(texels, heights, size, *o, out),
            Encoding::Png(o) => match o.depth {
                PngDepth::Eight => png_normals(&quantised::<[u8; 3]>(texels)?, heights, size, o, out),
                PngDepth::Sixteen => png_normals(&quantised::<[u16; 3]>(texels)?, heights, size, o, out),
            },
            Encoding::Tiff(o) => match o.depth {
                TiffDepth::Eight => tiff_normals(&quantised::<[u8; 3]>(texels)?, heights, size, o, None, tags, out),
                TiffDepth::Sixteen => tiff_normals(&quantised::<[u16; 3]>(texels)?, heights, size, o, None, tags, out),
                TiffDepth::Float => {
                    // n itself, or (n + 1)/2: the rule of EXR's samples,
                    // as the streamed writer applies it.
                    let rule = ExrOptions::new(ExrDepth::Float).with_signed(o.signed);
                    let store = |texels: &mut [[f32; 3]]| rule.store_all(texels);
                    let store: StoreInPlace<'_, f32> = &store;
                    tiff_normals(texels, heights, size, o, (!o.signed).then_some(store), tags, out)
                }
            },
        }
    }
}

impl GrayValue for u8 {
    fn encode<W: Write + Seek>(
        values: &[Self],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: W,
    ) -> Result<()> {
        match encoding {
            Encoding::Png(o) if o.depth == PngDepth::Eight => png_gray(values, size, o.compression, out),
            Encoding::Tiff(o) if o.depth == TiffDepth::Eight => tiff_gray(values, size, tags, out),
            other => Err(mismatch("u8", other)),
        }
    }
}

impl GrayValue for u16 {
    fn encode<W: Write + Seek>(
        values: &[Self],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: W,
    ) -> Result<()> {
        match encoding {
            Encoding::Png(o) if o.depth == PngDepth::Sixteen => png_gray(values, size, o.compression, out),
            Encoding::Tiff(o) if o.depth == TiffDepth::Sixteen => tiff_gray(values, size, tags, out),
            other => Err(mismatch("u16", other)),
        }
    }
}

impl GrayValue for f32 {
    fn encode<W: Write + Seek>(
        values: &[Self],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: W,
    ) -> Result<()> {
        match encoding {
            Encoding::Tiff(o) if o.depth == TiffDepth::Float => tiff_gray(values, size, tags, out),
            Encoding::Exr(o) => {
                let (width, height) = size;
                check_buffer(values.len(), width, height)?;
                write_exr_rows(out, width, height, o.depth, &["Y"], |push| {
                    values.chunks(width.saturating_mul(256).max(1)).try_for_each(push)
                })
            }
            other => Err(mismatch("f32", other)),
        }
    }
}

/// Writes a normal map of `width` × `height` texels, row-major, as
/// `encoding` says: the format, depth and channels, an alpha of `heights`
/// (one per texel in contract units, needed for [`Layout::RgbHeight`]
/// alone) or of 1. The texel type goes with the encoding
/// ([`NormalTexel`]); the streaming pipeline ([`crate::pipeline`]) writes
/// the same samples.
///
/// PNG: the adaptive filter, deflate as `compression` says. EXR: ZIP in
/// blocks of 16 rows, what most tools write by default; its offset table
/// comes before the pixels and is filled in at the end, so `out` must
/// seek (a file, or a `Cursor` over a buffer). TIFF: uncompressed, one
/// row a strip, without georeferencing (a conversion of a GeoTIFF copies
/// its tags); its directory comes last, so `out` must seek too.
///
/// Errors: [`Error::BufferSize`] if `texels` (or `heights`) does not hold
/// `width * height`, [`Error::InvalidOption`] for texels the encoding does
/// not store (u16 for an 8-bit PNG, …) or an alpha of heights without
/// them, [`Error::Encode`] for sizes the format cannot hold,
/// [`Error::Io`] if `out` fails.
pub fn encode_normals<T: NormalTexel>(
    texels: &[T],
    heights: Option<&[f32]>,
    width: usize,
    height: usize,
    encoding: &Encoding,
    out: impl Write + Seek,
) -> Result<()> {
    encode_normals_tagged(texels, heights, (width, height), encoding, TiffTags::default(), out)
}

/// [`encode_normals`], a TIFF with `tags`.
pub(crate) fn encode_normals_tagged<T: NormalTexel>(
    texels: &[T],
    heights: Option<&[f32]>,
    (width, height): (usize, usize),
    encoding: &Encoding,
    tags: TiffTags<'_>,
    out: impl Write + Seek,
) -> Result<()> {
    check_buffer(texels.len(), width, height)?;
    let heights = checked_heights(heights, encoding.layout(), texels.len())?;
    T::encode(texels, heights, (width, height), encoding, tags, out)
}

/// Writes a one-channel map of `width` × `height` values, row-major: a
/// picture such as [`shade`](crate::shade::shade) makes (8-bit gray PNG
/// or TIFF), or a quantity per texel such as the fit's residual (16-bit
/// gray PNG, an EXR with channel Y, or a float TIFF). The value type goes
/// with the encoding
/// ([`GrayValue`]); the encoding's layout is not used.
///
/// Errors: as [`encode_normals`].
pub fn encode_gray<V: GrayValue>(
    values: &[V],
    width: usize,
    height: usize,
    encoding: &Encoding,
    out: impl Write + Seek,
) -> Result<()> {
    encode_gray_tagged(values, (width, height), encoding, TiffTags::default(), out)
}

/// [`encode_gray`], a TIFF with `tags`.
pub(crate) fn encode_gray_tagged<V: GrayValue>(
    values: &[V],
    (width, height): (usize, usize),
    encoding: &Encoding,
    tags: TiffTags<'_>,
    out: impl Write + Seek,
) -> Result<()> {
    check_buffer(values.len(), width, height)?;
    V::encode(values, (width, height), encoding, tags, out)
}

/// TIFF output in a build without the `tiff` feature.
#[cfg(not(feature = "tiff"))]
fn tiff_normals<S>(
    _: &[[S; 3]],
    _: &[f32],
    _: (usize, usize),
    _: &TiffOptions,
    _: Option<StoreInPlace<'_, S>>,
    _: TiffTags<'_>,
    _: impl Write + Seek,
) -> Result<()> {
    Err(no_tiff())
}

/// TIFF output in a build without the `tiff` feature.
#[cfg(not(feature = "tiff"))]
fn tiff_gray<S>(_: &[S], _: (usize, usize), _: TiffTags<'_>, _: impl Write + Seek) -> Result<()> {
    Err(no_tiff())
}

/// The error of a GPU texture given to an image writer: its writer takes
/// a mip chain ([`super::gpu::write_chain`]).
pub(crate) fn not_a_chain() -> Error {
    Error::InvalidOption("a .dds or .ktx2 texture is written from a mip chain (io::gpu::write_chain)".into())
}

/// The error of TIFF output in a build without the `tiff` feature.
#[cfg(not(feature = "tiff"))]
pub(crate) fn no_tiff() -> Error {
    Error::Unsupported("TIFF output needs normalfit built with its `tiff` feature".into())
}

/// The heights a layout reads: `heights`, checked against the texel count,
/// or nothing when the layout needs none.
fn checked_heights(heights: Option<&[f32]>, layout: Layout, texels: usize) -> Result<&[f32]> {
    match heights {
        _ if !layout.needs_heights() => Ok(&[]),
        Some(h) if h.len() == texels => Ok(h),
        Some(h) => Err(Error::BufferSize { expected: texels, actual: h.len() }),
        None => Err(Error::InvalidOption("an alpha of heights needs the heights".into())),
    }
}
