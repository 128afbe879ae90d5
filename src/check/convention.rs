//! A normal map's green convention, guessed from its own curl.
//!
//! A normal map of a surface holds that surface's slopes, gx = −nx/nz and
//! gy = −σ·ny/nz (σ = −1 OpenGL, +1 DirectX: SPEC §2), and a slope field
//! has no curl: the ∮ of the slopes round every loop is 0. Read with the
//! wrong σ, the green slope changes sign and the loops' ∮ becomes about as
//! large as the slopes' variation. The guess is the σ with the smaller
//! relative residual, the idea behind `height --convention auto`
//! ([`crate::height::ConventionChoice::Auto`]), measured here round the
//! loops of 2 × 2 texels (so both derivatives are taken at the loop's
//! centre, which sharp edges need):
//!
//! ```text
//! ∮ = ½(gx(x,y) + gx(x+1,y)) + ½(gy(x+1,y) + gy(x+1,y+1))
//!   − ½(gx(x,y+1) + gx(x+1,y+1)) − ½(gy(x,y) + gy(x,y+1))  =  P + σ·Q
//! curl(σ) = Σ (P + σQ)² / Σ (P² + Q²)          (curl(−1) + curl(+1) = 2)
//! ```
//!
//! over the loops inside the image (the wrap is not used, so seams do not
//! count), at the scales of [`SCALES`]: the slopes averaged over blocks of
//! k × k texels (a mean of a slope field is a slope field), where a map's
//! noise and its rounding weigh less against its relief. The scale that
//! tells the two apart best (the largest confidence, among scales with at
//! least [`MIN_PAIRS`] loops) gives the guess.
//!
//! # Confidence
//!
//! ρ = min / max of the two residuals: 0 for an exact slope field, about 1
//! where the map cannot tell (a flat map, noise, a map whose green or red
//! is constant, 8-bit rounding larger than the relief). The confidence is
//! 1 − ρ, and the guess is *confident* when ρ ≤ [`CONFIDENT_RATIO`] over
//! at least [`MIN_PAIRS`] loops. docs/check.md gives the figures of the
//! maps of `../shared/data`; a guess that is not confident is still given,
//! and says so.

use crate::Convention;
use crate::error::Result;
use crate::par::prelude::*;
use crate::samples::try_filled;

/// The largest ratio of the smaller residual to the larger at which the
/// guess is confident.
pub const CONFIDENT_RATIO: f64 = 0.5;

/// The fewest loops (cells of 2 × 2 texels, at the scale chosen) for a
/// confident guess: below it, noise alone can make one residual half the
/// other.
pub const MIN_PAIRS: usize = 4096;

/// The scales (block sides, in texels) the loops are measured at.
pub const SCALES: [usize; 4] = [1, 2, 4, 8];

/// The guess of a normal map's green convention.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct ConventionGuess {
    /// The convention whose slopes have the smaller residual (OpenGL when
    /// they tie).
    #[cfg_attr(feature = "serde", serde(serialize_with = "convention_name"))]
    pub convention: Convention,
    /// Whether the guess can be relied on (see the module docs).
    pub confident: bool,
    /// 1 − ρ, ρ the smaller residual over the larger (0 where both are 0).
    pub confidence: f64,
    /// The relative residual read as OpenGL, then as DirectX, at the scale
    /// chosen (they add up to 2, or are both 0).
    pub curl: [f64; 2],
    /// The scale chosen: the side of the blocks of texels whose mean slopes
    /// the loops run through.
    pub scale: usize,
}

#[cfg(feature = "serde")]
fn convention_name<S: serde::Serializer>(c: &Convention, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(c.name())
}

impl ConventionGuess {
    /// The guess from the two residuals (OpenGL's, DirectX's) measured over
    /// `loops` loops at `scale`.
    #[must_use]
    pub fn from_curl(curl: [f64; 2], loops: usize, scale: usize) -> ConventionGuess {
        let [gl, dx] = curl;
        let convention = if gl <= dx { Convention::OpenGl } else { Convention::DirectX };
        let (lo, hi) = (gl.min(dx), gl.max(dx));
        let ratio = if hi > 0.0 { lo / hi } else { 1.0 };
        ConventionGuess {
            convention,
            confident: ratio <= CONFIDENT_RATIO && loops >= MIN_PAIRS,
            confidence: 1.0 - ratio,
            curl,
            scale,
        }
    }
}

/// The slopes (−nx/nz, −ny/nz) of a normal, 0 where nz ≤ 0 or a component
/// is not finite (as the height inverse reads them).
#[inline]
fn slope(n: [f64; 3]) -> [f64; 2] {
    let [x, y, z] = n;
    if x.is_finite() && y.is_finite() && z.is_finite() && z > 0.0 { [-x / z, -y / z] } else { [0.0, 0.0] }
}

/// The loops' sums at one scale: Σ P², Σ Q², Σ P·Q and the loop count,
/// where the ∮ of a cell is P + σ·Q.
fn loop_sums(sx: &[f64], sy: &[f64], w: usize, h: usize) -> ([f64; 3], usize) {
    let rows: Vec<[f64; 3]> = (0..h.saturating_sub(1))
        .into_par_iter()
        .map(|y| {
            let (a, b) = (y * w, (y + 1) * w);
            let mut sums = [0.0; 3];
            for x in 0..w.saturating_sub(1) {
                // Counter-clockwise in (x, y): along row y, down column x + 1,
                // back along row y + 1, up column x; trapezoids on each edge.
                let p = 0.5 * (sx[a + x] + sx[a + x + 1]) - 0.5 * (sx[b + x] + sx[b + x + 1]);
                let q = 0.5 * (sy[a + x + 1] + sy[b + x + 1]) - 0.5 * (sy[a + x] + sy[b + x]);
                sums[0] += p * p;
                sums[1] += q * q;
                sums[2] += p * q;
            }
            sums
        })
        .collect();
    let total = rows.iter().fold([0.0; 3], |s, r| [s[0] + r[0], s[1] + r[1], s[2] + r[2]]);
    (total, w.saturating_sub(1) * h.saturating_sub(1))
}

/// Slopes averaged over blocks of `k` × `k` texels (the last partial
/// blocks left out).
fn blocks(s: &[f64], w: usize, h: usize, k: usize) -> (Vec<f64>, usize, usize) {
    let (bw, bh) = (w / k, h / k);
    let mut out = vec![0.0; bw * bh];
    out.par_chunks_mut(bw.max(1)).enumerate().for_each(|(by, row)| {
        for (bx, o) in row.iter_mut().enumerate() {
            let mut sum = 0.0;
            for y in by * k..(by + 1) * k {
                sum += s[y * w + bx * k..][..k].iter().sum::<f64>();
            }
            *o = sum / (k * k) as f64;
        }
    });
    (out, bw, bh)
}

/// Guesses the convention of the normals `row(y, out)` gives (`width`
/// normals a row, n itself, any length; texels with nz ≤ 0 or a
/// non-finite component count as flat).
///
/// Errors: [`crate::Error::InvalidOption`] for a zero size,
/// [`crate::Error::Limits`] when the memory (16 bytes a texel) is not there.
pub fn guess_rows(
    row: &(dyn Fn(usize, &mut [[f64; 3]]) + Sync),
    width: usize,
    height: usize,
) -> Result<ConventionGuess> {
    let len = crate::fit::checked_len(width, height)?;
    crate::memory::check_memory("the convention's guess", (len as u64).saturating_mul(24))?;
    let (mut sx, mut sy) = (try_filled(len, 0.0)?, try_filled(len, 0.0)?);
    sx.par_chunks_mut(width).zip(sy.par_chunks_mut(width)).enumerate().for_each(|(y, (rx, ry))| {
        let mut normals = vec![[0.0; 3]; width];
        row(y, &mut normals);
        for ((n, gx), gy) in normals.into_iter().zip(rx).zip(ry) {
            [*gx, *gy] = slope(n);
        }
    });
    let mut best: Option<ConventionGuess> = None;
    for k in SCALES {
        let (bx, w, h) = if k == 1 { (Vec::new(), width, height) } else { blocks(&sx, width, height, k) };
        let (by, _, _) = if k == 1 { (Vec::new(), 0, 0) } else { blocks(&sy, width, height, k) };
        let (px, py) = if k == 1 { (&sx[..], &sy[..]) } else { (&bx[..], &by[..]) };
        let ([pp, qq, pq], loops) = loop_sums(px, py, w, h);
        let norm = pp + qq;
        // Σ (P + σQ)² / Σ (P² + Q²) for σ = −1 (OpenGL) and +1 (DirectX).
        let curl = if norm > 0.0 { [1.0 - 2.0 * pq / norm, 1.0 + 2.0 * pq / norm] } else { [0.0, 0.0] };
        let guess = ConventionGuess::from_curl(curl, loops, k);
        // The scale that tells the conventions apart best, among those with
        // loops enough; the finest when none has.
        let better = match best {
            None => true,
            Some(b) => (guess.confident && !b.confident) || (loops >= MIN_PAIRS && guess.confidence > b.confidence),
        };
        if better {
            best = Some(guess);
        }
        if loops < MIN_PAIRS {
            break;
        }
    }
    Ok(best.unwrap_or_else(|| ConventionGuess::from_curl([0.0, 0.0], 0, 1)))
}
/// [`guess_rows`] of normals given row-major, `width * height` of them.
///
/// Errors: [`crate::Error::BufferSize`] for a buffer of another length;
/// those of [`guess_rows`].
pub fn guess<T: crate::height::NormalComponent>(
    normals: &[[T; 3]],
    width: usize,
    height: usize,
) -> Result<ConventionGuess> {
    let len = crate::fit::checked_len(width, height)?;
    if normals.len() != len {
        return Err(crate::Error::BufferSize { expected: len, actual: normals.len() });
    }
    let row = |y: usize, out: &mut [[f64; 3]]| {
        for (o, n) in out.iter_mut().zip(&normals[y * width..][..width]) {
            *o = n.map(T::to_f64);
        }
    };
    guess_rows(&row, width, height)
}
