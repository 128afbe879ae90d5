//! Holes: the fit of a patch to its valid points alone.
//!
//! A texel is missing when its value is the nodata value or not finite
//! ([`Options::nodata`](crate::Options::nodata)). A patch with a missing
//! point is fitted to the c valid points (i, j, z) it has left, with the
//! full centred moments:
//!
//! ```text
//! Cii = Σi² − (Σi)²/c   Cjj, Cij likewise     (the valid points' (u, v) spread)
//! Ciz = Σiz − Σi·Σz/c   Cjz likewise,  Czz = Σz² − (Σz)²/c
//! ```
//!
//! (sums over the valid points). With u = i, v = ρσj (lengths in x
//! spacings, as for full patches) the vertical fit solves the 2×2 normal
//! equations [[Cuu, Cuv], [Cuv, Cvv]]·g = [Cuz, Cvz] and n ∝ (−gx, −gy, 1);
//! the orthogonal fit takes the smallest eigenvector of the 3×3 covariance
//! [[Cuu, Cuv, Cuz], [Cuv, Cvv, Cvz], [Cuz, Cvz, Czz]]: a rotation in (u, v)
//! makes its (u, v) block diagonal, and [`smallest_eigen`] (the unequal
//! spacing's solver) finds it. A texel that is itself missing, or whose
//! valid points are fewer than 3 or collinear, is missing.
//!
//! # Sums, and why they keep their digits
//!
//! * The z sums Σz, Σiz, Σjz, Σz² over the valid points are the sums the
//!   fast path already forms, on the image with its holes read as 0: a
//!   hole adds nothing. So they come from the same sliding sums, with the
//!   same rounding (stored integers exactly; floats by a few additions,
//!   no running sum of floats drifting across a row), and the cost per
//!   texel stays independent of N.
//! * The geometry, the count c and Σi, Σj, Σi², Σj², Σij of the valid
//!   points, is a sum of 0/1 masks weighted by the offsets i, j from the
//!   texel (−r … r, never absolute coordinates): integers, summed by
//!   running sums in `i64` (exact wherever the run starts, so strips,
//!   bands and threads give the same bits). The centred moments
//!   c·Cii = c·Σi² − (Σi)² are formed in `i128`, exactly, so collinear
//!   points give a determinant of exactly 0, and no cancellation in
//!   (u, v) is left. The z moments are centred as c·Σiz − Σi·Σz, whose
//!   terms are at most r·c·max|z| — the size of the full patch's own sums.
//! * A patch without a hole never comes here: its texel keeps the fast
//!   path's bits.

use std::ops::Range;

use super::{Plan, RowRef, SourceRows, smallest_eigen};
use crate::samples::Sample;

/// Whether a value as given is a hole.
#[inline(always)]
pub(super) fn is_hole(v: f64, nodata: f64) -> bool {
    !v.is_finite() || v == nodata
}

/// Whether a row holds a hole.
pub(crate) fn row_has_hole<H: Sample>(values: &[H], nodata: f64) -> bool {
    values.iter().fold(false, |any, &h| any | is_hole(h.to_f64(), nodata))
}

/// The valid points' moments of each column's patch, for the output rows
/// of one strip in order: running sums of the valid mask down the rows
/// (the leaving row's horizontal sums are made again rather than held, so
/// memory is two rows whatever N).
pub(super) struct MaskSums {
    cols: Range<usize>,
    /// The output row the sums are of.
    y: Option<isize>,
    pub(super) c: Vec<i64>,
    pub(super) si: Vec<i64>,
    pub(super) sj: Vec<i64>,
    pub(super) sii: Vec<i64>,
    pub(super) sjj: Vec<i64>,
    pub(super) sij: Vec<i64>,
    /// Whether each column's own texel (of row `y`) is valid.
    pub(super) centre: Vec<bool>,
    leaving: [Vec<i64>; 3],
    entering: [Vec<i64>; 3],
    valid: Vec<u8>,
}

impl MaskSums {
    pub(super) fn new(cols: Range<usize>) -> MaskSums {
        let w = cols.len();
        let z = vec![0i64; w];
        MaskSums {
            cols,
            y: None,
            c: z.clone(),
            si: z.clone(),
            sj: z.clone(),
            sii: z.clone(),
            sjj: z.clone(),
            sij: z.clone(),
            centre: vec![false; w],
            leaving: [z.clone(), z.clone(), z.clone()],
            entering: [z.clone(), z.clone(), z],
            valid: Vec::new(),
        }
    }

    /// Whether every patch of this row has all its points.
    pub(super) fn full(&self, n2: i64) -> bool {
        self.c.iter().all(|&c| c == n2)
    }

    /// The valid mask of one source row over the strip's columns and r on
    /// either side (through the x border), into `self.valid`.
    fn valid_row<H: Sample>(&mut self, plan: &Plan, src: RowRef<'_, H>, nodata: f64) {
        let r = plan.r as isize;
        let (lo, hi) = (self.cols.start as isize - r, self.cols.end as isize + r);
        let held = src.x0..src.x0 + src.values.len() as isize;
        self.valid.clear();
        if !src.holes {
            self.valid.resize((hi - lo) as usize, 1);
            return;
        }
        if lo >= held.start && hi <= held.end {
            // Away from the borders: the row's own values.
            let values = &src.values[(lo - src.x0) as usize..(hi - src.x0) as usize];
            self.valid.extend(values.iter().map(|&h| u8::from(!is_hole(h.to_f64(), nodata))));
            return;
        }
        self.valid.extend((lo..hi).map(|u| {
            let at = if held.contains(&u) { u } else { plan.borders.x.map(u, plan.width) as isize };
            u8::from(!is_hole(src.values[(at - src.x0) as usize].to_f64(), nodata))
        }));
    }

    /// Σm, Σi·m, Σi²·m over each column's window of one source row, by
    /// running sums (integers: exact).
    fn row_sums<H: Sample>(&mut self, plan: &Plan, src: RowRef<'_, H>, nodata: f64, entering: bool) {
        let (n, r) = (plan.n, plan.r as i64);
        let out = if entering { &mut self.entering } else { &mut self.leaving };
        if !src.holes {
            // Every window full: N, 0 and Σi² = r(r + 1)(2r + 1)/3.
            let [o0, o1, o2] = out;
            o0.fill(n as i64);
            o1.fill(0);
            o2.fill(r * (r + 1) * (2 * r + 1) / 3);
            return;
        }
        self.valid_row(plan, src, nodata);
        let out = if entering { &mut self.entering } else { &mut self.leaving };
        let m = &self.valid;
        let (mut c0, mut c1, mut c2) = (0i64, 0i64, 0i64);
        for (q, &v) in m[..n].iter().enumerate() {
            let i = q as i64 - r;
            let v = i64::from(v);
            c0 += v;
            c1 += i * v;
            c2 += i * i * v;
        }
        let [o0, o1, o2] = out;
        o0[0] = c0;
        o1[0] = c1;
        o2[0] = c2;
        for k in 1..self.cols.len() {
            let (l, e) = (i64::from(m[k - 1]), i64::from(m[k - 1 + n]));
            let t = c1 + r * l + (r + 1) * e;
            let new0 = c0 - l + e;
            c2 = c2 - r * r * l + (r + 1) * (r + 1) * e - 2 * t + new0;
            c1 = t - new0;
            c0 = new0;
            o0[k] = c0;
            o1[k] = c1;
            o2[k] = c2;
        }
    }

    /// Makes the sums those of output row `y`: slides down from row y − 1,
    /// or sums the N rows afresh.
    pub(super) fn advance<'a, H: Sample>(&mut self, plan: &Plan, rows: &SourceRows<'_, 'a, H>, y: isize, nodata: f64) {
        let r = plan.r as isize;
        let w = self.cols.len();
        if self.y == Some(y - 1) {
            self.row_sums(plan, rows(y - 1 - r), nodata, false);
            self.row_sums(plan, rows(y + r), nodata, true);
            let (rr, r1) = (r as i64, r as i64 + 1);
            let ([l0, l1, l2], [e0, e1, e2]) = (&self.leaving, &self.entering);
            for x in 0..w {
                let s0 = self.c[x] - l0[x] + e0[x];
                let t = self.sj[x] + rr * l0[x] + r1 * e0[x];
                self.sjj[x] = self.sjj[x] - rr * rr * l0[x] + r1 * r1 * e0[x] - 2 * t + s0;
                self.sj[x] = t - s0;
                let si = self.si[x] - l1[x] + e1[x];
                self.sij[x] = self.sij[x] + rr * l1[x] + r1 * e1[x] - si;
                self.si[x] = si;
                self.sii[x] += e2[x] - l2[x];
                self.c[x] = s0;
            }
        } else {
            for plane in [&mut self.c, &mut self.si, &mut self.sj, &mut self.sii, &mut self.sjj, &mut self.sij] {
                plane.fill(0);
            }
            for j in -r..=r {
                self.row_sums(plan, rows(y + j), nodata, true);
                let [e0, e1, e2] = &self.entering;
                let j = j as i64;
                for x in 0..w {
                    self.c[x] += e0[x];
                    self.si[x] += e1[x];
                    self.sii[x] += e2[x];
                    self.sj[x] += j * e0[x];
                    self.sjj[x] += j * j * e0[x];
                    self.sij[x] += j * e1[x];
                }
            }
        }
        self.y = Some(y);
        self.valid_row(plan, rows(y), nodata);
        let r = plan.r;
        for (x, centre) in self.centre.iter_mut().enumerate() {
            *centre = self.valid[x + r] != 0;
        }
    }
}

/// The moments of one patch's valid points, z in fit units (lengths in x
/// spacings).
pub(super) struct Moments {
    /// The count of valid points.
    pub c: i64,
    /// Σi, Σj, Σi², Σj², Σij (j down).
    pub geometry: [i64; 5],
    /// Σz, Σiz, Σjz (j down), Σz², over the valid points.
    pub z: [f64; 4],
}

/// The unit normal of a patch from its valid points' moments, and the
/// summed squared distance of the points from the plane (perpendicular or
/// vertical, as the fit measures), or `None` when the points do not
/// determine a plane (fewer than 3, or collinear).
pub(super) fn masked_normal(m: &Moments, orthogonal: bool, rho: f64, sigma: f64) -> Option<([f64; 3], f64)> {
    let c = m.c;
    if c < 3 {
        return None;
    }
    let [si, sj, sii, sjj, sij] = m.geometry.map(i128::from);
    let c128 = i128::from(c);
    // c·C, exact.
    let (cii, cjj, cij) = (c128 * sii - si * si, c128 * sjj - sj * sj, c128 * sij - si * sj);
    if cii * cjj - cij * cij <= 0 {
        return None;
    }
    let cf = c as f64;
    let [z0, zi, zj, zz] = m.z;
    let (cii, cjj, cij) = (cii as f64 / cf, cjj as f64 / cf, cij as f64 / cf);
    let (si, sj) = (si as f64, sj as f64);
    let ciz = (cf * zi - si * z0) / cf;
    let cjz = (cf * zj - sj * z0) / cf;
    let czz = ((cf * zz - z0 * z0) / cf).max(0.0);
    // u = i, v = ρσj.
    let rs = rho * sigma;
    let (cuu, cvv, cuv, cuz, cvz) = (cii, rho * rho * cjj, rs * cij, ciz, rs * cjz);
    // Flat as the full patches' rule (their A is Cii = Cjj).
    let flat = ciz * ciz + cjz * cjz <= 1e-20 * (cii.max(cjj) + czz) * (cii.max(cjj) + czz);
    if !orthogonal {
        let det = cuu * cvv - cuv * cuv;
        let gx = (cvv * cuz - cuv * cvz) / det;
        let gy = (cuu * cvz - cuv * cuz) / det;
        let residual = (czz - gx * cuz - gy * cvz).max(0.0);
        if flat {
            return Some(([0.0, 0.0, 1.0], czz));
        }
        let inv = 1.0 / (gx * gx + gy * gy + 1.0).sqrt();
        return Some(([-gx * inv, -gy * inv, inv], residual));
    }
    if flat {
        return Some(([0.0, 0.0, 1.0], czz));
    }
    // Rotate (u, v) by θ, tan 2θ = 2Cuv / (Cuu − Cvv), to diagonalise the
    // (u, v) block: a1 = Cuu + t·Cuv, a2 = Cvv − t·Cuv, t = tan θ.
    let (cos, sin) = if cuv == 0.0 {
        (1.0, 0.0)
    } else {
        let tau = (cvv - cuu) / (2.0 * cuv);
        let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
        let t = if tau == 0.0 { 1.0 } else { t };
        let cos = 1.0 / (1.0 + t * t).sqrt();
        (cos, t * cos)
    };
    let a1 = cuu - (sin / cos) * cuv;
    let a2 = cvv + (sin / cos) * cuv;
    let b1 = cos * cuz - sin * cvz;
    let b2 = sin * cuz + cos * cvz;
    let (lambda, e) = smallest_eigen(a1, a2, b1, b2, czz);
    let n = [cos * e[0] + sin * e[1], -sin * e[0] + cos * e[1], e[2]];
    let inv = 1.0 / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    Some((n.map(|v| v * inv), lambda.max(0.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The moments of a point list.
    fn moments(points: &[(i64, i64, f64)]) -> Moments {
        let mut m = Moments { c: 0, geometry: [0; 5], z: [0.0; 4] };
        for &(i, j, z) in points {
            m.c += 1;
            m.geometry[0] += i;
            m.geometry[1] += j;
            m.geometry[2] += i * i;
            m.geometry[3] += j * j;
            m.geometry[4] += i * j;
            m.z[0] += z;
            m.z[1] += i as f64 * z;
            m.z[2] += j as f64 * z;
            m.z[3] += z * z;
        }
        m
    }

    #[test]
    fn a_plane_is_found_from_any_three_points_not_in_a_line() {
        // z = 0.3 u − 0.2 v, v = σ j (σ = 1 here).
        let plane = |i: i64, j: i64| 0.3 * i as f64 - 0.2 * j as f64;
        let points: Vec<_> = [(-1, -1), (1, 0), (0, 1), (1, 1)].iter().map(|&(i, j)| (i, j, plane(i, j))).collect();
        let expected = {
            let l = (0.09f64 + 0.04 + 1.0).sqrt();
            [-0.3 / l, 0.2 / l, 1.0 / l]
        };
        for orthogonal in [false, true] {
            for k in 3..=4 {
                let (n, residual) = masked_normal(&moments(&points[..k]), orthogonal, 1.0, 1.0).unwrap();
                for c in 0..3 {
                    assert!((n[c] - expected[c]).abs() < 1e-12, "{orthogonal} {k}: {n:?}");
                }
                assert!(residual.abs() < 1e-12);
            }
        }
    }

    #[test]
    fn collinear_or_too_few_points_give_no_plane() {
        let line: Vec<_> = (-2..=2).map(|k| (k, k, k as f64)).collect();
        assert!(masked_normal(&moments(&line), true, 1.0, 1.0).is_none());
        assert!(masked_normal(&moments(&line), false, 1.0, 1.0).is_none());
        let two = [(0, 0, 1.0), (1, 0, 2.0)];
        assert!(masked_normal(&moments(&two), true, 1.0, 1.0).is_none());
        let row: Vec<_> = (-3..=3).map(|k| (k, 2, 0.1 * k as f64)).collect();
        assert!(masked_normal(&moments(&row), false, 2.0, -1.0).is_none());
    }
}
