//! The smallest eigenvector of a patch's scatter matrix where its rows
//! and columns are spaced unequally (the masked fit's, after a rotation,
//! and the unequal spacing's): Newton's steps on its characteristic
//! polynomial, each a function without branches that the row loops of
//! `masked` and `unequal` run over planes; and the per-patch statement of
//! that arithmetic (`smallest_eigen`, `unequal_normal`) their tests
//! hold them to. Pure functions of numbers: nothing here knows the fit.

/// Whether a patch has no tilt, up to rounding: Cx² + Cy² ≤ 1e-20 ·
/// (A + Czz)², the contract's rule (lengths in x spacings).
#[inline(always)]
pub(super) fn is_flat(a: f64, cx: f64, cy: f64, czz: f64) -> bool {
    cx * cx + cy * cy <= 1e-20 * (a + czz) * (a + czz)
}

/// The unit normal of a patch whose rows are ρ x-spacings apart (ρ ≠ 1),
/// lengths in x spacings, from its sums (A, Cx, Cy as on the square grid,
/// Czz; see the fit's module docs). The points are (i, ρ·σ·j, z), so the scatter
/// matrix is
///
/// ```text
/// [[A, 0, Cx], [0, ρ²A, ρCy], [Cx, ρCy, Czz]]
/// ```
///
/// * vertical: ordinary least squares, z = gx·u + gy·v with gx = Cx / A,
///   gy = ρCy / (ρ²A): n ∝ (−Cx, −Cy/ρ, A);
/// * orthogonal: the eigenvector of the smallest eigenvalue
///   ([`smallest_eigen`]), n_z ≥ 0. The spacing is in the moments: the
///   plane minimises perpendicular distances in real-world lengths, which
///   no scaling of the square-grid normal gives.
/// * a patch flat by [`is_flat`]: (0, 0, 1).
///
/// Patch by patch, with branches: the statement of the arithmetic that
/// `unequal`'s loops over a row's planes run, in the same order, for the
/// same bits (its tests hold them to it).
#[cfg(test)]
pub(super) fn unequal_normal(orthogonal: bool, a: f64, rho: f64, cx: f64, cy: f64, czz: f64) -> [f64; 3] {
    if is_flat(a, cx, cy, czz) {
        return [0.0, 0.0, 1.0];
    }
    let n = if orthogonal { smallest_eigen(a, rho * rho * a, cx, rho * cy, czz).1 } else { [-cx, -cy / rho, a] };
    let inv = 1.0 / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    n.map(|c| c * inv)
}

/// The smallest eigenvalue λ of the scatter matrix M = [[a1, 0, b1],
/// [0, a2, b2], [b1, b2, c]] (a1, a2 > 0, M positive semi-definite), and
/// an eigenvector of it (not normalised) with a non-negative z (with z = 0
/// up to rounding: z = 0, a non-negative y, then x).
///
/// λ is the smallest root of p(λ) = det(M − λI) =
/// (a1 − λ)(a2 − λ)(c − λ) − b1²(a2 − λ) − b2²(a1 − λ). Left of that root
/// p is positive, decreasing and convex (p'' changes sign only at the mean
/// eigenvalue), so Newton's steps from any point left of it rise to it
/// without overshooting. The start is a lower bound ([`eigen_start`]).
/// The eigenvector is
/// the longest cross product of two rows of M − λI (the first two rows'
/// is (−b1(a2 − λ), −b2(a1 − λ), (a1 − λ)(a2 − λ)), the normal of the
/// square grid's formula when a1 = a2; the others take over when λ meets
/// a1 or a2, a patch whose flattest direction is horizontal).
///
/// Patch by patch: the fit runs these steps over planes of patches
/// (`unequal` and `masked`, through [`eigen_start`], [`newton_step`] and
/// [`eigenvector`]), with the same bits.
#[cfg(test)]
pub(super) fn smallest_eigen(a1: f64, a2: f64, b1: f64, b2: f64, c: f64) -> (f64, [f64; 3]) {
    let (mut lambda, scale, settled) = eigen_start(a1, a2, b1, b2, c);
    for _ in 0..NEWTON_STEPS * usize::from(!settled) {
        let (next, more) = newton_step([a1, a2, b1, b2, c], scale, lambda);
        lambda = next;
        if !more {
            break;
        }
    }
    (lambda, eigenvector([a1, a2, b1, b2, c], lambda))
}

/// Newton's steps [`smallest_eigen`] takes at most.
pub(super) const NEWTON_STEPS: usize = 200;

/// [`smallest_eigen`]'s start: a lower bound λ₀ of λ, the scale of M its
/// steps are measured against, and whether λ₀ is λ already (by the rule
/// of [`settled`]: no step need be taken).
///
/// One Newton step from above: the Rayleigh quotient r of the vertical
/// fit's normal (−b1/a1, −b2/a2, 1), r = (c − b1²/a1 − b2²/a2) /
/// (1 + (b1/a1)² + (b2/a2)²), is at least λ and, as the two fits' normals
/// are close, within the square of their angle of it. Where r is at most
/// the mean eigenvalue (a1 + a2 + c)/3, p is convex on (−∞, r]
/// (p'' = 2(a1 + a2 + c) − 6λ), so where p(r) ≤ 0 and p'(r) < 0 the
/// tangent at r meets zero at or below λ, and its square of r's error
/// away. Newton's steps then rise from there to λ, one or two. Elsewhere
/// (rough patches, whose r is far above λ) they rise from 0, a lower
/// bound of every positive semi-definite M's λ (the closed form of the
/// square grid with both a's replaced by min(a1, a2), a closer bound, cost
/// a square root and a division a patch, which a shaded geographic DEM
/// felt: `perf`).
#[inline(always)]
pub(super) fn eigen_start(a1: f64, a2: f64, b1: f64, b2: f64, c: f64) -> (f64, f64, bool) {
    eigen_start_on(Diagonal::new(a1, a2), b1, b2, c)
}

/// What [`eigen_start`] computes from a1 and a2 alone: the same for every
/// patch of a row of unequal spacing, whose loop forms it once (a
/// division a texel less) by the same operations, so with the same bits.
#[derive(Clone, Copy)]
pub(super) struct Diagonal {
    a1: f64,
    a2: f64,
    /// a1 + a2 and 1 / (a1·a2).
    sum: f64,
    inv: f64,
}

impl Diagonal {
    #[inline(always)]
    pub(super) fn new(a1: f64, a2: f64) -> Diagonal {
        Diagonal { a1, a2, sum: a1 + a2, inv: 1.0 / (a1 * a2) }
    }
}

/// [`eigen_start`] with its diagonal's constants formed.
// The conditions negated rather than flipped: a NaN takes the first bound.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
pub(super) fn eigen_start_on(Diagonal { a1, a2, sum, inv }: Diagonal, b1: f64, b2: f64, c: f64) -> (f64, f64, bool) {
    let tilt2 = b1 * b1 + b2 * b2;
    // M is positive semi-definite: λ ≥ 0.
    let bound = 0.0;
    // a1 + a2 + c, as it reads: (a1 + a2) + c.
    let trace = sum + c;
    let (g1, g2) = (b1 * a2 * inv, b2 * a1 * inv);
    let r = (c - b1 * g1 - b2 * g2) / (1.0 + g1 * g1 + g2 * g2);
    let (p1, p2, p3) = (a1 - r, a2 - r, c - r);
    let p = p1 * p2 * p3 - b1 * b1 * p2 - b2 * b2 * p1;
    let slope = tilt2 - (p2 * p3 + p1 * p3 + p1 * p2);
    let below = r - p / slope;
    let tangent = !(p > 0.0) & !(slope >= 0.0) & !(3.0 * r > trace) & !(below <= bound);
    // The tangent from r is a Newton step from above: what it leaves is at
    // most p''·(r − below)² / (2|p'(r)|) (p'' is largest at `below`, and
    // |p'| is smallest at r on [below, r]), the rule `newton_step` stops by.
    let settled = settled(trace, below, r - below, slope);
    (select(tangent, below, bound), trace, tangent & settled)
}

/// Whether a Newton step of `step` from λ, where p' = `slope` < 0, left
/// λ within 1e-17 of the scale of the root: by Taylor, the next step would
/// be at most p''(λ)·step² / (2|p'|), p'' = 2·trace − 6λ its largest on
/// the way up. Quadratic convergence: a step of 1e-9 of the scale leaves
/// 1e-18, so the step that only confirms the root is not taken.
// Negated rather than flipped: a NaN is not settled.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
fn settled(trace: f64, lambda: f64, step: f64, slope: f64) -> bool {
    !(step * step * (2.0 * trace - 6.0 * lambda) > -2e-17 * trace * slope)
}

/// One of [`smallest_eigen`]'s Newton steps from λ, without branches (the
/// masked fit runs it over arrays of patches): the next λ, and whether
/// to step again. It stays at λ once p(λ) ≤ 0, the slope is not
/// negative or the step does not rise, and stops after a step below
/// 1e-17 of the scale.
// The stops negated rather than the comparisons flipped: a NaN steps on.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
pub(super) fn newton_step([a1, a2, b1, b2, c]: [f64; 5], scale: f64, lambda: f64) -> (f64, bool) {
    let (p1, p2, p3) = (a1 - lambda, a2 - lambda, c - lambda);
    let p = p1 * p2 * p3 - b1 * b1 * p2 - b2 * b2 * p1;
    let slope = b1 * b1 + b2 * b2 - (p2 * p3 + p1 * p3 + p1 * p2);
    let next = lambda - p / slope;
    let rises = !(p <= 0.0) & !(slope >= 0.0) & !(next <= lambda);
    let step = next - lambda;
    (if rises { next } else { lambda }, rises & !(step <= 1e-17 * scale) & !settled(scale, lambda, step, slope))
}

/// [`smallest_eigen`]'s eigenvector for its λ, without branches: the
/// first rows' cross product where λ is below half the smaller of a1 and
/// a2 (`near_plane`: nearly every patch of a terrain), else the longest
/// of three cross products (`any_plane`).
#[inline(always)]
pub(super) fn eigenvector(matrix: [f64; 5], lambda: f64) -> [f64; 3] {
    let near = near_plane(matrix, lambda);
    let any = any_plane(matrix, lambda);
    let take = is_near_plane(matrix, lambda);
    [0, 1, 2].map(|i| select(take, near[i], any[i]))
}

/// Whether λ is below half the smaller of a1 and a2: then
/// (a1 − λ)(a2 − λ) ≥ a1·a2 / 4, and the first two rows' cross product,
/// (−b1(a2 − λ), −b2(a1 − λ), (a1 − λ)(a2 − λ)), has a z that is no
/// rounding's, positive: it is the eigenvector, as accurate as λ (its
/// components' relative errors are λ's error over a1 − λ and a2 − λ).
#[inline(always)]
pub(super) fn is_near_plane([a1, a2, ..]: [f64; 5], lambda: f64) -> bool {
    lambda < 0.5 * a1.min(a2)
}

/// The first two rows' cross product ([`is_near_plane`]).
#[inline(always)]
pub(super) fn near_plane([a1, a2, b1, b2, _]: [f64; 5], lambda: f64) -> [f64; 3] {
    let (p1, p2) = (a1 - lambda, a2 - lambda);
    [-b1 * p2, -b2 * p1, p1 * p2]
}

/// The longest cross product of two rows of M − λI, turned to face up
/// (for λ that meets a1 or a2: a patch whose flattest direction is
/// horizontal).
#[inline(always)]
pub(super) fn any_plane([a1, a2, b1, b2, c]: [f64; 5], lambda: f64) -> [f64; 3] {
    let (p1, p2, p3) = (a1 - lambda, a2 - lambda, c - lambda);
    let candidates =
        [[-b1 * p2, -b2 * p1, p1 * p2], [-b1 * b2, b1 * b1 - p1 * p3, p1 * b2], [p2 * p3 - b2 * b2, b1 * b2, -p2 * b1]];
    let length2 = |v: &[f64; 3]| v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    let mut best = candidates[0];
    for v in &candidates[1..] {
        let longer = length2(v) > length2(&best);
        best = if longer { *v } else { best };
    }
    // n_z ≥ 0; a vertical plane (n_z = 0 up to rounding, 1e-12 of the
    // vector: a cliff whose heights spread more than the narrower axis's
    // texels) takes n_y ≥ 0, then n_x ≥ 0, and n_z = 0: its rounding, of
    // either sign, would turn the normal below the horizon.
    let tiny = 1e-12 * best[0].abs().max(best[1].abs()).max(best[2].abs());
    let [x, y, z] = best;
    let (z_counts, y_counts) = (z.abs() > tiny, y.abs() > tiny);
    let flip = (z_counts & (z < 0.0)) | (!z_counts & ((y_counts & (y < 0.0)) | (!y_counts & (x < 0.0))));
    let [x, y, z] = best.map(|c| select(flip, -c, c));
    [x, y, select(z_counts, z, 0.0)]
}

/// `if take { a } else { b }`, both already computed, chosen by masks:
/// the compiler cannot move a costly `b` (a division, a square root) into
/// a branch of its own, so a loop of it stays branch-free and vectorises.
#[inline(always)]
pub(super) fn select(take: bool, a: f64, b: f64) -> f64 {
    let mask = u64::from(take).wrapping_neg();
    f64::from_bits((a.to_bits() & mask) | (b.to_bits() & !mask))
}

#[cfg(test)]
mod tests {
    use super::smallest_eigen;

    /// Cliffs: 3 × 3 patches of heights 0 on the left and H on the right
    /// (H up to 1e20), tilted along the cliff, whose plane of least squares
    /// is vertical up to rounding. Their normals lie on the horizon, never
    /// below it: rounding of either sign in z is 0 (a python_entry fuzz case
    /// gave (7.8e-19, 1, −3.0e-17)).
    #[test]
    fn a_vertical_plane_faces_no_lower_than_the_horizon() {
        let mut vertical = 0;
        for e in 0..=200 {
            let cliff = 10f64.powf(f64::from(e) / 10.0);
            for tilt in [-7.0, -1.0, -0.3, 0.0, 0.3, 1.0, 7.0] {
                for edge in [0, 1] {
                    let (mut cx, mut cy, mut s, mut ss) = (0.0, 0.0, 0.0, 0.0);
                    for v in -1..=1 {
                        for u in -1..=1 {
                            let z = if u >= edge { cliff } else { 0.0 } + tilt * f64::from(v);
                            cx += f64::from(u) * z;
                            cy += f64::from(v) * z;
                            s += z;
                            ss += z * z;
                        }
                    }
                    let czz = ss - s * s / 9.0;
                    let (_, n) = smallest_eigen(6.0, 6.0, cx, cy, czz);
                    let len = n.iter().map(|c| c * c).sum::<f64>().sqrt();
                    assert!(n[2] >= 0.0, "H {cliff:e}, tilt {tilt}, edge {edge}: normal {n:?} faces down");
                    vertical += usize::from(n[2].abs() <= 1e-12 * len);
                }
            }
        }
        assert!(vertical > 0, "no case was vertical up to rounding");
    }
}
