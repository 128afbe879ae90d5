//! What the inverse holds, for the memory rule ([`crate::memory`]): one
//! estimate, checked at the entry points ([`super::heights_of_rows`] and
//! [`super::file::HeightConversion::convert`]) before anything is
//! allocated, so that a map too large for the memory limits is refused in
//! one line rather than aborting the process part way through.
//!
//! The estimate follows the solve's buffers; a change to what the solve
//! holds belongs here too.

use super::{HeightOptions, Model, SlopeField};
use crate::error::Result;
use crate::options::{Border, Fit};

/// Refuses the inverse of a `w` × `h` map with `opts` when what it will
/// hold ([`bytes_needed`]) does not fit in the memory the process may
/// still take.
///
/// Errors: [`crate::Error::InvalidOption`] for a zero or overflowing size,
/// [`crate::Error::Limits`] when the memory is not there.
pub(super) fn check(w: usize, h: usize, opts: &HeightOptions) -> Result<()> {
    crate::fit::checked_len(w, h)?;
    crate::memory::check_memory("finding the heights", bytes_needed(w, h, opts)?)
}

/// The bytes the inverse of a `w` × `h` map holds at most, beside the
/// caller's normals (or decoded image): its planes per texel
/// ([`per_texel`]); the exact model's patch operators, which grow with N
/// ([`patch_operators`]); the most of what the clamp's conjugate
/// gradients (the operators' transposes) and the orthogonal fit's re-fits
/// (a band of the forward fit's moments and its sums, which grow with N)
/// add; and the solve's scratch on every thread ([`row_scratch`], which
/// grows with N too). Gauss–Newton's steps come on
/// top only when their own room is there ([`gauss_newton_bytes`]).
///
/// Errors: those of the forward fit's options (the re-fit's plan).
pub(super) fn bytes_needed(w: usize, h: usize, opts: &HeightOptions) -> Result<u64> {
    let texels = (w as u64).saturating_mul(h as u64);
    let fit = &opts.fit;
    let exact = opts.model == Model::Exact;
    let operators = if exact { patch_operators(w, h, fit.patch) } else { 0 };
    let transposes = if exact && conjugate_gradients(opts) { transposed_operators(w, h, fit.patch) } else { 0 };
    let refit = if exact && fit.fit == Fit::Orthogonal { refit_bytes(w, h, opts)? } else { 0 };
    Ok(texels
        .saturating_mul(per_texel(opts, w))
        .saturating_add(operators)
        .saturating_add(transposes.max(refit))
        .saturating_add(row_scratch(w, h, opts)))
}

/// The bytes Gauss–Newton's steps add (the refinement runs only where they
/// fit): its planes per texel, the operators' transposes, rows of scratch.
pub(super) fn gauss_newton_bytes(w: usize, h: usize, opts: &HeightOptions) -> u64 {
    let texels = (w as u64).saturating_mul(h as u64);
    texels
        .saturating_mul(super::gauss_newton::BYTES_PER_TEXEL)
        .saturating_add(transposed_operators(w, h, opts.fit.patch))
        .saturating_add(row_scratch(w, h, opts))
}

/// Whether the exact model's vertical solve is by conjugate gradients
/// (clamp with N ≥ 5, which no transform fits).
fn conjugate_gradients(opts: &HeightOptions) -> bool {
    let fit = &opts.fit;
    (fit.borders.x == Border::Clamp || fit.borders.y == Border::Clamp) && fit.patch > 3
}

/// Bytes held per texel besides the decoded image: the slopes
/// ([`SlopeField`], 16), the solve's row spectra
/// ([`super::solve::Solver::memory`]: 8 bytes a texel for the exact model
/// with a wrapped or mirrored x, 16 clamped; the generic model's two
/// complex planes 16 or 32), the heights (8), the orthogonal fit's ratios
/// and kept heights (24), the conjugate gradients' vectors (48, clamp with
/// N ≥ 5), the output's samples (4), and the column pass's pieces of the
/// spectra's rows (16 bytes per row of 8 columns: 2 a texel, or 4 for a
/// period of 2w).
fn per_texel(opts: &HeightOptions, width: usize) -> u64 {
    let fit = &opts.fit;
    let spectra = super::solve::Solver::memory(width, 1, fit.borders, opts.model);
    let iterative = if conjugate_gradients(opts) { 48 } else { 0 };
    let orthogonal = if fit.fit == Fit::Orthogonal { 24 } else { 0 };
    SlopeField::BYTES_PER_TEXEL + spectra.div_ceil(width.max(1) as u64) + 8 + orthogonal + iterative + 4 + 4
}

/// The exact model's patch sums as sparse lists (`patch.rs`): per texel of
/// each axis, N (box) and N − 1 (ramp) pairs of 16 bytes, each list
/// collected into a vector grown by doubling (a power of two, at least 4),
/// and 24 bytes a list.
fn patch_operators(w: usize, h: usize, patch: usize) -> u64 {
    let cap = |k: usize| k.next_power_of_two().max(4) as u64;
    let per_texel = 16 * (cap(patch) + cap(patch - 1)) + 2 * 24;
    (w as u64 + h as u64).saturating_mul(per_texel)
}

/// The operators' transposes (the conjugate gradients', Gauss–Newton's):
/// as many pairs as [`patch_operators`], each list grown by doubling from
/// 4 (at most twice its pairs, and 4).
fn transposed_operators(w: usize, h: usize, patch: usize) -> u64 {
    let pairs = (2 * patch - 1) as u64;
    let per_texel = 16 * (2 * pairs + 8) + 2 * 24;
    (w as u64 + h as u64).saturating_mul(per_texel)
}

/// The orthogonal fit's re-fit: a band of the forward fit's moments (24
/// bytes a texel) and the fit's own work on it, which grows with N.
fn refit_bytes(w: usize, h: usize, opts: &HeightOptions) -> Result<u64> {
    let forward = crate::Options::new()
        .with_patch(opts.fit.patch)
        .with_fit(Fit::Vertical)
        .with_borders(opts.fit.borders)
        .with_strength(crate::Strength::Scale(1.0));
    let fit = crate::fit::BandFit::new(w, h, &forward)?.with_unit(1.0);
    let band = fit.band_rows().max(fit.radius()).min(h) as u64;
    Ok((band * w as u64).saturating_mul(24).saturating_add(fit.work_bytes::<f64>(false)))
}

/// Scratch on every thread at once: the exact model's right-hand side
/// (a task's rows of it, and its rows' box and ramp sums along x with r
/// rows more on either side: this grows with N), the transforms' rows and
/// columns, and a pass's rows of slopes and sums (up to eight planes of a
/// row).
fn row_scratch(w: usize, h: usize, opts: &HeightOptions) -> u64 {
    use super::solve::{COLUMNS_PER_TASK, RHS_ROWS_PER_TASK};
    let (w, h, rows, columns) = (w as u64, h as u64, RHS_ROWS_PER_TASK as u64, COLUMNS_PER_TASK as u64);
    let r = if opts.model == Model::Exact { (opts.fit.patch / 2) as u64 } else { 0 };
    let right_hand_side = 8 * w * rows + 16 * w * (rows + 2 * r) + 32 * (w + 2 * r);
    // Real transforms of rows (periods up to 2w + 2), complex ones of
    // columns: their input, output and scratch; a task's columns.
    let transforms = 96 * (2 * w + 2) + 64 * (2 * h + 2) + 16 * columns * h;
    let per_thread = right_hand_side.saturating_add(transforms).saturating_add(64 * w);
    (crate::par::current_num_threads() as u64).saturating_mul(crate::memory::in_heaps(per_thread))
}
