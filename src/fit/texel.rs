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
/// options, north-up axes and the GIS sun unless told otherwise.
#[derive(Clone, Copy, Debug)]
pub struct TexelFrame {
    pub(crate) axes: crate::units::MapAxes,
    pub(crate) convention: crate::options::Convention,
    pub(crate) lamp: crate::light::Lamp,
}

impl TexelFrame {
    /// North-up axes and the GIS sun, for a fit in `convention`.
    pub(crate) fn new(convention: crate::options::Convention) -> TexelFrame {
        let lamp = crate::light::Lamp::sun(crate::light::Sun::default(), None, convention);
        TexelFrame { axes: crate::units::MapAxes::NORTH_UP, convention, lamp }
    }
}
