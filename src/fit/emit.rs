//! From a texel's window sums to its normal: the closed forms of the
//! square grid, written without branches so that a row of them
//! vectorises, and the texels made from the normals.

use super::unequal::UnequalRow;
use super::{Texel, TexelFrame};

/// The summed squared distance of the patch's points from the fitted
/// plane, from the patch sums. The scatter matrix of the points is
/// [[A, 0, Cx], [0, A, Cy], [Cx, Cy, Czz]]; with t² = Cx² + Cy², the
/// product of its two eigenvalues in the (tilt, z) plane is A·Czz − t².
///
/// * orthogonal: the smallest eigenvalue λ = (A·Czz − t²) / λmax, with
///   λmax = (A + Czz)/2 + √(d² + t²) ≥ A > 0: the product over the largest
///   one, which does not cancel as (A + Czz)/2 − √(…) would on a near-planar
///   patch;
/// * vertical: Czz − t²/A = (A·Czz − t²) / A, the residual sum of squares
///   of ordinary least squares (the design is orthogonal: ΣiΣj = 0);
/// * a flat patch (see [`normal_from_sums`]) has the horizontal plane,
///   at summed squared distance Czz.
#[inline(always)]
pub(super) fn squared_distance_sum<const ORTHOGONAL: bool>(a: f64, cx: f64, cy: f64, czz: f64) -> f64 {
    let tilt2 = cx * cx + cy * cy;
    let flat = tilt2 <= 1e-20 * (a + czz) * (a + czz);
    let largest = if ORTHOGONAL {
        let d = 0.5 * (a - czz);
        0.5 * (a + czz) + (d * d + tilt2).sqrt()
    } else {
        a
    };
    let tilted = (a * czz - tilt2).max(0.0) / largest;
    if flat { czz } else { tilted }
}

/// The fitted plane's unit normal from the patch sums (see the module
/// docs), written without branches: every case is computed and the right
/// one selected, so that a loop of it vectorises. The unused
/// cases may divide by zero; their values are discarded.
///
/// `STEEP`: some patch of the loop may have Czz > A (d < 0), the case that
/// divides; without it, d ≥ 0 is taken as given. `unit` false: the
/// normal (−Cx, −Cy, n_z) as it is, not divided by its length, for the
/// texels made of its ratios ([`super::FromNormal::UNIT`]); a constant where it
/// is inlined, so the loop has no branch for it.
#[inline(always)]
pub(super) fn normal_from_sums<const ORTHOGONAL: bool, const STEEP: bool>(
    a: f64,
    cx: f64,
    cy: f64,
    czz: f64,
    unit: bool,
) -> [f64; 3] {
    let tilt2 = cx * cx + cy * cy;
    let flat = tilt2 <= 1e-20 * (a + czz) * (a + czz);
    let nz = if ORTHOGONAL {
        let d = 0.5 * (a - czz);
        let q = (d * d + tilt2).sqrt();
        if STEEP {
            let sloped = tilt2 / (q - d);
            if d >= 0.0 { d + q } else { sloped }
        } else {
            d + q
        }
    } else {
        a
    };
    let n = if unit {
        let inv = 1.0 / (tilt2 + nz * nz).sqrt();
        [-cx * inv, -cy * inv, nz * inv]
    } else {
        [-cx, -cy, nz]
    };
    if flat { [0.0, 0.0, 1.0] } else { n }
}

/// The texels of a row's normals (x, y and z planes).
#[inline(always)]
pub(super) fn store_normals<T: Texel>([nx, ny, nz]: &[Vec<f64>; 3], frame: &TexelFrame, out: &mut [T]) {
    // A copy of its own, which the texels' stores cannot alias: the loop
    // keeps it in registers and vectorises (through the plan, a grey's
    // loop reloaded the lamp after every byte stored, one texel at a time).
    let frame = *frame;
    for (((texel, &x), &y), &z) in out.iter_mut().zip(nx.iter()).zip(ny.iter()).zip(nz.iter()) {
        *texel = T::make([x, y, z], &frame);
    }
}

/// A strip's planes for turning window sums into texels, kept from row
/// to row: the normals' x, y and z planes, and the unequal spacing's.
pub(super) struct EmitScratch {
    pub(super) normal: [Vec<f64>; 3],
    pub(super) unequal: UnequalRow,
}

impl EmitScratch {
    pub(super) fn new(width: usize) -> Self {
        EmitScratch { normal: [vec![0.0; width], vec![0.0; width], vec![0.0; width]], unequal: UnequalRow::default() }
    }
}
