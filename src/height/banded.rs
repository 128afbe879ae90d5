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
//! N², so the path takes patches up to [`MAX_BAND`](super::cost::MAX_BAND) (N = 63), and the
//! shorter axis up to [`MAX_DENSE`](super::dense::MAX_DENSE) texels.
//!
//! The modes of V that the ramp does not see (ρ_k at rounding level: the
//! constant along the shorter axis) leave K_k = β_k P_l / A², blind to
//! the null vectors of the longer axis's ramp: the constant, and for some
//! lengths and N others; the modes its box does not see leave ρ_k Q_l /
//! A², blind to those of its box (a clamped box is singular at some
//! lengths, as at 2048 texels, N = 5; the strips 1030 × 3, 2 × 1100,
//! 1100 × 24 and 20 × 1040 at N = 5 need such pins). Those systems are solved
//! with one texel pinned per null direction (any solution of a
//! consistent system), and their null modes, u ⊗ v_k, are then taken out
//! of the heights in W's measure (`dense::project_out`), as the dense
//! solve does: the least squares of least norm. The pins are found when
//! the solver is made, by factoring P_l (and Q_l where a mode needs it)
//! with a pin wherever a pivot fails; each pinned solution K′⁻¹e_s must
//! be a null vector (else the pin would change the solution: no solver),
//! and they are the null vectors u projected out.

use crate::error::Result;
use crate::options::Border;
use crate::par::prelude::*;
use crate::samples::try_filled;

use super::cost::applies;
use super::dense::{Basis, DenseSolver, NULL, multiply_left, project_out};
use super::patch::Patch;

/// Modes solved per task (each task holds one factor, n (2r + 1) values).
const MODES_PER_TASK: usize = 4;

/// A pivot below this part of its row's diagonal is a singular system.
const PIVOT: f64 = 1e-12;

/// The most null directions pinned along the banded axis (the ramp's or
/// the box's); more, and there is no banded solver. A clamped edge folds
/// up to r texels' reads onto one, and the null directions grow with r:
/// at N = 63 the ramp's P had 15 to 22 and the box's Q 20 to 30 (1030,
/// 2048 and 20000 texels), against 1 at N = 5.
pub(super) const MAX_PINS: usize = 64;

/// How far c·x_s(t) may be from δ_st for the pinned texels' vectors x_s
/// to be taken as null vectors (c the pin). The rounding of a pinned
/// solve grows with the rest's conditioning, as n²: the null directions
/// at N = 63 came out within 1.5e-9 at 1030 texels, 3.5e-6 at 2048 and
/// 1.2e-5 at 20000; a direction that is seen is off by its eigenvalue's
/// share of the pin.
const PIN_CHECK: f64 = 1e-4;

/// The null directions of the banded axis's ramp or box: the texels
/// pinned, and a null vector for each.
#[derive(Default)]
struct Nulls {
    pins: Vec<usize>,
    vectors: Vec<Vec<f64>>,
}

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
    /// The null directions of P (the constant, and for some lengths
    /// others) and, where a mode of the dense axis needs them, of Q.
    ramp_nulls: Nulls,
    box_nulls: Nulls,
}

impl OneAxis {
    /// The solver of `patch`'s fit on an image of `h` rows, or `None`
    /// where the path does not apply: the shorter axis past
    /// [`MAX_DENSE`](super::dense::MAX_DENSE), the longer one not clamped (or one texel), a band
    /// wider than [`MAX_BAND`](super::cost::MAX_BAND), or the longer axis's ramp or box blind to
    /// more than [`MAX_PINS`] directions, or a pin on one that is seen.
    pub(super) fn new(patch: &Patch, h: usize) -> Option<OneAxis> {
        let w = patch.w;
        let transposed = w < h;
        let (m, n) = if transposed { (w, h) } else { (h, w) };
        let (dense_line, dense_border, long_border) = if transposed {
            (&patch.x, patch.borders.x, patch.borders.y)
        } else {
            (&patch.y, patch.borders.y, patch.borders.x)
        };
        let r = patch.patch / 2;
        if !applies(m, n, long_border, r) {
            return None;
        }
        let band = (2 * r).min(n - 1);
        let (p, q) = normal_bands(n, r, band);
        let basis = Basis::new(dense_line, m, dense_border)?;
        let mut solver = OneAxis {
            m,
            n,
            transposed,
            a: patch.a,
            basis,
            band,
            p,
            q,
            ramp_nulls: Nulls::default(),
            box_nulls: Nulls::default(),
        };
        // The longer axis's ramp blind to a few directions (the constant,
        // and for some lengths and N others: P with those texels pinned is
        // definite); where a mode of the dense axis is one its box does not
        // see, the longer axis's box's null directions too (its clamped box
        // can be singular, as at 2048 texels, N = 5, or 1030, N = 5).
        solver.ramp_nulls = solver.nulls(1.0, 0.0)?;
        let box_blind = (0..m).any(|k| !solver.basis.axis_null[k] && solver.basis.boxed[k] <= NULL);
        if box_blind {
            solver.box_nulls = solver.nulls(0.0, 1.0)?;
        }
        Some(solver)
    }

    /// The null directions of αP + βQ (one of them 0) along the banded
    /// axis: the texels whose pins make it definite, found by factoring
    /// with a pin wherever a pivot fails, and the null vectors, K'⁻¹ e_s
    /// for each pinned texel s (K' the pinned matrix). Every pin must
    /// stand for a null direction (K x_s = 0 to rounding: a pin where K is
    /// merely ill-conditioned would change the solution); `None` where one
    /// does not, or where more than [`MAX_PINS`] are needed.
    fn nulls(&self, alpha: f64, beta: f64) -> Option<Nulls> {
        let mut work = vec![0.0; self.n * (self.band + 1)];
        let pins = self.factor_pinning(&mut work, alpha, beta)?;
        if pins.is_empty() {
            return Some(Nulls::default());
        }
        if !self.factor(&mut work, alpha, beta, 0.0, &pins) {
            return None;
        }
        let c = self.pin_value(alpha, beta);
        let vectors: Vec<Vec<f64>> = pins
            .iter()
            .map(|&s| {
                let mut x = vec![0.0; self.n];
                x[s] = 1.0;
                self.substitute(&work, &mut x);
                x
            })
            .collect();
        // A null vector x_s of K has K' x_s = c x_s(S) = e_s: c·x_s(t) = δ_st.
        let genuine = vectors.iter().enumerate().all(|(i, x)| {
            pins.iter().enumerate().all(|(j, &t)| (c * x[t] - if i == j { 1.0 } else { 0.0 }).abs() <= PIN_CHECK)
        });
        genuine.then_some(Nulls { pins, vectors })
    }

    /// The value a pin adds to the diagonal: its largest entry, so the
    /// factor stays as well conditioned as K is on the directions it sees.
    fn pin_value(&self, alpha: f64, beta: f64) -> f64 {
        let b = self.band;
        let width = b + 1;
        (0..self.n)
            .map(|i| alpha * self.p[i * width + b] + beta * self.q[i * width + b])
            .fold(0.0f64, f64::max)
            .max(f64::MIN_POSITIVE)
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
        // u ⊗ v_k, u a null vector of the banded axis's ramp (or box), in
        // the frame of the bands (rows along the banded axis).
        let dense_weights = if self.transposed { weights.0 } else { weights.1 };
        let ones = vec![1.0; self.n];
        let modes: Vec<(Vec<f64>, Vec<f64>)> = nulls
            .iter()
            .flat_map(|&(k, ramp)| {
                let v: Vec<f64> = (0..self.m).map(|i| self.basis.u[i * self.m + k]).collect();
                let nulls = if ramp { &self.ramp_nulls } else { &self.box_nulls };
                nulls.vectors.iter().map(move |u| (u.clone(), v.clone()))
            })
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
    /// ramp (or box) does not see are pinned; returns the latter (the
    /// mode, and whether its ramp is the blind one).
    fn apply(&self, b: &mut [f64], lambda: f64, weights: Option<&[f64]>, z: &mut [f64]) -> Result<Vec<(usize, bool)>> {
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
    fn solve_modes(&self, c: &mut [f64], lambda: f64, weights: Option<&[f64]>) -> Vec<(usize, bool)> {
        let n = self.n;
        let measure = match weights {
            Some(w) => self.basis.measure(w),
            None => self.basis.norm2.clone(),
        };
        let every = weights.is_some();
        let a2 = self.a * self.a;
        let pinned: Vec<Vec<(usize, bool)>> = c
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
                    let box_blind = !every && self.basis.boxed[k] <= NULL;
                    let alpha = if box_blind { 0.0 } else { self.basis.boxed[k] / a2 };
                    let beta = if blind { 0.0 } else { self.basis.ramp[k] / a2 };
                    // A mode one of whose responses is blind solves with
                    // the other's null directions pinned (any solution of
                    // a consistent system; they are projected out after).
                    let pins: &[usize] = if blind {
                        &self.ramp_nulls.pins
                    } else if box_blind {
                        &self.box_nulls.pins
                    } else {
                        &[]
                    };
                    if self.factor(&mut work, alpha, beta, gamma, pins) {
                        self.substitute(&work, row);
                    } else {
                        // Not expected: the factorisations were checked
                        // when the solver was made.
                        row.fill(0.0);
                    }
                    if (blind || box_blind) && !pins.is_empty() {
                        pinned.push((k, blind));
                    }
                }
                pinned
            })
            .collect();
        pinned.into_iter().flatten().collect()
    }

    /// Factors K = αP + βQ + γI (plus the texels `pins` pinned) into
    /// `work`, its lower band's Cholesky factor L, row i holding columns
    /// i − band … i; false where a pivot fails (K not definite).
    fn factor(&self, work: &mut [f64], alpha: f64, beta: f64, gamma: f64, pins: &[usize]) -> bool {
        self.factor_with(work, alpha, beta, gamma, pins, false).is_some()
    }

    /// Factors αP + βQ as [`Self::factor`] does, pinning each texel whose
    /// pivot fails; the texels pinned, or `None` past [`MAX_PINS`].
    fn factor_pinning(&self, work: &mut [f64], alpha: f64, beta: f64) -> Option<Vec<usize>> {
        self.factor_with(work, alpha, beta, 0.0, &[], true)
    }

    /// [`Self::factor`], and where `pin_failures`, a failing pivot pinned
    /// (the diagonal's largest entry added) rather than a failure; the
    /// texels so pinned.
    fn factor_with(
        &self,
        work: &mut [f64],
        alpha: f64,
        beta: f64,
        gamma: f64,
        pins: &[usize],
        pin_failures: bool,
    ) -> Option<Vec<usize>> {
        let (n, b) = (self.n, self.band);
        let width = b + 1;
        for ((o, p), q) in work.iter_mut().zip(&self.p).zip(&self.q) {
            *o = alpha * p + beta * q;
        }
        for i in 0..n {
            work[i * width + b] += gamma;
        }
        let largest = self.pin_value(alpha, beta);
        for &s in pins {
            // The pin: as large as the diagonal, so the factor stays as
            // well conditioned as K is on the directions it sees.
            work[s * width + b] += largest;
        }
        let mut pinned = Vec::new();
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
            let mut pivot = diagonal - s;
            if !pivot.is_finite() {
                return None;
            }
            if pivot <= PIVOT * diagonal.abs() {
                if !pin_failures || pinned.len() >= MAX_PINS {
                    return None;
                }
                pinned.push(i);
                pivot += largest;
            }
            row[b] = pivot.sqrt();
        }
        Some(pinned)
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

/// P = RᵀR and Q = BᵀB of a clamped line of `n` texels, patch radius `r`,
/// as lower bands of half-bandwidth `band`. Row x of R and B from clamp's
/// index map (`line.rs`'s ramp[x] = Σ k·e[x + k], box[x] = Σ e[x + k],
/// e[t] = in[clamp(t)]), which reaches r texels at most: O(n r), where
/// the line's response to each unit vector cost O(n) each, O(n²) in all
/// (3.6 s of 3.7 at 3 × 20000, N = 5). Their values are small integers,
/// exact either way.
fn normal_bands(n: usize, r: usize, band: usize) -> (Vec<f64>, Vec<f64>) {
    let width = band + 1;
    let reach = 2 * r + 1;
    // Row x of R and B: columns x − r … x + r.
    let (mut rows_r, mut rows_b) = (vec![0.0; n * reach], vec![0.0; n * reach]);
    for x in 0..n {
        for k in -(r as isize)..=r as isize {
            let j = Border::Clamp.map(x as isize + k, n);
            rows_r[x * reach + j + r - x] += k as f64;
            rows_b[x * reach + j + r - x] += 1.0;
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
    /// The first path of [`super::cost::paths`] (those within the limit of
    /// time) that can be made: `Some` solver, or `None` for conjugate
    /// gradients.
    ///
    /// Errors: [`crate::Error::InvalidOption`], the limit's refusal, where
    /// none can (the banded path's pins failing, say, with conjugate
    /// gradients past the limit).
    pub(super) fn within_limit(patch: &Patch, h: usize, opts: &super::HeightOptions) -> Result<Option<Separable>> {
        use super::cost::Path;
        for path in super::cost::paths(patch.w, h, opts) {
            let made = match path {
                Path::Dense => DenseSolver::new(patch, h).map(Separable::Dense),
                Path::OneAxis => OneAxis::new(patch, h).map(Separable::OneAxis),
                Path::ConjugateGradients => return Ok(None),
            };
            if made.is_some() {
                return Ok(made);
            }
        }
        Err(super::cost::refusal(patch.w, h, opts))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::height::line::{Line, Scratch};

    /// The bands of P = RᵀR and Q = BᵀB from clamp's index map are those
    /// of R and B as the line applies them (each unit vector's response),
    /// bit for bit, on lines shorter and longer than the patch.
    #[test]
    fn the_bands_are_the_lines_own_normal_matrices() {
        for (n, r) in [(2, 1), (7, 2), (5, 7), (40, 3), (64, 31), (20, 31)] {
            let line = Line::border(n, Border::Clamp, r);
            let (mut rr, mut bb) = (vec![0.0; n * n], vec![0.0; n * n]);
            let (mut unit, mut boxed, mut ramped) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            let mut scratch = Scratch::default();
            for j in 0..n {
                unit[j] = 1.0;
                line.apply(&unit, Some(&mut boxed), Some(&mut ramped), &mut scratch);
                unit[j] = 0.0;
                for x in 0..n {
                    rr[x * n + j] = ramped[x];
                    bb[x * n + j] = boxed[x];
                }
            }
            let band = (2 * r).min(n - 1);
            let (p, q) = normal_bands(n, r, band);
            for (m, got) in [(&rr, &p), (&bb, &q)] {
                for i in 0..n {
                    for j in i.saturating_sub(band)..=i {
                        let want: f64 = (0..n).map(|x| m[x * n + i] * m[x * n + j]).sum();
                        assert_eq!(got[i * (band + 1) + j + band - i], want, "n {n} r {r}: ({i}, {j})");
                    }
                }
            }
        }
    }
}
