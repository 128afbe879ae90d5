//! Texels of unequal spacing (ρ = sy / sx ≠ 1): the last step of the fit,
//! from a row's window sums to its normals or residuals.
//!
//! Lengths in x spacings, the rows ρ apart (see the parent's docs): the
//! points are (i, ρσj, z) and their scatter matrix
//! [[A, 0, Cx], [0, ρ²A, ρCy], [Cx, ρCy, Czz]], so
//!
//! * vertical: n ∝ (−Cx, −Cy/ρ, A);
//! * orthogonal: the eigenvector of the smallest eigenvalue, found by
//!   Newton's steps from a lower bound (`eigen`);
//! * a patch flat by the contract's rule: (0, 0, 1).
//!
//! The rule the loops obey: no branch per texel. Every case is computed
//! and the right one selected, and Newton's steps run as passes over the
//! planes of the patches still stepping (the masked fit's `newton`), so
//! that the loops vectorise; [`pulp`] compiles them for the widest vectors
//! the processor has, as the square grid's `EmitRow`. Each texel's
//! arithmetic is the per-texel solve's, in its order, and nothing fuses a
//! multiply with an add: the same bits. Texel by texel, with its branches
//! and Newton loop, this step took three quarters of a geographic DEM's
//! conversion (`perf`, 4096², N = 3), which ran at a third of the square
//! grid's speed.

use super::eigen::{Diagonal, eigen_start_on, eigenvector, is_flat, is_near_plane, near_plane, select};
use super::masked::{NewtonWork, newton};
use super::{Plan, Texel, WindowSums, store_normals};

/// The planes of one row's unequal-spacing fit, kept from row to row (a
/// strip's scratch): the matrix's varying entries, the Newton state.
#[derive(Default)]
pub(super) struct UnequalRow {
    /// a1 = A and a2 = ρ²A, the same for every patch of the row (planes:
    /// [`newton`] takes every entry as one).
    a1: Vec<f64>,
    a2: Vec<f64>,
    /// b1 = Cx, b2 = ρ·Cy, Czz.
    b1: Vec<f64>,
    b2: Vec<f64>,
    czz: Vec<f64>,
    flat: Vec<bool>,
    lambda: Vec<f64>,
    scale: Vec<f64>,
    stepping: Vec<bool>,
    work: NewtonWork,
}

/// What a row's fit needs beside its sums: the x spacing's gain, ρ and
/// the fit.
#[derive(Clone, Copy)]
pub(super) struct RowSpacing {
    /// The sums' gain: z / sx per unit of the sums.
    pub gain: f64,
    pub rho: f64,
    pub orthogonal: bool,
}

impl RowSpacing {
    /// The matrix's diagonal a1 = A and a2 = ρ²A, the same for the whole
    /// row: the loops take them as numbers, not planes.
    #[inline(always)]
    fn diagonal(self, plan: &Plan) -> (f64, f64) {
        (plan.a, self.rho * self.rho * plan.a)
    }
}

impl UnequalRow {
    /// The normals of one row of window sums, into `normal` (x, y and z
    /// planes, as long as `out`) and then `out`.
    pub(super) fn normals<T: Texel>(
        &mut self,
        plan: &Plan,
        v: &WindowSums,
        row: RowSpacing,
        normal: &mut [Vec<f64>; 3],
        out: &mut [T],
    ) {
        pulp::Arch::new().dispatch(Normals { fit: self, plan, v, row, normal, out });
    }

    /// The unit normals of the patches whose window sums are `[s0, si,
    /// sj, szz]` (in units of z / `row.gain`), into `[nx, ny, nz]`: a
    /// row's planes ([`Self::normals`]), or the one-pass emit's chunk
    /// (`Plan::emit_fused`), with the same bits. Inlined into its caller's
    /// [`pulp::Arch::dispatch`].
    #[inline(always)]
    pub(super) fn fill_normals(
        &mut self,
        plan: &Plan,
        sums: [&[f64]; 4],
        row: RowSpacing,
        [nx, ny, nz]: [&mut [f64]; 3],
    ) {
        let w = sums[0].len();
        let (nx, ny, nz) = (&mut nx[..w], &mut ny[..w], &mut nz[..w]);
        if row.orthogonal {
            self.smallest_eigenvalues(plan, sums, row);
            let UnequalRow { b1, b2, czz, flat, lambda, .. } = &*self;
            let diagonal = row.diagonal(plan);
            orthogonal_normals(diagonal, &b1[..w], &b2[..w], &czz[..w], &lambda[..w], &flat[..w], nx, ny, nz);
        } else {
            vertical_normals(Sums::of(plan, sums, row), nx, ny, nz);
        }
    }

    /// The orthogonal fit's RMS distance of each patch's points from its
    /// plane, times `sx` (the heights' unit): the smallest eigenvalue
    /// (Czz for a flat patch) over N², its root.
    pub(super) fn residuals(&mut self, plan: &Plan, v: &WindowSums, row: RowSpacing, sx: f64, out: &mut [f32]) {
        pulp::Arch::new().dispatch(Residuals { fit: self, plan, v, row, sx, out });
    }

    /// Makes room for `w` patches.
    fn resize(&mut self, w: usize) {
        for plane in [&mut self.a1, &mut self.a2, &mut self.b1, &mut self.b2, &mut self.czz] {
            plane.resize(w, 0.0);
        }
        for plane in [&mut self.lambda, &mut self.scale] {
            plane.resize(w, 0.0);
        }
        self.flat.resize(w, false);
        self.stepping.resize(w, false);
    }

    /// The orthogonal fit's λ of the patches whose window sums are
    /// `sums`: the matrices, the start, and Newton's steps.
    #[inline(always)]
    fn smallest_eigenvalues(&mut self, plan: &Plan, sums: [&[f64]; 4], row: RowSpacing) {
        let w = sums[0].len();
        self.resize(w);
        let UnequalRow { a1, a2, b1, b2, czz, flat, lambda, scale, stepping, work } = self;
        let (a1, a2, b1, b2, czz) = (&mut a1[..w], &mut a2[..w], &mut b1[..w], &mut b2[..w], &mut czz[..w]);
        let (flat, lambda, scale, stepping) = (&mut flat[..w], &mut lambda[..w], &mut scale[..w], &mut stepping[..w]);
        let (a, rho_a) = row.diagonal(plan);
        a1.fill(a);
        a2.fill(rho_a);
        matrices(Sums::of(plan, sums, row), b1, b2, czz, flat);
        start(Diagonal::new(a, rho_a), b1, b2, czz, flat, lambda, scale, stepping);
        newton(a1, a2, b1, b2, czz, scale, lambda, stepping, work);
    }
}

/// Patches' window sums, each plane as long, and the constants that turn
/// them into moments (lengths in x spacings).
#[derive(Clone, Copy)]
struct Sums<'a> {
    s0: &'a [f64],
    si: &'a [f64],
    sj: &'a [f64],
    szz: &'a [f64],
    /// N², and the gain of N²·Czz (gain² / N²).
    n2: f64,
    czz_gain: f64,
    /// The gains of Cx and Cy (σ included).
    gx: f64,
    gy: f64,
    a: f64,
    rho: f64,
}

impl<'a> Sums<'a> {
    #[inline(always)]
    fn of(plan: &Plan, [s0, si, sj, szz]: [&'a [f64]; 4], row: RowSpacing) -> Sums<'a> {
        let n2 = plan.count;
        let w = s0.len();
        Sums {
            s0,
            si: &si[..w],
            sj: &sj[..w],
            szz: &szz[..w],
            n2,
            czz_gain: row.gain * row.gain / n2,
            gx: row.gain,
            gy: plan.sigma * row.gain,
            a: plan.a,
            rho: row.rho,
        }
    }

    /// Texel x's Cx, Cy (unscaled by ρ) and Czz, as the square grid's
    /// loop forms them.
    #[inline(always)]
    fn at(&self, x: usize) -> (f64, f64, f64) {
        let czz = Plan::czz(self.n2, self.czz_gain, self.s0[x], self.szz[x]);
        (self.gx * self.si[x], self.gy * self.sj[x], czz)
    }
}

/// [`UnequalRow::normals`]' loops, for [`pulp::Arch::dispatch`] (inlined
/// into `with_simd`, so compiled for each instruction set).
struct Normals<'a, T> {
    fit: &'a mut UnequalRow,
    plan: &'a Plan,
    v: &'a WindowSums,
    row: RowSpacing,
    normal: &'a mut [Vec<f64>; 3],
    out: &'a mut [T],
}

impl<T: Texel> pulp::WithSimd for Normals<'_, T> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let Normals { fit, plan, v, row, normal, out } = self;
        let w = out.len();
        fit.fill_normals(plan, v.planes(w), row, normal.each_mut().map(|plane| &mut plane[..w]));
        store_normals(normal, &plan.frame, out);
    }
}

/// [`UnequalRow::residuals`]' loops, for [`pulp::Arch::dispatch`].
struct Residuals<'a> {
    fit: &'a mut UnequalRow,
    plan: &'a Plan,
    v: &'a WindowSums,
    row: RowSpacing,
    sx: f64,
    out: &'a mut [f32],
}

impl pulp::WithSimd for Residuals<'_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let Residuals { fit, plan, v, row, sx, out } = self;
        let w = out.len();
        fit.smallest_eigenvalues(plan, v.planes(w), row);
        let inv_n2 = 1.0 / plan.count;
        let (czz, flat, lambda) = (&fit.czz[..w], &fit.flat[..w], &fit.lambda[..w]);
        for x in 0..w {
            let sum = select(flat[x], czz[x], lambda[x].max(0.0));
            out[x] = ((sum * inv_n2).sqrt() * sx) as f32;
        }
    }
}

// The loops' planes are separate arguments, each cut to the loop's
// length: the compiler then knows that they neither overlap nor end
// early, and vectorises the loops.

/// The vertical fit: n ∝ (−Cx, −Cy/ρ, A), or (0, 0, 1) where flat.
#[inline(always)]
fn vertical_normals(sums: Sums<'_>, nx: &mut [f64], ny: &mut [f64], nz: &mut [f64]) {
    let w = sums.s0.len();
    let (nx, ny, nz) = (&mut nx[..w], &mut ny[..w], &mut nz[..w]);
    let (a, rho) = (sums.a, sums.rho);
    for x in 0..w {
        let (cx, cy, czz) = sums.at(x);
        let flat = is_flat(a, cx, cy, czz);
        let n = [-cx, -cy / rho, a];
        let inv = 1.0 / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        (nx[x], ny[x], nz[x]) =
            (select(flat, 0.0, n[0] * inv), select(flat, 0.0, n[1] * inv), select(flat, 1.0, n[2] * inv));
    }
}

/// The orthogonal fit's matrix entries that vary along the row: b1 = Cx,
/// b2 = ρ·Cy, Czz, and whether the patch is flat.
#[inline(always)]
fn matrices(sums: Sums<'_>, b1: &mut [f64], b2: &mut [f64], czz: &mut [f64], flat: &mut [bool]) {
    let w = sums.s0.len();
    let (b1, b2, czz, flat) = (&mut b1[..w], &mut b2[..w], &mut czz[..w], &mut flat[..w]);
    let (a, rho) = (sums.a, sums.rho);
    for x in 0..w {
        let (cx, cy, c) = sums.at(x);
        flat[x] = is_flat(a, cx, cy, c);
        (b1[x], b2[x], czz[x]) = (cx, rho * cy, c);
    }
}

/// Newton's start for every patch of the row, whose diagonal is
/// `diagonal`; a flat patch does not step.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn start(
    diagonal: Diagonal,
    b1: &[f64],
    b2: &[f64],
    czz: &[f64],
    flat: &[bool],
    lambda: &mut [f64],
    scale: &mut [f64],
    stepping: &mut [bool],
) {
    let w = flat.len();
    let (b1, b2, czz) = (&b1[..w], &b2[..w], &czz[..w]);
    let (lambda, scale, stepping) = (&mut lambda[..w], &mut scale[..w], &mut stepping[..w]);
    for x in 0..w {
        let settled;
        (lambda[x], scale[x], settled) = eigen_start_on(diagonal, b1[x], b2[x], czz[x]);
        stepping[x] = !flat[x] & !settled;
    }
}

/// The orthogonal fit's unit normals from the converged λ: the
/// eigenvector, normalised, or (0, 0, 1) where flat. `(a1, a2)` is the
/// row's diagonal.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn orthogonal_normals(
    (a1, a2): (f64, f64),
    b1: &[f64],
    b2: &[f64],
    czz: &[f64],
    lambda: &[f64],
    flat: &[bool],
    nx: &mut [f64],
    ny: &mut [f64],
    nz: &mut [f64],
) {
    let w = flat.len();
    let (b1, b2, czz, lambda) = (&b1[..w], &b2[..w], &czz[..w], &lambda[..w]);
    let (nx, ny, nz) = (&mut nx[..w], &mut ny[..w], &mut nz[..w]);
    // Runs of texels whose λ are all below half a1 and a2 (nearly every
    // run of a terrain) skip the other cross products: `eigenvector`
    // would select the first anyway, so the bits are its.
    let mut x0 = 0;
    while x0 < w {
        let end = (x0 + RUN).min(w);
        let near = (x0..end).fold(true, |all, x| all & is_near_plane([a1, a2, b1[x], b2[x], czz[x]], lambda[x]));
        for x in x0..end {
            let matrix = [a1, a2, b1[x], b2[x], czz[x]];
            let n = if near { near_plane(matrix, lambda[x]) } else { eigenvector(matrix, lambda[x]) };
            let inv = 1.0 / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let flat = flat[x];
            (nx[x], ny[x], nz[x]) =
                (select(flat, 0.0, n[0] * inv), select(flat, 0.0, n[1] * inv), select(flat, 1.0, n[2] * inv));
        }
        x0 = end;
    }
}

/// The texels [`orthogonal_normals`] decides for together: a few vectors.
const RUN: usize = 16;

#[cfg(test)]
mod tests {
    use super::super::eigen::{eigen_start, newton_step, smallest_eigen, unequal_normal};
    use super::*;
    use crate::options::{Convention, Options};

    /// Window sums of every kind of patch, by column: flat, gentle, tilted
    /// along one axis only, cliffs (Czz far above A), and patches whose two
    /// smallest eigenvalues nearly meet (dozens of Newton steps), in an
    /// order that puts each kind in runs and alone.
    fn sums(w: usize, n2: f64) -> WindowSums {
        let mut v = WindowSums::zeros(w);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut unit = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for x in 0..w {
            let kind = if x < 40 { x / 8 } else { x % 7 };
            let s0 = 50.0 * unit();
            let (si, sj, czz) = match kind {
                0 => (0.0, 0.0, 1e-3 * unit().abs()),
                1 => (0.3 * unit(), 0.3 * unit(), 0.05 * unit().abs()),
                2 => (40.0 * unit(), 0.0, 500.0 * unit().abs()),
                3 => (0.0, 40.0 * unit(), 500.0 * unit().abs()),
                4 => (1e-7 * unit(), 1e-7 * unit(), 6.0 + 1e-9 * unit()),
                5 => (2.0 * unit(), 3.0 * unit(), 1e4 * unit().abs()),
                _ => (10.0 * unit(), 10.0 * unit(), 30.0 * unit().abs()),
            };
            v.s0[x] = s0;
            v.si[x] = si;
            v.sj[x] = sj;
            v.szz[x] = czz + s0 * s0 / n2;
        }
        v
    }

    /// The row's loops give the per-texel solve's normals and residuals
    /// bit for bit (the fit's output before they ran over planes), for
    /// both fits, conventions, gains, ρ on either side of 1 and widths
    /// that leave a partial vector and a partial run of 32.
    #[test]
    #[allow(clippy::needless_range_loop)] // x indexes the sums and the planes
    fn rows_of_planes_give_the_per_texel_solve_bit_for_bit() {
        let mut row = UnequalRow::default();
        for (n, w) in [(3, 77), (5, 200), (9, 33)] {
            for convention in [Convention::OpenGl, Convention::DirectX] {
                let plan = Plan::new(w, 4, &Options::new().with_patch(n).with_convention(convention)).unwrap();
                let n2 = (n * n) as f64;
                let v = sums(w, n2);
                for rho in [0.37, 0.9, 1.41, 2.5] {
                    for gain in [1.0, 0.13] {
                        for orthogonal in [true, false] {
                            let spacing = RowSpacing { gain, rho, orthogonal };
                            let mut normal = [vec![0.0; w], vec![0.0; w], vec![0.0; w]];
                            let mut out = vec![[0.0f64; 3]; w];
                            row.normals(&plan, &v, spacing, &mut normal, &mut out);
                            let mut residual = vec![0.0f32; w];
                            if orthogonal {
                                row.residuals(&plan, &v, spacing, 2.0, &mut residual);
                            }
                            for x in 0..w {
                                let czz = Plan::czz(n2, gain * gain / n2, v.s0[x], v.szz[x]);
                                let (cx, cy) = (gain * v.si[x], gain * v.sj[x]);
                                let want = unequal_normal(orthogonal, plan.a, rho, cx, plan.sigma * cy, czz);
                                let at = format!("N {n} {convention:?} ρ {rho} gain {gain} {orthogonal} texel {x}");
                                assert_eq!(out[x].map(f64::to_bits), want.map(f64::to_bits), "{at}");
                                if orthogonal {
                                    let sum = if is_flat(plan.a, cx, cy, czz) {
                                        czz
                                    } else {
                                        smallest_eigen(plan.a, rho * rho * plan.a, cx, rho * cy, czz).0.max(0.0)
                                    };
                                    let want = ((sum * (1.0 / n2)).sqrt() * 2.0) as f32;
                                    assert_eq!(residual[x].to_bits(), want.to_bits(), "{at}: residual");
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// The test's patches reach every part of the solve: flat ones, and
    /// some that still step three passes after three quarters have
    /// stopped (the passes in place end there: the rest are moved
    /// together, `newton`'s second loop).
    #[test]
    fn the_patches_include_flat_and_slow_ones() {
        let (n2, a, rho) = (9.0, 6.0, 1.41);
        let v = sums(77, n2);
        let mut flat = 0;
        let mut steps_taken = Vec::new();
        for x in 0..77 {
            let czz = Plan::czz(n2, 1.0 / n2, v.s0[x], v.szz[x]);
            if is_flat(a, v.si[x], v.sj[x], czz) {
                flat += 1;
                continue;
            }
            let [a1, a2, b1, b2] = [a, rho * rho * a, v.si[x], rho * v.sj[x]];
            let (mut lambda, scale, settled) = eigen_start(a1, a2, b1, b2, czz);
            let mut steps = 0;
            let mut more = !settled;
            while more {
                (lambda, more) = newton_step([a1, a2, b1, b2, czz], scale, lambda);
                steps += 1;
            }
            steps_taken.push(steps);
        }
        assert!(flat >= 8, "{flat} flat patches");
        steps_taken.sort_unstable();
        let (quarter_left, longest) = (steps_taken[steps_taken.len() * 3 / 4], steps_taken[steps_taken.len() - 1]);
        assert!(
            longest >= quarter_left + 3,
            "Newton steps: three quarters at most {quarter_left}, the longest {longest}"
        );
    }
}
