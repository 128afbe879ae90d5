//! Normal maps read back: their stored colours as normals again, and
//! whether a decoded image is a normal map at all or a height map.
//!
//! A normal map stores c = (n + 1)/2 per channel (SPEC §3): integers
//! divided by their top value, or floats (EXR); a signed float map stores
//! n itself. [`decode`] undoes either. [`kind_of`] tells the two kinds of
//! image apart by [`ImageKind::detect`], unless told.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::{self, Channel, Raster, ReadOptions, SampleType};
use crate::tiling::{ImageKind, KindChoice};

/// The R, G and B planes as stored values in [0, 1] (integers divided by
/// their top value; floats as they are), when the image has all three.
///
/// Errors: [`Error::Limits`] when the memory for the planes is not there.
pub fn rgb_planes(raster: &Raster) -> Result<Option<[Vec<f32>; 3]>> {
    match (raster.plane("R"), raster.plane("G"), raster.plane("B")) {
        (Some(r), Some(g), Some(b)) => Ok(Some([r.data.to_f32()?, g.data.to_f32()?, b.data.to_f32()?])),
        _ => Ok(None),
    }
}

/// What a decoded image holds: as `choice` says, or detected from its R,
/// G, B planes ([`ImageKind::detect`]). Naming a height channel
/// (`channel`) says it is a height map; an image without R, G and B is one.
///
/// Errors: [`Error::Unsupported`] for [`KindChoice::Normal`] of an image
/// without R, G and B; those of [`rgb_planes`].
pub fn kind_of(raster: &Raster, choice: KindChoice, channel: Option<&Channel>) -> Result<ImageKind> {
    Ok(match (choice, rgb_planes(raster)?) {
        (KindChoice::Height, _) => ImageKind::Height,
        (KindChoice::Normal, Some(_)) => ImageKind::Normal,
        (KindChoice::Normal, None) => return Err(no_rgb()),
        (KindChoice::Auto, Some(planes)) if channel.is_none() => {
            ImageKind::detect(&planes.each_ref().map(Vec::as_slice), raster.width, raster.height)?
        }
        (KindChoice::Auto, _) => ImageKind::Height,
    })
}

/// A normal map's stored colours back to normals, row-major: n = 2c − 1
/// per channel (c in [0, 1] as [`rgb_planes`] gives it), or n = c for a
/// `signed` float map. The normals are not renormalised: quantisation
/// leaves them within about 1/255 (8 bits) of unit length, and what reads
/// them ([`crate::shade::shade`]) normalises.
///
/// Errors: [`Error::Unsupported`] for an image without R, G and B;
/// [`Error::InvalidOption`] for `signed` with integer samples, which store
/// (n + 1)/2; those of [`rgb_planes`].
pub fn decode(raster: &Raster, signed: bool) -> Result<Vec<[f32; 3]>> {
    let planes = rgb_planes(raster)?.ok_or_else(no_rgb)?;
    if signed && raster.sample != SampleType::Float {
        return Err(Error::InvalidOption(
            "signed normal maps are float (EXR); an integer image stores (n + 1)/2".into(),
        ));
    }
    let stored = |c: f32| if signed { c } else { 2.0 * c - 1.0 };
    let len = raster.width * raster.height;
    let mut normals = crate::samples::try_vec(len)?;
    normals.extend((0..len).map(|k| planes.each_ref().map(|p| stored(p[k]))));
    Ok(normals)
}

/// Reads the normal map at `path` ([`io::read_path`]) and [`decode`]s it;
/// returns its width, height and normals.
///
/// Errors: those of [`io::read_path`] and [`decode`].
pub fn read(path: &Path, opts: &ReadOptions, signed: bool) -> Result<(usize, usize, Vec<[f32; 3]>)> {
    let raster = io::read_path(path, opts)?;
    Ok((raster.width, raster.height, decode(&raster, signed)?))
}

fn no_rgb() -> Error {
    Error::Unsupported("a normal map needs R, G and B channels".into())
}
