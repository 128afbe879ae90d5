//! The fit's patch sums as exact operators on planes of heights, with the
//! borders' index maps ([`Border::map`](crate::Border::map)): the box
//! (weights 1) and the ramp (weights i) of the patch along each axis
//! (`line.rs`: a few operations a texel whatever N), and their transposes.
//! The iterations (`iterative.rs`) and Gauss–Newton's steps
//! (`gauss_newton.rs`) both apply them; they live here so that each of
//! those imports this module, and the iterations Gauss–Newton, never the
//! other way.

use super::HeightOptions;
use super::line::{Line, Work, columns, rows};

/// The patch sums of the fit, with the borders' maps.
pub(super) struct Patch {
    pub(super) w: usize,
    pub(super) patch: usize,
    pub(super) borders: crate::Borders,
    pub(super) a: f64,
    /// Along a row (x) and down a column (y).
    pub(super) x: Line,
    pub(super) y: Line,
}

impl Patch {
    pub(super) fn new(w: usize, h: usize, opts: &HeightOptions) -> Patch {
        let r = opts.fit.patch / 2;
        let (bx, by) = (opts.fit.borders.x, opts.fit.borders.y);
        Patch {
            w,
            patch: opts.fit.patch,
            borders: opts.fit.borders,
            a: (opts.fit.patch * r * (r + 1) * (2 * r + 1)) as f64 / 3.0,
            x: Line::border(w, bx, r),
            y: Line::border(h, by, r),
        }
    }

    /// The vertical fit's slopes of `z` into the planes `gx` = Dx z =
    /// ramp_x box_y z / A and `gy` = Dy z = box_x ramp_y z / A.
    pub(super) fn slopes(&self, z: &[f64], gx: &mut [f64], gy: &mut [f64]) {
        let (w, a) = (self.w, self.a);
        columns(w, &[z], &mut [&mut *gx, &mut *gy], |_, ins, outs, work| {
            let [boxed, ramped] = outs else { unreachable!() };
            self.y.apply(ins[0], Some(&mut boxed[..]), Some(&mut ramped[..]), &mut work.scratch);
        });
        rows(w, &mut [gx, gy], |_, planes, work| {
            let Work { scratch, temps } = work;
            let [gx, gy] = planes else { unreachable!() };
            let [tx, ty, ..] = temps;
            self.x.apply(gx, None, Some(&mut tx[..]), scratch);
            self.x.apply(gy, Some(&mut ty[..]), None, scratch);
            gx.iter_mut().zip(tx.iter()).for_each(|(g, t)| *g = t / a);
            gy.iter_mut().zip(ty.iter()).for_each(|(g, t)| *g = t / a);
        });
    }

    /// Dᵀ(gx, gy) = (box_yᵀ ramp_xᵀ gx + ramp_yᵀ box_xᵀ gy) / A into `out`;
    /// `gx` and `gy` are overwritten.
    pub(super) fn adjoint(&self, gx: &mut [f64], gy: &mut [f64], out: &mut [f64]) {
        let (w, a) = (self.w, self.a);
        rows(w, &mut [&mut *gx, &mut *gy], |_, planes, work| {
            let Work { scratch, temps } = work;
            let [gx, gy] = planes else { unreachable!() };
            let [tx, ty, ..] = temps;
            self.x.apply_transposed(gx, None, Some(&mut tx[..]), scratch);
            self.x.apply_transposed(gy, Some(&mut ty[..]), None, scratch);
            gx.copy_from_slice(tx);
            gy.copy_from_slice(ty);
        });
        columns(w, &[gx, gy], &mut [out], |_, ins, outs, work| {
            let Work { scratch, temps } = work;
            let [o] = outs else { unreachable!() };
            let [t, ..] = temps;
            self.y.apply_transposed(ins[0], Some(&mut o[..]), None, scratch);
            self.y.apply_transposed(ins[1], None, Some(&mut t[..]), scratch);
            o.iter_mut().zip(t.iter()).for_each(|(o, t)| *o = (*o + t) / a);
        });
    }
}

/// The one reference the tests compare with (plain N² loops through the
/// border rule), shared with the integration tests. Its arms for values
/// the options may gain (their enums are `non_exhaustive` outside the
/// crate) cannot be reached from inside it.
#[cfg(test)]
#[allow(unreachable_patterns)]
#[path = "../../tests/common/reference.rs"]
mod reference;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Border, Borders, Fit, Options, Strength};

    /// Against the tests' reference fit: the slopes D z are the vertical
    /// fit's −nx/nz and −σ ny/nz of the reference's normals, for every
    /// border pair and N = 3 to 41 (patches added outright, by blocks, and
    /// wider than the image: whole periods, clamp's clipped windows), on a
    /// 13 × 11 image, a row, a column and a mirrored pair; and Dᵀ is D's
    /// adjoint there.
    #[test]
    fn patch_slopes_match_the_reference_fit_and_their_adjoint() {
        let modes = [Border::Wrap, Border::Mirror, Border::Clamp];
        for (w, h) in [(13, 11), (1, 9), (17, 1), (2, 7)] {
            let len = w * h;
            let z: Vec<f64> = (0..len)
                .map(|k| {
                    let (x, y) = ((k % w) as f64, (k / w) as f64);
                    0.7 * (0.9 * x).sin() + 0.4 * (0.6 * y + 0.2 * x).cos() + ((k * 7919) % 101) as f64 * 0.01
                })
                .collect();
            let u: Vec<[f64; 2]> = (0..len)
                .map(|k| [(((k * 1013) % 89) as f64 / 89.0) - 0.5, (((k * 211) % 83) as f64 / 83.0) - 0.5])
                .collect();
            for n in [3, 5, 9, 15, 41] {
                for (bx, by) in modes.iter().flat_map(|&x| modes.iter().map(move |&y| (x, y))) {
                    let fit = Options::new()
                        .with_patch(n)
                        .with_fit(Fit::Vertical)
                        .with_borders(Borders { x: bx, y: by })
                        .with_strength(Strength::Scale(1.0));
                    let patch = Patch::new(w, h, &HeightOptions::from_fit(&fit));
                    let (mut gx, mut gy) = (vec![0.0; len], vec![0.0; len]);
                    patch.slopes(&z, &mut gx, &mut gy);
                    let sigma = fit.convention.sigma();
                    let want = reference::normal_map(&z, w, h, &fit);
                    let (mut worst, mut size) = (0.0f64, 0.0f64);
                    for (k, nv) in want.iter().enumerate() {
                        let (wx, wy) = (-nv[0] / nv[2], -sigma * nv[1] / nv[2]);
                        worst = worst.max((gx[k] - wx).abs()).max((gy[k] - wy).abs());
                        size = size.max(wx.abs()).max(wy.abs());
                    }
                    let case = format!("{w}×{h} N {n} {bx:?}/{by:?}");
                    assert!(worst <= 1e-12 * size.max(1.0), "{case}: off by {worst:e} of {size:e}");

                    // ⟨D z, u⟩ = ⟨z, Dᵀ u⟩.
                    let (mut ux, mut uy): (Vec<f64>, Vec<f64>) = u.iter().map(|p| (p[0], p[1])).unzip();
                    let left: f64 = (0..len).map(|k| gx[k] * u[k][0] + gy[k] * u[k][1]).sum();
                    let mut back = vec![0.0; len];
                    patch.adjoint(&mut ux, &mut uy, &mut back);
                    let right: f64 = z.iter().zip(&back).map(|(a, b)| a * b).sum();
                    assert!((left - right).abs() <= 1e-12 * left.abs().max(1.0), "{case}: {left} against {right}");
                }
            }
        }
    }
}
