//! Lit views of normal maps, for people to look at.
//!
//! A normal map's colours say little to the eye; the same normals lit by a
//! single raking light show the relief at once, and tiling the lit view 2×2
//! shows whether the seams match. The shading is Lambert's law with a
//! little ambient light, so faces turned away from the light stay grey
//! rather than black:
//!
//! ```text
//! L     = (cos e · cos a,  cos e · sin a,  sin e)      a = azimuth, e = elevation
//! value = AMBIENT + (1 − AMBIENT) · max(0, n · L)      in [0, 1], then × 255
//! ```
//!
//! n and L are in the OpenGL tangent frame: +x to the right (larger column
//! index), +y up the image (smaller row index), +z out of the surface.
//!
//! [`lit_view`] makes the picture of a decoded image as `normalfit shade`
//! does: a normal map's colours decoded ([`crate::normal_map`]), a height
//! map fitted first, the light applied, tiled if asked; [`LitView::encode`]
//! writes it as a gray PNG.

use std::borrow::Cow;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use crate::convert::{BorderChoices, Warning};
use crate::error::{Error, Result};
use crate::fit::checked_len;
use crate::io::encoding::{TiffDepth, TiffOptions};
use crate::io::read::georef::holes_value;
use crate::io::{
    self, Affine, Channel, Georef, OutputFormat, PngCompression, PngDepth, PngOptions, Raster, ReadOptions,
};
use crate::options::{Convention, Options};
use crate::samples::Samples;
use crate::tiling::{self, ImageKind, KindChoice, TilingOptions};
use crate::units::MapSpacing;

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
                "the light's azimuth must be a finite number of degrees, got {azimuth_deg}"
            )));
        }
        if !(0.0..=90.0).contains(&elevation_deg) {
            return Err(Error::InvalidOption(format!(
                "the light's elevation must be from 0 to 90 degrees, got {elevation_deg}"
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
    Ok(shade_with(normals, Lamp::light(light, convention)))
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
    Ok(shade_with(normals, Lamp::sun(sun, affine, convention)))
}

/// Every texel's grey under `lamp`.
fn shade_with(normals: &[[f32; 3]], lamp: Lamp) -> Vec<u8> {
    let mut grey = vec![0u8; normals.len()];
    lamp.grey_row(normals, &mut grey);
    grey
}

/// A light resolved for one image: its direction in the fit's frame
/// (DirectX's y already flipped) and how n · L becomes a grey.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lamp {
    direction: [f64; 3],
    /// gdaldem's scale (1 + 254 · cos) rather than the texture view's
    /// ambient share.
    gis: bool,
}

impl Lamp {
    /// The texture view's light.
    fn light(light: Light, convention: Convention) -> Lamp {
        Lamp { direction: flip_y(light.direction(), convention), gis: false }
    }

    /// The GIS sun over a raster placed by `affine`.
    pub(crate) fn sun(sun: Sun, affine: Option<&Affine>, convention: Convention) -> Lamp {
        Lamp { direction: flip_y(sun.direction(affine), convention), gis: true }
    }

    /// The grey of a texel whose normal is `n` (normalised here; a zero
    /// or non-finite one is taken as flat).
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
                "the sun's azimuth must be a finite number of degrees, got {azimuth_deg}"
            )));
        }
        if !(0.0..=90.0).contains(&altitude_deg) {
            return Err(Error::InvalidOption(format!(
                "the sun's altitude must be from 0 to 90 degrees, got {altitude_deg}"
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
        let unit = |x: f64, y: f64| {
            let l = x.hypot(y);
            if l > 0.0 && l.is_finite() { (x / l, y / l) } else { (0.0, 0.0) }
        };
        let ((xe, xn), (ye, yn)) = match affine {
            Some(t) => (unit(t.a, t.d), unit(-t.b, -t.e)),
            None => ((1.0, 0.0), (0.0, 1.0)),
        };
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
    let mut out = Vec::with_capacity(out_len);
    for _ in 0..2 {
        for row in pixels.chunks_exact(width) {
            out.extend_from_slice(row);
            out.extend_from_slice(row);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The command line's and Python's rule: a light, a sun angle (the
    /// other the default's), or neither; not both, nor an angle out of
    /// range.
    #[test]
    fn the_lighting_chosen_is_a_light_a_sun_or_the_default() {
        let base = LitOptions::new();
        let light = Light::new(45.0, 60.0).unwrap();
        let chosen = |l: Option<Light>, az: Option<f64>, alt: Option<f64>| base.clone().with_lighting(l, az, alt);
        let none = chosen(None, None, None).unwrap();
        assert_eq!((none.light, none.sun), (Light::default(), SunChoice::Georeferenced(Sun::default())));
        let lit = chosen(Some(light), None, None).unwrap();
        assert_eq!((lit.light, lit.sun), (light, SunChoice::Off));
        let sun = |az, alt| SunChoice::Always(Sun::new(az, alt).unwrap());
        assert_eq!(chosen(None, Some(200.0), None).unwrap().sun, sun(200.0, 45.0));
        assert_eq!(chosen(None, None, Some(30.0)).unwrap().sun, sun(315.0, 30.0));
        assert_eq!(chosen(None, Some(90.0), Some(10.0)).unwrap().sun, sun(90.0, 10.0));
        for (l, az, alt) in [(Some(light), Some(1.0), None), (Some(light), None, Some(1.0)), (None, None, Some(95.0))] {
            assert!(matches!(chosen(l, az, alt), Err(Error::InvalidOption(_))), "{l:?} {az:?} {alt:?}");
        }
    }

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

/// When [`lit_view`] lights an image with the GIS sun ([`shade_sun`],
/// gdaldem's convention) rather than the texture view's light ([`shade`]).
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

/// What [`lit_view`] does with an image.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct LitOptions {
    /// The fit for height maps; its convention is also the one a normal
    /// map's green follows. Its borders are replaced by
    /// [`LitOptions::borders`]'.
    pub fit: Options,
    /// The border modes for height maps, fixed or `auto`.
    pub borders: BorderChoices,
    /// The light of the texture view, for inputs the sun does not light.
    pub light: Light,
    /// When the GIS sun lights the image instead ([`shade_sun`]).
    /// Default: [`SunChoice::Georeferenced`] with [`Sun::default`].
    pub sun: SunChoice,
    /// Repeat the picture 2×2, so seams show.
    pub tile: bool,
    /// Whether the image is a normal or a height map (detected by default).
    pub kind: KindChoice,
    /// The channel of a height map that holds the height.
    pub channel: Option<Channel>,
    /// A float normal map holds n itself, not (n + 1)/2.
    pub signed: bool,
    /// Fit height maps in real-world units ([`crate::Units::Map`]), the
    /// spacing from the file or given, as a conversion does
    /// ([`crate::convert::Conversion::map_units`]): heights as stored (a
    /// DEM's metres), texels as far apart as the ground says, so that at
    /// gain 1 the slopes, and the sun's hillshade, are the terrain's, as
    /// `gdaldem hillshade` draws them at its default `-z 1`. The fit's own
    /// [`Options::units`] are replaced by what this gives. Normal maps are
    /// lit as they are. Default: `None`, the contract's units.
    pub map_units: Option<MapSpacing>,
}

impl Default for LitOptions {
    fn default() -> Self {
        let fit = Options::new();
        LitOptions {
            borders: fit.borders.into(),
            fit,
            light: Light::default(),
            sun: SunChoice::Georeferenced(Sun::default()),
            tile: false,
            kind: KindChoice::Auto,
            channel: None,
            signed: false,
            map_units: None,
        }
    }
}

impl LitOptions {
    /// The defaults: the fit's defaults, the default light, not tiled,
    /// the kind detected.
    #[must_use]
    pub fn new() -> LitOptions {
        LitOptions::default()
    }

    /// With this fit, its borders fixed as they are.
    #[must_use]
    pub fn with_fit(mut self, fit: Options) -> LitOptions {
        self.borders = fit.borders.into();
        self.fit = fit;
        self
    }

    /// With these border choices.
    #[must_use]
    pub fn with_borders(mut self, borders: BorderChoices) -> LitOptions {
        self.borders = borders;
        self
    }

    /// With this light, for every input (the sun off: a light given is
    /// the texture view's).
    #[must_use]
    pub fn with_light(mut self, light: Light) -> LitOptions {
        self.light = light;
        self.sun = SunChoice::Off;
        self
    }

    /// With this choice of sun.
    #[must_use]
    pub fn with_sun(mut self, sun: SunChoice) -> LitOptions {
        self.sun = sun;
        self
    }

    /// With the lighting a caller chose (`normalfit shade`'s `--light`,
    /// `--azimuth` and `--altitude`; Python's `lit_view`): a `light`, the
    /// texture view's for every input; else a sun angle, the GIS sun for
    /// every input (the other angle [`Sun::default`]'s); else neither, the
    /// default (the sun for georeferenced inputs, the default light for the
    /// others).
    ///
    /// Errors: [`Error::InvalidOption`] for a light and a sun angle both,
    /// or a sun angle out of range ([`Sun::new`]).
    pub fn with_lighting(
        self,
        light: Option<Light>,
        azimuth: Option<f64>,
        altitude: Option<f64>,
    ) -> Result<LitOptions> {
        match (light, azimuth, altitude) {
            (Some(_), Some(_), _) | (Some(_), _, Some(_)) => Err(Error::InvalidOption(
                "a light (the texture view's) or the sun's azimuth and altitude, not both".into(),
            )),
            (Some(light), None, None) => Ok(self.with_light(light)),
            (None, None, None) => Ok(self),
            (None, azimuth, altitude) => {
                let default = Sun::default();
                let sun = Sun::new(azimuth.unwrap_or(default.azimuth_deg), altitude.unwrap_or(default.altitude_deg))?;
                Ok(self.with_sun(SunChoice::Always(sun)))
            }
        }
    }

    /// The lamp for an image placed by `georef` (none: not georeferenced),
    /// in the fit's convention.
    pub(crate) fn lamp(&self, georef: Option<&crate::io::Georef>) -> Lamp {
        let affine = georef.and_then(crate::io::Georef::affine);
        let convention = self.fit.convention;
        match self.sun {
            SunChoice::Always(sun) => Lamp::sun(sun, affine.as_ref(), convention),
            SunChoice::Georeferenced(sun) if affine.is_some() => Lamp::sun(sun, affine.as_ref(), convention),
            _ => Lamp::light(self.light, convention),
        }
    }

    /// Tiled 2×2 (`true`) or not.
    #[must_use]
    pub fn with_tile(mut self, tile: bool) -> LitOptions {
        self.tile = tile;
        self
    }

    /// The image is this kind.
    #[must_use]
    pub fn with_kind(mut self, kind: KindChoice) -> LitOptions {
        self.kind = kind;
        self
    }

    /// Reading a height map's height from this channel.
    #[must_use]
    pub fn with_channel(mut self, channel: Option<Channel>) -> LitOptions {
        self.channel = channel;
        self
    }

    /// A float normal map holding n itself (`true`).
    #[must_use]
    pub fn with_signed(mut self, signed: bool) -> LitOptions {
        self.signed = signed;
        self
    }

    /// Fitting height maps in map units, the spacing from the file
    /// ([`MapSpacing::FromFile`]) or given; `None` for the contract's
    /// units. Front ends take it from `--units` and `--pixel-size` by
    /// [`MapSpacing::choose`].
    #[must_use]
    pub fn with_map_units(mut self, map_units: Option<MapSpacing>) -> LitOptions {
        self.map_units = map_units;
        self
    }

    /// The fit of a `height`-row image placed by `georef`, in map units
    /// when asked.
    fn fit_for(&self, georef: Option<&Georef>, height: usize) -> Result<Options> {
        match &self.map_units {
            Some(map) => Ok(self.fit.clone().with_units(map.units(georef, height)?)),
            None => Ok(self.fit.clone()),
        }
    }
}

/// A lit picture: 8-bit gray, row-major.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct LitView {
    /// The gray values.
    pub pixels: Vec<u8>,
    /// Columns (twice the image's when tiled).
    pub width: usize,
    /// Rows (twice the image's when tiled).
    pub height: usize,
    /// What the image was taken for.
    pub kind: ImageKind,
    /// For a height map, the warning about a wrap that draws a seam.
    pub warnings: Vec<Warning>,
    /// The georeferencing of the image (a GeoTIFF's), which the picture
    /// keeps when it is not tiled: [`LitView::write_file`] writes it beside.
    pub georef: Option<Georef>,
    /// Missing texels of a height map with holes (a nodata value, the
    /// fit's or the GeoTIFF's): grey 0, as `gdaldem hillshade` writes
    /// nodata (counted once, not per tile).
    pub missing: usize,
}

impl LitView {
    /// Writes the picture as an 8-bit gray PNG (balanced compression).
    ///
    /// Errors: those of [`io::encode_gray`].
    pub fn encode(&self, out: impl Write + Seek) -> Result<()> {
        let encoding = PngOptions::new(PngDepth::Eight).with_compression(PngCompression::Default).into();
        io::encode_gray(&self.pixels, self.width, self.height, &encoding, out)
    }

    /// Writes the picture as an 8-bit grey TIFF: a GeoTIFF with the
    /// image's georeferencing when it has any, and GDAL's nodata value 0,
    /// as `gdaldem hillshade` writes (missing texels are grey 0; lit ones
    /// are at least 1).
    ///
    /// Errors: those of [`io::encode_gray`]; [`Error::Unsupported`] in a
    /// build without the `tiff` feature.
    pub fn encode_tiff(&self, out: impl Write + Seek) -> Result<()> {
        let encoding = TiffOptions::new(TiffDepth::Eight).into();
        let size = (self.width, self.height);
        io::write::encode_gray_tagged(&self.pixels, size, &encoding, lit_tiff_tags(self.georef.as_ref()), out)
    }

    /// Writes the picture to the file `path`, whole or not at all, in the
    /// format [`lit_format`] gives: a TIFF ([`LitView::encode_tiff`]), or
    /// a PNG ([`LitView::encode`]) and beside it the georeferencing
    /// sidecars ([`io::sidecar`]) when it has any. Returns the sidecars
    /// written.
    ///
    /// Errors: those of [`lit_format`], of the encoders and of writing the
    /// files.
    pub fn write_file(&self, path: &Path) -> Result<Vec<PathBuf>> {
        if lit_format(path)? == OutputFormat::Tiff {
            io::write_file_atomically(path, |out| self.encode_tiff(out))?;
            return Ok(Vec::new());
        }
        io::write_file_atomically(path, |out| self.encode(out))?;
        match &self.georef {
            Some(georef) => io::sidecar::write_sidecars(path, georef),
            None => Ok(Vec::new()),
        }
    }
}

/// The format of a lit view written to the file `path`: TIFF for a name
/// ending in `.tif` or `.tiff`, PNG for `.png` or no extension.
///
/// Errors: [`Error::Unsupported`] for any other name.
pub fn lit_format(path: &Path) -> Result<OutputFormat> {
    match OutputFormat::from_path(path) {
        Ok(None | Some(OutputFormat::Png)) => Ok(OutputFormat::Png),
        Ok(Some(OutputFormat::Tiff)) => Ok(OutputFormat::Tiff),
        _ => Err(Error::Unsupported("a lit view is written as PNG or TIFF: name the output .png or .tif".into())),
    }
}

/// A lit view's TIFF tags: the source's georeferencing, and nodata 0.
fn lit_tiff_tags(georef: Option<&Georef>) -> io::write::TiffTags<'_> {
    io::write::TiffTags { georef, nodata: Some(0.0) }
}

/// The lit picture of a decoded image (lit by the sun or the light as
/// [`LitOptions::sun`] says): a normal map's colours read back
/// ([`crate::normal_map::decode`]), or a height map's normals fitted with
/// `opts.fit` (`auto` borders and the warning about a wrap that draws a
/// seam from the tiling check, as a conversion does; in map units when
/// [`LitOptions::map_units`] says, the heights as stored); then lit in the
/// frame of `opts.fit.convention`, which [`shade`] undoes, so both
/// conventions light the same on screen.
///
/// Errors: those of [`crate::normal_map::kind_of`] and
/// [`crate::normal_map::decode`], of the fit, of
/// [`MapSpacing::units`] (map units of a file without georeferencing and
/// no pixel size given, …), and [`Error::InvalidOption`] for `signed` with
/// a height map.
pub fn lit_view(raster: &Raster, opts: &LitOptions) -> Result<LitView> {
    lit(Cow::Borrowed(raster), opts)
}

/// [`lit_view`] of a raster the caller gives up: in map units its stored
/// heights are taken out of it rather than copied.
///
/// Errors: those of [`lit_view`].
pub fn lit_view_owned(raster: Raster, opts: &LitOptions) -> Result<LitView> {
    lit(Cow::Owned(raster), opts)
}

fn lit(raster: Cow<'_, Raster>, opts: &LitOptions) -> Result<LitView> {
    let (w, h) = (raster.width, raster.height);
    let kind = crate::normal_map::kind_of(&raster, opts.kind, opts.channel.as_ref())?;
    let georef = if opts.tile { None } else { raster.georef.clone() };
    let lamp = opts.lamp(raster.georef.as_ref());
    let mut warnings = Vec::new();
    let mut valid: Option<Vec<bool>> = None;
    let normals = match kind {
        ImageKind::Normal => crate::normal_map::decode(&raster, opts.signed)?,
        ImageKind::Height => {
            if opts.signed {
                return Err(Error::InvalidOption(
                    "signed is for normal maps, and this is a height map (name its kind normal if it is not)".into(),
                ));
            }
            let fit = opts.fit_for(raster.georef.as_ref(), h)?;
            let nodata = holes_value(opts.fit.nodata, raster.georef.as_ref());
            // Map units fit the heights as stored (a DEM's metres).
            let stored = opts.map_units.is_some();
            let (heights, nodata) = match nodata {
                Some(v) => {
                    let (heights, v) = raster.into_owned().into_heights_with_holes(opts.channel.clone(), stored, v)?;
                    (heights, Some(v))
                }
                None if stored => (raster.into_owned().into_stored_heights(opts.channel.clone())?, None),
                None => (Samples::F32(raster.heights(opts.channel.clone())?), None),
            };
            let report = opts
                .borders
                .needs_check()
                .then(|| {
                    let plane = heights.to_f32()?;
                    tiling::check(&[&plane], w, h, &TilingOptions::new().with_kind(KindChoice::Height))
                })
                .transpose()?;
            warnings.extend(report.as_ref().and_then(|r| opts.borders.seams(r)));
            let fit = fit.with_borders(opts.borders.resolve(report.as_ref())).with_nodata(nodata);
            let mut normals = crate::samples::try_vec(checked_len(w, h)?)?;
            normals.resize(checked_len(w, h)?, [0.0f32; 3]);
            if nodata.is_some() {
                let mut mask = vec![false; normals.len()];
                crate::FitRequest::new(&fit).holes(&mut mask).normals_into(&heights, w, h, &mut normals)?;
                valid = Some(mask);
            } else {
                crate::FitRequest::new(&fit).normals_into(&heights, w, h, &mut normals)?;
            }
            normals
        }
    };
    let len = checked_len(w, h)?;
    if normals.len() != len {
        return Err(Error::BufferSize { expected: len, actual: normals.len() });
    }
    let mut lit = shade_with(&normals, lamp);
    let mut missing = 0;
    if let Some(valid) = &valid {
        for (g, _) in lit.iter_mut().zip(valid).filter(|(_, v)| !**v) {
            *g = 0;
            missing += 1;
        }
    }
    let (pixels, width, height) = if opts.tile { (tile_2x2(&lit, w, h)?, 2 * w, 2 * h) } else { (lit, w, h) };
    Ok(LitView { pixels, width, height, kind, warnings, georef, missing })
}

/// [`lit_view`] of the image at `path`.
///
/// Errors: those of [`io::read_path`] and [`lit_view`].
pub fn lit_view_of_file(path: &Path, read: &ReadOptions, opts: &LitOptions) -> Result<LitView> {
    lit_view_owned(io::read_path(path, read)?, opts)
}

/// What [`lit_file_streamed`] did.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct LitStreamed {
    /// Columns of the picture.
    pub width: usize,
    /// Rows of the picture.
    pub height: usize,
    /// The warning about a wrap that draws a seam, if any.
    pub warnings: Vec<Warning>,
    /// The georeferencing sidecars written beside the picture.
    pub sidecars: Vec<PathBuf>,
    /// Missing texels (grey 0), as [`LitView::missing`].
    pub missing: usize,
}

/// The lit view of the height map at `input`, written to the PNG file
/// `output` without holding the image, when it can stream: a TIFF band the
/// `tiff` crate reads (GeoTIFF elevation: float, signed or 32-bit
/// samples, or any TIFF with [`ReadOptions::band`]), fixed borders, not
/// tiled, not a normal map, no channel. `Ok(None)` otherwise, with nothing
/// written: [`lit_view_of_file`] then does it whole. The picture is
/// [`lit_view`]'s, grey for grey; the sidecars as [`LitView::write_file`]
/// writes them. Memory: a few bands of rows (see [`crate::pipeline`]).
///
/// Errors: those of reading the input and of the fit;
/// [`Error::InvalidOption`] if `output` is `input`; [`Error::Io`] when
/// writing fails (the output is then not there).
#[cfg(feature = "tiff")]
pub fn lit_file_streamed(
    input: &Path,
    read: &ReadOptions,
    opts: &LitOptions,
    output: &Path,
) -> Result<Option<LitStreamed>> {
    use crate::pipeline::{RowSource, TiffRows};
    let Ok(borders) = opts.borders.fixed() else { return Ok(None) };
    if opts.tile || opts.signed || opts.kind == KindChoice::Normal || opts.channel.is_some() {
        return Ok(None);
    }
    let Some(rows) = TiffRows::open(input, read, None)? else { return Ok(None) };
    if crate::convert::same_file(input, output) {
        return Err(Error::InvalidOption(
            "the output is the input (or a link to it): normalfit never writes over an input".into(),
        ));
    }
    let (width, height) = (rows.width(), rows.height());
    let georef = rows.georef().cloned();
    let lamp = opts.lamp(georef.as_ref());
    // Map units fit the samples as stored; a band the rows give in
    // contract units (signed and 32-bit integers: value / (2^bits − 1))
    // is given back its stored values, as `Raster::into_stored_heights`
    // does.
    let restore = opts.map_units.is_some() && rows.unit() == 1.0 && rows.sample().stored_per_unit() != 1.0;
    // The nodata value as the fit sees the rows: stored, or the rows' own.
    let nodata = holes_value(opts.fit.nodata, georef.as_ref());
    let nodata = nodata.map(|v| if restore { v } else { rows.row_value(v) });
    let fit = opts.fit_for(georef.as_ref(), height)?.with_borders(borders).with_nodata(nodata);
    let mut seams = if opts.borders.needs_check() { tiling::HeightSeams::new(width, height).ok() } else { None };
    let visit = |row: &[f32]| {
        if let Some(s) = seams.as_mut() {
            let _ = s.push_row(row);
        }
    };
    let mut missing = 0;
    let tiff = lit_format(output)? == OutputFormat::Tiff;
    // A TIFF is written in order: a wrap in y reads the last rows first.
    let tail = match (tiff, fit.borders.y) {
        (true, crate::Border::Wrap) => {
            let mut tail = TiffRows::last_rows(input, read, None, fit.patch / 2)?;
            if restore {
                StoredRows::new(TiffRows::open(input, read, None)?.ok_or_else(changed)?).restore(&mut tail);
            }
            Some(tail)
        }
        _ => None,
    };
    let tags = lit_tiff_tags(georef.as_ref());
    io::write_file_atomically(output, |file| {
        use crate::pipeline::{shade_png_seekable, shade_tiff};
        missing = match (tiff, restore) {
            (true, true) => shade_tiff(StoredRows::new(rows), tail.as_deref(), &fit, lamp, tags, visit, file)?,
            (true, false) => shade_tiff(rows, tail.as_deref(), &fit, lamp, tags, visit, file)?,
            (false, true) => shade_png_seekable(StoredRows::new(rows), &fit, lamp, visit, file)?,
            (false, false) => shade_png_seekable(rows, &fit, lamp, visit, file)?,
        };
        Ok(())
    })?;
    let mut warnings = Vec::new();
    if let Some(seams) = seams {
        let report = seams.finish(&TilingOptions::new().with_kind(KindChoice::Height))?;
        warnings.extend(opts.borders.seams(&report));
    }
    let sidecars = match (&georef, tiff) {
        (Some(georef), false) => io::sidecar::write_sidecars(output, georef)?,
        _ => Vec::new(),
    };
    Ok(Some(LitStreamed { width, height, warnings, sidecars, missing }))
}

/// Rows given in contract units (value / (2^bits − 1)) as the values
/// stored: each times 2^bits − 1, made whole again for integers of up to
/// 32 bits (the division's error is under 2⁻²⁰), exactly as
/// [`Raster::into_stored_heights`] computes them. For a fit in map units,
/// which takes the values as they are.
#[cfg(feature = "tiff")]
struct StoredRows<R> {
    rows: R,
    scale: f64,
    whole: bool,
}

#[cfg(feature = "tiff")]
impl StoredRows<crate::pipeline::TiffRows> {
    fn new(rows: crate::pipeline::TiffRows) -> Self {
        use crate::io::SampleType;
        let sample = rows.sample();
        let whole = matches!(sample, SampleType::Int { bits } | SampleType::SignedInt { bits } if bits <= 32);
        StoredRows { scale: sample.stored_per_unit(), whole, rows }
    }
}

#[cfg(feature = "tiff")]
impl<R> StoredRows<R> {
    /// Row values as the values stored.
    fn restore(&self, values: &mut [f64]) {
        let scale = self.scale;
        match self.whole {
            true => values.iter_mut().for_each(|v| *v = (*v * scale).round()),
            false => values.iter_mut().for_each(|v| *v *= scale),
        }
    }
}

/// The error of an input that no longer opens as it did.
#[cfg(feature = "tiff")]
fn changed() -> Error {
    Error::Io(std::io::Error::other("changed while being read"))
}

#[cfg(feature = "tiff")]
impl<R: crate::pipeline::RowSource> crate::pipeline::RowSource for StoredRows<R> {
    fn width(&self) -> usize {
        self.rows.width()
    }

    fn height(&self) -> usize {
        self.rows.height()
    }

    /// Only a fit in map units reads these rows, and it takes the values
    /// as they are; the tiling check's heights are then stored values too,
    /// as a whole image's are.
    fn unit(&self) -> f64 {
        1.0
    }

    fn next_row(&mut self, out: &mut [f64]) -> Result<()> {
        self.rows.next_row(out)?;
        self.restore(out);
        Ok(())
    }
}
