//! The texels the fit makes, inside the crate ([`Texel`]), and the frame
//! some of them are made in ([`TexelFrame`]). Public in name only, in a
//! private module: [`super::Heights`]' hidden methods take them.

use super::FromNormal;

/// What the fit makes at each texel: every
/// [`FromNormal`] type, and the texels that need the map's frame beside
/// the normal (an aspect: the raster's axes and the convention; a
/// hillshade: the lamp), made in the fit's loop from [`TexelFrame`] rather
/// than from a band of normals stored and read back.
pub trait Texel: Copy + Send + Sync {
    /// [`FromNormal::UNIT`].
    const UNIT: bool = true;
    /// The texel of normal `n` (as [`FromNormal::from_normal`] takes it)
    /// in `frame`.
    fn make(n: [f64; 3], frame: &TexelFrame) -> Self;
}

impl<T: FromNormal> Texel for T {
    const UNIT: bool = T::UNIT;
    #[inline(always)]
    fn make(n: [f64; 3], _: &TexelFrame) -> Self {
        T::from_normal(n)
    }
}

/// Where a fit's normals lie on the map, for the texels that need it
/// ([`Texel`]): the raster's axes (from its geotransform), the fit's
/// convention (which way the normal's y points) and the lamp of a lit
/// view. [`FitRequest`] and [`BandFit`] take the convention from their
/// options, north-up axes and a lamp overhead unless told otherwise.
#[derive(Clone, Copy, Debug)]
pub struct TexelFrame {
    pub(crate) axes: MapAxes,
    pub(crate) convention: crate::options::Convention,
    pub(crate) lamp: Lamp,
}

impl TexelFrame {
    /// North-up axes and a lamp overhead, for a fit in `convention`: a lit
    /// view sets its own lamp (`lit`) before any grey is made.
    pub(crate) fn new(convention: crate::options::Convention) -> TexelFrame {
        TexelFrame { axes: MapAxes::NORTH_UP, convention, lamp: Lamp::OVERHEAD }
    }
}

/// Where a raster's axes point on the map: the map directions (east,
/// north), each made unit, of a column step (a, d) and of a step up the
/// image (−b, −e), as GDAL's geotransform places them. A normal's +x runs
/// along a row and its +y (OpenGL's) up the image, so these turn a normal
/// into the map's east and north: row 0 is north on the usual north-up
/// raster (e < 0) and south on a south-up one (e > 0), whose aspect and
/// sun would otherwise come out mirrored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MapAxes {
    /// (east, north) of a column step.
    pub(crate) x: (f64, f64),
    /// (east, north) of a step up the image.
    pub(crate) up: (f64, f64),
}

impl MapAxes {
    /// A north-up raster's, and a raster's without georeferencing.
    pub(crate) const NORTH_UP: MapAxes = MapAxes { x: (1.0, 0.0), up: (0.0, 1.0) };

    /// The axes of a raster placed by `affine` (none: north-up).
    pub(crate) fn of(affine: Option<&crate::io::Affine>) -> MapAxes {
        let unit = |x: f64, y: f64| {
            let l = x.hypot(y);
            if l > 0.0 && l.is_finite() { (x / l, y / l) } else { (0.0, 0.0) }
        };
        match affine {
            Some(t) => MapAxes { x: unit(t.a, t.d), up: unit(-t.b, -t.e) },
            None => MapAxes::NORTH_UP,
        }
    }
}

/// A light resolved for one image: its direction in the fit's frame
/// (DirectX's y already flipped) and how n · L becomes a grey.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lamp {
    pub(crate) direction: [f64; 3],
    /// gdaldem's scale (1 + 254 · cos) rather than the texture view's
    /// ambient share.
    pub(crate) gis: bool,
}

impl Lamp {
    /// Light straight down the normal's z, the texture view's scale: the
    /// frame's lamp until a lit view gives its own (the light's rules, a
    /// sun's placing among them, are `crate::light`'s, a layer above).
    pub(crate) const OVERHEAD: Lamp = Lamp { direction: [0.0, 0.0, 1.0], gis: false };
}
