//! What the inverse holds, for the memory rule ([`crate::memory`]): one
//! estimate, checked at the entry points ([`super::heights_of_rows`] and
//! [`super::file::HeightConversion::convert`]) before anything is
//! allocated, so that a map too large for the memory limits is refused in
//! one line rather than aborting the process part way through.
//!
//! The estimate follows the solve's buffers as they are: the patch sums
//! are line sums (`line.rs`, a few values a texel whatever N), so what
//! grows with N is only a line's scratch (2r values a thread); what grows
//! with the shape besides the planes is clamp's dense bases (`dense.rs`:
//! several n × n matrices per axis while they are made) and their null
//! modes, or past 1024 texels its one dense basis and the bands of the
//! longer axis (`banded.rs`: 2r + 1 values a texel of that axis, and a
//! factor of them on each thread). A change to what the solve holds belongs here too.

use super::dense::MAX_DENSE;
use super::solve::{Axis, RHS_DIRECT_RADIUS, Solver};
use super::{HeightOptions, Model};
use crate::error::Result;
use crate::options::{Borders, Fit};

/// Bytes of an f64.
const F64: u64 = 8;

/// A thread's packing buffers in the dense bases' matrix products
/// (matrixmultiply's blocks of A and B: some 2.2 MB for f64), rounded up.
const PACKING: u64 = 4 << 20;

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
/// caller's normals (or decoded image), from which the slopes are made
/// row by row ([`super::SlopeField`]): the heights (8 a texel) and the output's
/// samples (4); the most the
/// solve holds at once on top ([`generic_bytes`], [`exact_bytes`]); and
/// every thread's scratch ([`thread_scratch`]). Gauss–Newton's steps come
/// on top only when their own room is there ([`gauss_newton_bytes`]).
///
/// Errors: those of the forward fit's options (the re-fit's plan).
pub(super) fn bytes_needed(w: usize, h: usize, opts: &HeightOptions) -> Result<u64> {
    let texels = (w as u64).saturating_mul(h as u64);
    let base = texels.saturating_mul(F64 + 4);
    let solve = match opts.model {
        Model::Generic => generic_bytes(w, h, opts.fit.borders),
        Model::Exact => exact_bytes(w, h, opts)?,
    };
    Ok(base.saturating_add(solve).saturating_add(threads_scratch(w, h, opts)))
}

/// The bytes Gauss–Newton's steps add (the refinement runs only where
/// they fit), checked where they start, with the solver's planes and the
/// dense bases already held: its planes ([`super::gauss_newton::BYTES_PER_TEXEL`],
/// the heights it started from among them), its preconditioner's (the
/// dense bases' two planes and null modes; a transform's spectra are
/// held already, their column pass is not), the patch sums' column pass
/// (three planes of it), and every thread's scratch.
pub(super) fn gauss_newton_bytes(w: usize, h: usize, opts: &HeightOptions) -> u64 {
    let texels = (w as u64).saturating_mul(h as u64);
    let preconditioner =
        if has_transform(w, h, opts) { spectra_pieces(w, h) } else { 2 * plane(w, h) + null_list(w, h) };
    texels
        .saturating_mul(super::gauss_newton::BYTES_PER_TEXEL)
        .saturating_add(preconditioner)
        .saturating_add(column_pieces(w, h, 3))
        .saturating_add(threads_scratch(w, h, opts))
}

/// One plane of f64 over the image.
fn plane(w: usize, h: usize) -> u64 {
    (w as u64).saturating_mul(h as u64).saturating_mul(F64)
}

/// The generic model's solve: two complex planes of row spectra (clamp
/// as mirror: no more than [`Solver::memory`] gives for clamp) and their
/// column pass.
fn generic_bytes(w: usize, h: usize, borders: Borders) -> u64 {
    Solver::memory(w, h, borders, Model::Generic).saturating_add(spectra_pieces(w, h))
}

/// Whether a transform solves the exact model's vertical fit (every
/// border but clamp with N ≥ 5 on an axis of two texels or more).
fn has_transform(w: usize, h: usize, opts: &HeightOptions) -> bool {
    let (b, r) = (opts.fit.borders, opts.fit.patch / 2);
    Axis::new(w, b.x, r).is_some() && Axis::new(h, b.y, r).is_some()
}

/// The most the exact model's solve holds at once, beside the slopes and
/// heights: the vertical solve's (a transform's plane of spectra, or
/// clamp's dense bases, or conjugate gradients' planes), and for the
/// orthogonal fit its ratios, their directions and the heights kept
/// (13 bytes a texel) with the larger of a vertical solve and a re-fit.
///
/// Errors: those of the forward fit's options (the re-fit's plan).
pub(super) fn exact_bytes(w: usize, h: usize, opts: &HeightOptions) -> Result<u64> {
    let r = opts.fit.patch / 2;
    let borders = opts.fit.borders;
    let p = plane(w, h);
    // The transform's spectra (or, without a transform, the nearest one's,
    // which the conjugate gradients solve with), kept from solve to solve.
    let spectra = Solver::memory(w, h, borders, Model::Exact);
    // (held between solves, the peak of a vertical solve, the dense bases'
    // making)
    let (held, vertical, making) = if has_transform(w, h, opts) {
        // Wide patches form the right-hand side as a plane by line sums
        // (a column pass of two planes) beside the spectra.
        let rhs = if r > RHS_DIRECT_RADIUS { p.saturating_add(column_pieces(w, h, 2)) } else { 0 };
        (spectra, spectra.saturating_add(spectra_pieces(w, h)).saturating_add(rhs), 0)
    } else {
        // Conjugate gradients: eight planes, the nearest transform's
        // spectra and column pass, the patch sums' column pass (two planes).
        let cg = spectra
            .saturating_add(spectra_pieces(w, h))
            .saturating_add(p.saturating_mul(8))
            .saturating_add(column_pieces(w, h, 2));
        if w <= MAX_DENSE && h <= MAX_DENSE {
            // The dense bases, or conjugate gradients where a basis cannot
            // be made.
            let bases = dense_bases(w, h);
            let dense = bases.saturating_add(dense_solve(w, h));
            (bases.max(spectra), dense.max(cg), dense_making(w, h))
        } else if let Some(band) = one_axis_band(w, h, opts) {
            // One dense basis and the banded solves, or conjugate
            // gradients where they cannot be made.
            let held = one_axis_held(w, h, band);
            let solve = held.saturating_add(one_axis_solve(w, h, band));
            (held.max(spectra), solve.max(cg), one_axis_making(w, h, r, band))
        } else {
            (spectra, cg, 0)
        }
    };
    let solve = vertical.max(making);
    if opts.fit.fit != Fit::Orthogonal {
        return Ok(solve);
    }
    let refit = if super::line::refit_by_lines(w, h, opts.fit.patch) {
        // Three planes of line sums and their column pass.
        p.saturating_mul(3).saturating_add(column_pieces(w, h, 3))
    } else {
        band_refit(w, h, opts)?
    };
    let ratios = (w as u64).saturating_mul(h as u64).saturating_mul(8 + 1 + 4);
    Ok(solve.max(ratios.saturating_add(vertical.max(held.saturating_add(refit)))))
}

/// The orthogonal fit's re-fit by the forward fit's sums: a band of its
/// moments (24 bytes a texel) and the fit's own work on it.
fn band_refit(w: usize, h: usize, opts: &HeightOptions) -> Result<u64> {
    let forward = crate::Options::new()
        .with_patch(opts.fit.patch)
        .with_fit(Fit::Vertical)
        .with_borders(opts.fit.borders)
        .with_strength(crate::Strength::Scale(1.0));
    let fit = crate::fit::BandFit::new(w, h, &forward)?.with_unit(1.0);
    let band = fit.band_rows().max(fit.radius()).min(h) as u64;
    Ok((band * w as u64).saturating_mul(24).saturating_add(fit.work_bytes::<f64>(false)))
}

/// The dense bases held between solves: per axis its n × n basis and
/// five vectors of n (a square map with one border holds two copies of
/// one basis, no more than two).
fn dense_bases(w: usize, h: usize) -> u64 {
    let axis = |n: u64| F64 * (n * n + 5 * n);
    axis(w as u64) + axis(h as u64)
}

/// The most making the bases holds: an axis's basis takes up to ten n × n
/// matrices at once (its ramp and box responses, their Gram matrices, the
/// eigenvectors and the products that rotate them), the first axis's
/// basis held while the second's is made.
fn dense_making(w: usize, h: usize) -> u64 {
    let (x, y) = (w as u64, h as u64);
    F64 * (10 * x * x).max(x * x + 10 * y * y)
}

/// The half-bandwidth of the banded solves (`banded.rs`) where they take
/// the map: clamp with N ≥ 5, an axis past [`MAX_DENSE`].
fn one_axis_band(w: usize, h: usize, opts: &HeightOptions) -> Option<usize> {
    let (m, n) = (w.min(h), w.max(h));
    let border = if w < h { opts.fit.borders.y } else { opts.fit.borders.x };
    let r = opts.fit.patch / 2;
    super::cost::applies(m, n, border, r).then(|| (2 * r).min(n - 1))
}

/// What the banded solves hold between solves: the shorter axis's basis
/// (as [`dense_bases`] counts one), the longer axis's P and Q bands, and
/// their null vectors (up to [`super::banded::MAX_PINS`] each, n values).
fn one_axis_held(w: usize, h: usize, band: usize) -> u64 {
    let (m, n) = (w.min(h) as u64, w.max(h) as u64);
    let nulls = 2 * super::banded::MAX_PINS as u64 * n;
    F64 * (m * m + 5 * m) + 2 * F64 * n * (band as u64 + 1) + F64 * nulls
}

/// Making them: the shorter axis's basis (ten m × m matrices, as
/// [`dense_making`]), the longer axis's rows of R and B (2r + 1 values a
/// texel each) and its bands.
fn one_axis_making(w: usize, h: usize, r: usize, band: usize) -> u64 {
    let (m, n) = (w.min(h) as u64, w.max(h) as u64);
    let rows = 2 * F64 * n * (2 * r as u64 + 1);
    (F64 * 10 * m * m).max(rows).saturating_add(one_axis_held(w, h, band))
}

/// One banded solve beside what is held: the right-hand side as a dense
/// solve forms it, then the right-hand side, a plane of work, a plane for
/// the preconditioner's weighted copy or the null modes' transposed
/// heights, every thread's factor (n (band + 1) values) and the null
/// modes' Gram matrix (one a mode of the shorter axis at most).
fn one_axis_solve(w: usize, h: usize, band: usize) -> u64 {
    let (m, n) = (w.min(h) as u64, w.max(h) as u64);
    let p = plane(w, h);
    let factors = (crate::par::current_num_threads() as u64).saturating_mul(F64 * n * (band as u64 + 1));
    let nulls = F64 * (m * m + m * (m + n + 2)) + 48 * m;
    (3 * p + column_pieces(w, h, 1)).max(3 * p + factors + nulls)
}

/// One dense solve beside the bases: the right-hand side and its two
/// slope planes (three planes) with the adjoint's column pass, then the
/// right-hand side, a plane of work and the null modes found
/// ([`null_list`]). Those modes' projection is checked where the solve
/// has counted them (`dense.rs`): a handful as a rule, up to 4096 (some
/// 160 MiB at 1024 × 1024) for an operator that sees next to nothing.
fn dense_solve(w: usize, h: usize) -> u64 {
    let p = plane(w, h);
    let right_hand_side = 3 * p + column_pieces(w, h, 1);
    let apply = 2 * p + null_list(w, h);
    right_hand_side.max(apply)
}

/// The null modes a dense solve lists, at most one a texel: 16 bytes
/// each in a row's list and again in the list of all of them, each grown
/// by doubling (up to twice its length).
fn null_list(w: usize, h: usize) -> u64 {
    (w as u64).saturating_mul(h as u64).saturating_mul(64)
}

/// The line sums' column pass (`line.rs`) over `outs` planes of `w` × `h`:
/// for each block of 16 columns and each output, its piece of every row
/// (a slice, 16 bytes).
fn column_pieces(w: usize, h: usize, outs: u64) -> u64 {
    let blocks = w.div_ceil(super::line::COLUMNS_PER_TASK) as u64;
    outs.saturating_mul(blocks).saturating_mul(16 * h as u64 + 24)
}

/// The transforms' column pass over the plane of row spectra (at most
/// w + 1 of them a row): for each block of 8 columns its piece of every
/// row (a slice, 16 bytes).
fn spectra_pieces(w: usize, h: usize) -> u64 {
    let blocks = (w + 1).div_ceil(super::solve::COLUMNS_PER_TASK) as u64;
    blocks.saturating_mul(16 * h as u64 + 24)
}

/// Scratch on every thread at once ([`crate::memory::in_heaps`] each):
/// the transforms' right-hand side (a task's rows of it, and its rows'
/// box and ramp sums along x with r ≤ [`RHS_DIRECT_RADIUS`] rows more on
/// either side; wider patches take the plane of line sums instead), the
/// transforms' rows and columns; the line sums' tasks (a row's or a block
/// of 16 columns' gathered inputs and outputs, up to six of them, four
/// lines of temporaries, rows of slopes and sums, and a line's scratch:
/// its values, two periods or the line and 2r more, and their block sums,
/// 40 bytes a value); the dense bases' packing buffers.
fn threads_scratch(w: usize, h: usize, opts: &HeightOptions) -> u64 {
    use super::solve::RHS_ROWS_PER_TASK;
    let (w, h, rows) = (w as u64, h as u64, RHS_ROWS_PER_TASK as u64);
    let r = (opts.fit.patch / 2) as u64;
    let direct = if opts.model == Model::Exact { r.min(RHS_DIRECT_RADIUS as u64) } else { 0 };
    let right_hand_side = 8 * w * rows + 16 * w * (rows + 2 * direct) + 32 * (w + 2 * direct);
    // Real transforms of rows (periods up to 2w + 2), complex ones of
    // columns: their input, output and scratch; a task's columns.
    let transforms = 96 * (2 * w + 2) + 64 * (2 * h + 2) + 16 * 8 * h;
    let line = |n: u64| 40 * (4 * n + 2 * r) + 32 * n;
    // A row of normals and two of slopes ([`super::SlopeField`]'s, kept by each
    // thread) beside the row tasks' planes.
    let slope_rows = 24 * w + 16 * w;
    let rows_task = 32 * w + 48 * w + line(w) + slope_rows;
    let columns_task = 6 * 16 * 8 * h + 32 * h + line(h);
    let dense = if has_transform(w as usize, h as usize, opts) { 0 } else { PACKING };
    let per_thread = right_hand_side
        .saturating_add(transforms)
        .saturating_add(rows_task)
        .saturating_add(columns_task)
        .saturating_add(dense);
    (crate::par::current_num_threads() as u64).saturating_mul(crate::memory::in_heaps(per_thread))
}
