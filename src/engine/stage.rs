//! The normals stage on a whole image: the fit straight into the output's
//! texel type ([`Texels`]), with the residual and the holes when asked for.
//! Band by band, the pipeline does the same fit ([`crate::pipeline`]).

use super::sink::{WriteSeek, zeroed};
use crate::error::Result;
use crate::fit::Texel;
use crate::io::encoding::{TiffDepth, TiffOptions, TiffTags};
use crate::io::{self, Encoding, PngDepth, PngOptions};
use crate::{Options, Samples};

/// The texel type an encoding stores: 8- or 16-bit integers, or floats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Depth {
    Eight,
    Sixteen,
    Float,
}

impl Depth {
    /// The texel type of `encoding` (an image's; a GPU texture is written
    /// from a mip chain).
    pub(crate) fn of(encoding: &Encoding) -> Result<Depth> {
        Ok(match encoding {
            Encoding::Texture(_) => return Err(crate::io::write::not_a_chain()),
            Encoding::Png(PngOptions { depth: PngDepth::Eight, .. })
            | Encoding::Tiff(TiffOptions { depth: TiffDepth::Eight, .. }) => Depth::Eight,
            Encoding::Png(PngOptions { depth: PngDepth::Sixteen, .. })
            | Encoding::Tiff(TiffOptions { depth: TiffDepth::Sixteen, .. }) => Depth::Sixteen,
            Encoding::Exr(_) | Encoding::Tiff(TiffOptions { depth: TiffDepth::Float, .. }) => Depth::Float,
        })
    }
}

/// A normal map fitted straight into the output's texel type.
pub(crate) enum Texels {
    Eight(Vec<[u8; 3]>),
    Sixteen(Vec<[u16; 3]>),
    /// The normals n, stored as the EXR options say when encoded.
    Float(Vec<[f32; 3]>),
}

impl Texels {
    /// Texels made by `make` for the texel type of `encoding`: normals
    /// computed elsewhere (a blend, a repaired map) straight into it.
    pub(crate) fn of<R>(encoding: &Encoding, make: impl FnOnce(Depth) -> Result<(Texels, R)>) -> Result<(Texels, R)> {
        make(Depth::of(encoding)?)
    }

    /// Fits the normals for `encoding`; with `residual`, the fit's RMS
    /// distances too (in surface units).
    pub(crate) fn fit(
        heights: &Samples,
        w: usize,
        h: usize,
        opts: &Options,
        encoding: &Encoding,
        residual: Option<&mut [f32]>,
        valid: Option<&mut [bool]>,
    ) -> Result<Texels> {
        let request = with_holes(crate::FitRequest::new(opts), residual, valid);
        Ok(match encoding {
            Encoding::Texture(_) => return Err(crate::io::write::not_a_chain()),
            Encoding::Png(PngOptions { depth: PngDepth::Eight, .. }) => {
                Texels::Eight(fitted(heights, (w, h), request)?)
            }
            Encoding::Png(PngOptions { depth: PngDepth::Sixteen, .. }) => {
                Texels::Sixteen(fitted(heights, (w, h), request)?)
            }
            Encoding::Exr(_) | Encoding::Tiff(TiffOptions { depth: TiffDepth::Float, .. }) => {
                Texels::Float(fitted(heights, (w, h), request)?)
            }
            Encoding::Tiff(TiffOptions { depth: TiffDepth::Eight, .. }) => {
                Texels::Eight(fitted(heights, (w, h), request)?)
            }
            Encoding::Tiff(TiffOptions { depth: TiffDepth::Sixteen, .. }) => {
                Texels::Sixteen(fitted(heights, (w, h), request)?)
            }
        })
    }

    /// Encodes the map (`heights` for an alpha of heights; a TIFF with
    /// `tags`).
    pub(crate) fn encode(
        &self,
        heights: &[f32],
        size: (usize, usize),
        encoding: &Encoding,
        tags: TiffTags<'_>,
        out: &mut dyn WriteSeek,
    ) -> Result<()> {
        match self {
            Texels::Eight(t) => io::write::encode_normals_tagged(t, Some(heights), size, encoding, tags, out),
            Texels::Sixteen(t) => io::write::encode_normals_tagged(t, Some(heights), size, encoding, tags, out),
            Texels::Float(t) => io::write::encode_normals_tagged(t, Some(heights), size, encoding, tags, out),
        }
    }
}

/// The texels `T` of `heights` (`size`), fitted straight into them as
/// `request` asks ([`with_holes`]: the fit's RMS distances too, or holes
/// and which texels have a normal).
///
/// Errors: those of the fit; [`Error::Limits`] when the memory is not there.
pub(crate) fn fitted<T: Texel + Default + Clone>(
    heights: &Samples,
    size: (usize, usize),
    request: crate::FitRequest<'_>,
) -> Result<Vec<T>> {
    let mut texels = zeroed::<T>(heights.len())?;
    request.texels_into(heights, size, &mut texels)?;
    Ok(texels)
}

/// `request` with the fit's residual into `residual` and, with `valid`,
/// holes (see [`fitted`]).
pub(crate) fn with_holes<'a>(
    mut request: crate::FitRequest<'a>,
    residual: Option<&'a mut [f32]>,
    valid: Option<&'a mut [bool]>,
) -> crate::FitRequest<'a> {
    if let Some(residual) = residual {
        request = request.residual(residual);
    }
    if let Some(valid) = valid {
        request = request.holes(valid);
    }
    request
}

/// Writes the normal map `texels` of `size` as `encoding` says into
/// `output`: a file appears whole or not at all (its folder made if
/// asked), a writer gets the whole encoded image.
///
/// Errors: those of encoding and writing.
pub(crate) fn write_normals(
    output: super::sink::Output<'_>,
    texels: &Texels,
    size: (usize, usize),
    encoding: &Encoding,
) -> Result<()> {
    super::sink::prepare(&output, None)?;
    let mut files = io::FileSet::new(io::Replace::Always);
    super::sink::write_to(output, &mut files, |file| {
        texels.encode(&[], size, encoding, io::encoding::TiffTags::default(), file)
    })?;
    files.commit()
}
