//! The exact vertical solve under clamp with N ≥ 5 where an axis is too
//! long for a dense basis (`dense.rs`): the dense basis on the shorter
//! axis only, and along the longer, clamped one a banded solve per mode.
//!
//! With V the shorter axis's generalised eigenbasis (`dense::Basis`:
//! VᵀP V = diag(ρ), VᵀQ V = diag(β) over the modes it sees), the normal
//! matrix (Q_s ⊗ P_l + P_s ⊗ Q_l)/A² (s the shorter axis, l the longer)
//! falls apart into one system per mode k of V along the longer axis:
//!
//! ```text
//! K_k = (β_k P_l + ρ_k Q_l) / A² + λ |v_k|² I,   P_l = R_lᵀR_l,  Q_l = B_lᵀB_l
//! ```
//!
//! A clamped axis reads only texels within r of each output (its edge
//! weights fall on the first and last texel, within r too), so R_l and B_l
//! are banded with half-bandwidth r, and P_l, Q_l with 2r: K_k is factored
//! by banded Cholesky in O(n r²) and solved in O(n r). A solve is then two
//! dense products along the shorter axis, O(texels · m), and the banded
//! systems, O(texels · r²): linear in the longer axis. The cost grows with
//! N², so the path takes patches up to [`MAX_BAND`] (N = 63), and the
//! shorter axis up to [`MAX_DENSE`] texels.
//!
//! The modes of V that the ramp does not see (ρ_k at rounding level: the
//! constant along the shorter axis) leave K_k = β_k P_l / A², whose null
//! vector is the constant along the longer axis (its ramp is 0): those
//! systems are solved with the first texel pinned (any solution of a
//! consistent system), and their null modes, 1 ⊗ v_k, are then taken out
//! of the heights in W's measure (`dense::project_out`), as the dense
//! solve does: the least squares of least norm. The modes of V that
//! neither the ramp nor the box sees are 0. That the longer axis's ramp
//! sees every direction but the constant, and its box every direction, is
//! checked when the solver is made (each factorisation's pivots); where
//! it does not hold there is no solver.

use crate::error::Result;
use crate::options::Border;
use crate::par::prelude::*;
use crate::samples::try_filled;

use super::dense::{Basis, DenseSolver, MAX_DENSE, NULL, multiply_left, project_out};
use super::line::{Line, Scratch};
use super::patch::Patch;

/// The widest band taken: P and Q of patches up to N = 63 (2r = 62). A
/// solve's banded part costs some n r² a mode, 1 GFlop at 2048 × 256,
/// N = 63; wider patches are refused (`memory.rs` says so up front).
pub(super) const MAX_BAND: usize = 62;

/// Modes solved per task (each task holds one factor, n (2r + 1) values).
const MODES_PER_TASK: usize = 4;

/// A pivot below this part of its row's diagonal is a singular system.
const PIVOT: f64 = 1e-12;

/// The solve with one dense axis.
pub(super) struct OneAxis {
    /// The shorter (dense) axis's texels m and the longer (banded) one's n.
    m: usize,
    n: usize,
    /// Whether the dense axis is x: the planes are then transposed, so
    /// that rows run along the banded axis in either case.
    transposed: bool,
    a: f64,
    basis: Basis,
    /// The half-bandwidth of P and Q: 2r, at most n − 1.
    band: usize,
    /// P and Q of the banded axis, lower band: row i holds columns
    /// i − band … i (those before 0 are 0).
    p: Vec<f64>,
    q: Vec<f64>,
}

impl OneAxis {
    /// The solver of `patch`'s fit on an image of `h` rows, or `None`
    /// where the path does not apply: the shorter axis past
    /// [`MAX_DENSE`], the longer one not clamped (or one texel), a band
    /// wider than [`MAX_BAND`], or the longer axis's ramp or box blind to
    /// more than the constant.
    pub(super) fn new(patch: &Patch, h: usize) -> Option<OneAxis> {
        let w = patch.w;
        let transposed = w < h;
        let (m, n) = if transposed { (w, h) } else { (h, w) };
        let (dense_line, dense_border, long_line, long_border) = if transposed {
            (&patch.x, patch.borders.x, &patch.y, patch.borders.y)
        } else {
            (&patch.y, patch.borders.y, &patch.x, patch.borders.x)
        };
        let r = patch.patch / 2;
        if !applies(m, n, long_border, r) {
            return None;
        }
        let band = (2 * r).min(n - 1);
        let (p, q) = normal_bands(long_line, n, r, band);
        let basis = Basis::new(dense_line, m, dense_border)?;
        let solver = OneAxis { m, n, transposed, a: patch.a, basis, band, p, q };
        // The longer axis's ramp blind to the constant alone (P with its
        // first texel pinned is definite); where a mode of the dense axis
        // is one its box does not see, the longer axis's box blind to
        // nothing (Q definite: its clamped box can be singular, as at
        // 2048 texels, N = 5).
        let mut work = vec![0.0; n * (band + 1)];
        let pinned = solver.factor(&mut work, 1.0, 0.0, 0.0, true);
        let box_blind = (0..m).any(|k| !solver.basis.axis_null[k] && solver.basis.boxed[k] <= NULL);
        let boxed = !box_blind || solver.factor(&mut work, 0.0, 1.0, 0.0, false);
        (pinned && boxed).then_some(solver)
    }

    /// As [`super::dense::DenseSolver::solve`]: the heights whose
    /// vertical-fit slopes are closest to those whose right-hand side
    /// DᵀWg is `b` (overwritten), of least W-norm, into `z`.
    ///
    /// Errors: [`crate::Error::Limits`] when a plane's memory is not there.
    pub(super) fn solve(&self, b: &mut [f64], lambda: f64, weights: (&[f64], &[f64]), z: &mut [f64]) -> Result<()> {
        let nulls = self.apply(b, lambda, None, z)?;
        if nulls.is_empty() || nulls.len() > super::dense::MAX_NULLS {
            return Ok(());
        }
        // 1 ⊗ v_k in the frame of the bands (rows along the banded axis).
        let dense_weights = if self.transposed { weights.0 } else { weights.1 };
        let ones = vec![1.0; self.n];
        let modes: Vec<(Vec<f64>, Vec<f64>)> = nulls
            .iter()
            .map(|&k| (ones.clone(), (0..self.m).map(|i| self.basis.u[i * self.m + k]).collect()))
            .collect();
        if self.transposed {
            let mut t = try_filled(z.len(), 0.0)?;
            transpose(z, self.m, &mut t);
            project_out(&modes, (&ones, dense_weights), &mut t)?;
            transpose(&t, self.n, z);
            Ok(())
        } else {
            project_out(&modes, (&ones, dense_weights), z)
        }
    }

    /// As [`super::dense::DenseSolver::inverse`]: (DᵀWD + (λ + ε)W)⁻¹ W b,
    /// every mode divided. `b` is kept.
    ///
    /// Errors: [`crate::Error::Limits`] when a plane's memory is not there.
    pub(super) fn inverse(
        &self,
        b: &[f64],
        lambda: f64,
        epsilon: f64,
        (wx, wy): (&[f64], &[f64]),
        out: &mut [f64],
    ) -> Result<()> {
        let w = wx.len();
        let mut weighted = try_filled(b.len(), 0.0)?;
        weighted.par_chunks_mut(w).zip(b.par_chunks(w)).enumerate().for_each(|(y, (o, b))| {
            for ((o, b), m) in o.iter_mut().zip(b).zip(wx) {
                *o = b * m * wy[y];
            }
        });
        let dense_weights = if self.transposed { wx } else { wy };
        self.apply(&mut weighted, lambda + epsilon, Some(dense_weights), out).map(|_| ())
    }

    /// z = V K⁻¹ Vᵀ b along the dense axis, K per mode: λ in each mode's
    /// measure along the dense axis (W's where `weights` is given, else the
    /// identity's) times the identity along the banded one. Without
    /// `weights` the modes the dense axis does not see are 0 and those its
    /// ramp does not see are pinned; returns the latter.
    fn apply(&self, b: &mut [f64], lambda: f64, weights: Option<&[f64]>, z: &mut [f64]) -> Result<Vec<usize>> {
        let (m, n, u) = (self.m, self.n, &self.basis.u);
        let mut t = try_filled(b.len(), 0.0)?;
        // In the frame of the bands: m rows (the dense axis) of n (the
        // banded one). c = Vᵀ b, each mode solved, z = V c.
        let pinned = if self.transposed {
            transpose(b, m, &mut t);
            multiply_left(u, m, true, &t, n, b);
            let pinned = self.solve_modes(b, lambda, weights);
            multiply_left(u, m, false, b, n, &mut t);
            transpose(&t, n, z);
            pinned
        } else {
            multiply_left(u, m, true, b, n, &mut t);
            let pinned = self.solve_modes(&mut t, lambda, weights);
            multiply_left(u, m, false, &t, n, z);
            pinned
        };
        Ok(pinned)
    }

    /// Each mode's row of `c` (the dense axis's coefficients, rows along
    /// the banded axis) solved in place; returns the pinned modes.
    fn solve_modes(&self, c: &mut [f64], lambda: f64, weights: Option<&[f64]>) -> Vec<usize> {
        let n = self.n;
        let measure = match weights {
            Some(w) => self.basis.measure(w),
            None => self.basis.norm2.clone(),
        };
        let every = weights.is_some();
        let a2 = self.a * self.a;
        let pinned: Vec<Vec<usize>> = c
            .par_chunks_mut(n * MODES_PER_TASK)
            .enumerate()
            .map(|(task, rows)| {
                let mut work = vec![0.0; n * (self.band + 1)];
                let mut pinned = Vec::new();
                for (i, row) in rows.chunks_mut(n).enumerate() {
                    let k = task * MODES_PER_TASK + i;
                    let gamma = lambda * measure[k];
                    if self.basis.axis_null[k] {
                        let scale = if every && gamma > 0.0 { 1.0 / gamma } else { 0.0 };
                        row.iter_mut().for_each(|v| *v *= scale);
                        continue;
                    }
                    let blind = !every && self.basis.ramp[k] <= NULL;
                    let alpha = if !every && self.basis.boxed[k] <= NULL { 0.0 } else { self.basis.boxed[k] / a2 };
                    let beta = if blind { 0.0 } else { self.basis.ramp[k] / a2 };
                    if self.factor(&mut work, alpha, beta, gamma, blind) {
                        self.substitute(&work, row);
                    } else {
                        // Not expected: the factorisations were checked
                        // when the solver was made.
                        row.fill(0.0);
                    }
                    if blind {
                        pinned.push(k);
                    }
                }
                pinned
            })
            .collect();
        pinned.into_iter().flatten().collect()
    }

    /// Factors K = αP + βQ + γI (plus the first texel pinned) into `work`,
    /// its lower band's Cholesky factor L, row i holding columns
    /// i − band … i; false where a pivot fails (K not definite).
    fn factor(&self, work: &mut [f64], alpha: f64, beta: f64, gamma: f64, pin: bool) -> bool {
        let (n, b) = (self.n, self.band);
        let width = b + 1;
        for ((o, p), q) in work.iter_mut().zip(&self.p).zip(&self.q) {
            *o = alpha * p + beta * q;
        }
        for i in 0..n {
            work[i * width + b] += gamma;
        }
        if pin {
            // The pin: as large as the diagonal, so the factor stays as
            // well conditioned as P is on the directions it sees.
            let largest = (0..n).map(|i| work[i * width + b]).fold(0.0f64, f64::max);
            work[b] += largest.max(f64::MIN_POSITIVE);
        }
        for i in 0..n {
            let (before, rest) = work.split_at_mut(i * width);
            let row = &mut rest[..width];
            let lo = i.saturating_sub(b);
            for j in lo..i {
                let other = &before[j * width..][..width];
                // L[i][p] = row[p + b − i], L[j][p] = other[p + b − j].
                let from = lo.max(j.saturating_sub(b));
                let s: f64 = row[from + b - i..j + b - i].iter().zip(&other[from + b - j..b]).map(|(x, y)| x * y).sum();
                row[j + b - i] = (row[j + b - i] - s) / other[b];
            }
            let diagonal = row[b];
            let s: f64 = row[lo + b - i..b].iter().map(|x| x * x).sum();
            let pivot = diagonal - s;
            if !(pivot > PIVOT * diagonal.abs() && pivot.is_finite()) {
                return false;
            }
            row[b] = pivot.sqrt();
        }
        true
    }

    /// Solves L Lᵀ x = `rhs` in place, L the factor in `work`.
    fn substitute(&self, work: &[f64], rhs: &mut [f64]) {
        let (n, b) = (self.n, self.band);
        let width = b + 1;
        for i in 0..n {
            let row = &work[i * width..][..width];
            let lo = i.saturating_sub(b);
            let s: f64 = row[lo + b - i..b].iter().zip(&rhs[lo..i]).map(|(l, y)| l * y).sum();
            rhs[i] = (rhs[i] - s) / row[b];
        }
        for i in (0..n).rev() {
            let row = &work[i * width..][..width];
            rhs[i] /= row[b];
            let (lo, x) = (i.saturating_sub(b), rhs[i]);
            for (p, l) in rhs[lo..i].iter_mut().zip(&row[lo + b - i..b]) {
                *p -= l * x;
            }
        }
    }
}

/// Refuses, before any solve, the exact inverse of a map that no exact
/// solve here takes in time linear in its texels: clamp with N ≥ 5 (no
/// transform) with both sides past [`MAX_DENSE`], where a dense basis
/// would cost O(n³) and each solve O(texels · n), and conjugate
/// gradients with the half-sample preconditioner took more than 1000
/// iterations a solve (2048 × 256, N = 5: 151 s, unsettled at N = 63).
/// A map without a slope never comes here: its heights are 0.
///
/// Errors: [`crate::Error::InvalidOption`] naming the limit and what to
/// use instead.
pub(super) fn check_shape(w: usize, h: usize, borders: crate::Borders, patch: usize) -> Result<()> {
    use super::solve::Axis;
    let r = patch / 2;
    let transform = Axis::new(w, borders.x, r).is_some() && Axis::new(h, borders.y, r).is_some();
    if transform || w.min(h) <= MAX_DENSE {
        return Ok(());
    }
    Err(crate::Error::InvalidOption(format!(
        "clamp borders with N ≥ 5 are solved for maps with a side of at most {MAX_DENSE} texels; \
         this one is {w} × {h}: use --border mirror or wrap, or N = 3"
    )))
}

/// Whether the path takes a map whose shorter axis has `m` texels and
/// whose longer one `n`, with `border`, for a patch of radius `r`.
pub(super) fn applies(m: usize, n: usize, border: Border, r: usize) -> bool {
    m <= MAX_DENSE && n >= 2 && border == Border::Clamp && (2 * r).min(n - 1) <= MAX_BAND
}

/// P = RᵀR and Q = BᵀB of a clamped line of `n` texels, patch radius `r`,
/// as lower bands of half-bandwidth `band`: R and B read from the line's
/// own sums (`line.rs`) of each unit vector, which reach r texels at most.
fn normal_bands(line: &Line, n: usize, r: usize, band: usize) -> (Vec<f64>, Vec<f64>) {
    let width = band + 1;
    let reach = 2 * r + 1;
    // Row x of R and B: columns x − r … x + r.
    let (mut rows_r, mut rows_b) = (vec![0.0; n * reach], vec![0.0; n * reach]);
    let (mut unit, mut boxed, mut ramped) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut scratch = Scratch::default();
    for j in 0..n {
        unit[j] = 1.0;
        line.apply(&unit, Some(&mut boxed), Some(&mut ramped), &mut scratch);
        unit[j] = 0.0;
        for x in j.saturating_sub(r)..(j + r + 1).min(n) {
            rows_r[x * reach + j + r - x] = ramped[x];
            rows_b[x * reach + j + r - x] = boxed[x];
        }
    }
    let gram = |rows: &[f64]| {
        let mut g = vec![0.0; n * width];
        for x in 0..n {
            let row = &rows[x * reach..][..reach];
            for (a, &u) in row.iter().enumerate() {
                if u == 0.0 || x + a < r || x + a - r >= n {
                    continue;
                }
                let i = x + a - r;
                for (c, &v) in row[..=a].iter().enumerate() {
                    if x + c < r {
                        continue;
                    }
                    // Column j = x + c − r ≤ i, within the band.
                    let j = x + c - r;
                    g[i * width + j + band - i] += u * v;
                }
            }
        }
        g
    };
    (gram(&rows_r), gram(&rows_b))
}

/// `m` (rows of `w`) transposed into `out` (rows of m.len() / w).
fn transpose(m: &[f64], w: usize, out: &mut [f64]) {
    let h = m.len() / w.max(1);
    // Blocks of rows of the output in parallel, each reading its columns.
    out.par_chunks_mut(h * 16).enumerate().for_each(|(block, chunk)| {
        let x0 = block * 16;
        for (c, row) in chunk.chunks_mut(h).enumerate() {
            for (y, o) in row.iter_mut().enumerate() {
                *o = m[y * w + x0 + c];
            }
        }
    });
}

/// The exact vertical solve of a clamped map without a transform: dense
/// bases on both axes (`dense.rs`) where both are short enough, else the
/// dense basis on the shorter one and banded solves along the other.
pub(super) enum Separable {
    Dense(DenseSolver),
    OneAxis(OneAxis),
}

impl Separable {
    /// The solver of `patch`'s fit on an image of `h` rows, or `None`
    /// where neither applies.
    pub(super) fn new(patch: &Patch, h: usize) -> Option<Separable> {
        DenseSolver::new(patch, h).map(Separable::Dense).or_else(|| OneAxis::new(patch, h).map(Separable::OneAxis))
    }

    /// As [`DenseSolver::solve`]; `null` (the threshold of the modes left
    /// out) is the dense bases', whose 2-D modes each have their own d: the
    /// banded solves take the exact least squares.
    pub(super) fn solve(
        &self,
        b: &mut [f64],
        lambda: f64,
        null: f64,
        weights: (&[f64], &[f64]),
        z: &mut [f64],
    ) -> Result<()> {
        match self {
            Separable::Dense(dense) => dense.solve(b, lambda, null, weights, z),
            Separable::OneAxis(one) => one.solve(b, lambda, weights, z),
        }
    }

    /// As [`DenseSolver::inverse`].
    pub(super) fn inverse(
        &self,
        b: &[f64],
        lambda: f64,
        epsilon: f64,
        weights: (&[f64], &[f64]),
        out: &mut [f64],
    ) -> Result<()> {
        match self {
            Separable::Dense(dense) => dense.inverse(b, lambda, epsilon, weights, out),
            Separable::OneAxis(one) => one.inverse(b, lambda, epsilon, weights, out),
        }
    }
}
