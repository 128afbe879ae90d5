//! Normal maps read back: their stored colours as normals again, and
//! whether a decoded image is a normal map at all or a height map.
//!
//! A normal map stores c = (n + 1)/2 per channel (SPEC §3): integers
//! divided by their top value, or floats (EXR); a signed float map stores
//! n itself. [`decode`] undoes either; [`Storage`] is that rule for one
//! stored component, in f64, with the step of its rounding (what the
//! height inverse reads, from a file or from an array). [`kind_of`] tells
//! the two kinds of image apart by [`ImageKind::detect`], unless told
//! ([`KindChoice`]); the tiling check and the lit view ask the same.
//!
//! # Height map or normal map
//!
//! An image of three or more planes is a normal map when at least 90 % of
//! a sample of its texels decode to vectors within 0.2 of unit length with
//! z > 0, and their mean has z ≥ 0.5 and an (x, y) part shorter than 0.3 —
//! the encoding c = (n + 1)/2 is tried, and for float images the raw n as
//! well. Everything else, gray or a colour photo, is a height map. Colour
//! photos fail the test (their decoded vectors have all lengths), as do
//! gray images stored as RGB (equal channels decode to (t, t, t), whose
//! mean is not near the z axis).

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::{self, Channel, Raster, ReadOptions, SampleType};
use crate::options::named_values;
use crate::samples::{Sample, check_planes, contract, image_len};

/// How a normal map's components are stored: integers of `bits` bits hold
/// c = (n + 1)/2 as c · (2^bits − 1); floats hold (n + 1)/2, or n itself
/// when `signed` (SPEC §3). What reading them back as normals needs
/// ([`Storage::normal`]), and the step of their rounding
/// ([`Storage::step`], the height inverse's
/// [`HeightOptions::step`](crate::height::HeightOptions::step)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Storage {
    /// Integers of `bits` bits holding (n + 1)/2.
    Int {
        /// Bits per component.
        bits: u8,
    },
    /// Floats of float32's precision or less (float32, half): n itself
    /// when `signed`, else (n + 1)/2.
    Float32 {
        /// They hold n itself.
        signed: bool,
    },
    /// float64, taken as exact: n itself when `signed`, else (n + 1)/2.
    Float64 {
        /// They hold n itself.
        signed: bool,
    },
}

impl Storage {
    /// The components of a decoded file of `sample` type (a file's floats
    /// are float32 at most, as the readers give them), `signed` when its
    /// floats hold n itself.
    ///
    /// Errors: [`Error::InvalidOption`] for `signed` with integer samples,
    /// which store (n + 1)/2.
    pub fn of_file(sample: SampleType, signed: bool) -> Result<Storage> {
        match sample {
            SampleType::Float => Ok(Storage::Float32 { signed }),
            _ if signed => Err(Error::InvalidOption(
                "signed normal maps are float (EXR); an integer image stores (n + 1)/2".into(),
            )),
            SampleType::Int { bits } | SampleType::SignedInt { bits } => Ok(Storage::Int { bits }),
        }
    }

    /// The step between neighbouring stored values of a component n:
    /// 2/(2^bits − 1) for integers (2/255, 2/65535), float32's epsilon,
    /// 0 for float64 (exact).
    #[must_use]
    pub fn step(self) -> f64 {
        match self {
            Storage::Int { bits } => 2.0 / ((1u64 << bits.min(63)) - 1) as f64,
            Storage::Float32 { .. } => f64::from(f32::EPSILON),
            Storage::Float64 { .. } => 0.0,
        }
    }

    /// The normal component n that the stored sample `v` holds (an integer
    /// as stored, a float as it is): 2c − 1 with c the sample in contract
    /// units (v / (2^bits − 1) for an integer: [`Sample::UNIT`]), or c
    /// itself for signed floats.
    #[inline]
    #[must_use]
    pub fn normal<T: Sample>(self, v: T) -> f64 {
        normal_component(v, self.is_signed())
    }

    /// Whether the samples hold n itself (signed floats), not (n + 1)/2.
    #[must_use]
    pub fn is_signed(self) -> bool {
        matches!(self, Storage::Float32 { signed: true } | Storage::Float64 { signed: true })
    }
}

/// [`Storage::normal`] with its choice given (`signed`: the sample is n
/// itself), for loops that make that choice once, outside.
#[inline(always)]
pub(crate) fn normal_component<T: Sample>(v: T, signed: bool) -> f64 {
    let c = contract(v);
    if signed { c } else { 2.0 * c - 1.0 }
}

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

/// What the planes of an image hold: heights, or a normal map's encoded
/// normals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize), serde(rename_all = "lowercase"))]
pub enum ImageKind {
    /// Heights. The tiling check judges them on the height (gray, or luma
    /// of R, G, B), for seams of value and of slope.
    Height,
    /// An encoded normal map. The tiling check judges it on R, G and B, for
    /// seams of value.
    Normal,
}

/// How the [`ImageKind`] of an image is decided: detected, or as the
/// caller says ([`kind_of`], [`TilingOptions::kind`](crate::tiling::TilingOptions::kind),
/// [`LitOptions::kind`](crate::shade::LitOptions::kind)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum KindChoice {
    /// [`ImageKind::detect`] decides. The default.
    #[default]
    Auto,
    /// Judge as a height map.
    Height,
    /// Judge as a normal map.
    Normal,
}

named_values!(KindChoice, "kind", { Auto => "auto", Height => "height", Normal => "normal" });

impl ImageKind {
    /// Decides whether `planes` hold a height map or an encoded normal map
    /// (the rule is in the
    /// [module docs](self#height-map-or-normal-map)).
    ///
    /// Looks at a grid sample of at most about 65 000 texels, so the cost is
    /// the same for any image size.
    ///
    /// Errors: [`Error::BufferSize`] when a plane is shorter than
    /// `width * height`.
    pub fn detect(planes: &[&[f32]], width: usize, height: usize) -> Result<ImageKind> {
        let len = image_len(width, height)?;
        check_planes(planes, len)?;
        if planes.len() < 3 || len == 0 {
            return Ok(ImageKind::Height);
        }
        let (r, g, b) = (&planes[0][..len], &planes[1][..len], &planes[2][..len]);
        // A grid stride per axis so that the sample covers the whole image.
        let step = |n: usize| n.div_ceil(256).max(1);
        let (sx, sy) = (step(width), step(height));
        let decodings: [fn(f32) -> f64; 2] = [|c| 2.0 * f64::from(c) - 1.0, f64::from];
        let normal = decodings.iter().any(|decode| {
            let (mut count, mut unit) = (0usize, 0usize);
            let mut mean = [0.0f64; 3];
            for y in (0..height).step_by(sy) {
                for x in (0..width).step_by(sx) {
                    let k = y * width + x;
                    let v = [decode(r[k]), decode(g[k]), decode(b[k])];
                    let length = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                    count += 1;
                    if (length - 1.0).abs() <= 0.2 && v[2] > 0.0 {
                        unit += 1;
                    }
                    for (m, c) in mean.iter_mut().zip(v) {
                        *m += c;
                    }
                }
            }
            let n = count as f64;
            let [mx, my, mz] = mean.map(|m| m / n);
            unit as f64 >= 0.9 * n && mz >= 0.5 && mx.hypot(my) <= 0.3
        });
        Ok(if normal { ImageKind::Normal } else { ImageKind::Height })
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
    Storage::of_file(raster.sample, signed)?;
    decode_planes(planes.each_ref().map(Vec::as_slice), signed)
}

/// The normals of R, G and B planes of stored values in [0, 1] (integers
/// over their top value, floats as they are: [`rgb_planes`]): each
/// component 2c − 1 (c = (n + 1)/2 stored), or c itself when `signed`
/// (floats that hold n), in f32. The one decoding of stored colours:
/// [`decode`]'s, and the Python package's for arrays.
///
/// Errors: [`Error::BufferSize`] for planes of different lengths;
/// [`Error::Limits`] when the memory is not there.
pub fn decode_planes(planes: [&[f32]; 3], signed: bool) -> Result<Vec<[f32; 3]>> {
    let len = planes[0].len();
    if let Some(p) = planes.iter().find(|p| p.len() != len) {
        return Err(Error::BufferSize { expected: len, actual: p.len() });
    }
    let stored = |c: f32| if signed { c } else { 2.0 * c - 1.0 };
    let mut normals = crate::samples::try_vec(len)?;
    normals.extend((0..len).map(|k| planes.map(|p| stored(p[k]))));
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A file's sample type gives its storage; the step is 2/(2^bits − 1)
    /// for integers, float32's epsilon, 0 for float64; a stored component
    /// reads back as 2c − 1, or c for signed floats.
    #[test]
    fn stored_components_read_back_with_their_step() {
        assert_eq!(Storage::of_file(SampleType::Int { bits: 8 }, false).unwrap(), Storage::Int { bits: 8 });
        assert_eq!(Storage::of_file(SampleType::SignedInt { bits: 16 }, false).unwrap(), Storage::Int { bits: 16 });
        assert_eq!(Storage::of_file(SampleType::Float, true).unwrap(), Storage::Float32 { signed: true });
        let e = Storage::of_file(SampleType::Int { bits: 16 }, true).unwrap_err();
        assert_eq!(
            e.to_string(),
            "invalid option: signed normal maps are float (EXR); an integer image stores (n + 1)/2"
        );
        assert_eq!(Storage::Int { bits: 8 }.step(), 2.0 / 255.0);
        assert_eq!(Storage::Int { bits: 16 }.step(), 2.0 / 65535.0);
        assert_eq!(Storage::Int { bits: 32 }.step(), 2.0 / 4294967295.0);
        assert_eq!(Storage::Float32 { signed: false }.step(), f64::from(f32::EPSILON));
        assert_eq!(Storage::Float64 { signed: true }.step(), 0.0);
        let int8 = Storage::Int { bits: 8 };
        assert_eq!((int8.normal(0u8), int8.normal(255u8)), (-1.0, 1.0));
        assert_eq!(int8.normal(37u8), 2.0 * (37.0 * (1.0 / 255.0)) - 1.0);
        assert_eq!(Storage::Int { bits: 16 }.normal(65535u16), 1.0);
        assert_eq!(Storage::Float32 { signed: false }.normal(0.75f32), 0.5);
        assert_eq!(Storage::Float32 { signed: true }.normal(-0.25f32), -0.25);
        assert_eq!(Storage::Float64 { signed: true }.normal(0.1f64), 0.1);
    }
}
