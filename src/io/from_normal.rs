//! The texels the fit makes straight from a unit normal ([`FromNormal`]):
//! the normal itself, or the contract's RGB encoding c = (n + 1)/2 rounded
//! to 8 or 16 bits (SPEC §3). The fit writes them; every writer stores them.

/// A type an output texel can be made from a unit normal.
///
/// Implemented for `[f32; 3]` (the normal n itself, components in [−1, 1])
/// and for `[u8; 3]` / `[u16; 3]` (the contract's RGB encoding
/// c = (n + 1)/2, rounded). Writing texels straight from the fit saves a
/// pass and a float copy of the image.
pub trait FromNormal: Copy + Send + Sync {
    /// Whether the texel needs the normal at unit length. A texel made of
    /// ratios of its components (a slope: √(x² + y²) / z) takes any
    /// positive multiple of it, and the square grid's fit then hands it
    /// the plane's (−Cx, −Cy, n_z) as they are: a square root, a division
    /// and three products a texel saved (see `emit::normal_from_sums`).
    const UNIT: bool = true;
    /// Makes the texel from the normal's (x, y, z), a unit vector with z ≥ 0
    /// (with [`Self::UNIT`] false, a positive multiple of one).
    fn from_normal(n: [f64; 3]) -> Self;
}

impl FromNormal for [f32; 3] {
    #[inline(always)]
    fn from_normal(n: [f64; 3]) -> Self {
        [n[0] as f32, n[1] as f32, n[2] as f32]
    }
}

/// The normal itself, in f64.
impl FromNormal for [f64; 3] {
    #[inline(always)]
    fn from_normal(n: [f64; 3]) -> Self {
        n
    }
}

/// 2⁵²: adding it to an x in [0, 2⁵²) leaves round(x) (to nearest, ties
/// to even) in the low bits of the sum's mantissa.
const ROUND_MAGIC: f64 = 4_503_599_627_370_496.0;

// Rounding by the magic number, in plain float and integer instructions
// that vectorise, where `f64::round` is a library call on baseline x86-64
// and a saturating `as` cast is a chain of compares. The scaled value
// (n + 1) · (2^bits − 1) / 2 lies in [0, 2^bits − 1] for |n| ≤ 1; its ties
// (x.5 exactly) fall only at n = 0, where nearest-even gives 128 and 32768,
// as rounding half up does.
impl FromNormal for [u8; 3] {
    #[inline(always)]
    fn from_normal(n: [f64; 3]) -> Self {
        n.map(|c| ((c + 1.0) * 127.5 + ROUND_MAGIC).to_bits() as u8)
    }
}

impl FromNormal for [u16; 3] {
    #[inline(always)]
    fn from_normal(n: [f64; 3]) -> Self {
        n.map(|c| ((c + 1.0) * 32767.5 + ROUND_MAGIC).to_bits() as u16)
    }
}
