//! Light on normals: Lambert's law with a little ambient light, for the
//! texture view (a [`Light`] fixed on the image) and the GIS view (a
//! [`Sun`] placed by the compass, as `gdaldem hillshade`), and the 2×2
//! tiling that shows a texture's seams. Knows nothing of files or of the
//! fit: [`crate::shade`] makes lit views with it, and the engine's lit
//! stage lights bands of normals with [`Lamp`].
//!
//! ```text
//! L     = (cos e · cos a,  cos e · sin a,  sin e)      a = azimuth, e = elevation
//! value = AMBIENT + (1 − AMBIENT) · max(0, n · L)      in [0, 1], then × 255
//! ```
//!
//! n and L are in the OpenGL tangent frame: +x to the right (larger column
//! index), +y up the image (smaller row index), +z out of the surface.

use crate::error::{Error, Number, Result};
use crate::fit::checked_len;
use crate::io::Affine;
use crate::options::Convention;

/// The share of full brightness a texel gets even when it faces away from
/// the light, so shadowed slopes keep some visible detail.
pub const AMBIENT: f64 = 0.15;

/// A directional light, as seen on the image as it is displayed.
///
/// Angles are in degrees:
/// * `azimuth_deg`: the direction *towards* the light in the image plane,
///   counter-clockwise from the image's right (+x), with up the image
///   (towards row 0) at 90°. So 0° is light from the right, 90° from the
///   top, 135° from the top-left, 180° from the left.
/// * `elevation_deg`: the light's height above the surface: 90° is straight
///   overhead (no relief visible), small angles rake across it.
///
/// ```
/// use normalfit::shade::Light;
/// let from_top_left = Light::default();
/// assert_eq!((from_top_left.azimuth_deg, from_top_left.elevation_deg), (135.0, 35.0));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Direction towards the light in the image plane, degrees
    /// counter-clockwise from +x (right), 90° = up. Default: 135 (top-left).
    pub azimuth_deg: f64,
    /// Height of the light above the surface, degrees, 90 = overhead.
    /// Default: 35.
    pub elevation_deg: f64,
}

impl Default for Light {
    /// Light from the top-left at 35° above the surface: the usual
    /// convention of relief drawings (bumps read as bumps, not dents), low
    /// enough to rake across fine detail.
    fn default() -> Self {
        Light { azimuth_deg: 135.0, elevation_deg: 35.0 }
    }
}

impl Light {
    /// A light from `azimuth_deg` at `elevation_deg` above the surface, as
    /// a caller gives it (`--light`, `light=`).
    ///
    /// Errors: [`Error::InvalidOption`] for a non-finite azimuth or an
    /// elevation outside 0 to 90 degrees.
    pub fn new(azimuth_deg: f64, elevation_deg: f64) -> Result<Light> {
        if !azimuth_deg.is_finite() {
            return Err(Error::InvalidOption(format!(
                "the light's azimuth must be a finite number of degrees, got {}",
                Number(azimuth_deg)
            )));
        }
        if !(0.0..=90.0).contains(&elevation_deg) {
            return Err(Error::InvalidOption(format!(
                "the light's elevation must be from 0 to 90 degrees, got {}",
                Number(elevation_deg)
            )));
        }
        Ok(Light { azimuth_deg, elevation_deg })
    }

    /// The unit vector towards the light in the OpenGL tangent frame.
    #[must_use]
    pub fn direction(self) -> [f64; 3] {
        let (a, e) = (self.azimuth_deg.to_radians(), self.elevation_deg.to_radians());
        [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()]
    }
}

/// An 8-bit grey picture of `normals` lit by `light`, row-major,
/// `width * height` bytes.
///
/// `normals` are tangent-space `[x, y, z]` in `convention`'s frame (what
/// [`normals`](crate::normals) returns for the same
/// [`Options::convention`](crate::Options)); DirectX normals have their y
/// flipped here, so both conventions light the same way on screen. They
/// need not be exactly unit length (decoded 8-bit maps are not): each is
/// normalised first, and a zero or non-finite vector is taken as flat.
///
/// Fails with [`Error::BufferSize`] if `normals` is not `width * height`
/// long, or [`Error::InvalidOption`] for a zero or overflowing size.
///
/// ```
/// use normalfit::{shade::{shade, Light}, Convention};
/// let flat = vec![[0.0f32, 0.0, 1.0]; 4];
/// let overhead = Light { azimuth_deg: 0.0, elevation_deg: 90.0 };
/// assert_eq!(shade(&flat, 2, 2, overhead, Convention::OpenGl).unwrap(), [255; 4]);
/// ```
pub fn shade(
    normals: &[[f32; 3]],
    width: usize,
    height: usize,
    light: Light,
    convention: Convention,
) -> Result<Vec<u8>> {
    let len = checked_len(width, height)?;
    if normals.len() != len {
        return Err(Error::BufferSize { expected: len, actual: normals.len() });
    }
    shade_with(normals, Lamp::light(light, convention))
}

/// The hillshade of `normals` under `sun`, as `gdaldem hillshade` draws it:
/// 1 + 254 · max(0, n · L), rounded, so 1 is full shadow (gdaldem keeps 0
/// for nodata). North, for the sun's azimuth, is found from `affine`, the
/// raster's georeferencing (up the image when there is none, or for a
/// north-up raster). `normals` and the errors as [`shade`].
///
/// ```
/// use normalfit::{shade::{shade_sun, Sun}, Convention};
/// let flat = vec![[0.0f32, 0.0, 1.0]; 4];
/// // sin 45° = 0.7071: 1 + 254 · 0.7071 = 180.6.
/// assert_eq!(shade_sun(&flat, 2, 2, Sun::default(), None, Convention::OpenGl).unwrap(), [181; 4]);
/// ```
pub fn shade_sun(
    normals: &[[f32; 3]],
    width: usize,
    height: usize,
    sun: Sun,
    affine: Option<&Affine>,
    convention: Convention,
) -> Result<Vec<u8>> {
    let len = checked_len(width, height)?;
    if normals.len() != len {
        return Err(Error::BufferSize { expected: len, actual: normals.len() });
    }
    shade_with(normals, Lamp::sun(sun, affine, convention))
}

/// Every texel's grey under `lamp`.
///
/// Errors: [`Error::Limits`] when the memory for the greys is not there.
pub(crate) fn shade_with(normals: &[[f32; 3]], lamp: Lamp) -> Result<Vec<u8>> {
    let mut grey = crate::samples::try_vec(normals.len())?;
    grey.resize(normals.len(), 0u8);
    lamp.grey_row(normals, &mut grey);
    Ok(grey)
}

pub(crate) use crate::fit::Lamp;

impl Lamp {
    /// The texture view's light.
    pub(crate) fn light(light: Light, convention: Convention) -> Lamp {
        Lamp { direction: flip_y(light.direction(), convention), gis: false }
    }

    /// The GIS sun over a raster placed by `affine`.
    pub(crate) fn sun(sun: Sun, affine: Option<&Affine>, convention: Convention) -> Lamp {
        Lamp { direction: flip_y(sun.direction(affine), convention), gis: true }
    }

    /// Whether this is the GIS sun ([`Lamp::sun`]): a lit view's texel is
    /// then [`Grey<true>`].
    pub(crate) fn is_sun(&self) -> bool {
        self.gis
    }

    /// The grey of a texel whose normal is `n` (normalised here; a zero
    /// or non-finite one is taken as flat).
    #[inline(always)]
    pub(crate) fn grey(&self, n: [f32; 3]) -> u8 {
        if self.gis {
            return self.sun_grey(n);
        }
        let [lx, ly, lz] = self.direction;
        let [x, y, z] = n.map(f64::from);
        let len = (x * x + y * y + z * z).sqrt();
        let cos = if len > 0.0 && len.is_finite() { (x * lx + y * ly + z * lz) / len } else { lz };
        ((AMBIENT + (1.0 - AMBIENT) * cos.max(0.0)) * 255.0).round() as u8
    }

    /// The greys of a row of normals, [`Lamp::grey`] each: under the sun,
    /// compiled for the widest vectors the processor has
    /// ([`pulp::Arch::dispatch`]), which round as the baseline's do.
    pub(crate) fn grey_row(&self, normals: &[[f32; 3]], out: &mut [u8]) {
        if self.gis {
            pulp::Arch::new().dispatch(SunRow { lamp: self, normals, out });
        } else {
            out.iter_mut().zip(normals).for_each(|(g, &n)| *g = self.grey(n));
        }
    }

    /// [`Lamp::grey`] under the sun, in `f32` (a grey level is 1/254 of
    /// the range; f32 carries 2^-24) and rounded by adding ½ (the value is
    /// at least 1): `f64::round` is a call into libm on the baseline x86-64
    /// target, and this grey was 40 % of a streamed lit view's processor
    /// time before.
    #[inline(always)]
    fn sun_grey(&self, n: [f32; 3]) -> u8 {
        grey_of(sun_level(self.sun_direction(), n))
    }

    /// The sun's direction, in `f32`.
    #[inline(always)]
    fn sun_direction(&self) -> [f32; 3] {
        self.direction.map(|v| v as f32)
    }
}

/// A lit view's texel, made by the fit in its own loop over a row (the
/// row's normals still in the core's cache) rather than from a band of
/// `f32` normals stored and read back: the grey of the unit normal, cast
/// to `f32` as the normal map's texel is, under the fit's lamp
/// ([`crate::fit::TexelFrame`]): [`Lamp::grey`], the same bits as
/// [`Lamp::grey_row`] of the `f32` normals gives. `SUN`: the lamp is the
/// GIS sun ([`Lamp::is_sun`]), whose grey the fit's loop vectorises (the
/// texture view's rounds by libm, which it would not), so its loop has no
/// branch on the lamp.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Grey<const SUN: bool>(pub(crate) u8);

impl<const SUN: bool> crate::fit::Texel for Grey<SUN> {
    #[inline(always)]
    fn make(n: [f64; 3], frame: &crate::fit::TexelFrame) -> Self {
        let n = n.map(|c| c as f32);
        Grey(if SUN { frame.lamp.sun_grey(n) } else { frame.lamp.grey(n) })
    }
}

/// [`Lamp::sun_grey`] under the sun `[lx, ly, lz]`, before its cast: a
/// value in [1.5, 255] (or NaN, which the cast makes 0) whose integer part
/// is the grey.
#[inline(always)]
fn sun_level([lx, ly, lz]: [f32; 3], [x, y, z]: [f32; 3]) -> f32 {
    let len2 = x * x + y * y + z * z;
    let cos = if len2 > 0.0 && len2.is_finite() { (x * lx + y * ly + z * lz) / len2.sqrt() } else { lz };
    // NaN compares false: max gives 0 for it.
    (1.5 + 254.0 * cos.max(0.0)).min(255.0)
}

/// The grey of a level from [`sun_level`]: its integer part, as `as u8`
/// gives it (NaN gives 0), from the low byte of floor + 2^23, which is
/// exact for integers below 2^23 (a NaN stays NaN, whose low byte is 0).
#[inline(always)]
fn grey_of(level: f32) -> u8 {
    (level.floor() + 8_388_608.0).to_bits() as u8
}

/// [`Lamp::grey_row`] under the sun, for [`pulp::Arch::dispatch`].
struct SunRow<'a> {
    lamp: &'a Lamp,
    normals: &'a [[f32; 3]],
    out: &'a mut [u8],
}

impl pulp::WithSimd for SunRow<'_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let SunRow { lamp, normals, out } = self;
        let sun = lamp.sun_direction();
        // One loop, which the compiler vectorises: the byte comes from the
        // level's floor by the bits of floor + 2^23, not by a saturating
        // cast, which it leaves scalar.
        out.iter_mut().zip(normals).for_each(|(g, &n)| *g = grey_of(sun_level(sun, n)));
    }
}

/// Flipping the light's y is the same as flipping every DirectX normal's.
fn flip_y([x, y, z]: [f64; 3], convention: Convention) -> [f64; 3] {
    match convention {
        Convention::OpenGl => [x, y, z],
        Convention::DirectX => [x, -y, z],
    }
}

/// The sun as GIS tools give it (`gdaldem hillshade -az -alt`): the
/// azimuth in degrees clockwise from north (0 north, 90 east, 315
/// north-west), the altitude in degrees above the horizon.
///
/// ```
/// use normalfit::shade::Sun;
/// let sun = Sun::default();
/// assert_eq!((sun.azimuth_deg, sun.altitude_deg), (315.0, 45.0));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// Degrees clockwise from north. Default: 315 (north-west).
    pub azimuth_deg: f64,
    /// Degrees above the horizon, 90 = overhead. Default: 45.
    pub altitude_deg: f64,
}

impl Default for Sun {
    /// gdaldem's: 315°, 45°.
    fn default() -> Self {
        Sun { azimuth_deg: 315.0, altitude_deg: 45.0 }
    }
}

impl Sun {
    /// A sun at `azimuth_deg` (clockwise from north), `altitude_deg` above
    /// the horizon.
    ///
    /// Errors: [`Error::InvalidOption`] for a non-finite azimuth or an
    /// altitude outside 0 to 90 degrees.
    pub fn new(azimuth_deg: f64, altitude_deg: f64) -> Result<Sun> {
        if !azimuth_deg.is_finite() {
            return Err(Error::InvalidOption(format!(
                "the sun's azimuth must be a finite number of degrees, got {}",
                Number(azimuth_deg)
            )));
        }
        if !(0.0..=90.0).contains(&altitude_deg) {
            return Err(Error::InvalidOption(format!(
                "the sun's altitude must be from 0 to 90 degrees, got {}",
                Number(altitude_deg)
            )));
        }
        Ok(Sun { azimuth_deg, altitude_deg })
    }

    /// The unit vector towards the sun in the OpenGL tangent frame of a
    /// raster placed by `affine` (+x along a row, +y up the image, +z up).
    /// The sun's horizontal direction in map coordinates, (sin az, cos az)
    /// east and north, is projected on the raster's axes: a column step
    /// (a, d) and a step up the image (−b, −e), each made unit. A north-up
    /// raster (b = d = 0, e < 0), and a raster without georeferencing,
    /// give (cos alt · sin az, cos alt · cos az, sin alt).
    #[must_use]
    pub fn direction(self, affine: Option<&Affine>) -> [f64; 3] {
        let (az, alt) = (self.azimuth_deg.to_radians(), self.altitude_deg.to_radians());
        let (east, north) = (az.sin(), az.cos());
        let crate::units::MapAxes { x: (xe, xn), up: (ye, yn) } = crate::units::MapAxes::of(affine);
        [alt.cos() * (east * xe + north * xn), alt.cos() * (east * ye + north * yn), alt.sin()]
    }
}

/// `pixels` (one byte a texel, `width * height`, row-major) repeated 2×2:
/// a `2 * width` × `2 * height` image whose middle cross is where the
/// texture's right edge meets its left and its bottom meets its top, so a
/// seam that does not match shows there.
///
/// Fails like [`shade`] if the buffer does not match the size.
///
/// ```
/// use normalfit::shade::tile_2x2;
/// assert_eq!(tile_2x2(&[1, 2], 2, 1).unwrap(), [1, 2, 1, 2, 1, 2, 1, 2]);
/// ```
pub fn tile_2x2(pixels: &[u8], width: usize, height: usize) -> Result<Vec<u8>> {
    let len = checked_len(width, height)?;
    if pixels.len() != len {
        return Err(Error::BufferSize { expected: len, actual: pixels.len() });
    }
    let out_len = len
        .checked_mul(4)
        .ok_or_else(|| Error::InvalidOption(format!("a 2×2 tiling of {width}×{height} texels is too large")))?;
    let mut out = crate::samples::try_vec(out_len)?;
    for _ in 0..2 {
        for row in pixels.chunks_exact(width) {
            out.extend_from_slice(row);
            out.extend_from_slice(row);
        }
    }
    Ok(out)
}

/// When a lit view is lit by the GIS sun ([`shade_sun`], gdaldem's
/// convention) rather than the texture view's light ([`shade`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum SunChoice {
    /// Never: the light for every image.
    Off,
    /// For georeferenced images (a GeoTIFF with a transform), north from
    /// their transform; the light for the others. The default.
    Georeferenced(Sun),
    /// For every image; north is up the image where there is no transform.
    Always(Sun),
}

/// How a lit view is lit: the texture view's light, or the GIS sun for
/// the images [`SunChoice`] says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Lighting {
    pub light: Light,
    pub sun: SunChoice,
}

impl Lighting {
    /// The lamp for an image placed by `georef` (none: not georeferenced),
    /// in the fit's `convention`.
    pub(crate) fn lamp(&self, georef: Option<&crate::io::Georef>, convention: Convention) -> Lamp {
        let affine = georef.and_then(crate::io::Georef::affine);
        match self.sun {
            SunChoice::Always(sun) => Lamp::sun(sun, affine.as_ref(), convention),
            SunChoice::Georeferenced(sun) if affine.is_some() => Lamp::sun(sun, affine.as_ref(), convention),
            _ => Lamp::light(self.light, convention),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row of greys under the sun (the vectorised loop) is each texel's
    /// grey as the plain formula gives it, with its saturating cast: on
    /// every level, on unnormalised, zero, infinite and NaN normals, and on
    /// rows of every length (the vector loop's remainders).
    #[test]
    fn a_row_of_sun_greys_is_each_texels_grey() {
        let lamp = Lamp::sun(Sun::new(315.0, 45.0).unwrap(), None, Convention::OpenGl);
        let sun = lamp.sun_direction();
        let plain = |[x, y, z]: [f32; 3]| {
            let [lx, ly, lz] = sun;
            let len2 = x * x + y * y + z * z;
            let cos = if len2 > 0.0 && len2.is_finite() { (x * lx + y * ly + z * lz) / len2.sqrt() } else { lz };
            (1.5 + 254.0 * cos.max(0.0)).min(255.0) as u8
        };
        let mut normals: Vec<[f32; 3]> = (0..4000)
            .map(|k| {
                let (a, b) = (k as f32 * 0.0123, k as f32 * 0.00071);
                [a.cos() * b.sin(), a.sin() * b.sin(), b.cos() * (1.0 + (k % 5) as f32)]
            })
            .collect();
        normals.extend([
            [0.0; 3],
            [f32::NAN, 0.0, 1.0],
            [f32::INFINITY, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [1e30, 1e30, 1e30],
            [-sun[0], -sun[1], -sun[2]],
            sun,
        ]);
        for len in [0, 1, 7, 8, 9, 31, normals.len()] {
            let mut greys = vec![0u8; len];
            lamp.grey_row(&normals[..len], &mut greys);
            let expected: Vec<u8> = normals[..len].iter().map(|&n| plain(n)).collect();
            assert_eq!(greys, expected, "a row of {len}");
        }
        let mut all = vec![0u8; normals.len()];
        lamp.grey_row(&normals, &mut all);
        assert!(all.contains(&255) && all.contains(&1), "the extremes are reached");
    }

    fn unit(v: [f64; 3]) -> [f32; 3] {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| (c / l) as f32)
    }

    #[test]
    fn flat_map_is_uniform_lambert_of_the_elevation() {
        // n · L = sin 30° = 1/2, so 0.15 + 0.85 · 0.5 = 0.575; × 255 = 146.6.
        let light = Light { azimuth_deg: 200.0, elevation_deg: 30.0 };
        let out = shade(&[[0.0, 0.0, 1.0]; 12], 4, 3, light, Convention::OpenGl).unwrap();
        assert_eq!(out, vec![147u8; 12]);
    }

    #[test]
    fn facing_the_light_is_brighter_than_facing_away() {
        // Default light from the top-left: a slope whose normal leans up-left
        // (−x, +y in OpenGL) faces it, its mirror image faces away.
        let toward = unit([-1.0, 1.0, 2.0]);
        let away = unit([1.0, -1.0, 2.0]);
        let flat = [0.0, 0.0, 1.0];
        let out = shade(&[toward, flat, away], 3, 1, Light::default(), Convention::OpenGl).unwrap();
        assert!(out[0] > out[1] && out[1] > out[2], "{out:?}");
        // Turned fully away from the light: only the ambient share is left.
        let back = Light { azimuth_deg: 0.0, elevation_deg: 10.0 };
        let dark = shade(&[unit([-1.0, 0.0, 0.1])], 1, 1, back, Convention::OpenGl).unwrap();
        assert_eq!(dark, [(AMBIENT * 255.0).round() as u8]);
    }

    #[test]
    fn directx_normals_light_like_their_opengl_twins() {
        // The same surface: DirectX stores y negated.
        let gl = [unit([0.3, 0.5, 1.0]), unit([-0.2, -0.7, 1.0])];
        let dx = gl.map(|[x, y, z]| [x, -y, z]);
        let light = Light { azimuth_deg: 90.0, elevation_deg: 40.0 };
        let a = shade(&gl, 2, 1, light, Convention::OpenGl).unwrap();
        let b = shade(&dx, 2, 1, light, Convention::DirectX).unwrap();
        assert_eq!(a, b);
        assert!(a[0] > a[1], "the normal leaning up faces a light from the top");
    }

    #[test]
    fn unnormalised_and_degenerate_normals_are_handled() {
        let light = Light::default();
        let a = shade(&[[0.0, 0.0, 1.0], [0.0, 0.0, 7.0], [0.0; 3], [f32::NAN; 3]], 4, 1, light, Convention::OpenGl)
            .unwrap();
        assert!(a.iter().all(|&v| v == a[0]), "{a:?}");
    }

    #[test]
    fn wrong_sizes_are_errors_not_panics() {
        let l = Light::default();
        assert!(matches!(
            shade(&[[0.0, 0.0, 1.0]; 3], 2, 2, l, Convention::OpenGl),
            Err(Error::BufferSize { expected: 4, actual: 3 })
        ));
        assert!(shade(&[], 0, 0, l, Convention::OpenGl).is_err());
        assert!(tile_2x2(&[1, 2, 3], 2, 2).is_err());
        assert!(tile_2x2(&[], 0, 3).is_err());
    }

    #[test]
    fn tiling_repeats_the_image_two_by_two() {
        // 3 × 2 image, values naming their texel.
        let img = [1, 2, 3, 4, 5, 6];
        let out = tile_2x2(&img, 3, 2).unwrap();
        #[rustfmt::skip]
        let want = [
            1, 2, 3, 1, 2, 3,
            4, 5, 6, 4, 5, 6,
            1, 2, 3, 1, 2, 3,
            4, 5, 6, 4, 5, 6,
        ];
        assert_eq!(out, want);
    }
}
