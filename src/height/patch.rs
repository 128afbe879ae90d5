//! The fit's patch sums as exact sparse operators, with the borders'
//! index maps ([`Border::map`]): per axis, lists "output texel ← input
//! texels with weights" for the box (weights 1) and the ramp (weights i)
//! of the patch. The iterations (`iterative.rs`) and Gauss–Newton's steps
//! (`gauss_newton.rs`) both apply them; they live here so that each of
//! those imports this module, and the iterations Gauss–Newton, never the
//! other way.

use crate::options::Border;

use super::HeightOptions;

/// A sparse 1-D operator: `lists[o]` holds (input index, weight) pairs.
pub(super) struct Lists(pub(super) Vec<Vec<(usize, f64)>>);

impl Lists {
    /// out[x] = Σ_i weight(i) · in[map(x + i)], i ∈ [−r, r].
    fn correlation(n: usize, border: Border, r: usize, weight: impl Fn(isize) -> f64) -> Lists {
        let r = r as isize;
        Lists(
            (0..n as isize)
                .map(|x| (-r..=r).map(|i| (border.map(x + i, n), weight(i))).filter(|p| p.1 != 0.0).collect())
                .collect(),
        )
    }

    /// The transpose.
    pub(super) fn transposed(&self) -> Lists {
        let mut t = vec![Vec::new(); self.0.len()];
        for (o, list) in self.0.iter().enumerate() {
            for &(i, wgt) in list {
                t[i].push((o, wgt));
            }
        }
        Lists(t)
    }

    /// Applied along a row.
    pub(super) fn row(&self, src: &[f64], dst: &mut [f64]) {
        for (d, list) in dst.iter_mut().zip(&self.0) {
            *d = list.iter().map(|&(i, wgt)| wgt * src[i]).sum();
        }
    }

    /// Row `y` of the operator applied down the columns of `src` (rows of
    /// `w`), through `f` on each value.
    pub(super) fn column(&self, src: &[f64], w: usize, y: usize, dst: &mut [f64], f: impl Fn(f64) -> f64) {
        dst.fill(0.0);
        for &(i, wgt) in &self.0[y] {
            for (d, &s) in dst.iter_mut().zip(&src[i * w..][..w]) {
                *d += wgt * f(s);
            }
        }
    }
}

/// The patch sums of the fit, with the borders' maps.
pub(super) struct Patch {
    pub(super) w: usize,
    pub(super) patch: usize,
    pub(super) borders: crate::Borders,
    pub(super) a: f64,
    pub(super) box_x: Lists,
    pub(super) ramp_x: Lists,
    pub(super) box_y: Lists,
    pub(super) ramp_y: Lists,
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
            box_x: Lists::correlation(w, bx, r, |_| 1.0),
            ramp_x: Lists::correlation(w, bx, r, |i| i as f64),
            box_y: Lists::correlation(h, by, r, |_| 1.0),
            ramp_y: Lists::correlation(h, by, r, |i| i as f64),
        }
    }

    /// The vertical fit's slopes of row y of `z`: Dx z, Dy z.
    pub(super) fn slopes(&self, z: &[f64], y: usize, gx: &mut [f64], gy: &mut [f64]) {
        let w = self.w;
        let (mut boxed, mut ramped) = (vec![0.0; w], vec![0.0; w]);
        self.box_y.column(z, w, y, &mut boxed, |v| v);
        self.ramp_y.column(z, w, y, &mut ramped, |v| v);
        self.ramp_x.row(&boxed, gx);
        self.box_x.row(&ramped, gy);
        gx.iter_mut().chain(gy.iter_mut()).for_each(|g| *g /= self.a);
    }
}
