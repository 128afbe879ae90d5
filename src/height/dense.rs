//! The exact vertical solve where no transform fits (clamp with N ≥ 5), by
//! the fit's separable structure: per axis a dense basis in which the
//! normal equations are diagonal (fast diagonalisation).
//!
//! The vertical fit's slopes are Dx = (B_y ⊗ R_x)/A and Dy = (R_y ⊗ B_x)/A,
//! R and B an axis's ramp and box through its border (`line.rs`), so with
//! W = W_y ⊗ W_x the period's multiplicities the normal matrix is
//!
//! ```text
//! DᵀWD = (Q_y ⊗ P_x + P_y ⊗ Q_x) / A²,   P = RᵀWR,  Q = BᵀWB  (per axis)
//! ```
//!
//! Per axis, the generalised eigenvectors of (P, P + Q): P U = (P + Q) U M
//! with Uᵀ(P + Q)U = I, so UᵀPU = M and UᵀQU = I − M, μ in [0, 1]. P + Q
//! is singular where both the box and the ramp vanish (the box's zeros an
//! axis holds under clamp), so it is diagonalised first, in W's measure,
//! as E Σ Eᵀ: its rank is read off there, the seen vectors are
//! E_s Σ_s^-1/2 Y with Y the eigenvectors of Σ_s^-1/2 E_sᵀ P E_s Σ_s^-1/2,
//! and the unseen ones are E's remaining columns (both eigenproblems by
//! Householder's tridiagonal form and the implicit QL method). In the basis
//! V ⊗ U the normal matrix is diagonal, so
//!
//! ```text
//! z = (V ⊗ U) diag(1 / (d/A² + λ s)) (V ⊗ U)ᵀ DᵀWg,   d = (1 − μ_y) μ_x + μ_y (1 − μ_x)
//! ```
//!
//! with four dense products along the rows and columns; λ, the
//! quantisation's regularisation, is added in the measure of each basis
//! vector (s = |u|²|v|², the diagonal of the identity in that basis), and
//! the modes the fit does not see (d at rounding level: the constant, the
//! box's zeros, the unseen vectors) are 0. The heights are the least-squares solution exactly,
//! whatever N: a patch reaching past a clamped edge changes the bases, not
//! the cost, which is O(n³) for an axis of n texels and O(texels · (w + h))
//! a solve. Axes up to [`MAX_DENSE`] texels take it; past that the
//! conjugate gradients of `iterative.rs` do, within their budget.

use crate::error::Result;
use crate::options::Border;
use crate::par::prelude::*;
use crate::samples::try_filled;

use super::line::{Line, Scratch};
use super::patch::Patch;
use super::solve::SlopeRows;

/// The longest axis given a dense basis: its eigenproblem takes some 6n³
/// operations (a second or two at 1024) and each solve 4n per texel.
pub(super) const MAX_DENSE: usize = 1024;

/// Modes whose d is below this are the fit's null modes (0 up to
/// rounding; d is at most 1): the vertical fit's least squares.
pub(super) const NULL: f64 = 1e-13;

/// Modes whose d is below this are left out of the orthogonal fit's
/// fixed-point solves: the vertical fit barely sees them (a response of
/// √d ≈ 3e-4 of the mode's size), so while the ratios have not settled,
/// and the slopes asked for are not yet any heights' slopes, the exact
/// least squares fill them with heights of thousands of texels, which the
/// orthogonal fit then sees as roughness and the iteration chases
/// (clamp, N = 15 on 40 × 32: unsettled after 122 solves, against 6).
/// Gauss–Newton, with the exact operator, restores what they held.
pub(super) const ORTHOGONAL_NULL: f64 = 1e-7;

/// An axis's directions where P + Q (in W's measure) is below this part of
/// its largest eigenvalue are seen by neither the ramp nor the box: the
/// eigensolver's rounding is some n·ε of the largest (2e-13 at 1024).
const RANK: f64 = 1e-11;

/// The null modes the solve takes out of its heights at most.
pub(super) const MAX_NULLS: usize = 4096;

/// One axis's basis: U (n × n, row-major: U[i][k] = component i of basis
/// vector k), what the ramp and the box see of each basis vector (the
/// generalised eigenvalue μ_k = |Ru_k|²_W and 1 − μ_k = |Bu_k|²_W, each
/// summed from its own response rather than one taken from 1: a vector the
/// box does not see then measures 1e-16 or so, not the 1e-12 that 1 − μ
/// keeps of the rounding), and |u_k|².
#[derive(Clone)]
pub(super) struct Basis {
    pub(super) u: Vec<f64>,
    pub(super) ramp: Vec<f64>,
    pub(super) boxed: Vec<f64>,
    pub(super) norm2: Vec<f64>,
    /// The vectors neither the ramp nor the box sees (the last ones): null
    /// modes with every vector of the other axis, and orthogonal in W's
    /// measure to every other vector of their axis.
    pub(super) axis_null: Vec<bool>,
}

/// The dense solve of an image's vertical fit.
pub(super) struct DenseSolver {
    w: usize,
    h: usize,
    a: f64,
    x: Basis,
    y: Basis,
}

impl DenseSolver {
    /// The solver of `patch`'s fit on an image of `h` rows, or `None` when
    /// an axis is longer than [`MAX_DENSE`] or a basis cannot be made.
    pub(super) fn new(patch: &Patch, h: usize) -> Option<DenseSolver> {
        let w = patch.w;
        if w > MAX_DENSE || h > MAX_DENSE {
            return None;
        }
        let x = Basis::new(&patch.x, w, patch.borders.x)?;
        // A square map with one border: both axes are the same line.
        let y = if (h, patch.borders.y) == (w, patch.borders.x) {
            x.clone()
        } else {
            Basis::new(&patch.y, h, patch.borders.y)?
        };
        Some(DenseSolver { w, h, a: patch.a, x, y })
    }

    /// The heights z (texel units) whose vertical-fit slopes are closest,
    /// in the period's least squares plus λ|z|², to the slopes whose
    /// right-hand side DᵀWg is `b` (w × h, overwritten), into `z`; of least
    /// W-norm among them: the basis vectors are orthogonal in P + Q's
    /// measure, not W's, so the part of z along the null modes (W's
    /// projection on the few of them) is taken out, as the transforms'
    /// solutions and the least squares over the period have none.
    /// `weights`: W per column and per row.
    ///
    /// Errors: [`crate::Error::Limits`] when a plane's memory is not there.
    /// `null`: the threshold of d below which a mode is null ([`NULL`],
    /// [`ORTHOGONAL_NULL`]).
    pub(super) fn solve(
        &self,
        b: &mut [f64],
        lambda: f64,
        null: f64,
        weights: (&[f64], &[f64]),
        z: &mut [f64],
    ) -> Result<()> {
        let nulls = self.apply(b, lambda, null, None, z)?;
        self.remove_null_modes(&nulls, weights, z)
    }

    /// (DᵀWD + (λ + ε)W)⁻¹ W b, W's part in each basis vector's own
    /// measure (`weights`: W per column and per row), every mode divided:
    /// Gauss–Newton's preconditioner, as `Solver::inverse` is the
    /// transforms'. `b` is kept.
    ///
    /// Errors: [`crate::Error::Limits`] when a plane's memory is not there.
    pub(super) fn inverse(
        &self,
        b: &[f64],
        lambda: f64,
        epsilon: f64,
        weights: (&[f64], &[f64]),
        out: &mut [f64],
    ) -> Result<()> {
        let w = self.w;
        let (wx, wy) = weights;
        let mut weighted = try_filled(b.len(), 0.0)?;
        weighted.par_chunks_mut(w).zip(b.par_chunks(w)).enumerate().for_each(|(y, (o, b))| {
            for ((o, b), m) in o.iter_mut().zip(b).zip(wx) {
                *o = b * m * wy[y];
            }
        });
        self.apply(&mut weighted, lambda + epsilon, NULL, Some(weights), out).map(|_| ())
    }

    /// z = (V ⊗ U) diag(1/(d/A² + λ s)) (V ⊗ U)ᵀ b, s each basis vector's
    /// measure (W's where `weights` is given, else the identity's); the null
    /// modes (d at rounding level) are 0 unless `weights` is given (then
    /// divided by λ s alone). Returns the null modes, (k, l).
    fn apply(
        &self,
        b: &mut [f64],
        lambda: f64,
        null_below: f64,
        weights: Option<(&[f64], &[f64])>,
        z: &mut [f64],
    ) -> Result<Vec<(usize, usize)>> {
        let (w, h) = (self.w, self.h);
        let mut t = try_filled(w * h, 0.0)?;
        // c = Vᵀ B U: the rows times U, then Vᵀ times that.
        multiply_right(b, w, &self.x.u, false, &mut t);
        multiply_left(&self.y.u, h, true, &t, w, b);
        let (sx, sy) = match weights {
            Some((wx, wy)) => (self.x.measure(wx), self.y.measure(wy)),
            None => (self.x.norm2.clone(), self.y.norm2.clone()),
        };
        let a2 = self.a * self.a;
        let every = weights.is_some();
        let nulls: Vec<Vec<(usize, usize)>> = b
            .par_chunks_mut(w)
            .enumerate()
            .map(|(l, row)| {
                let mut nulls = Vec::new();
                for (k, c) in row.iter_mut().enumerate() {
                    let d = self.y.boxed[l] * self.x.ramp[k] + self.y.ramp[l] * self.x.boxed[k];
                    let axis_null = self.x.axis_null[k] || self.y.axis_null[l];
                    let null = axis_null || d <= null_below;
                    // The axes' null vectors are orthogonal in W to every
                    // mode the solution holds: nothing of them to take out.
                    if null && !axis_null {
                        nulls.push((k, l));
                    }
                    *c = if null && !every { 0.0 } else { *c / (d.max(0.0) / a2 + lambda * sx[k] * sy[l]) };
                }
                nulls
            })
            .collect();
        // z = V c Uᵀ.
        multiply_left(&self.y.u, h, false, b, w, &mut t);
        multiply_right(&t, w, &self.x.u, true, z);
        Ok(nulls.into_iter().flatten().collect())
    }

    /// Takes out of `z` its W-orthogonal projection on the null modes
    /// u_k ⊗ v_l (`nulls`): their Gram matrix is the product of the axes'
    /// ([`project_out`]). Past [`MAX_NULLS`] of them (an operator seeing
    /// next to nothing) z is left as it is.
    ///
    /// Errors: [`crate::Error::Limits`] as [`project_out`].
    fn remove_null_modes(&self, nulls: &[(usize, usize)], weights: (&[f64], &[f64]), z: &mut [f64]) -> Result<()> {
        if nulls.is_empty() || nulls.len() > MAX_NULLS {
            return Ok(());
        }
        let column = |basis: &Basis, n: usize, k: usize| -> Vec<f64> { (0..n).map(|i| basis.u[i * n + k]).collect() };
        let modes: Vec<(Vec<f64>, Vec<f64>)> =
            nulls.iter().map(|&(k, l)| (column(&self.x, self.w, k), column(&self.y, self.h, l))).collect();
        project_out(&modes, weights, z)
    }

    /// The right-hand side DᵀWg of `slopes` into `b`, W the period's
    /// multiplicities `weights` (per column, per row), with `planes` as work.
    pub(super) fn right_hand_side(
        patch: &Patch,
        slopes: SlopeRows<'_>,
        weights: (&[f64], &[f64]),
        planes: (&mut [f64], &mut [f64]),
        b: &mut [f64],
    ) {
        let w = patch.w;
        let (wx, wy) = weights;
        let (gx, gy) = planes;
        gx.par_chunks_mut(w).zip(gy.par_chunks_mut(w)).enumerate().for_each(|(y, (rx, ry))| {
            slopes(y, rx, ry);
            for ((gx, gy), m) in rx.iter_mut().zip(ry.iter_mut()).zip(wx) {
                *gx *= m * wy[y];
                *gy *= m * wy[y];
            }
        });
        patch.adjoint(gx, gy, b);
    }
}

impl Basis {
    /// The generalised eigenbasis of (RᵀWR, RᵀWR + BᵀWB) of an axis of `n`
    /// texels with `border`; `None` if the eigenproblem fails.
    pub(super) fn new(line: &Line, n: usize, border: Border) -> Option<Basis> {
        // R and B, row-major: column j is the line's response to texel j.
        let (mut r, mut b) = (vec![0.0; n * n], vec![0.0; n * n]);
        let (mut unit, mut boxed, mut ramped) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut scratch = Scratch::default();
        for j in 0..n {
            unit.fill(0.0);
            unit[j] = 1.0;
            line.apply(&unit, Some(&mut boxed), Some(&mut ramped), &mut scratch);
            for i in 0..n {
                r[i * n + j] = ramped[i];
                b[i * n + j] = boxed[i];
            }
        }
        let weight = |i: usize| if border == Border::Mirror && n > 2 && i != 0 && i != n - 1 { 2.0 } else { 1.0 };
        // P = RᵀWR, Q = BᵀWB.
        let gram = |m: &[f64]| {
            let weighted: Vec<f64> = (0..n * n).map(|k| weight(k / n) * m[k]).collect();
            let mut g = vec![0.0; n * n];
            product((m, n, n, true), (&weighted, n, false), &mut g);
            g
        };
        let (p, q) = (gram(&r), gram(&b));
        // In W's measure (z = W^-1/2 z'), P' + Q' = E Σ Eᵀ, E orthonormal:
        // its eigenvalues at rounding level span the vectors neither the
        // ramp nor the box sees (the box's zeros the axis holds under clamp,
        // the constant under wrap with N a multiple of the period). Those
        // stay unit vectors in W's measure, orthogonal there to every other
        // basis vector, rather than the long vectors a shifted Cholesky
        // factor would make of them (|u|² of 1e7 and more, losing the
        // digits the seen vectors need).
        let root: Vec<f64> = (0..n).map(|i| weight(i).sqrt()).collect();
        let scaled = |m: &[f64]| -> Vec<f64> { (0..n * n).map(|k| m[k] / (root[k / n] * root[k % n])).collect() };
        let p = scaled(&p);
        let sum: Vec<f64> = p.iter().zip(scaled(&q)).map(|(a, b)| a + b).collect();
        drop(q);
        let (sigma, e) = symmetric_eigen(sum, n)?;
        let largest = sigma.iter().fold(0.0f64, |m, s| m.max(*s));
        let seen: Vec<usize> = (0..n).filter(|&k| sigma[k] > RANK * largest).collect();
        let unseen: Vec<usize> = (0..n).filter(|&k| sigma[k] <= RANK * largest).collect();
        let r_count = seen.len();
        // F = E_s Σ_s^-1/2 (n × r), C = Fᵀ P' F (r × r), C = Y M Yᵀ; the
        // seen vectors are W^-1/2 F Y: (P + Q)-orthonormal, UᵀPU = M.
        let f: Vec<f64> = (0..n * r_count)
            .map(|k| e[(k / r_count) * n + seen[k % r_count]] / sigma[seen[k % r_count]].sqrt())
            .collect();
        let mut pf = vec![0.0; n * r_count];
        product((&p, n, n, false), (&f, r_count, false), &mut pf);
        let mut c = vec![0.0; r_count * r_count];
        product((&f, r_count, n, true), (&pf, r_count, false), &mut c);
        drop(p);
        for i in 0..r_count {
            for j in 0..i {
                let v = 0.5 * (c[i * r_count + j] + c[j * r_count + i]);
                c[i * r_count + j] = v;
                c[j * r_count + i] = v;
            }
        }
        let (_, y) = symmetric_eigen(c, r_count)?;
        let mut fy = vec![0.0; n * r_count];
        product((&f, n, r_count, false), (&y, r_count, false), &mut fy);
        let mut u = vec![0.0; n * n];
        u.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
            for (k, v) in row[..r_count].iter_mut().enumerate() {
                *v = fy[i * r_count + k] / root[i];
            }
            for (k, &j) in unseen.iter().enumerate() {
                row[r_count + k] = e[i * n + j] / root[i];
            }
        });
        let norm2: Vec<f64> = (0..n).map(|k| (0..n).map(|i| u[i * n + k] * u[i * n + k]).sum()).collect();
        // |M u_k|²_W for M = R and B, column k of M U; 0 for the unseen.
        let response =
            |m: &[f64]| -> Vec<f64> {
                let mut mu = vec![0.0; n * n];
                product((m, n, n, false), (&u, n, false), &mut mu);
                (0..n)
                    .map(|k| {
                        if k >= r_count { 0.0 } else { (0..n).map(|i| weight(i) * mu[i * n + k] * mu[i * n + k]).sum() }
                    })
                    .collect()
            };
        let (ramp, boxed) = (response(&r), response(&b));
        let axis_null: Vec<bool> = (0..n).map(|k| k >= r_count).collect();
        u.iter().all(|v| v.is_finite()).then_some(Basis { u, ramp, boxed, norm2, axis_null })
    }
}

impl Basis {
    /// Each basis vector's measure Σ_i W_i u_k[i]².
    pub(super) fn measure(&self, weights: &[f64]) -> Vec<f64> {
        let n = weights.len();
        (0..n).map(|k| (0..n).map(|i| weights[i] * self.u[i * n + k] * self.u[i * n + k]).sum()).collect()
    }
}

/// Takes out of `z` (rows of `wx.len()`) its W-orthogonal projection on
/// the separable modes u ⊗ v of `modes` (u along the rows, v down the
/// columns): their Gram matrix is the product of the axes' (W is
/// W_y ⊗ W_x), solved by Gaussian elimination.
///
/// Errors: [`crate::Error::Limits`] when the projection's memory
/// ([`null_projection_bytes`]) is not there. It is checked here, with
/// the count found, rather than up front: the count depends on the
/// slopes, and is a handful where the worst case is [`MAX_NULLS`]
/// (a Gram matrix of 128 MiB).
pub(super) fn project_out(modes: &[(Vec<f64>, Vec<f64>)], (wx, wy): (&[f64], &[f64]), z: &mut [f64]) -> Result<()> {
    let count = modes.len();
    let (w, h) = (wx.len(), wy.len());
    crate::memory::check_memory("taking the fit's null modes out of the heights", null_projection_bytes(count, w, h))?;
    let dot = |a: &[f64], b: &[f64], m: &[f64]| a.iter().zip(b).zip(m).map(|((a, b), m)| a * b * m).sum::<f64>();
    let mut gram = vec![0.0; count * count];
    for i in 0..count {
        for j in 0..count {
            gram[i * count + j] = dot(&modes[i].0, &modes[j].0, wx) * dot(&modes[i].1, &modes[j].1, wy);
        }
    }
    // ⟨n_i, z⟩_W = Σ_y v[y] W_y Σ_x u[x] W_x z[y][x].
    let mut rhs: Vec<f64> = modes
        .iter()
        .map(|(u, v)| z.chunks(w).enumerate().map(|(y, row)| v[y] * wy[y] * dot(u, row, wx)).sum())
        .collect();
    let Some(alpha) = gauss(&mut gram, &mut rhs, count) else { return Ok(()) };
    z.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for ((u, v), a) in modes.iter().zip(&alpha) {
            let f = a * v[y];
            if f != 0.0 {
                row.iter_mut().zip(u).for_each(|(z, u)| *z -= f * u);
            }
        }
    });
    Ok(())
}

/// The solution of the small dense system `a x = b` (count × count) by
/// Gaussian elimination with partial pivoting; `None` if singular.
fn gauss(a: &mut [f64], b: &mut [f64], n: usize) -> Option<Vec<f64>> {
    for col in 0..n {
        let pivot = (col..n).max_by(|&p, &q| a[p * n + col].abs().total_cmp(&a[q * n + col].abs()))?;
        if a[pivot * n + col].abs() <= f64::MIN_POSITIVE {
            return None;
        }
        if pivot != col {
            for k in 0..n {
                a.swap(col * n + k, pivot * n + k);
            }
            b.swap(col, pivot);
        }
        for row in col + 1..n {
            let f = a[row * n + col] / a[col * n + col];
            for k in col..n {
                a[row * n + k] -= f * a[col * n + k];
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = vec![0.0; n];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|k| a[row * n + k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row * n + row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// What taking `count` null modes out of a `w` × `h` map holds: each
/// mode's two axis vectors, their Gram matrix and its right-hand side and
/// solution, and the list of them.
fn null_projection_bytes(count: usize, w: usize, h: usize) -> u64 {
    let count = count as u64;
    8 * (count * count + count * (w as u64 + h as u64 + 2)) + 48 * count
}

/// out = m · U (`transposed`: m · Uᵀ), m of rows of `w`, U w × w.
fn multiply_right(m: &[f64], w: usize, u: &[f64], transposed: bool, out: &mut [f64]) {
    product((m, m.len() / w, w, false), (u, w, transposed), out);
}

/// out = V · m (`transposed`: Vᵀ · m), V h × h, m of h rows of `w`.
pub(super) fn multiply_left(v: &[f64], h: usize, transposed: bool, m: &[f64], w: usize, out: &mut [f64]) {
    product((v, h, h, transposed), (m, w, false), out);
}

/// out = A B, A of `rows` × `inner` and B of `inner` × `columns`, each
/// row-major or (its flag) given as its transpose; bands of out's rows in
/// parallel, each one matrixmultiply's blocked product (through ndarray:
/// the crate forbids unsafe code).
fn product(
    (a, rows, inner, a_transposed): (&[f64], usize, usize, bool),
    (b, columns, b_transposed): (&[f64], usize, bool),
    out: &mut [f64],
) {
    use ndarray::{ArrayView2, ArrayViewMut2, Axis, Slice, linalg::general_mat_mul};
    fn view(m: &[f64], r: usize, c: usize, transposed: bool) -> ArrayView2<'_, f64> {
        let m = &m[..r * c];
        if transposed {
            ArrayView2::from_shape((c, r), m).expect("a matrix of its size").reversed_axes()
        } else {
            ArrayView2::from_shape((r, c), m).expect("a matrix of its size")
        }
    }
    let (a, b) = (view(a, rows, inner, a_transposed), view(b, inner, columns, b_transposed));
    if rows == 0 || columns == 0 {
        return;
    }
    // One band a thread: each band packs all of B again (four a thread
    // took 8 % longer on 512² clamp, N = 63; the same bits).
    let band = rows.div_ceil(crate::par::current_num_threads()).max(16);
    out[..rows * columns].par_chunks_mut(band * columns).enumerate().for_each(|(i, chunk)| {
        let first = i * band;
        let count = chunk.len() / columns;
        let mut c = ArrayViewMut2::from_shape((count, columns), chunk).expect("a band of its size");
        general_mat_mul(1.0, &a.slice_axis(Axis(0), Slice::from(first..first + count)), &b, 0.0, &mut c);
    });
}

fn transpose(m: &[f64], n: usize) -> Vec<f64> {
    let mut t = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            t[j * n + i] = m[i * n + j];
        }
    }
    t
}

/// The eigenvalues and eigenvectors (row-major: Y[i][k] = component i of
/// vector k) of the symmetric `a`: Householder's reduction to tridiagonal
/// form and the implicit QL method (`tred2` and `tql2` of EISPACK, as in
/// JAMA). `None` if QL does not converge (a matrix not finite). The loops
/// keep EISPACK's indices, line for line, so the port can be read against
/// it.
#[allow(clippy::needless_range_loop)]
fn symmetric_eigen(a: Vec<f64>, n: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    // Column-major work matrix: v[j * n + i] = V[i][j].
    let mut v = transpose(&a, n);
    drop(a);
    let at = |v: &Vec<f64>, i: usize, j: usize| v[j * n + i];
    let (mut d, mut e) = (vec![0.0; n], vec![0.0; n]);
    if n == 0 {
        return Some((d, v));
    }
    // tred2.
    for j in 0..n {
        d[j] = at(&v, n - 1, j);
    }
    for i in (1..n).rev() {
        let (mut scale, mut h) = (0.0, 0.0);
        for k in 0..i {
            scale += d[k].abs();
        }
        if scale == 0.0 {
            e[i] = d[i - 1];
            for j in 0..i {
                d[j] = at(&v, i - 1, j);
                v[j * n + i] = 0.0;
                v[i * n + j] = 0.0;
            }
        } else {
            for k in 0..i {
                d[k] /= scale;
                h += d[k] * d[k];
            }
            let mut f = d[i - 1];
            let mut g = h.sqrt();
            if f > 0.0 {
                g = -g;
            }
            e[i] = scale * g;
            h -= f * g;
            d[i - 1] = f - g;
            for ej in e.iter_mut().take(i) {
                *ej = 0.0;
            }
            for j in 0..i {
                f = d[j];
                v[i * n + j] = f;
                g = e[j] + at(&v, j, j) * f;
                for k in j + 1..i {
                    g += at(&v, k, j) * d[k];
                    e[k] += at(&v, k, j) * f;
                }
                e[j] = g;
            }
            f = 0.0;
            for j in 0..i {
                e[j] /= h;
                f += e[j] * d[j];
            }
            let hh = f / (h + h);
            for j in 0..i {
                e[j] -= hh * d[j];
            }
            for j in 0..i {
                f = d[j];
                g = e[j];
                for k in j..i {
                    v[j * n + k] -= f * e[k] + g * d[k];
                }
                d[j] = at(&v, i - 1, j);
                v[j * n + i] = 0.0;
            }
        }
        d[i] = h;
    }
    for i in 0..n - 1 {
        v[i * n + n - 1] = at(&v, i, i);
        v[i * n + i] = 1.0;
        let h = d[i + 1];
        if h != 0.0 {
            for k in 0..=i {
                d[k] = at(&v, k, i + 1) / h;
            }
            for j in 0..=i {
                let mut g = 0.0;
                for k in 0..=i {
                    g += at(&v, k, i + 1) * at(&v, k, j);
                }
                for k in 0..=i {
                    v[j * n + k] -= g * d[k];
                }
            }
        }
        for k in 0..=i {
            v[(i + 1) * n + k] = 0.0;
        }
    }
    for j in 0..n {
        d[j] = at(&v, n - 1, j);
        v[j * n + n - 1] = 0.0;
    }
    v[(n - 1) * n + n - 1] = 1.0;
    e[0] = 0.0;

    // tql2.
    for i in 1..n {
        e[i - 1] = e[i];
    }
    e[n - 1] = 0.0;
    let (mut f, mut tst1) = (0.0f64, 0.0f64);
    let eps = f64::EPSILON;
    for l in 0..n {
        tst1 = tst1.max(d[l].abs() + e[l].abs());
        let mut m = l;
        while m < n - 1 && e[m].abs() > eps * tst1 {
            m += 1;
        }
        if m > l {
            let mut iterations = 0;
            loop {
                iterations += 1;
                if iterations > 60 {
                    return None;
                }
                let mut g = d[l];
                let mut p = (d[l + 1] - g) / (2.0 * e[l]);
                let mut r = p.hypot(1.0);
                if p < 0.0 {
                    r = -r;
                }
                d[l] = e[l] / (p + r);
                d[l + 1] = e[l] * (p + r);
                let dl1 = d[l + 1];
                let mut h = g - d[l];
                for di in d.iter_mut().skip(l + 2) {
                    *di -= h;
                }
                f += h;
                p = d[m];
                let (mut c, mut c2, mut c3) = (1.0, 1.0, 1.0);
                let el1 = e[l + 1];
                let (mut s, mut s2) = (0.0, 0.0);
                for i in (l..m).rev() {
                    c3 = c2;
                    c2 = c;
                    s2 = s;
                    g = c * e[i];
                    h = c * p;
                    r = p.hypot(e[i]);
                    e[i + 1] = s * r;
                    s = e[i] / r;
                    c = p / r;
                    p = c * d[i] - s * g;
                    d[i + 1] = h + s * (c * g + s * d[i]);
                    // Columns i and i + 1 of V, each contiguous here.
                    let (left, right) = v.split_at_mut((i + 1) * n);
                    let (ci, ci1) = (&mut left[i * n..], &mut right[..n]);
                    for (a, b) in ci.iter_mut().zip(ci1.iter_mut()) {
                        let hk = *b;
                        *b = s * *a + c * hk;
                        *a = c * *a - s * hk;
                    }
                }
                p = -s * s2 * c3 * el1 * e[l] / dl1;
                e[l] = s * p;
                d[l] = c * p;
                // Converged, or not a number (then QL stops, and the
                // eigenvalues' finiteness check below refuses them).
                if e[l].abs() <= eps * tst1 || e[l].is_nan() {
                    break;
                }
            }
        }
        d[l] += f;
        e[l] = 0.0;
    }
    if !d.iter().all(|x| x.is_finite()) {
        return None;
    }
    Some((d, transpose(&v, n)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The eigensolver against its definition: A Y = Y Λ and YᵀY = I, on
    /// symmetric matrices with repeated, zero and spread eigenvalues.
    #[test]
    fn symmetric_eigen_meets_its_definition() {
        for n in [1, 2, 3, 7, 40] {
            let mut a = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..=i {
                    let v = (((i * 31 + j * 17) % 23) as f64 - 11.0) / 7.0 + if i == j { (i % 3) as f64 } else { 0.0 };
                    a[i * n + j] = v;
                    a[j * n + i] = v;
                }
            }
            // A rank-deficient one too: the outer product of a vector.
            let ones: Vec<f64> = (0..n * n).map(|k| ((k / n + 1) * (k % n + 1)) as f64).collect();
            for m in [a, ones] {
                let (d, y) = symmetric_eigen(m.clone(), n).unwrap();
                let scale = m.iter().fold(1.0f64, |s, v| s.max(v.abs())) * n as f64;
                for k in 0..n {
                    for i in 0..n {
                        let ay: f64 = (0..n).map(|j| m[i * n + j] * y[j * n + k]).sum();
                        assert!((ay - d[k] * y[i * n + k]).abs() < 1e-12 * scale, "n {n}: A y ≠ λ y");
                    }
                    for l in 0..n {
                        let dot: f64 = (0..n).map(|i| y[i * n + k] * y[i * n + l]).sum();
                        let want = if k == l { 1.0 } else { 0.0 };
                        assert!((dot - want).abs() < 1e-12, "n {n}: YᵀY ≠ I");
                    }
                }
            }
        }
    }
}
