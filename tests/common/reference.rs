//! An independent, slow, obviously-right plane fit for the tests.
//!
//! Written apart from `src/fit.rs` and sharing nothing with it: N² loops in
//! f64 over the patch's actual points, the full 3×3 covariance (no sums
//! assumed zero), a Jacobi eigen-solver for the orthogonal fit and the
//! normal equations solved by Gaussian elimination for the vertical fit.
#![allow(dead_code)]
// Matrix code reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

use normalfit::{Border, Convention, Fit, Options, Strength};

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

/// The N² points (u, v, z) of texel (x, y)'s patch.
fn patch_points<H: Copy + Into<f64>>(
    heights: &[H],
    w: usize,
    h: usize,
    opts: &Options,
    x: usize,
    y: usize,
) -> Vec<[f64; 3]> {
    let n = opts.patch as i64;
    let r = n / 2;
    let s = gain(opts, w);
    let sigma = match opts.convention {
        Convention::OpenGl => -1.0,
        Convention::DirectX => 1.0,
    };
    let mut pts = Vec::new();
    for j in -r..=r {
        for i in -r..=r {
            let sx = source_index(x as i64 + i, w as i64, opts.borders.x) as usize;
            let sy = source_index(y as i64 + j, h as i64, opts.borders.y) as usize;
            pts.push([i as f64, sigma * j as f64, s * heights[sy * w + sx].into()]);
        }
    }
    pts
}

/// The reference residual of texel (x, y): the root-mean-square distance
/// of the patch's points from the plane the reference fits, measured
/// point by point. Orthogonal fit: perpendicular distance from the plane
/// through the points' centroid with the reference normal (the flat
/// normal's horizontal plane included). Vertical fit: z minus the least
/// squares plane c0 + c1·u + c2·v, or minus the mean where the contract
/// calls the patch flat.
pub fn residual_at<H: Copy + Into<f64>>(heights: &[H], w: usize, h: usize, opts: &Options, x: usize, y: usize) -> f64 {
    let pts = patch_points(heights, w, h, opts, x, y);
    let count = pts.len() as f64;
    let mean = centroid(&pts);
    let normal = normal_at(heights, w, h, opts, x, y);
    let flat = normal == [0.0, 0.0, 1.0];
    let squared: f64 = match opts.fit {
        Fit::Orthogonal => pts.iter().map(|p| (0..3).map(|k| normal[k] * (p[k] - mean[k])).sum::<f64>().powi(2)).sum(),
        Fit::Vertical if flat => pts.iter().map(|p| (p[2] - mean[2]).powi(2)).sum(),
        Fit::Vertical => {
            let c = least_squares_plane(&pts);
            pts.iter().map(|p| (p[2] - (c[0] + c[1] * p[0] + c[2] * p[1])).powi(2)).sum()
        }
        other => panic!("the reference knows no fit {other:?}"),
    };
    (squared / count).sqrt()
}

/// The mean of the points, coordinate by coordinate.
fn centroid(pts: &[[f64; 3]]) -> [f64; 3] {
    let count = pts.len() as f64;
    std::array::from_fn(|k| pts.iter().map(|p| p[k]).sum::<f64>() / count)
}

/// (c0, c1, c2) of the plane z = c0 + c1 u + c2 v closest to the points in
/// z, by least squares: the normal equations, solved by elimination.
fn least_squares_plane(pts: &[[f64; 3]]) -> [f64; 3] {
    let mut m = [[0.0f64; 4]; 3];
    for p in pts {
        let row = [1.0, p[0], p[1]];
        for a in 0..3 {
            for b in 0..3 {
                m[a][b] += row[a] * row[b];
            }
            m[a][3] += row[a] * p[2];
        }
    }
    solve3(m)
}

/// The reference normal of texel (x, y).
pub fn normal_at<H: Copy + Into<f64>>(
    heights: &[H],
    w: usize,
    h: usize,
    opts: &Options,
    x: usize,
    y: usize,
) -> [f64; 3] {
    let pts = patch_points(heights, w, h, opts, x, y);
    let mean = centroid(&pts);
    let mut cov = [[0.0f64; 3]; 3];
    for p in &pts {
        for a in 0..3 {
            for b in 0..3 {
                cov[a][b] += (p[a] - mean[a]) * (p[b] - mean[b]);
            }
        }
    }
    // The contract's "no tilt" rule, from the same covariance entries.
    let (a, cx, cy, czz) = (cov[0][0], cov[0][2], cov[1][2], cov[2][2]);
    if cx * cx + cy * cy <= 1e-20 * (a + czz) * (a + czz) {
        return [0.0, 0.0, 1.0];
    }
    let n = match opts.fit {
        Fit::Orthogonal => smallest_eigenvector(cov),
        Fit::Vertical => {
            // The normal of z = c0 + c1 u + c2 v is (−c1, −c2, 1).
            let c = least_squares_plane(&pts);
            [-c[1], -c[2], 1.0]
        }
        other => panic!("the reference knows no fit {other:?}"),
    };
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let sign = if n[2] < 0.0 { -1.0 } else { 1.0 };
    [sign * n[0] / len, sign * n[1] / len, sign * n[2] / len]
}

/// The whole reference normal map.
pub fn normal_map<H: Copy + Into<f64>>(heights: &[H], w: usize, h: usize, opts: &Options) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            out.push(normal_at(heights, w, h, opts, x, y));
        }
    }
    out
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

/// Solves a 3×3 system given as an augmented matrix, with partial pivoting.
fn solve3(mut m: [[f64; 4]; 3]) -> [f64; 3] {
    for col in 0..3 {
        let piv = (col..3).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs())).unwrap();
        m.swap(col, piv);
        for row in 0..3 {
            if row != col {
                let f = m[row][col] / m[col][col];
                for k in col..4 {
                    m[row][k] -= f * m[col][k];
                }
            }
        }
    }
    [m[0][3] / m[0][0], m[1][3] / m[1][1], m[2][3] / m[2][2]]
}
