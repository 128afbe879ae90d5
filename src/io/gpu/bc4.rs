//! BC4 blocks from floats: the one-channel block BC4 stores, and BC5 as
//! two of them (x, then y).
//!
//! A block holds two 8-bit endpoints and a 3-bit index per texel of its
//! 4 × 4 (Direct3D's BC4_UNORM; the Khronos Data Format Specification's
//! "BC4 unsigned"): with r0 > r1 the eight values r0, r1 and the six
//! evenly spaced between them, ((7 − i)·r0 + i·r1) / 7 for i = 1..6. The
//! values come in as code units, real numbers in [0, 255] (a normal's
//! component c is (c + 1) · 127.5, as the 8-bit encoding scales it before
//! it rounds), so the endpoints are chosen against the unrounded values:
//! the rounding of an 8-bit map first would be a second error on top of
//! the block's (docs/mips.md measures both).
//!
//! The rule the encoder follows: endpoints start at the block's extremes;
//! three rounds of assigning each value its nearest step of the ramp and
//! solving the two endpoints by least squares for those assignments (a
//! 2 × 2 system), rounded; then the eight integer neighbours of the best
//! pair; the pair of least squared error over every pair tried is kept.
//! The ramp's steps are evenly spaced, so a value's nearest step is a
//! rounding, not a search. Blocks of one integer code are stored as that
//! code with r0 = r1 (every index 0); the extremes start at the codes
//! below and above the values, so a block of one value between two codes
//! (a flat normal's x, 127.5) lies on the ramp between them. The six-value mode
//! (r0 ≤ r1: 0 and 255 beside four steps) is never written; it helps
//! blocks that hold both extremes and an interior cluster, which unit
//! normals' x and y almost never do.
//!
//! Self-contained (no other module of the crate), so the crate
//! comparison in `bench/gpu-crates/` compiles this very file.

/// Bytes of a BC4 block.
pub(crate) const BC4_BYTES: usize = 8;

/// The value of each of the eight positions along the ramp from `a`
/// (position 0) to `b` (position 7), as a decoder computes it in float.
#[cfg_attr(not(test), allow(dead_code))]
#[inline]
fn ramp(a: f32, b: f32, p: f32) -> f32 {
    (a * (7.0 - p) + b * p) / 7.0
}

/// 2²³: adding it to a float in [0, 2²²) and taking it away again leaves
/// the float rounded to the nearest integer (ties to even).
const ROUND: f32 = 8_388_608.0;

/// The nearest position of `t` on the ramp from `a` to `b`, given
/// `scale` = 7 / (b − a) (a ≠ b): a rounding, clamped to [0, 7]. Rounded
/// by the magic number in plain float operations, which vectorise where
/// `f32::round` is a library call on baseline x86-64.
#[inline(always)]
fn position(t: f32, a: f32, scale: f32) -> f32 {
    let p = ((t - a) * scale).clamp(0.0, 7.0);
    (p + ROUND) - ROUND
}

/// Squared error of the block's values against the ramp from `a` to `b`
/// (a ≠ b), each value at its nearest position; summed in four lanes.
fn error(values: &[f32; 16], a: f32, b: f32) -> f32 {
    let (scale, step) = (7.0 / (b - a), (b - a) / 7.0);
    let mut lanes = [0.0f32; 4];
    for quad in values.chunks_exact(4) {
        for (lane, &t) in lanes.iter_mut().zip(quad) {
            let d = t - (a + step * position(t, a, scale));
            *lane += d * d;
        }
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3])
}

/// The endpoints (a, b) that minimise the squared error of the values
/// against the ramp, with each value's position fixed at its nearest on
/// the ramp from `a` to `b`; `None` when every value sits at one end.
fn least_squares(values: &[f32; 16], a: f32, b: f32) -> Option<(f32, f32)> {
    // value ≈ a·(1 − w) + b·w with w = p / 7.
    let (mut aa, mut ab, mut bb, mut ta, mut tb) = (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0.0f32);
    let scale = 7.0 / (b - a);
    for &t in values {
        let w = position(t, a, scale) / 7.0;
        let v = 1.0 - w;
        aa += v * v;
        ab += v * w;
        bb += w * w;
        ta += t * v;
        tb += t * w;
    }
    let det = aa * bb - ab * ab;
    if det.abs() < 1e-6 {
        return None;
    }
    Some(((ta * bb - tb * ab) / det, (tb * aa - ta * ab) / det))
}

/// A code: `v` rounded into [0, 255].
#[inline]
fn code(v: f32) -> f32 {
    v.round().clamp(0.0, 255.0)
}

/// The BC4 block of 16 values in code units ([0, 255], row-major in the
/// block), by the module's rule.
pub(crate) fn encode_block(values: &[f32; 16]) -> [u8; BC4_BYTES] {
    let (lo, hi) = values.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    // The codes around the values: a block of one value between two codes
    // (a flat normal's 127.5) is stored on the ramp between them, within
    // a fourteenth of a code, not rounded by half a code.
    let (lo, hi) = (lo.floor().clamp(0.0, 255.0), hi.ceil().clamp(0.0, 255.0));
    if lo == hi {
        let c = lo as u8;
        return [c, c, 0, 0, 0, 0, 0, 0];
    }
    let mut best = (lo, hi, error(values, lo, hi));
    let (mut a, mut b) = (lo, hi);
    for _ in 0..3 {
        let Some((na, nb)) = least_squares(values, a, b) else { break };
        let (na, nb) = (code(na), code(nb));
        if na == nb || (na, nb) == (a, b) {
            break;
        }
        (a, b) = (na, nb);
        let e = error(values, a, b);
        if e < best.2 {
            best = (a, b, e);
        }
    }
    let (ba, bb) = (best.0, best.1);
    for da in [-1.0, 0.0, 1.0] {
        for db in [-1.0, 0.0, 1.0] {
            let (a, b) = (code(ba + da), code(bb + db));
            if a == b {
                continue;
            }
            let e = error(values, a, b);
            if e < best.2 {
                best = (a, b, e);
            }
        }
    }
    pack(values, best.0, best.1)
}

/// The block of the ramp from `a` to `b` (codes, a ≠ b), each value at its
/// nearest position: r0 the larger endpoint (the eight-value mode), index
/// 0 for r0, 1 for r1, i + 1 for the i-th step between.
fn pack(values: &[f32; 16], a: f32, b: f32) -> [u8; BC4_BYTES] {
    let (r0, r1) = if a > b { (a, b) } else { (b, a) };
    let mut bits = 0u64;
    let scale = 7.0 / (r1 - r0);
    for (i, &t) in values.iter().enumerate() {
        let p = position(t, r0, scale) as u64;
        let index = match p {
            0 => 0,
            7 => 1,
            p => p + 1,
        };
        bits |= index << (3 * i);
    }
    let mut block = [0u8; BC4_BYTES];
    block[0] = r0 as u8;
    block[1] = r1 as u8;
    block[2..].copy_from_slice(&bits.to_le_bytes()[..6]);
    block
}

/// The 16 values of a BC4 block, in code units, as Direct3D's decoder
/// gives them in float (the eight- and the six-value modes): for the
/// tests, and the crate comparison in `bench/gpu-crates/`.
#[cfg_attr(not(test), allow(dead_code))]
pub(crate) fn decode_block(block: &[u8; BC4_BYTES]) -> [f32; 16] {
    let (r0, r1) = (f32::from(block[0]), f32::from(block[1]));
    let mut palette = [r0, r1, 0.0, 0.0, 0.0, 0.0, 0.0, 255.0];
    if r0 > r1 {
        for i in 1..7 {
            palette[i + 1] = ramp(r0, r1, i as f32);
        }
    } else {
        for i in 1..5 {
            palette[i + 1] = (r0 * (5 - i) as f32 + r1 * i as f32) / 5.0;
        }
    }
    let mut raw = [0u8; 8];
    raw[..6].copy_from_slice(&block[2..]);
    let bits = u64::from_le_bytes(raw);
    std::array::from_fn(|i| palette[((bits >> (3 * i)) & 7) as usize])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plain reference: every pair of integer endpoints, each value at
    /// its nearest of the eight.
    fn best_possible(values: &[f32; 16]) -> f32 {
        let mut best = f32::INFINITY;
        for a in 0..256 {
            for b in 0..a {
                let (a, b) = (a as f32, b as f32);
                let e: f32 = values
                    .iter()
                    .map(|&t| (0..8).map(|p| (t - ramp(a, b, p as f32)).powi(2)).fold(f32::INFINITY, f32::min))
                    .sum();
                best = best.min(e);
            }
        }
        best
    }

    fn pseudo_random(seed: u32) -> impl FnMut() -> f32 {
        let mut s = seed;
        move || {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1u32 << 24) as f32
        }
    }

    #[test]
    fn decodes_what_it_encodes_within_the_step() {
        let mut next = pseudo_random(7);
        for _ in 0..200 {
            let (centre, spread) = (next() * 255.0, next() * 60.0);
            let values: [f32; 16] = std::array::from_fn(|_| (centre + (next() - 0.5) * spread).clamp(0.0, 255.0));
            let decoded = decode_block(&encode_block(&values));
            let (lo, hi) = values.iter().fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
            // Each value within half a step of the ramp spanning the
            // block, plus the endpoints' rounding.
            let bound = (hi - lo) / 14.0 + 1.0;
            for (t, d) in values.iter().zip(decoded) {
                assert!((t - d).abs() <= bound, "{t} decoded {d}, bound {bound}");
            }
        }
    }

    #[test]
    fn close_to_the_best_pair_of_endpoints() {
        let mut next = pseudo_random(11);
        let (mut ours, mut best) = (0.0, 0.0);
        for _ in 0..40 {
            let (centre, spread) = (30.0 + next() * 195.0, next() * 50.0);
            let values: [f32; 16] = std::array::from_fn(|_| centre + (next() - 0.5) * spread);
            let decoded = decode_block(&encode_block(&values));
            ours += values.iter().zip(decoded).map(|(t, d)| (t - d).powi(2)).sum::<f32>();
            best += best_possible(&values);
        }
        // Within 10 % of the exhaustive search's squared error.
        assert!(ours <= best * 1.1 + 1e-3, "squared error {ours}, best possible {best}");
    }

    #[test]
    fn a_constant_block_is_exact_or_within_a_fourteenth() {
        for v in [0.0, 128.0, 255.0] {
            let decoded = decode_block(&encode_block(&[v; 16]));
            assert!(decoded.iter().all(|&d| d == v), "{v}: {decoded:?}");
        }
        // Between two codes: on the ramp between them.
        for v in [0.4, 127.5, 200.2, 254.9] {
            let decoded = decode_block(&encode_block(&[v; 16]));
            assert!(decoded.iter().all(|&d| (d - v).abs() <= 1.0 / 14.0 + 1e-4), "{v}: {decoded:?}");
        }
    }

    #[test]
    fn indices_land_on_their_texels() {
        // A ramp across the block: texel i's value grows with i.
        let values: [f32; 16] = std::array::from_fn(|i| i as f32 * 17.0);
        let decoded = decode_block(&encode_block(&values));
        for (i, pair) in decoded.windows(2).enumerate() {
            assert!(pair[0] <= pair[1], "texel {i}: {decoded:?}");
        }
        assert!((decoded[0] - 0.0).abs() <= 9.0 && (decoded[15] - 255.0).abs() <= 9.0, "{decoded:?}");
    }
}
