//! An independent, slow, obviously-right plane fit: the one reference the
//! tests of the fit compare with.
//!
//! Written apart from `src/fit.rs` and `src/fit/masked.rs` and sharing
//! nothing with them: N² loops in f64 over the patch's actual points
//! (sx·i, σ·sy·j, S·h) through the border rule, the full 3×3 covariance (no
//! sums assumed zero), a Jacobi eigen-solver for the orthogonal fit and the
//! normal equations of z = c0 + c1·u + c2·v solved by Gaussian elimination
//! for the vertical fit. Spacing (SPEC §2, docs/terrain.md): 1 × 1 in
//! texels, the map's in map units, row y's for the whole patch of texel
//! (x, y) with a per-row spacing. Holes (docs/terrain.md "Holes"): the
//! caller says which texels are heights; a hole is left out of every patch,
//! and a texel is missing when it is a hole or its valid points are fewer
//! than 3 or on one line. Weights (SPEC §2 "Weights"): each point weighs
//! w(i)·w(j), and every sum above (the centroid, the covariance, the
//! normal equations, the residual) is the weighted one.
#![allow(dead_code)]
// Matrix code reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

use normalfit::{Border, Convention, Fit, Options, Spacing, Strength, Units, Weights};

/// The index rule of SPEC.md section 2, written out case by case.
pub fn source_index(k: i64, n: i64, mode: Border) -> i64 {
    match mode {
        Border::Wrap => ((k % n) + n) % n,
        Border::Clamp => k.max(0).min(n - 1),
        Border::Mirror => {
            if n == 1 {
                return 0;
            }
            let mut k = k;
            // Reflect until inside; each reflection is about an edge texel.
            loop {
                if k < 0 {
                    k = -k;
                } else if k > n - 1 {
                    k = 2 * (n - 1) - k;
                } else {
                    return k;
                }
            }
        }
        other => panic!("the reference knows no border {other:?}"),
    }
}

/// S of SPEC.md section 1, for an image `w` columns wide: `--scale S` as
/// given, `--relief F` as F · W, negated by `--invert`. Worked out here
/// from the options' fields, not asked of the library, so a wrong gain in
/// the library shows as a difference.
pub fn gain(opts: &Options, w: usize) -> f64 {
    let s = match opts.strength {
        Strength::Scale(s) => s,
        Strength::Relief(f) => f * w as f64,
        other => panic!("the reference knows no strength {other:?}"),
    };
    if opts.invert { -s } else { s }
}

/// (sx, sy), the distances between texel centres along a row and down a
/// column that the patch of a texel in row `y` is fitted with: 1 × 1 in
/// texels; in map units the map's, or row y's of a per-row spacing.
pub fn spacing(opts: &Options, y: usize) -> (f64, f64) {
    match &opts.units {
        Units::Texels => (1.0, 1.0),
        Units::Map(Spacing::Uniform { x, y }) => (*x, *y),
        Units::Map(Spacing::Rows(rows)) => (rows[y][0], rows[y][1]),
        other => panic!("the reference knows no units {other:?}"),
    }
}

/// One point of a patch: its offset (i, j) from the texel, and its place
/// (u, v, z) = (sx·i, σ·sy·j, S·h).
struct Point {
    offset: [i64; 2],
    place: [f64; 3],
    /// The point's weight in the fit: 1, or w(i)·w(j) ([`axis_weight`]).
    weight: f64,
}

/// The weight of offset k ∈ [−r, r] along one axis of an N-point patch:
/// 1 for uniform weights; for binomial ones C(N − 1, k + r) / 2^(N − 1)
/// (Pascal's row, SPEC §2 "Weights"), the binomial coefficient as the
/// product of its factors, not the library's recurrence.
pub fn axis_weight(weights: Weights, n: i64, k: i64) -> f64 {
    match weights {
        Weights::Uniform => 1.0,
        Weights::Binomial => {
            let (m, c) = (n - 1, k + n / 2);
            let choose = (1..=c).fold(1.0f64, |acc, i| acc * (m - c + i) as f64 / i as f64);
            choose / 2f64.powi(m as i32)
        }
        other => panic!("the reference knows no weights {other:?}"),
    }
}

/// The points of texel (x, y)'s N×N patch, each looked up through the
/// border rule on its axis; a texel that `valid` marks as a hole gives no
/// point (`valid` None: every texel is a height).
fn patch_points<H: Copy + Into<f64>>(
    heights: &[H],
    valid: Option<&[bool]>,
    w: usize,
    h: usize,
    opts: &Options,
    x: usize,
    y: usize,
) -> Vec<Point> {
    let n = opts.patch as i64;
    let r = n / 2;
    let s = gain(opts, w);
    let (sx, sy) = spacing(opts, y);
    let sigma = match opts.convention {
        Convention::OpenGl => -1.0,
        Convention::DirectX => 1.0,
    };
    let mut pts = Vec::new();
    for j in -r..=r {
        for i in -r..=r {
            let col = source_index(x as i64 + i, w as i64, opts.borders.x) as usize;
            let row = source_index(y as i64 + j, h as i64, opts.borders.y) as usize;
            let k = row * w + col;
            if valid.is_some_and(|valid| !valid[k]) {
                continue;
            }
            let place = [sx * i as f64, sigma * sy * j as f64, s * heights[k].into()];
            let weight = axis_weight(opts.weights, n, i) * axis_weight(opts.weights, n, j);
            pts.push(Point { offset: [i, j], place, weight });
        }
    }
    pts
}

/// Whether every point lies on one straight line (in offsets, exactly:
/// the cross product of each point's offset from the first with the
/// second's is zero).
fn collinear(pts: &[Point]) -> bool {
    let [i0, j0] = pts[0].offset;
    let [i1, j1] = pts[1].offset;
    pts.iter().all(|p| (i1 - i0) * (p.offset[1] - j0) - (j1 - j0) * (p.offset[0] - i0) == 0)
}

/// The reference fit of one texel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// The unit normal, n_z ≥ 0.
    pub normal: [f64; 3],
    /// The root-mean-square distance of the patch's points from the plane,
    /// in the heights' unit (times S).
    pub residual: f64,
}

/// The reference fit of texel (x, y), or None where the texel is missing:
/// a hole itself, or its valid points fewer than 3 or on one line.
/// `valid[k]`: texel k is a height, not a hole (None: there are no holes).
///
/// The normal: (0, 0, 1) where the patch has no tilt (SPEC §2's rule, in
/// x spacings and of the valid points: (Σ(i − ī)(z − z̄))² + (Σ(j − j̄)(z − z̄))²
/// ≤ 1e-20 · (max(Σ(i − ī)², Σ(j − j̄)²) + Σ(z − z̄)²)², z = S·h / sx);
/// else the covariance's eigenvector of the smallest eigenvalue
/// (orthogonal) or (−c1, −c2, 1) of the least-squares plane
/// z = c0 + c1·u + c2·v (vertical); unit length, n_z ≥ 0 (where n_z is 0
/// up to 1e-12, n_y ≥ 0, then n_x ≥ 0).
///
/// The residual, point by point: perpendicular distance from the plane
/// through the points' centroid with that normal (orthogonal), z minus
/// the least-squares plane (vertical), z minus the mean where the patch is
/// flat.
pub fn fit_at<H: Copy + Into<f64>>(
    heights: &[H],
    valid: Option<&[bool]>,
    w: usize,
    h: usize,
    opts: &Options,
    x: usize,
    y: usize,
) -> Option<Plane> {
    if valid.is_some_and(|valid| !valid[y * w + x]) {
        return None;
    }
    let pts = patch_points(heights, valid, w, h, opts, x, y);
    if pts.len() < 3 || collinear(&pts) {
        return None;
    }
    let places: Vec<[f64; 3]> = pts.iter().map(|p| p.place).collect();
    let weights: Vec<f64> = pts.iter().map(|p| p.weight).collect();
    let count: f64 = weights.iter().sum();
    let mean = centroid(&places, &weights);

    // The contract's "no tilt" rule, in x spacings.
    let (sx, _) = spacing(opts, y);
    let in_x: Vec<[f64; 3]> = pts.iter().map(|p| [p.offset[0] as f64, p.offset[1] as f64, p.place[2] / sx]).collect();
    let m = covariance(&in_x, &weights);
    let (tilt, spread) = (m[0][2].powi(2) + m[1][2].powi(2), m[0][0].max(m[1][1]) + m[2][2]);
    let flat = tilt <= 1e-20 * spread * spread;

    let (normal, squared): ([f64; 3], f64) = if flat {
        ([0.0, 0.0, 1.0], places.iter().zip(&weights).map(|(p, w)| w * (p[2] - mean[2]).powi(2)).sum())
    } else {
        match opts.fit {
            Fit::Orthogonal => {
                let n = orient(unit(smallest_eigenvector(covariance(&places, &weights))));
                let distance = |p: &[f64; 3]| (0..3).map(|k| n[k] * (p[k] - mean[k])).sum::<f64>();
                (n, places.iter().zip(&weights).map(|(p, w)| w * distance(p).powi(2)).sum())
            }
            Fit::Vertical => {
                let c = least_squares_plane(&places, &weights);
                let n = unit([-c[1], -c[2], 1.0]);
                let off = |p: &[f64; 3]| p[2] - (c[0] + c[1] * p[0] + c[2] * p[1]);
                (n, places.iter().zip(&weights).map(|(p, w)| w * off(p).powi(2)).sum())
            }
            other => panic!("the reference knows no fit {other:?}"),
        }
    };
    Some(Plane { normal, residual: (squared / count).sqrt() })
}

/// The reference normal of texel (x, y), without holes.
pub fn normal_at<H: Copy + Into<f64>>(
    heights: &[H],
    w: usize,
    h: usize,
    opts: &Options,
    x: usize,
    y: usize,
) -> [f64; 3] {
    fit_at(heights, None, w, h, opts, x, y).expect("a whole patch has a plane").normal
}

/// The reference residual of texel (x, y), without holes.
pub fn residual_at<H: Copy + Into<f64>>(heights: &[H], w: usize, h: usize, opts: &Options, x: usize, y: usize) -> f64 {
    fit_at(heights, None, w, h, opts, x, y).expect("a whole patch has a plane").residual
}

/// The whole reference normal map, without holes.
pub fn normal_map<H: Copy + Into<f64>>(heights: &[H], w: usize, h: usize, opts: &Options) -> Vec<[f64; 3]> {
    masked_normal_map(heights, None, w, h, opts).into_iter().map(|n| n.expect("a whole patch has a plane")).collect()
}

/// The whole reference normal map with holes: None where a texel is
/// missing.
pub fn masked_normal_map<H: Copy + Into<f64>>(
    heights: &[H],
    valid: Option<&[bool]>,
    w: usize,
    h: usize,
    opts: &Options,
) -> Vec<Option<[f64; 3]>> {
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            out.push(fit_at(heights, valid, w, h, opts, x, y).map(|plane| plane.normal));
        }
    }
    out
}

/// `v` over its length.
pub fn unit(v: [f64; 3]) -> [f64; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / len)
}

/// The unit normal n or −n: n_z ≥ 0; for a vertical plane (n_z zero up to
/// 1e-12) n_y ≥ 0, then n_x ≥ 0 (SPEC §2).
fn orient(n: [f64; 3]) -> [f64; 3] {
    let flip = if n[2].abs() > 1e-12 {
        n[2] < 0.0
    } else if n[1].abs() > 1e-12 {
        n[1] < 0.0
    } else {
        n[0] < 0.0
    };
    if flip { n.map(|c| -c) } else { n }
}

/// The weighted mean of the points, coordinate by coordinate.
fn centroid(pts: &[[f64; 3]], weights: &[f64]) -> [f64; 3] {
    let total: f64 = weights.iter().sum();
    std::array::from_fn(|k| pts.iter().zip(weights).map(|(p, w)| w * p[k]).sum::<f64>() / total)
}

/// Σ w·(p − p̄)(p − p̄)ᵀ over the points: the 3×3 weighted scatter matrix.
fn covariance(pts: &[[f64; 3]], weights: &[f64]) -> [[f64; 3]; 3] {
    let mean = centroid(pts, weights);
    let mut cov = [[0.0f64; 3]; 3];
    for (p, w) in pts.iter().zip(weights) {
        for a in 0..3 {
            for b in 0..3 {
                cov[a][b] += w * (p[a] - mean[a]) * (p[b] - mean[b]);
            }
        }
    }
    cov
}

/// (c0, c1, c2) of the plane z = c0 + c1 u + c2 v closest to the points in
/// z, by weighted least squares: the normal equations Σ w·rowᵀrow · c =
/// Σ w·row·z, solved by elimination.
fn least_squares_plane(pts: &[[f64; 3]], weights: &[f64]) -> [f64; 3] {
    let mut m = [[0.0f64; 4]; 3];
    for (p, w) in pts.iter().zip(weights) {
        let row = [1.0, p[0], p[1]];
        for a in 0..3 {
            for b in 0..3 {
                m[a][b] += w * row[a] * row[b];
            }
            m[a][3] += w * row[a] * p[2];
        }
    }
    solve(m)
}

/// Eigenvector of the smallest eigenvalue of a symmetric 3×3 matrix, by
/// cyclic Jacobi rotations.
fn smallest_eigenvector(mut m: [[f64; 3]; 3]) -> [f64; 3] {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..100 {
        let off = m[0][1].powi(2) + m[0][2].powi(2) + m[1][2].powi(2);
        let diag = m[0][0].powi(2) + m[1][1].powi(2) + m[2][2].powi(2);
        if off <= 1e-34 * diag || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if m[p][q] == 0.0 {
                continue;
            }
            let theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // m ← Jᵀ m J, v ← v J for the rotation J in the (p, q) plane.
            for k in 0..3 {
                let (mkp, mkq) = (m[k][p], m[k][q]);
                m[k][p] = c * mkp - s * mkq;
                m[k][q] = s * mkp + c * mkq;
            }
            for k in 0..3 {
                let (mpk, mqk) = (m[p][k], m[q][k]);
                m[p][k] = c * mpk - s * mqk;
                m[q][k] = s * mpk + c * mqk;
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let k = (0..3).min_by(|&a, &b| m[a][a].total_cmp(&m[b][b])).unwrap();
    [v[0][k], v[1][k], v[2][k]]
}

/// Solves an N × N system given as an augmented matrix (N rows of
/// `M` = N + 1 values), by Gaussian elimination with partial pivoting.
fn solve<const N: usize, const M: usize>(mut m: [[f64; M]; N]) -> [f64; N] {
    assert_eq!(M, N + 1, "an augmented matrix");
    for col in 0..N {
        let piv = (col..N).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs())).unwrap();
        m.swap(col, piv);
        for row in 0..N {
            if row != col {
                let f = m[row][col] / m[col][col];
                for k in col..M {
                    m[row][k] -= f * m[col][k];
                }
            }
        }
    }
    std::array::from_fn(|k| m[k][N] / m[k][k])
}

/// The reference curvature of texel (x, y): the least-squares quadratic
/// z = a·u² + b·uv + c·v² + d·u + e·v + f through the patch's points
/// (u, v, z) = (sx·i, sy·j, S·h), its 6 × 6 normal equations (no moment
/// assumed zero) solved by Gaussian elimination with partial pivoting, and
/// the mean curvature of that surface at the texel, convex positive:
/// −((1 + e²)·2a − 2·d·e·b + (1 + d²)·2c) / (2·(1 + d² + e²)^{3/2}).
/// None where any texel of the patch is a hole (`valid[k]` false).
pub fn curvature_at<H: Copy + Into<f64>>(
    heights: &[H],
    valid: Option<&[bool]>,
    w: usize,
    h: usize,
    opts: &Options,
    x: usize,
    y: usize,
) -> Option<f64> {
    let n = opts.patch;
    let pts = patch_points(heights, valid, w, h, opts, x, y);
    if pts.len() < n * n {
        return None;
    }
    let mut m = [[0.0f64; 7]; 6];
    for p in &pts {
        // The y axis's sign (σ) plays no part in the curvature: undo it.
        let (u, v, z) = (p.place[0], p.place[1].abs() * (p.offset[1].signum() as f64), p.place[2]);
        let row = [u * u, u * v, v * v, u, v, 1.0];
        for a in 0..6 {
            for b in 0..6 {
                m[a][b] += row[a] * row[b];
            }
            m[a][6] += row[a] * z;
        }
    }
    let [a, b, cc, d, e, _] = solve(m);
    let g = 1.0 + d * d + e * e;
    Some(-((1.0 + e * e) * 2.0 * a - 2.0 * d * e * b + (1.0 + d * d) * 2.0 * cc) / (2.0 * g * g.sqrt()))
}

/// [`curvature_at`] of every texel, row-major; NaN where it is None.
pub fn curvature_map<H: Copy + Into<f64>>(
    heights: &[H],
    valid: Option<&[bool]>,
    w: usize,
    h: usize,
    opts: &Options,
) -> Vec<f64> {
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| curvature_at(heights, valid, w, h, opts, x, y).unwrap_or(f64::NAN))
        .collect()
}

/// The slope (degrees) and the aspect (degrees clockwise from north, None
/// where the plane is flat) of a plane with unit normal `n` in OpenGL's
/// frame (+x east, +y north), by gdaldem's formulas (GDAL's
/// `gdaldem_lib.cpp`, written out again from the gradient): dx = dz/dx
/// eastwards = −nx/nz, dy = dz/dy southwards (down the rows) = ny/nz,
/// slope = atan √(dx² + dy²), aspect = 90° − atan2(dy, −dx) (450° − it
/// above 90°).
pub fn slope_aspect_gdal(n: [f64; 3]) -> (f64, Option<f64>) {
    let (dx, dy) = (-n[0] / n[2], n[1] / n[2]);
    let slope = (dx * dx + dy * dy).sqrt().atan().to_degrees();
    let aspect = if dx == 0.0 && dy == 0.0 {
        None
    } else {
        let a = dy.atan2(-dx).to_degrees();
        Some(if a > 90.0 { 450.0 - a } else { 90.0 - a })
    };
    (slope, aspect)
}

/// The tiling check's seam scores (x, y) of a height map of `w` × `h` ≤ 512
/// (every line read), written plainly from `src/tiling/mod.rs`'s docs in
/// f64: at each level l (runs of 2^l texels along the lines compared, a
/// run holding a hole a hole), the value sums V[k] = Σ |h(k+1) − h(k)| and
/// the creases C[k] over the pairs whose texels are all valid, with their
/// counts; each sum scaled to the level's fullest count; the seam against
/// the k-th largest interior sum; the largest level; infinite when level 0
/// has no valid seam pair or no valid interior pair. `hole(texel)` says
/// which texels are holes.
pub fn seam_scores(heights: &[f64], w: usize, h: usize, hole: impl Fn(f64) -> bool) -> (f64, f64) {
    let at = |x: usize, y: usize| {
        let v = heights[y * w + x];
        if hole(v) { None } else { Some(v) }
    };
    let transposed = |x: usize, y: usize| at(y, x);
    // Each axis's per-level sums and counts: value, crease, their counts.
    let x = axis_sums(&at, w, h);
    let y = axis_sums(&transposed, h, w);
    // ε from the level-0 value sums over every pair of both axes.
    let total: f64 = x[0].0.iter().chain(&y[0].0).sum();
    let count: f64 = x[0].2.iter().chain(&y[0].2).sum();
    let mean = if count > 0.0 { total / count } else { 0.0 };
    let score = |levels: &[LevelSums], line: usize| {
        let eps = 1e-3 * mean * line as f64 + 1e-30;
        let mut best = 0.0f64;
        for (l, (v, c, nv, nc)) in levels.iter().enumerate() {
            if l > 0 && line < 8 << l {
                continue;
            }
            match level_score_plain(v, c, nv, nc, eps) {
                Some(s) => best = best.max(s),
                None if l == 0 => return f64::INFINITY,
                None => {}
            }
        }
        best
    };
    (score(&x, h), score(&y, w))
}

type LevelSums = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// The sums of the pairs of columns k → k + 1 (mod `n`) of an image whose
/// texel (k, j) is `at(k, j)`, lines `len` long, at levels 0 … 5.
fn axis_sums(at: &dyn Fn(usize, usize) -> Option<f64>, n: usize, len: usize) -> Vec<LevelSums> {
    (0..6)
        .map(|l| {
            let run = 1usize << l;
            let runs = len.div_ceil(run);
            // The run J of line k: the sum of its texels, None if one is a hole.
            let r = |k: usize, j: usize| -> Option<f64> {
                (j * run..((j + 1) * run).min(len)).map(|t| at(k % n, t)).sum::<Option<f64>>()
            };
            let (mut v, mut c, mut nv, mut nc) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            for k in 0..n {
                for j in 0..runs {
                    if let (Some(a), Some(b)) = (r(k, j), r(k + 1, j)) {
                        v[k] += (b - a).abs();
                        nv[k] += 1.0;
                    }
                    if let (Some(a), Some(b), Some(cc), Some(d)) = (r(k + n - 1, j), r(k, j), r(k + 1, j), r(k + 2, j))
                    {
                        c[k] += ((d - cc) - (b - a)).abs();
                        nc[k] += 1.0;
                    }
                }
            }
            (v, c, nv, nc)
        })
        .collect()
}

/// One level's score (seam last), or None when it cannot be judged.
fn level_score_plain(v: &[f64], c: &[f64], nv: &[f64], nc: &[f64], eps: f64) -> Option<f64> {
    let n = v.len();
    if n < 2 {
        return Some(1.0);
    }
    let ratio = |p: &[f64], counts: &[f64], interior: std::ops::Range<usize>| -> Option<f64> {
        // The fullest of the pairs judged: the interior and the seam.
        let full = interior.clone().chain([n - 1]).map(|k| counts[k]).fold(0.0, f64::max);
        if counts[n - 1] == 0.0 {
            return None;
        }
        let mut inner: Vec<f64> = interior.filter(|&k| counts[k] > 0.0).map(|k| p[k] * full / counts[k]).collect();
        if inner.is_empty() {
            return None;
        }
        inner.sort_by(|a, b| b.total_cmp(a));
        let m = inner.len();
        let rank = 4usize.max((m as f64 * 0.01).ceil() as usize).min(m.div_ceil(2)).max(1);
        Some((p[n - 1] * full / counts[n - 1] + eps) / (inner[rank - 1] + eps))
    };
    let mut score = ratio(v, nv, 0..n - 1)?;
    if n >= 4
        && let Some(s) = ratio(c, nc, 1..n - 2)
    {
        score = score.max(s);
    }
    Some(score)
}

/// The slope (degrees) and aspect (degrees clockwise from north, in
/// [0, 360]; None where the normal does not lean) of normal `n` in
/// OpenGL's frame by libm's `hypot` and `atan2` in f64: what
/// `normalfit::units::slope_aspect` computed before its own arctangent,
/// which is held to this.
pub fn slope_aspect_libm(n: [f64; 3]) -> (f64, Option<f64>) {
    let [east, north, up] = n;
    let horizontal = east.hypot(north);
    let slope = horizontal.atan2(up).to_degrees();
    let aspect = (horizontal > 0.0).then(|| {
        let a = east.atan2(north).to_degrees();
        if a < 0.0 { a + 360.0 } else { a }
    });
    (slope, aspect)
}
