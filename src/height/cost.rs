//! What the exact inverse costs where no transform fits (clamp with
//! N ≥ 5), estimated from the shape alone, and the refusal of a map whose
//! estimate passes a limit linear in its texels (issue 32: the inverse in
//! time linear in the texels, or a refusal naming the limit).
//!
//! The paths (`iterative.rs` picks one by these figures): dense bases on
//! both axes (`dense.rs`: O(n³) an axis once, O(texels · (w + h)) a
//! solve); one dense basis on the shorter axis and banded solves along the
//! longer, clamped one (`banded.rs`: O(m³) once, O(texels · (m + r²)) a
//! solve); conjugate gradients (their budget of iterations, each a few
//! passes and a transform). Each is taken only within the limit. Figures are operations: the scalar loops
//! (eigenproblems, banded Cholesky) count one a multiply–add, the dense
//! matrix products a quarter (matrixmultiply's blocked kernels run some
//! four times as fast on this kind of CPU). The orthogonal fit counts
//! [`ORTHOGONAL_SOLVES`] vertical solves.

use crate::error::{Error, Result};
use crate::options::{Border, Fit};

use super::HeightOptions;
use super::dense::MAX_DENSE;
use super::solve::Axis;

/// Operations a texel the inverse may take; below [`FLOOR`] in all, any
/// map may. At some 1.5e9 a second on one core, 1024² texels may take
/// about 3 s.
pub(super) const PER_TEXEL: f64 = 4000.0;

/// Operations any map may take, however few its texels (about 1.5 s).
pub(super) const FLOOR: f64 = 2_147_483_648.0;

/// Operations the solves (not the bases, made once) of any map may take,
/// however few its texels (about 0.4 s): [`FLOOR`] is for a small map's
/// one-off bases, and a strip's orthogonal fit, a dozen banded solves of
/// 2000 operations a texel at N = 63, must not spend it (3 × 20000 took
/// over 20 s within it).
pub(super) const SOLVE_FLOOR: f64 = 536_870_912.0;

/// The vertical solves the orthogonal fit is counted as: its fixed point
/// takes a few, Gauss–Newton's steps some more (256², clamp, N = 63: six
/// times the vertical fit's time).
const ORTHOGONAL_SOLVES: f64 = 12.0;

/// The dense products' weight against a scalar loop's multiply–add.
const PRODUCT: f64 = 0.25;

/// Operations a texel a conjugate gradients' iteration takes (the exact
/// operator and its adjoint, the half-sample transform's solve; 1030 × 3
/// at N = 63 spent its 2000 iterations in 2 s).
const CG_TEXEL: f64 = 500.0;

/// The widest band taken: P and Q of patches up to N = 63 (2r = 62). A
/// solve's banded part costs some n r² a mode, 1 GFlop at 2048 × 256,
/// N = 63; wider patches are refused (this estimate says so up front).
pub(super) const MAX_BAND: usize = 62;

/// Whether the path takes a map whose shorter axis has `m` texels and
/// whose longer one `n`, with `border`, for a patch of radius `r`.
pub(super) fn applies(m: usize, n: usize, border: Border, r: usize) -> bool {
    m <= MAX_DENSE && n >= 2 && border == Border::Clamp && (2 * r).min(n - 1) <= MAX_BAND
}

/// The conjugate gradients' iterations at most, over every solve of one
/// inverse (`iterative.rs`): each is a few passes over the texels whatever
/// N, so the time is bounded by the texels; past it the heights are the
/// closest found, unsettled.
pub(super) const CG_ITERATIONS: usize = 2000;

/// A way to solve clamp with N ≥ 5.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Path {
    /// Dense bases on both axes.
    Dense,
    /// One dense basis and banded solves.
    OneAxis,
    /// Conjugate gradients.
    ConjugateGradients,
}

/// The limit for `texels`: [`PER_TEXEL`] each, at least [`FLOOR`].
fn limit(texels: f64) -> f64 {
    (PER_TEXEL * texels).max(FLOOR)
}

/// Whether a transform solves the exact model on this shape (every border
/// but clamp with N ≥ 5 on an axis of two texels or more): linear, no
/// estimate needed.
pub(super) fn has_transform(w: usize, h: usize, opts: &HeightOptions) -> bool {
    let (b, r) = (opts.fit.borders, opts.fit.patch / 2);
    Axis::new(w, b.x, r).is_some() && Axis::new(h, b.y, r).is_some()
}

/// Whether `path` takes the shape within the limit: all its operations
/// within [`limit`], its solves within [`PER_TEXEL`] a texel (at least
/// [`SOLVE_FLOOR`]).
fn within_limit(path: Path, w: usize, h: usize, opts: &HeightOptions) -> bool {
    let texels = w as f64 * h as f64;
    costs(path, w, h, opts).is_some_and(|(setup, solves)| {
        setup + solves <= limit(texels) && solves <= (PER_TEXEL * texels).max(SOLVE_FLOOR)
    })
}

/// The estimated operations of `path` on a `w` × `h` map with `opts`, in
/// two: the bases made once, and the solves; `None` where the path does
/// not take the shape.
fn costs(path: Path, w: usize, h: usize, opts: &HeightOptions) -> Option<(f64, f64)> {
    let texels = w as f64 * h as f64;
    let solves = if opts.fit.fit == Fit::Orthogonal { ORTHOGONAL_SOLVES } else { 1.0 };
    // An axis's dense basis: Householder's form and the QL method, some
    // 6n³.
    let basis = |n: usize| if n > 1 { 6.0 * (n as f64).powi(3) } else { 0.0 };
    let r = opts.fit.patch / 2;
    match path {
        Path::Dense => {
            if w > MAX_DENSE || h > MAX_DENSE {
                return None;
            }
            // A square map with one border makes one basis for both axes.
            let same = w == h && opts.fit.borders.x == opts.fit.borders.y;
            let setup = basis(w) + if same { 0.0 } else { basis(h) };
            Some((setup, solves * PRODUCT * 2.0 * texels * (w + h) as f64))
        }
        Path::OneAxis => {
            let (m, n) = (w.min(h), w.max(h));
            let long = if w < h { opts.fit.borders.y } else { opts.fit.borders.x };
            if !applies(m, n, long, r) {
                return None;
            }
            let band = (2 * r).min(n - 1) as f64;
            // The null directions' factors (P's and Q's), once; a solve: the
            // products along the dense axis, then per mode a banded
            // Cholesky factor (band²/2 a texel) and its substitutions.
            let setup = basis(m) + 2.0 * n as f64 * band * band;
            let solve = texels * (PRODUCT * 2.0 * m as f64 + 0.5 * band * band + 4.0 * band);
            Some((setup, solves * solve))
        }
        Path::ConjugateGradients => Some((0.0, texels * CG_ITERATIONS as f64 * CG_TEXEL)),
    }
}

/// The paths that take the shape within the limit, in the order they are
/// tried: dense bases, then the banded solves (a basis, or the pins, can
/// fail to be made), then conjugate gradients.
pub(super) fn paths(w: usize, h: usize, opts: &HeightOptions) -> Vec<Path> {
    [Path::Dense, Path::OneAxis, Path::ConjugateGradients]
        .into_iter()
        .filter(|&p| within_limit(p, w, h, opts))
        .collect()
}

/// Refuses, before any solve, a map that no path takes within the limit
/// (a transform always does): one line naming the estimate, the limit,
/// and what to use instead. A map without a slope never comes here: its
/// heights are 0.
///
/// Errors: [`Error::InvalidOption`].
pub(super) fn check(w: usize, h: usize, opts: &HeightOptions) -> Result<()> {
    if has_transform(w, h, opts) || !paths(w, h, opts).is_empty() {
        return Ok(());
    }
    Err(refusal(w, h, opts))
}

/// The refusal of a `w` × `h` map with `opts`: the cheapest path's
/// estimate against the limit, and what runs instead.
pub(super) fn refusal(w: usize, h: usize, opts: &HeightOptions) -> Error {
    let texels = w as f64 * h as f64;
    let (setup, solves) = [Path::Dense, Path::OneAxis, Path::ConjugateGradients]
        .into_iter()
        .filter_map(|p| costs(p, w, h, opts))
        .fold((f64::INFINITY, 0.0), |best, c| if c.0 + c.1 < best.0 + best.1 { c } else { best });
    let vertical = HeightOptions { fit: opts.fit.clone().with_fit(Fit::Vertical), ..opts.clone() };
    let also =
        if opts.fit.fit == Fit::Orthogonal && !paths(w, h, &vertical).is_empty() { ", --fit vertical" } else { "" };
    // Within the limit in all, the solves are what passes theirs.
    let cost = if setup + solves <= limit(texels) {
        format!(
            "solves of some {solves:.1e} operations, past their limit of {:.1e} ({PER_TEXEL} a texel, at least \
             {SOLVE_FLOOR:.1e})",
            (PER_TEXEL * texels).max(SOLVE_FLOOR)
        )
    } else {
        format!(
            "some {:.1e} operations, past the limit of {:.1e} ({PER_TEXEL} a texel, at least {FLOOR:.1e})",
            setup + solves,
            limit(texels)
        )
    };
    Error::InvalidOption(format!(
        "clamp borders with N = {} on {w} × {h} texels take {cost}: use --border mirror or wrap{also}, or N = 3",
        opts.fit.patch,
    ))
}

#[cfg(test)]
mod tests {
    use super::super::banded::OneAxis;
    use super::super::dense::{DenseSolver, NULL};
    use super::super::patch::Patch;
    use super::*;
    use crate::{Border, Borders, Options};

    fn clamp(n: usize, fit: Fit) -> HeightOptions {
        HeightOptions::from_fit(&Options::new().with_patch(n).with_fit(fit).with_borders(Borders::both(Border::Clamp)))
    }

    /// The paths each shape takes, by the estimate: those that ran in a
    /// few seconds (2048 × 256 at N = 5 and 15, both fits: 1.1 s; 256² at
    /// any N), the strips by their banded solves even under 1024 texels
    /// (1024 × 3: dense bases would take 6e9 operations for 3072 texels),
    /// the memory rule's 600 × 3 at N = 255 by dense bases; refused: 1024²
    /// at any N (7 s for one vertical solve's bases), 2048 × 256 at N = 63
    /// orthogonal, and every band past the banded path's. The refusal is one
    /// line, naming the limit, and says --fit vertical where that passes.
    #[test]
    fn the_limit_keeps_the_paths_that_run_in_time_and_refuses_the_rest() {
        use Fit::{Orthogonal, Vertical};
        let first = |w, h, n, fit| paths(w, h, &clamp(n, fit)).first().copied();
        for n in [5, 15] {
            for fit in [Orthogonal, Vertical] {
                assert_eq!(first(2048, 256, n, fit), Some(Path::OneAxis), "N {n} {fit:?}");
                assert_eq!(first(1024, 3, n, fit), Some(Path::OneAxis), "N {n} {fit:?}");
            }
        }
        for n in [5, 63, 255, 1023] {
            assert_eq!(first(256, 256, n, Orthogonal), Some(Path::Dense), "N {n}");
            assert_eq!(first(600, 3, n, Orthogonal), Some(Path::Dense), "N {n}");
            for fit in [Orthogonal, Vertical] {
                assert!(check(1024, 1024, &clamp(n, fit)).is_err(), "1024², N {n} {fit:?}");
            }
        }
        assert_eq!(first(2048, 256, 63, Vertical), Some(Path::OneAxis));
        let message = check(2048, 256, &clamp(63, Orthogonal)).unwrap_err().to_string();
        assert!(message.contains("2048 × 256") && message.contains("past the limit of 2.1e9"), "{message}");
        assert!(message.contains("--fit vertical") && !message.contains('\n'), "{message}");
        // A strip's orthogonal fit at N = 63: within the floor in all
        // (1.7e9), but a dozen banded solves past what its texels may
        // spend on solves; its vertical fit, one solve, runs.
        for (w, h) in [(3, 20000), (20000, 3)] {
            let message = check(w, h, &clamp(63, Orthogonal)).unwrap_err().to_string();
            assert!(message.contains("--fit vertical"), "{message}");
            assert_eq!(first(w, h, 63, Vertical), Some(Path::OneAxis));
        }
        assert_eq!(first(1030, 3, 63, Orthogonal), Some(Path::OneAxis));
        assert_eq!(first(2, 1100, 63, Orthogonal), Some(Path::OneAxis));
        for (w, h) in [(2048, 256), (3, 20000), (1030, 3)] {
            let message = check(w, h, &clamp(255, Vertical)).unwrap_err().to_string();
            assert!(message.contains("N = 255") && !message.contains("--fit vertical"), "{message}");
        }
        // A transform takes any shape: nothing to estimate.
        assert!(check(4096, 4096, &clamp(3, Orthogonal)).is_ok());
        let wrap = HeightOptions::from_fit(&Options::new().with_patch(1023));
        assert!(check(4096, 4096, &wrap).is_ok());
    }

    /// Where both apply, the banded solves give the dense bases' answer
    /// (the least squares of least norm, random slopes: a map the fit did
    /// not make), either way round. Their heights agree where the system is
    /// well conditioned; where it is not (5 × 40 at N = 15, 4 × 160 at
    /// N = 63: the dense bases keep modes the fit barely sees, heights of
    /// 1e5 from slopes of 0.5) the two differ in those modes, and what
    /// both must hold is the fit of their heights: the least-squares
    /// projection of the given slopes, which is unique, and its misfit.
    #[test]
    fn the_banded_solve_gives_the_dense_solves_heights() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let cases = [(37, 6, 5, true), (37, 6, 7, true), (5, 40, 5, true), (5, 40, 15, false), (4, 160, 63, false)];
        for (w, h, n, well_conditioned) in cases {
            let opts = clamp(n, Fit::Vertical);
            let patch = Patch::new(w, h, &opts);
            let dense = DenseSolver::new(&patch, h).unwrap();
            let banded = OneAxis::new(&patch, h).unwrap();
            let len = w * h;
            let (gx, gy): (Vec<f64>, Vec<f64>) = (0..len).map(|_| (next(), next())).unzip();
            let slopes = |y: usize, rx: &mut [f64], ry: &mut [f64]| {
                rx.copy_from_slice(&gx[y * w..][..w]);
                ry.copy_from_slice(&gy[y * w..][..w]);
            };
            let (ones_w, ones_h) = (vec![1.0; w], vec![1.0; h]);
            let (mut px, mut py, mut b) = (vec![0.0; len], vec![0.0; len], vec![0.0; len]);
            DenseSolver::right_hand_side(&patch, &slopes, (&ones_w, &ones_h), (&mut px, &mut py), &mut b);
            let mut b2 = b.clone();
            let (mut z_dense, mut z_banded) = (vec![0.0; len], vec![0.0; len]);
            dense.solve(&mut b, 0.0, NULL, (&ones_w, &ones_h), &mut z_dense).unwrap();
            banded.solve(&mut b2, 0.0, (&ones_w, &ones_h), &mut z_banded).unwrap();
            let largest = |v: &[f64]| v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let farthest = |a: &[f64], b: &[f64]| a.iter().zip(b).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            if well_conditioned {
                let (scale, worst) = (largest(&z_dense), farthest(&z_dense, &z_banded));
                assert!(scale > 0.1 && worst <= 1e-8 * scale, "{w}×{h} N {n}: {worst:e} of {scale:e}");
            }
            let fitted = |z: &[f64]| {
                let (mut sx, mut sy) = (vec![0.0; len], vec![0.0; len]);
                patch.slopes(z, &mut sx, &mut sy);
                [sx, sy].concat()
            };
            let (s_dense, s_banded) = (fitted(&z_dense), fitted(&z_banded));
            let (scale, worst) = (largest(&s_dense), farthest(&s_dense, &s_banded));
            let given = [gx.clone(), gy.clone()].concat();
            let misfit = |s: &[f64]| s.iter().zip(&given).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
            // Both reach the least-squares minimum: their misfits agree to
            // 1e-9 (1e-7 ill-conditioned; measured 2e-12 at 5 × 40, N = 15,
            // and 1.5e-8 at 4 × 160, N = 63, where the banded solve's pins
            // are checked to 1e-4), and their slopes to 1e-7 of the largest
            // (1e-3 ill-conditioned; measured 2.6e-6 and 2.9e-4).
            let (m_dense, m_banded) = (misfit(&s_dense), misfit(&s_banded));
            let (bound, misfit_bound) = if well_conditioned { (1e-7, 1e-9) } else { (1e-3, 1e-7) };
            assert!(
                scale > 0.05 && worst <= bound * scale && (m_dense - m_banded).abs() <= misfit_bound * m_dense,
                "{w}×{h} N {n}: slopes {worst:e} of {scale:e}; misfit dense {m_dense:e} banded {m_banded:e}"
            );
        }
    }
}
