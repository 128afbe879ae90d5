//! The least-squares solve of the vertical fit's slopes, per frequency.
//!
//! Every border that a transform fits is a periodic problem in disguise:
//!
//! * wrap: the image itself is the period (P = n);
//! * mirror (SPEC §2: reflection about the edge texel, edge not repeated):
//!   the whole-sample symmetric extension, period P = 2(n − 1), which the
//!   type-I cosine transform diagonalises; heights and the slope across
//!   the axis extend evenly, the slope along it oddly (zero on the two
//!   texels the reflection fixes);
//! * clamp with N = 3 (r = 1): index −1 maps to 0 and n to n − 1, the
//!   half-sample symmetric extension, period P = 2n (the type-II cosine
//!   transform's). Wider patches read −2 → 0, which no symmetric extension
//!   gives: those go to the iterative solver (`iterative.rs`).
//!
//! An axis of one texel acts as wrap with P = 1, and a mirrored axis of two
//! texels has period 2, the same as wrap.
//!
//! So each axis is extended to its period and transformed by a real (rows)
//! or complex (columns) FFT of length P; the cosine and sine transforms are
//! those FFTs of the extended sequences, computed as such. On the period the
//! vertical fit is a correlation, with frequency responses (ω = 2πk/P)
//!
//! ```text
//! Dx: i · S(ωx) · B(ωy) / A        Dy: i · B(ωx) · S(ωy) / A
//! S(ω) = 2 Σ_{m=1..r} m sin(mω)    B(ω) = 1 + 2 Σ_{m=1..r} cos(mω)
//! ```
//!
//! and the normal equations are one division per frequency:
//! Z = −i (ux Gx + uy Gy) / (ux² + uy² + λ), with ux = S(ωx)B(ωy)/A and
//! uy = B(ωx)S(ωy)/A. Where ux² + uy² vanishes (the constant, the
//! checkerboards ω = π, and the zeros of B, which a window of N texels
//! cannot see) Z = 0: the minimum-norm solution over the period. λ is the
//! regularisation the input's quantisation calls for (0 for exact input).
//!
//! The restriction of the periodic solution to the image is the answer:
//! the minimiser over the period is unique up to the null space, and the
//! extension's symmetry maps it to itself, so it has that symmetry.
//!
//! The exact model's patch responses are short correlations, so its
//! right-hand side Dxᵀgx + Dyᵀgy is formed on the texels (on the period's
//! extension) before any transform: one real 2-D transform of it, one
//! division per frequency by ux² + uy² + λ, one inverse, and a single plane
//! of row spectra (real for a mirrored x, whose rows are even). The
//! generic model's derivative iω is not short: it transforms both slopes
//! and combines them per frequency (two planes).
//!
//! Rows are transformed in parallel blocks; the column pass works on
//! blocks of columns, each a set of disjoint slices of every row, so it
//! runs in place. Each 1-D transform is the same whatever the thread count:
//! the result is too.

use std::sync::{Arc, Mutex};

use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use crate::error::Result;
use crate::options::{Border, Borders};
use crate::par::prelude::*;
use crate::samples::{try_filled, try_vec};

use super::Model;
use super::line::{Line, Work, columns_in_place, rows};

type C = Complex<f64>;

/// Fills row y's slopes (gx, gy).
pub(crate) type SlopeRows<'a> = &'a (dyn Fn(usize, &mut [f64], &mut [f64]) + Sync);

/// Fills the right-hand side's rows `rows` (w values each).
type RhsRows<'a> = &'a (dyn Fn(std::ops::Range<usize>, &mut [f64]) + Sync);

/// Below this, ux² + uy² is a zero of the response (a null mode), not a
/// small one: rounding leaves the exact zeros at about 1e-32, while the
/// lowest frequency of an image of 2^20 texels a side gives about 4e-11.
const NULL: f64 = 1e-20;

/// Patches of radius up to this form the right-hand side a block of rows
/// at a time, each texel's patch added outright (O(N) a texel, and no plane
/// besides the spectra); wider ones by the line sums of `line.rs`, a plane
/// at a time (a few operations a texel whatever N).
pub(super) const RHS_DIRECT_RADIUS: usize = 4;

/// Patches of radius up to this add their responses' terms outright
/// (O(r) a frequency); wider ones take their closed forms.
const RESPONSE_DIRECT_RADIUS: usize = 16;

/// Rows per task in the row passes.
const ROWS_PER_TASK: usize = 8;
/// Rows per task in the right-hand side's pass (which reads r rows more
/// on either side of its block).
pub(super) const RHS_ROWS_PER_TASK: usize = 32;
/// Columns per task in the column pass.
pub(super) const COLUMNS_PER_TASK: usize = 8;

/// How an axis extends to its period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Extension {
    /// The axis is its own period.
    Periodic,
    /// Whole-sample symmetric (mirror): P = 2(n − 1).
    Whole,
    /// Half-sample symmetric (clamp with r = 1): P = 2n.
    Half,
}

/// One axis: its texels, how it extends, its period.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Axis {
    pub n: usize,
    pub ext: Extension,
    pub period: usize,
}

impl Axis {
    /// The axis of `n` texels with `border` for a patch of radius `r`;
    /// `None` when no symmetric extension matches (clamp, r ≥ 2).
    pub fn new(n: usize, border: Border, r: usize) -> Option<Axis> {
        let periodic = Axis { n, ext: Extension::Periodic, period: n };
        match border {
            Border::Wrap => Some(periodic),
            Border::Mirror if n <= 2 => Some(periodic),
            Border::Mirror => Some(Axis { n, ext: Extension::Whole, period: 2 * (n - 1) }),
            Border::Clamp if n == 1 => Some(periodic),
            Border::Clamp if r == 1 => Some(Axis { n, ext: Extension::Half, period: 2 * n }),
            Border::Clamp => None,
        }
    }

    /// `src` (n values) extended to the period in `dst` (P values): evenly,
    /// or oddly (`odd`: the slope along this axis).
    pub fn extend<T: Copy + Default + std::ops::Neg<Output = T>>(&self, src: &[T], dst: &mut [T], odd: bool) {
        let (n, p) = (self.n, self.period);
        dst[..n].copy_from_slice(src);
        let sign = |v: T| if odd { -v } else { v };
        match self.ext {
            Extension::Periodic => {}
            Extension::Whole => {
                for j in 1..n - 1 {
                    dst[p - j] = sign(src[j]);
                }
                if odd {
                    // The texels the reflection fixes: an odd sequence is 0 there.
                    dst[0] = T::default();
                    dst[n - 1] = T::default();
                }
            }
            Extension::Half => {
                for j in 0..n {
                    dst[p - 1 - j] = sign(src[j]);
                }
            }
        }
    }

    /// The texel that index `k` of the period (any integer) reads, and the
    /// sign the extension gives it: 1 for an even sequence; for an odd one
    /// −1 where reflected and 0 on the texels the reflection fixes.
    pub fn map(&self, k: isize, odd: bool) -> (usize, f64) {
        let (n, p) = (self.n, self.period);
        let k = k.rem_euclid(p as isize) as usize;
        let reflected = if odd { -1.0 } else { 1.0 };
        match self.ext {
            Extension::Periodic => (k, 1.0),
            Extension::Whole if k < n => (k, if odd && (k == 0 || k == n - 1) { 0.0 } else { 1.0 }),
            Extension::Whole => (p - k, reflected),
            Extension::Half if k < n => (k, 1.0),
            Extension::Half => (p - 1 - k, reflected),
        }
    }

    /// The slope response S and the box response B at the frequencies
    /// k = 0 … count − 1 of the period.
    fn responses(&self, count: usize, model: Model, r: usize) -> (Vec<f64>, Vec<f64>) {
        let p = self.period as f64;
        let mut s = Vec::with_capacity(count);
        let mut b = Vec::with_capacity(count);
        // Σ_{m=1..r} m^(2j+2), for the series of S at low frequencies.
        let powers: Vec<f64> = if model == Model::Exact && r > RESPONSE_DIRECT_RADIUS {
            (0..SERIES_TERMS).map(|j| (1..=r).map(|m| (m as f64).powi(2 * j as i32 + 2)).sum()).collect()
        } else {
            Vec::new()
        };
        for k in 0..count {
            let omega = std::f64::consts::TAU * k as f64 / p;
            match model {
                Model::Exact if r <= RESPONSE_DIRECT_RADIUS => {
                    let (mut sk, mut bk) = (0.0, 1.0);
                    for m in 1..=r {
                        let (sin, cos) = (m as f64 * omega).sin_cos();
                        sk += 2.0 * m as f64 * sin;
                        bk += 2.0 * cos;
                    }
                    s.push(sk);
                    b.push(bk);
                }
                Model::Exact => {
                    let (sk, bk) = closed_responses(signed(k, self.period), r, &powers);
                    s.push(sk);
                    b.push(bk);
                }
                Model::Generic => {
                    // The ideal derivative iω, ω in (−π, π); the Nyquist
                    // frequency of an even period has no sign, and no slope.
                    let signed = if 2 * k < self.period {
                        omega
                    } else if 2 * k == self.period {
                        0.0
                    } else {
                        omega - std::f64::consts::TAU
                    };
                    s.push(signed);
                    b.push(1.0);
                }
            }
        }
        (s, b)
    }
}

/// Terms of the series of S where r|ω| < 1: the ratio of the j-th to the
/// first is below 3/((2j + 1)!(2j + 3)), 1e-26 at j = 12.
const SERIES_TERMS: usize = 13;

/// Frequency k of a period p as an angle in (−π, π].
fn signed(k: usize, p: usize) -> f64 {
    let k = if 2 * k > p { k as f64 - p as f64 } else { k as f64 };
    std::f64::consts::TAU * k / p as f64
}

/// S(ω) = 2 Σ_{m=1..r} m sin(mω) and B(ω) = 1 + 2 Σ_{m=1..r} cos(mω) in
/// closed form, ω in (−π, π]: B = sin((r + ½)ω) / sin(ω/2) (N at 0), and
/// S = ((r + 1) sin(rω) − r sin((r + 1)ω)) / (2 sin²(ω/2)) where r|ω| ≥ 1;
/// below, where that difference cancels, its series
/// S = 2 Σ_j (−1)^j ω^(2j+1) / (2j + 1)! · Σ_m m^(2j+2) (`powers`), whose
/// terms fall fast and whose first dominates. Both are the sums' values to
/// a few units of rounding relative (the sums themselves round by r of
/// them), and exact zeros come out at rounding level, far below the
/// solve's null threshold.
fn closed_responses(omega: f64, r: usize, powers: &[f64]) -> (f64, f64) {
    if omega == 0.0 {
        return (0.0, (2 * r + 1) as f64);
    }
    let rf = r as f64;
    let half = (0.5 * omega).sin();
    let b = ((rf + 0.5) * omega).sin() / half;
    let s = if rf * omega.abs() < 1.0 {
        let (w2, mut term, mut sum) = (omega * omega, omega, 0.0);
        for (j, p) in powers.iter().enumerate() {
            sum += term * p;
            term *= -w2 / ((2 * j + 2) as f64 * (2 * j + 3) as f64);
        }
        2.0 * sum
    } else {
        ((rf + 1.0) * (rf * omega).sin() - rf * ((rf + 1.0) * omega).sin()) / (2.0 * half * half)
    };
    (s, b)
}

/// What a solve found besides the heights.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SolveStats {
    /// The RMS height error (texel units) that white noise of unit RMS in
    /// each slope component would leave, through the same solve: the
    /// quantisation's figure is this times the slope noise.
    pub noise_gain: f64,
}

/// The planned solve for one image size, border pair, patch and model.
pub(crate) struct Solver {
    w: usize,
    h: usize,
    x: Axis,
    y: Axis,
    /// Row coefficients kept: P_x / 2 + 1.
    kx: usize,
    sx: Vec<f64>,
    bx: Vec<f64>,
    sy: Vec<f64>,
    by: Vec<f64>,
    /// Σ i² of the patch (1 for the generic model).
    a: f64,
    /// The patch's radius; `None` for the generic model, whose derivative
    /// is no short correlation.
    radius: Option<usize>,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    /// The columns' real transforms, for a plane of real spectra.
    column_r2c: Arc<dyn RealToComplex<f64>>,
    column_c2r: Arc<dyn ComplexToReal<f64>>,
    /// The plane of row spectra of the last solve, kept for the next: the
    /// iterations solve again and again (Gauss–Newton up to 300 times),
    /// and a fresh plane each time cost its page faults and zeroing, 9 %
    /// of the time of `normalfit height` at 4096².
    spare: Mutex<Option<Vec<C>>>,
}

impl Solver {
    /// Plans the solve; `None` when a border has no matching transform.
    pub fn new(w: usize, h: usize, borders: Borders, patch: usize, model: Model) -> Option<Solver> {
        let r = patch / 2;
        Some(Solver::with_axes(w, h, Axis::new(w, borders.x, r)?, Axis::new(h, borders.y, r)?, patch, model))
    }

    /// The solve with the nearest transform: clamp read as a half-sample
    /// reflection whatever N (exact for N = 3 only), the start of the
    /// iterative solver.
    pub fn nearest(w: usize, h: usize, borders: Borders, patch: usize, model: Model) -> Option<Solver> {
        Some(Solver::with_axes(w, h, Axis::new(w, borders.x, 1)?, Axis::new(h, borders.y, 1)?, patch, model))
    }

    fn with_axes(w: usize, h: usize, x: Axis, y: Axis, patch: usize, model: Model) -> Solver {
        let r = patch / 2;
        let kx = x.period / 2 + 1;
        let (sx, bx) = x.responses(kx, model, r);
        let (sy, by) = y.responses(y.period, model, r);
        let a = match model {
            Model::Exact => (patch * r * (r + 1) * (2 * r + 1)) as f64 / 3.0,
            Model::Generic => 1.0,
        };
        let mut real = RealFftPlanner::<f64>::new();
        let mut complex = FftPlanner::<f64>::new();
        Solver {
            w,
            h,
            x,
            y,
            kx,
            sx,
            bx,
            sy,
            by,
            a,
            radius: (model == Model::Exact).then_some(r),
            r2c: real.plan_fft_forward(x.period),
            c2r: real.plan_fft_inverse(x.period),
            forward: complex.plan_fft_forward(y.period),
            inverse: complex.plan_fft_inverse(y.period),
            column_r2c: real.plan_fft_forward(y.period),
            column_c2r: real.plan_fft_inverse(y.period),
            spare: Mutex::new(None),
        }
    }

    /// A plane of row spectra (`kx` × h): the last solve's, whose every
    /// value the row pass writes again, or a new one filled with `zero`.
    ///
    /// Errors: [`crate::Error::Limits`] when the memory is not there.
    fn plane<T: Copy + Send + Sync>(&self, spare: &Mutex<Option<Vec<T>>>, zero: T) -> Result<Vec<T>> {
        let len = self.kx * self.h;
        let kept = spare.lock().ok().and_then(|mut slot| slot.take());
        match kept {
            Some(plane) if plane.len() == len => Ok(plane),
            _ => try_filled(len, zero),
        }
    }

    /// Keeps `plane` for the next solve.
    fn give_back<T>(&self, spare: &Mutex<Option<Vec<T>>>, plane: Vec<T>) {
        if let Ok(mut slot) = spare.lock() {
            *slot = Some(plane);
        }
    }

    /// Bytes the solve holds besides its output: for the exact model none
    /// where the row spectra fit in the output (a mirrored x, a wrapped
    /// one of even width), else one plane of them (16 bytes a texel for
    /// clamp); the generic model two complex ones.
    pub fn memory(w: usize, h: usize, borders: Borders, model: Model) -> u64 {
        let (kx, planes, bytes) = match (borders.x, model) {
            // Even widths keep the spectra in the output (`solve_packed`).
            (Border::Wrap, Model::Exact) if w.is_multiple_of(2) => (0, 0, 0),
            (Border::Wrap, Model::Exact) => (w / 2 + 1, 1, size_of::<C>()),
            // Its w real coefficients a row are kept in the output.
            (Border::Mirror, Model::Exact) if w > 2 => (0, 0, 0),
            (Border::Mirror, Model::Exact) => (w, 1, size_of::<C>()),
            (Border::Clamp, Model::Exact) => (w + 1, 1, size_of::<C>()),
            (Border::Wrap, Model::Generic) => (w / 2 + 1, 2, size_of::<C>()),
            (Border::Mirror, Model::Generic) => (w, 2, size_of::<C>()),
            (Border::Clamp, Model::Generic) => (w + 1, 2, size_of::<C>()),
        };
        (planes * kx * bytes) as u64 * h as u64
    }

    /// The heights z (texel units, mean not fixed) whose vertical-fit
    /// slopes are closest to the slopes `slopes(y, gx, gy)` fills for row
    /// y (gx = ∂z/∂x, gy = ∂z/∂y, y down), into `out` (w × h).
    pub fn solve(&self, slopes: SlopeRows<'_>, lambda: f64, out: &mut [f64]) -> Result<SolveStats> {
        let whole = self.x.ext == Extension::Whole;
        match self.radius {
            Some(r) if r > RHS_DIRECT_RADIUS => {
                // The right-hand side as a plane, in `out`, which the last
                // pass overwrites with the heights.
                self.right_hand_side_plane(slopes, r, out)?;
                if whole {
                    self.solve_real(None, lambda, None, out)
                } else {
                    self.solve_complex(None, lambda, None, out)
                }
            }
            Some(r) => {
                let fill = |rows: std::ops::Range<usize>, dst: &mut [f64]| self.right_hand_side(slopes, r, rows, dst);
                if whole {
                    self.solve_real(Some(&fill), lambda, None, out)
                } else {
                    self.solve_complex(Some(&fill), lambda, None, out)
                }
            }
            None => self.solve_two_planes(slopes, lambda, out),
        }
    }

    /// The noise gain of [`Self::solve`] without solving (the same sums,
    /// in the same order): for a map without slopes, whose heights are 0.
    pub fn noise_gain(&self, lambda: f64) -> SolveStats {
        let partial: Vec<f64> = (0..self.kx.div_ceil(COLUMNS_PER_TASK))
            .into_par_iter()
            .map(|block| {
                let columns = block * COLUMNS_PER_TASK..((block + 1) * COLUMNS_PER_TASK).min(self.kx);
                let mut noise = 0.0;
                for kxi in columns {
                    let mut column_noise = 0.0;
                    for ky in 0..self.y.period {
                        column_noise += self.inverse_response(kxi, ky, lambda, None).1;
                    }
                    noise += self.column_weight(kxi) * column_noise;
                }
                noise
            })
            .collect();
        self.stats(&partial)
    }

    /// The right-hand side Dxᵀgx + Dyᵀgy of [`Self::right_hand_side`] for
    /// every row, into `out` (w × h), by the line sums of `line.rs`: the
    /// ramp of gx (odd along x) and the box of gy (even) along each row,
    /// then the box of the first (even along y) and the ramp of the second
    /// (odd) down each column. A few operations a texel whatever N, and
    /// one plane more than the spectra.
    ///
    /// Errors: [`crate::Error::Limits`] when the plane's memory is not there.
    fn right_hand_side_plane(&self, slopes: SlopeRows<'_>, r: usize, out: &mut [f64]) -> Result<()> {
        let w = self.w;
        let line = |axis: &Axis, odd: bool| {
            Line::periodic(axis.n, r, (0..axis.period).map(|t| axis.map(t as isize, odd)).collect())
        };
        let (x_odd, x_even, y_even, y_odd) =
            (line(&self.x, true), line(&self.x, false), line(&self.y, false), line(&self.y, true));
        let mut v = try_filled(out.len(), 0.0)?;
        rows(w, &mut [&mut *out, &mut v], |y, row, work| {
            let Work { scratch, temps } = work;
            let [gx, gy, ..] = temps;
            slopes(y, gx, gy);
            let [u, v] = row else { unreachable!() };
            x_odd.apply(gx, None, Some(&mut u[..]), scratch);
            x_even.apply(gy, Some(&mut v[..]), None, scratch);
        });
        let scale = -1.0 / self.a;
        columns_in_place(w, &mut [out, &mut v], |_, cols, work| {
            let Work { scratch, temps } = work;
            let [boxed, ramped, ..] = temps;
            let [u, v] = cols else { unreachable!() };
            y_even.apply(u, Some(&mut boxed[..]), None, scratch);
            y_odd.apply(v, None, Some(&mut ramped[..]), scratch);
            for ((u, b), r) in u.iter_mut().zip(boxed.iter()).zip(ramped.iter()) {
                *u = scale * (b + r);
            }
        });
        Ok(())
    }

    /// (DᵀD + λ + ε)⁻¹ b for a right-hand side `b` given on the texels
    /// (w × h, as the least squares over the period see it), into `out`:
    /// every frequency divided, the null modes by λ + ε alone. The
    /// exact model's preconditioner for the orthogonal fit's Gauss–Newton
    /// steps (`gauss_newton.rs`), whose operator does see some of the
    /// vertical fit's null modes (through the patches' roughness).
    ///
    /// Errors: [`crate::Error::Limits`] when the plane's memory is not there.
    pub fn inverse(&self, b: &[f64], lambda: f64, epsilon: f64, out: &mut [f64]) -> Result<()> {
        let w = self.w;
        let fill = |rows: std::ops::Range<usize>, dst: &mut [f64]| {
            dst.copy_from_slice(&b[rows.start * w..rows.end * w]);
        };
        match self.radius {
            Some(_) if self.x.ext == Extension::Whole => self.solve_real(Some(&fill), lambda, Some(epsilon), out),
            _ => self.solve_complex(Some(&fill), lambda, Some(epsilon), out),
        }
        .map(|_| ())
    }

    /// The right-hand side of the normal equations, Dxᵀgx + Dyᵀgy, for the
    /// rows `rows` into `dst` (rows of w), on the period: with gx odd along
    /// x and even along y, gy the reverse, Dxᵀ = −(ramp_x ⊗ box_y)/A and
    /// Dyᵀ = −(box_x ⊗ ramp_y)/A (the ramp is odd, the box even). The rows
    /// within r of the block are read again: every value is the same sum
    /// in the same order whatever the blocks.
    fn right_hand_side(&self, slopes: SlopeRows<'_>, r: usize, rows: std::ops::Range<usize>, dst: &mut [f64]) {
        let w = self.w;
        let ri = r as isize;
        let window = rows.len() + 2 * r;
        // ramp_x(gx) and box_x(gy) of the window's rows of the period.
        let (mut u, mut v) = (vec![0.0; window * w], vec![0.0; window * w]);
        let (mut gx, mut gy) = (vec![0.0; w], vec![0.0; w]);
        let (mut px, mut py) = (vec![0.0; w + 2 * r], vec![0.0; w + 2 * r]);
        let pads: Vec<(usize, f64)> = (-ri..w as isize + ri).map(|k| self.x.map(k, true)).collect();
        for (t, (ur, vr)) in u.chunks_mut(w).zip(v.chunks_mut(w)).enumerate() {
            let (source, _) = self.y.map(rows.start as isize + t as isize - ri, false);
            slopes(source, &mut gx, &mut gy);
            for ((a, b), &(k, sign)) in px.iter_mut().zip(py.iter_mut()).zip(&pads) {
                *a = sign * gx[k];
                *b = gy[k];
            }
            for (x, (uo, vo)) in ur.iter_mut().zip(vr.iter_mut()).enumerate() {
                let c = x + r;
                let (mut ramp, mut boxed) = (0.0, py[c]);
                for m in 1..=r {
                    ramp += m as f64 * (px[c + m] - px[c - m]);
                    boxed += py[c + m] + py[c - m];
                }
                *uo = ramp;
                *vo = boxed;
            }
        }
        let scale = -1.0 / self.a;
        for (k, row) in dst.chunks_mut(w).enumerate() {
            let y = rows.start + k;
            row.copy_from_slice(&u[(k + r) * w..][..w]);
            for j in -ri..=ri {
                let (_, sign) = self.y.map(y as isize + j, true);
                let weight = j as f64 * sign;
                let t = (k as isize + ri + j) as usize;
                let (ut, vt) = (&u[t * w..][..w], &v[t * w..][..w]);
                if j != 0 {
                    row.iter_mut().zip(ut).for_each(|(o, &a)| *o += a);
                }
                if weight != 0.0 {
                    row.iter_mut().zip(vt).for_each(|(o, &b)| *o += weight * b);
                }
            }
            row.iter_mut().for_each(|o| *o *= scale);
        }
    }

    /// 1/(ux² + uy² + λ) at column kxi, frequency ky (0 on the null
    /// modes), and its term of the noise gain's sum.
    #[inline]
    fn inverse_response(&self, kxi: usize, ky: usize, lambda: f64, epsilon: Option<f64>) -> (f64, f64) {
        let ux = self.sx[kxi] * self.by[ky] / self.a;
        let uy = self.bx[kxi] * self.sy[ky] / self.a;
        let den = ux * ux + uy * uy;
        if let Some(e) = epsilon {
            (1.0 / (den + lambda + e), 0.0)
        } else if den <= NULL {
            (0.0, 0.0)
        } else {
            let scale = 1.0 / (den + lambda);
            (scale, den * scale * scale)
        }
    }

    /// The weight of row-spectrum column kxi in sums over the period: both
    /// halves of a real row's spectrum but its first and (even period)
    /// last coefficient.
    fn column_weight(&self, kxi: usize) -> f64 {
        if kxi != 0 && 2 * kxi != self.x.period { 2.0 } else { 1.0 }
    }

    /// The exact model for an x of any extension: the right-hand side's
    /// rows → real FFT, one plane of complex spectra; columns: FFT, divided
    /// by the response, inverse FFT; rows: inverse real FFT.
    fn solve_complex(
        &self,
        fill: Option<RhsRows<'_>>,
        lambda: f64,
        epsilon: Option<f64>,
        out: &mut [f64],
    ) -> Result<SolveStats> {
        if self.packs_into_output() {
            return Ok(self.solve_packed(fill, lambda, epsilon, out));
        }
        self.solve_in_plane(fill, lambda, epsilon, out)
    }

    /// [`Self::solve_complex`] with the row spectra in a plane of their own.
    fn solve_in_plane(
        &self,
        fill: Option<RhsRows<'_>>,
        lambda: f64,
        epsilon: Option<f64>,
        out: &mut [f64],
    ) -> Result<SolveStats> {
        let (w, h, kx) = (self.w, self.h, self.kx);
        let mut a = self.plane(&self.spare, C::default())?;
        let chunk = kx * RHS_ROWS_PER_TASK;
        let given: &[f64] = out;
        a.par_chunks_mut(chunk).enumerate().for_each(|(block, spectra)| {
            let y0 = block * RHS_ROWS_PER_TASK;
            let rows = spectra.len() / kx;
            let mut filled = Vec::new();
            let rhs = right_hand_side_rows(fill, given, y0..y0 + rows, w, &mut filled);
            let mut ext = self.r2c.make_input_vec();
            let mut scratch = self.r2c.make_scratch_vec();
            for (row, spectrum) in rhs.chunks(w).zip(spectra.chunks_mut(kx)) {
                self.x.extend(row, &mut ext, false);
                let _ = self.r2c.process_with_scratch(&mut ext, spectrum, &mut scratch);
            }
        });
        let blocks = column_blocks(&mut a, kx, COLUMNS_PER_TASK);
        let partial: Vec<f64> = blocks
            .into_par_iter()
            .enumerate()
            .map(|(block, mut rows)| {
                let p = self.y.period;
                let mut ext = vec![C::default(); p];
                let scratch_len = self.forward.get_inplace_scratch_len().max(self.inverse.get_inplace_scratch_len());
                let mut scratch = vec![C::default(); scratch_len];
                let width = rows.first().map_or(0, |r| r.len());
                let mut columns = gather(&rows, h);
                let mut noise = 0.0;
                for (c, col) in columns.chunks_mut(h.max(1)).enumerate() {
                    let kxi = block * COLUMNS_PER_TASK + c;
                    self.y.extend(col, &mut ext, false);
                    self.forward.process_with_scratch(&mut ext, &mut scratch);
                    let mut column_noise = 0.0;
                    for (ky, e) in ext.iter_mut().enumerate() {
                        let (scale, n) = self.inverse_response(kxi, ky, lambda, epsilon);
                        *e *= scale;
                        column_noise += n;
                    }
                    noise += self.column_weight(kxi) * column_noise;
                    self.inverse.process_with_scratch(&mut ext, &mut scratch);
                    col.copy_from_slice(&ext[..h]);
                }
                scatter(&columns, &mut rows, width);
                noise
            })
            .collect();
        self.inverse_rows(&mut a, out);
        self.give_back(&self.spare, a);
        Ok(self.stats(&partial))
    }

    /// Whether the row spectra fit in the output itself ([`Self::solve_packed`]):
    /// a periodic x of even width, whose w/2 + 1 coefficients a row are w
    /// numbers once the two that are always real share a slot.
    fn packs_into_output(&self) -> bool {
        self.x.ext == Extension::Periodic && self.w.is_multiple_of(2) && self.w >= 2
    }

    /// [`Self::solve_complex`] with the row spectra kept in `out` rather
    /// than a plane of their own (128 MiB at 4096², an eighth of the
    /// inverse's peak): row y's w numbers hold its real FFT's first
    /// coefficient's real part, then its last's (x = w/2; both are real),
    /// then the real and imaginary parts of coefficients 1 to w/2 − 1.
    /// The same transforms of the same numbers in the same order, and the
    /// noise's sums in the plane's order: the same bits as the plane.
    fn solve_packed(
        &self,
        fill: Option<RhsRows<'_>>,
        lambda: f64,
        epsilon: Option<f64>,
        out: &mut [f64],
    ) -> SolveStats {
        let (w, h, kx) = (self.w, self.h, self.kx);
        let last = kx - 1;
        self.forward_rows_in_output(fill, out, |spectrum, row| {
            (row[0], row[1]) = (spectrum[0].re, spectrum[last].re);
            for (pair, c) in row[2..].chunks_exact_mut(2).zip(&spectrum[1..last]) {
                (pair[0], pair[1]) = (c.re, c.im);
            }
        });
        // Blocks of COLUMNS_PER_TASK coefficients, as the plane's: block 0
        // also holds the last coefficient, whose noise is set aside to be
        // added where the plane's order has it, at the very end.
        let blocks = column_blocks(out, w, 2 * COLUMNS_PER_TASK);
        let partial: Vec<(f64, f64)> = blocks
            .into_par_iter()
            .enumerate()
            .map(|(block, mut rows)| {
                let p = self.y.period;
                let mut ext = vec![C::default(); p];
                let scratch_len = self.forward.get_inplace_scratch_len().max(self.inverse.get_inplace_scratch_len());
                let mut scratch = vec![C::default(); scratch_len];
                let slots = rows.first().map_or(0, |r| r.len() / 2);
                let mut columns = vec![C::default(); slots * h];
                for (y, row) in rows.iter().enumerate() {
                    for (c, pair) in row.chunks_exact(2).enumerate() {
                        columns[c * h + y] = C::new(pair[0], pair[1]);
                    }
                }
                let mut column = |kxi: usize, col: &mut [C]| -> f64 {
                    self.y.extend(col, &mut ext, false);
                    self.forward.process_with_scratch(&mut ext, &mut scratch);
                    let mut column_noise = 0.0;
                    for (ky, e) in ext.iter_mut().enumerate() {
                        let (scale, n) = self.inverse_response(kxi, ky, lambda, epsilon);
                        *e *= scale;
                        column_noise += n;
                    }
                    self.inverse.process_with_scratch(&mut ext, &mut scratch);
                    col.copy_from_slice(&ext[..h]);
                    self.column_weight(kxi) * column_noise
                };
                let (mut noise, mut set_aside) = (0.0, 0.0);
                for (c, col) in columns.chunks_mut(h.max(1)).enumerate() {
                    let kxi = block * COLUMNS_PER_TASK + c;
                    if kxi == 0 {
                        // The slot of the first and last coefficients: each
                        // its own column, of real values as the plane held.
                        let mut first: Vec<C> = col.iter().map(|v| C::new(v.re, 0.0)).collect();
                        let mut final_: Vec<C> = col.iter().map(|v| C::new(v.im, 0.0)).collect();
                        noise += column(0, &mut first);
                        set_aside = column(last, &mut final_);
                        // Their imaginary parts the inverse rows do not read.
                        for ((v, a), b) in col.iter_mut().zip(&first).zip(&final_) {
                            *v = C::new(a.re, b.re);
                        }
                    } else {
                        noise += column(kxi, col);
                    }
                }
                for (y, row) in rows.iter_mut().enumerate() {
                    for (c, pair) in row.chunks_exact_mut(2).enumerate() {
                        let v = columns[c * h + y];
                        (pair[0], pair[1]) = (v.re, v.im);
                    }
                }
                (noise, set_aside)
            })
            .collect();
        let mut sums: Vec<f64> = partial.iter().map(|&(noise, _)| noise).collect();
        let last_noise = partial.first().map_or(0.0, |&(_, n)| n);
        // The plane's blocks: one more where the last coefficient begins one.
        if kx.div_ceil(COLUMNS_PER_TASK) > sums.len() {
            sums.push(0.0 + last_noise);
        } else if let Some(end) = sums.last_mut() {
            *end += last_noise;
        }
        self.inverse_rows_in_output(out, |row, spectrum| {
            spectrum[0] = C::new(row[0], 0.0);
            spectrum[last] = C::new(row[1], 0.0);
            for (c, pair) in spectrum[1..last].iter_mut().zip(row[2..].chunks_exact(2)) {
                *c = C::new(pair[0], pair[1]);
            }
        });
        self.stats(&sums)
    }

    /// The exact model for a mirrored x: the right-hand side is even along
    /// x, so its rows' spectra are real (the type-I cosine transform), and
    /// the columns real FFTs. A row's kx = w real coefficients (a mirrored
    /// x is at least 3 wide) are as many as its heights: they are kept in
    /// `out` itself, not in a plane of their own (128 MiB at 4096²; the
    /// same transforms of the same numbers as that plane, so its bits).
    fn solve_real(
        &self,
        fill: Option<RhsRows<'_>>,
        lambda: f64,
        epsilon: Option<f64>,
        out: &mut [f64],
    ) -> Result<SolveStats> {
        let w = self.w;
        debug_assert_eq!(self.kx, w);
        self.forward_rows_in_output(fill, out, |spectrum, row| {
            row.iter_mut().zip(spectrum).for_each(|(o, s)| *o = s.re);
        });
        let partial = self.real_columns(out, lambda, epsilon);
        self.inverse_rows_in_output(out, |row, spectrum| {
            spectrum.iter_mut().zip(row).for_each(|(s, &v)| *s = C::new(v, 0.0));
        });
        Ok(self.stats(&partial))
    }

    /// The row pass of a solve whose spectra are kept in `out`: each row's
    /// right-hand side (from `fill`, else `out`'s own row) through the real
    /// FFT, its spectrum laid into the row by `store`.
    fn forward_rows_in_output(
        &self,
        fill: Option<RhsRows<'_>>,
        out: &mut [f64],
        store: impl Fn(&[C], &mut [f64]) + Sync,
    ) {
        let w = self.w;
        out.par_chunks_mut(w * RHS_ROWS_PER_TASK).enumerate().for_each(|(block, rows)| {
            let y0 = block * RHS_ROWS_PER_TASK;
            let mut filled = Vec::new();
            if let Some(fill) = fill {
                filled.resize(rows.len(), 0.0);
                fill(y0..y0 + rows.len() / w, &mut filled);
            }
            let mut ext = self.r2c.make_input_vec();
            let mut spectrum = self.r2c.make_output_vec();
            let mut scratch = self.r2c.make_scratch_vec();
            for (k, row) in rows.chunks_mut(w).enumerate() {
                // Without `fill`, the right-hand side is `out` itself.
                let rhs: &[f64] = if fill.is_some() { &filled[k * w..][..w] } else { row };
                self.x.extend(rhs, &mut ext, false);
                let _ = self.r2c.process_with_scratch(&mut ext, &mut spectrum, &mut scratch);
                store(&spectrum, row);
            }
        });
    }

    /// The last pass of a solve whose spectra are kept in `out`: each
    /// row's spectrum read back by `load`, through the inverse real FFT,
    /// normalised into the row.
    fn inverse_rows_in_output(&self, out: &mut [f64], load: impl Fn(&[f64], &mut [C]) + Sync) {
        let w = self.w;
        let norm = 1.0 / (self.x.period as f64 * self.y.period as f64);
        out.par_chunks_mut(w * ROWS_PER_TASK).for_each(|rows| {
            let mut spectrum = self.c2r.make_input_vec();
            let mut ext = self.c2r.make_output_vec();
            let mut scratch = self.c2r.make_scratch_vec();
            for row in rows.chunks_mut(w) {
                load(row, &mut spectrum);
                let _ = self.c2r.process_with_scratch(&mut spectrum, &mut ext, &mut scratch);
                for (o, &e) in row.iter_mut().zip(&ext[..w]) {
                    *o = e * norm;
                }
            }
        });
    }

    /// The column pass of [`Self::solve_real`] over the real row spectra
    /// `a` (rows of kx): each column's real FFT divided by the response
    /// and transformed back; the noise's sums of each block of columns.
    fn real_columns(&self, a: &mut [f64], lambda: f64, epsilon: Option<f64>) -> Vec<f64> {
        let (h, kx) = (self.h, self.kx);
        column_blocks(a, kx, COLUMNS_PER_TASK)
            .into_par_iter()
            .enumerate()
            .map(|(block, mut rows)| {
                let p = self.y.period;
                let mut ext = self.column_r2c.make_input_vec();
                let mut spectrum = self.column_r2c.make_output_vec();
                let scratch_len = self.column_r2c.get_scratch_len().max(self.column_c2r.get_scratch_len());
                let mut scratch = vec![C::default(); scratch_len];
                let width = rows.first().map_or(0, |r| r.len());
                let mut columns = gather(&rows, h);
                let mut noise = 0.0;
                for (c, col) in columns.chunks_mut(h.max(1)).enumerate() {
                    let kxi = block * COLUMNS_PER_TASK + c;
                    self.y.extend(col, &mut ext, false);
                    let _ = self.column_r2c.process_with_scratch(&mut ext, &mut spectrum, &mut scratch);
                    let mut column_noise = 0.0;
                    for ky in 0..p {
                        let (scale, n) = self.inverse_response(kxi, ky, lambda, epsilon);
                        if let Some(e) = spectrum.get_mut(ky) {
                            *e *= scale;
                        }
                        column_noise += n;
                    }
                    noise += self.column_weight(kxi) * column_noise;
                    spectrum[0].im = 0.0;
                    if p.is_multiple_of(2) {
                        spectrum[p / 2].im = 0.0;
                    }
                    let _ = self.column_c2r.process_with_scratch(&mut spectrum, &mut ext, &mut scratch);
                    col.copy_from_slice(&ext[..h]);
                }
                scatter(&columns, &mut rows, width);
                noise
            })
            .collect()
    }

    /// The last pass: inverse real FFT of each row of spectra, the first w
    /// values of the period, normalised, into `out`.
    fn inverse_rows(&self, a: &mut [C], out: &mut [f64]) {
        let (w, kx) = (self.w, self.kx);
        let norm = 1.0 / (self.x.period as f64 * self.y.period as f64);
        out.par_chunks_mut(w * ROWS_PER_TASK).zip(a.par_chunks_mut(chunk_rows(kx))).for_each(|(out_rows, spectra)| {
            let mut ext = self.c2r.make_output_vec();
            let mut scratch = self.c2r.make_scratch_vec();
            for (row, spectrum) in out_rows.chunks_mut(w).zip(spectra.chunks_mut(kx)) {
                spectrum[0].im = 0.0;
                if self.x.period.is_multiple_of(2) {
                    spectrum[kx - 1].im = 0.0;
                }
                let _ = self.c2r.process_with_scratch(spectrum, &mut ext, &mut scratch);
                for (o, &e) in row.iter_mut().zip(&ext[..w]) {
                    *o = e * norm;
                }
            }
        });
    }

    /// The noise gain from the columns' sums.
    fn stats(&self, partial: &[f64]) -> SolveStats {
        let periods = self.x.period as f64 * self.y.period as f64;
        SolveStats { noise_gain: (partial.iter().sum::<f64>() / periods).sqrt() }
    }

    /// The generic model: each slope's rows and columns transformed, the
    /// two planes combined per frequency (its derivative is no short
    /// correlation to apply before the transforms).
    fn solve_two_planes(&self, slopes: SlopeRows<'_>, lambda: f64, out: &mut [f64]) -> Result<SolveStats> {
        let (w, h, kx) = (self.w, self.h, self.kx);
        let len = kx * h;
        let mut a: Vec<C> = try_vec(len)?;
        a.resize(len, C::default());
        let mut b: Vec<C> = try_vec(len)?;
        b.resize(len, C::default());

        // Rows: slopes → extended → real FFT.
        let chunk = kx * ROWS_PER_TASK;
        a.par_chunks_mut(chunk).zip(b.par_chunks_mut(chunk)).enumerate().for_each(|(block, (ra, rb))| {
            let p = self.x.period;
            let (mut gx, mut gy) = (vec![0.0; w], vec![0.0; w]);
            let mut ext = self.r2c.make_input_vec();
            let mut scratch = self.r2c.make_scratch_vec();
            for (k, (row_a, row_b)) in ra.chunks_mut(kx).zip(rb.chunks_mut(kx)).enumerate() {
                let y = block * ROWS_PER_TASK + k;
                slopes(y, &mut gx, &mut gy);
                debug_assert_eq!(ext.len(), p);
                self.x.extend(&gx, &mut ext, true);
                // The transform cannot fail on buffers it made itself.
                let _ = self.r2c.process_with_scratch(&mut ext, row_a, &mut scratch);
                self.x.extend(&gy, &mut ext, false);
                let _ = self.r2c.process_with_scratch(&mut ext, row_b, &mut scratch);
            }
        });

        // Columns: extended → FFT, combined, inverse FFT, back in place.
        let blocks = column_blocks(&mut a, kx, COLUMNS_PER_TASK);
        let spectra_b = &b;
        let partial: Vec<f64> = blocks
            .into_par_iter()
            .enumerate()
            .map(|(block, mut rows)| {
                let p = self.y.period;
                let (mut col_a, mut col_b) = (vec![C::default(); h], vec![C::default(); h]);
                let (mut ext_a, mut ext_b) = (vec![C::default(); p], vec![C::default(); p]);
                let scratch_len = self.forward.get_inplace_scratch_len().max(self.inverse.get_inplace_scratch_len());
                let mut scratch = vec![C::default(); scratch_len];
                let width = rows.first().map_or(0, |r| r.len());
                let mut noise = 0.0;
                for c in 0..width {
                    let kxi = block * COLUMNS_PER_TASK + c;
                    for (y, row) in rows.iter().enumerate() {
                        col_a[y] = row[c];
                        col_b[y] = spectra_b[y * kx + kxi];
                    }
                    self.y.extend(&col_a, &mut ext_a, false);
                    self.y.extend(&col_b, &mut ext_b, true);
                    self.forward.process_with_scratch(&mut ext_a, &mut scratch);
                    self.forward.process_with_scratch(&mut ext_b, &mut scratch);
                    let (s_x, b_x) = (self.sx[kxi], self.bx[kxi]);
                    // Both halves of a real row's spectrum but its first and
                    // (even period) last coefficient.
                    let twice = kxi != 0 && 2 * kxi != self.x.period;
                    let weight = if twice { 2.0 } else { 1.0 };
                    for ky in 0..p {
                        let ux = s_x * self.by[ky] / self.a;
                        let uy = b_x * self.sy[ky] / self.a;
                        let den = ux * ux + uy * uy;
                        ext_a[ky] = if den <= NULL {
                            C::default()
                        } else {
                            let num = ext_a[ky] * ux + ext_b[ky] * uy;
                            let scale = 1.0 / (den + lambda);
                            noise += weight * den * scale * scale;
                            C::new(num.im * scale, -num.re * scale)
                        };
                    }
                    self.inverse.process_with_scratch(&mut ext_a, &mut scratch);
                    for (y, row) in rows.iter_mut().enumerate() {
                        row[c] = ext_a[y];
                    }
                }
                noise
            })
            .collect();
        drop(b);
        self.inverse_rows(&mut a, out);
        Ok(self.stats(&partial))
    }
}

/// The right-hand side's rows `rows`: `fill`'s into `filled`, or (`fill`
/// None) those `given` already holds.
fn right_hand_side_rows<'a>(
    fill: Option<RhsRows<'_>>,
    given: &'a [f64],
    rows: std::ops::Range<usize>,
    w: usize,
    filled: &'a mut Vec<f64>,
) -> &'a [f64] {
    match fill {
        Some(fill) => {
            filled.resize(rows.len() * w, 0.0);
            fill(rows, filled);
            filled
        }
        None => &given[rows.start * w..rows.end * w],
    }
}

/// Elements of a block of `ROWS_PER_TASK` rows of `row_len`.
fn chunk_rows(row_len: usize) -> usize {
    row_len * ROWS_PER_TASK
}

/// `data` (rows of `row_len`) cut into blocks of `block` columns: for each
/// block, its slice of every row, so blocks of columns can be worked on in
/// parallel, in place.
fn column_blocks<T>(data: &mut [T], row_len: usize, block: usize) -> Vec<Vec<&mut [T]>> {
    let rows = data.len() / row_len.max(1);
    let mut blocks: Vec<Vec<&mut [T]>> = (0..row_len.div_ceil(block)).map(|_| Vec::with_capacity(rows)).collect();
    for row in data.chunks_mut(row_len) {
        for (k, piece) in row.chunks_mut(block).enumerate() {
            blocks[k].push(piece);
        }
    }
    blocks
}

/// The values of a block of columns (`rows`: the block's slice of every
/// row), column after column: one pass over the block, where reading one
/// column at a time strides through every row for each (4 % of a solve).
fn gather<T: Copy + Default>(rows: &[&mut [T]], h: usize) -> Vec<T> {
    let width = rows.first().map_or(0, |r| r.len());
    let mut columns = vec![T::default(); width * h];
    for (y, row) in rows.iter().enumerate() {
        for (c, &v) in row.iter().enumerate() {
            columns[c * h + y] = v;
        }
    }
    columns
}

/// The inverse of [`gather`]: columns of `h` values back into the rows.
fn scatter<T: Copy>(columns: &[T], rows: &mut [&mut [T]], width: usize) {
    let h = rows.len();
    for (y, row) in rows.iter_mut().enumerate() {
        for (c, v) in row[..width].iter_mut().enumerate() {
            *v = columns[c * h + y];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The row spectra packed into the output give the plane's bits: the
    /// heights and the noise gain, for right-hand sides given row by row
    /// and as a plane, every y border, widths with the last coefficient
    /// alone in its block of columns and sharing one.
    #[test]
    fn packed_spectra_give_the_planes_bits() {
        for (w, h) in [(2, 3), (6, 5), (16, 7), (20, 4), (34, 9)] {
            for by in [Border::Wrap, Border::Mirror, Border::Clamp] {
                let borders = Borders { x: Border::Wrap, y: by };
                let Some(solver) = Solver::new(w, h, borders, 3, Model::Exact) else { continue };
                assert!(solver.packs_into_output());
                let b: Vec<f64> = (0..w * h).map(|k| ((k * 7919) % 101) as f64 / 10.0 - 5.0).collect();
                let fill = |rows: std::ops::Range<usize>, dst: &mut [f64]| {
                    dst.copy_from_slice(&b[rows.start * w..rows.end * w])
                };
                for epsilon in [None, Some(1e-3)] {
                    let mut packed = vec![0.0; w * h];
                    let mut plane = vec![0.0; w * h];
                    let p = solver.solve_packed(Some(&fill), 1e-4, epsilon, &mut packed);
                    let q = solver.solve_in_plane(Some(&fill), 1e-4, epsilon, &mut plane).unwrap();
                    assert_eq!(
                        packed.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                        plane.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                        "{w}×{h} {by:?} {epsilon:?}"
                    );
                    assert_eq!(p.noise_gain.to_bits(), q.noise_gain.to_bits(), "{w}×{h} {by:?}");
                    assert!(packed.iter().any(|&v| v != 0.0));
                    // The right-hand side as the output's own plane.
                    let mut given = b.clone();
                    solver.solve_packed(None, 1e-4, epsilon, &mut given);
                    assert_eq!(
                        given.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                        plane.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                    );
                }
            }
        }
    }

    #[test]
    fn extensions_follow_the_borders() {
        let src = [1.0, 2.0, 3.0, 4.0];
        let mirror = Axis::new(4, Border::Mirror, 1).unwrap();
        let mut ext = vec![0.0; mirror.period];
        mirror.extend(&src, &mut ext, false);
        assert_eq!(ext, [1.0, 2.0, 3.0, 4.0, 3.0, 2.0]);
        for k in -4..10isize {
            assert_eq!(ext[k.rem_euclid(6) as usize], src[Border::Mirror.map(k, 4)], "{k}");
        }
        mirror.extend(&src, &mut ext, true);
        assert_eq!(ext, [0.0, 2.0, 3.0, 0.0, -3.0, -2.0]);
        let clamp = Axis::new(4, Border::Clamp, 1).unwrap();
        let mut ext = vec![0.0; clamp.period];
        clamp.extend(&src, &mut ext, false);
        assert_eq!(ext, [1.0, 2.0, 3.0, 4.0, 4.0, 3.0, 2.0, 1.0]);
        for k in -1..5isize {
            assert_eq!(ext[k.rem_euclid(8) as usize], src[Border::Clamp.map(k, 4)], "{k}");
        }
        assert!(Axis::new(4, Border::Clamp, 2).is_none());
        assert_eq!(Axis::new(2, Border::Mirror, 3).unwrap().ext, Extension::Periodic);
    }
}
