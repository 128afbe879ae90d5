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
//! makes its (u, v) block diagonal, and the unequal spacing's solver
//! ([`smallest_eigen`](super::eigen::smallest_eigen)) finds it. A texel that is itself missing, or whose
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

use super::eigen::{NEWTON_STEPS, eigen_start, eigenvector, newton_step, select};
use super::{Plan, RowRef, SourceRows, Texel};
use crate::samples::Sample;

/// Whether a value as given is a hole.
#[inline(always)]
pub(super) fn is_hole(v: f64, nodata: f64) -> bool {
    !v.is_finite() || v == nodata
}

/// Whether a row holds a hole.
pub(super) fn row_has_hole<H: Sample>(values: &[H], nodata: f64) -> bool {
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
        valid_row(plan, self.cols.clone(), src, nodata, &mut self.valid);
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
            let MaskSums { c, si, sj, sii, sjj, sij, leaving: [l0, l1, l2], entering: [e0, e1, e2], .. } = self;
            slide_down(r as i64, c, si, sj, sii, sjj, sij, l0, l1, l2, e0, e1, e2);
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
        let valid = &self.valid[plan.r..plan.r + w];
        self.centre.iter_mut().zip(valid).for_each(|(centre, &valid)| *centre = valid != 0);
    }
}

/// The valid mask (1 valid, 0 a hole) of one source row over the columns
/// `cols` and r on either side (through the x border), into `valid`.
pub(super) fn valid_row<H: Sample>(
    plan: &Plan,
    cols: Range<usize>,
    src: RowRef<'_, H>,
    nodata: f64,
    valid: &mut Vec<u8>,
) {
    let r = plan.r as isize;
    let (lo, hi) = (cols.start as isize - r, cols.end as isize + r);
    let held = src.x0..src.x0 + src.values.len() as isize;
    valid.clear();
    if !src.holes {
        valid.resize((hi - lo) as usize, 1);
        return;
    }
    if lo >= held.start && hi <= held.end {
        // Away from the borders: the row's own values.
        let values = &src.values[(lo - src.x0) as usize..(hi - src.x0) as usize];
        valid.extend(values.iter().map(|&h| u8::from(!is_hole(h.to_f64(), nodata))));
        return;
    }
    valid.extend((lo..hi).map(|u| {
        let at = if held.contains(&u) { u } else { plan.borders.x.map(u, plan.width) as isize };
        u8::from(!is_hole(src.values[(at - src.x0) as usize].to_f64(), nodata))
    }));
}

/// Slides the valid points' moments down one row: the row sums `l` of
/// the leaving row (offset −r) go, `e` of the entering one (offset r + 1
/// before the slide) come, and every row's offset j drops by one. The
/// planes are separate arguments, so that the compiler knows they do not
/// overlap and vectorises the loop (through `self`, it reloaded every
/// plane's pointer at every column).
#[allow(clippy::too_many_arguments)]
fn slide_down(
    r: i64,
    c: &mut [i64],
    si: &mut [i64],
    sj: &mut [i64],
    sii: &mut [i64],
    sjj: &mut [i64],
    sij: &mut [i64],
    l0: &[i64],
    l1: &[i64],
    l2: &[i64],
    e0: &[i64],
    e1: &[i64],
    e2: &[i64],
) {
    let w = c.len();
    let (si, sj, sii, sjj, sij) = (&mut si[..w], &mut sj[..w], &mut sii[..w], &mut sjj[..w], &mut sij[..w]);
    let (l0, l1, l2, e0, e1, e2) = (&l0[..w], &l1[..w], &l2[..w], &e0[..w], &e1[..w], &e2[..w]);
    let r1 = r + 1;
    for x in 0..w {
        let s0 = c[x] - l0[x] + e0[x];
        let t = sj[x] + r * l0[x] + r1 * e0[x];
        sjj[x] = sjj[x] - r * r * l0[x] + r1 * r1 * e0[x] - 2 * t + s0;
        sj[x] = t - s0;
        let s1 = si[x] - l1[x] + e1[x];
        sij[x] = sij[x] + r * l1[x] + r1 * e1[x] - s1;
        si[x] = s1;
        sii[x] += e2[x] - l2[x];
        c[x] = s0;
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
    /// With weights: Σw, Σwi, Σwj, Σwi², Σwj², Σwij over the valid points
    /// (the z sums then weighted too). `c` and `geometry` still decide
    /// whether the points determine a plane.
    pub weighted: Option<[f64; 6]>,
}

/// The patches of one row that hold a hole, as planes (one value per
/// patch in each `Vec`), so that their fits run as loops without branches
/// over whole planes, which vectorise, rather than patch by patch (whose
/// branches and Newton loop took 55 % of a 10 %-holes conversion).
///
/// Each patch's fit is [`smallest_eigen`](super::eigen::smallest_eigen)'s
/// arithmetic, in its order: the normals are those of a per-patch solve,
/// bit for bit.
#[derive(Default)]
pub(super) struct MaskedRow {
    /// The patches pushed: the planes' first `len` values (the planes are
    /// as long as the strip is wide).
    len: usize,
    /// The patch's column in the strip.
    column: Vec<usize>,
    /// The columns whose patch determines no plane (as [`MaskedRow::push`]
    /// decides), apart: they cost no solve (a nodata region's inside).
    undetermined: Vec<usize>,
    count: Vec<f64>,
    /// c·Cii, c·Cjj, c·Cij (exact integers, as f64).
    c_cii: Vec<f64>,
    c_cjj: Vec<f64>,
    c_cij: Vec<f64>,
    si: Vec<f64>,
    sj: Vec<f64>,
    /// Σz, Σiz, Σjz, Σz².
    z0: Vec<f64>,
    zi: Vec<f64>,
    zj: Vec<f64>,
    zz: Vec<f64>,
    /// The centred moments [Cuu, Cvv, Cuv, Cuz, Cvz, Czz]; the orthogonal
    /// fit rotates them in place into [a1, a2, cos θ, b1, b2, Czz] (see
    /// [`smallest_eigen`](super::eigen::smallest_eigen)).
    moments: [Vec<f64>; 6],
    sin: Vec<f64>,
    flat: Vec<bool>,
    /// The orthogonal fit's Newton state.
    lambda: Vec<f64>,
    scale: Vec<f64>,
    stepping: Vec<bool>,
    work: NewtonWork,
    /// The fit: the unit normal, and the summed squared distance of the
    /// points from the plane.
    normal: [Vec<f64>; 3],
    distances: Vec<f64>,
}

impl MaskedRow {
    /// Empties the row, and makes room for `width` patches.
    pub(super) fn clear(&mut self, width: usize) {
        self.len = 0;
        self.column.resize(width, 0);
        self.undetermined.clear();
        self.flat.resize(width, false);
        self.stepping.resize(width, false);
        let planes = [&mut self.count, &mut self.c_cii, &mut self.c_cjj, &mut self.c_cij, &mut self.si, &mut self.sj];
        let planes = planes.into_iter().chain([&mut self.z0, &mut self.zi, &mut self.zj, &mut self.zz]);
        let planes = planes.chain([&mut self.sin, &mut self.lambda, &mut self.scale, &mut self.distances]);
        for plane in planes.chain(self.moments.iter_mut()).chain(self.normal.iter_mut()) {
            plane.resize(width, 0.0);
        }
    }

    /// Adds the patch of `column`, whose own texel is valid when `centre`.
    /// Whether its points determine a plane (at least 3, not collinear)
    /// is decided on the integers: c·Cii = c·Σi² − (Σi)² and its like are
    /// exact in `i64` (below 2^57 for N ≤ 1023), their determinant in
    /// `i128`, so collinear points give exactly 0.
    #[inline]
    pub(super) fn push(&mut self, column: usize, centre: bool, m: &Moments) {
        let c = m.c;
        let [si, sj, sii, sjj, sij] = m.geometry;
        let (c_cii, c_cjj, c_cij) = (c * sii - si * si, c * sjj - sj * sj, c * sij - si * sj);
        let det = i128::from(c_cii) * i128::from(c_cjj) - i128::from(c_cij) * i128::from(c_cij);
        if !(centre && c >= 3 && det > 0) {
            self.undetermined.push(column);
            return;
        }
        let k = self.len;
        self.len += 1;
        self.column[k] = column;
        if let Some([c, si, sj, sii, sjj, sij]) = m.weighted {
            // The weighted moments, centred as the counts are: W·Cii =
            // W·Σwi² − (Σwi)², and the z moments below as W·Σwiz − Σwi·Σwz.
            self.count[k] = c;
            self.c_cii[k] = c * sii - si * si;
            self.c_cjj[k] = c * sjj - sj * sj;
            self.c_cij[k] = c * sij - si * sj;
            self.si[k] = si;
            self.sj[k] = sj;
        } else {
            self.count[k] = c as f64;
            self.c_cii[k] = c_cii as f64;
            self.c_cjj[k] = c_cjj as f64;
            self.c_cij[k] = c_cij as f64;
            self.si[k] = si as f64;
            self.sj[k] = sj as f64;
        }
        [self.z0[k], self.zi[k], self.zj[k], self.zz[k]] = m.z;
    }

    /// Fits every patch pushed: with u = i, v = ρσj, the vertical fit's
    /// closed form or the orthogonal fit's smallest eigenvector (see the
    /// module docs).
    pub(super) fn solve(&mut self, orthogonal: bool, rho: f64, sigma: f64) {
        pulp::Arch::new().dispatch(SolveRow { row: self, orthogonal, rho, sigma });
    }

    /// Writes the patches' texels into the strip's row: the normal, or
    /// `missing` (by default (0, 0, 1)) and invalid where the points
    /// determine no plane (or the
    /// patch's own texel is missing); and, when asked for, the RMS distance
    /// of the points from the plane times `sx` (NaN where none).
    pub(super) fn store<T: Texel>(
        &self,
        out: &mut [T],
        valid: &mut [bool],
        residual: Option<&mut [f32]>,
        sx: f64,
        (frame, missing): (&super::TexelFrame, T),
    ) {
        let len = self.len;
        let column = &self.column[..len];
        let [nx, ny, nz] = &self.normal;
        let (nx, ny, nz) = (&nx[..len], &ny[..len], &nz[..len]);
        for k in 0..len {
            out[column[k]] = T::make([nx[k], ny[k], nz[k]], frame);
        }
        for &x in &self.undetermined {
            out[x] = missing;
            valid[x] = false;
        }
        if let Some(residual) = residual {
            let (count, distances) = (&self.count[..len], &self.distances[..len]);
            for k in 0..len {
                residual[column[k]] = ((distances[k] / count[k]).sqrt() * sx) as f32;
            }
            for &x in &self.undetermined {
                residual[x] = f32::NAN;
            }
        }
    }
}

/// [`MaskedRow::solve`]'s loops, for [`pulp::Arch::dispatch`]: compiled
/// for the widest vectors the processor has, as the full patches' `EmitRow`
/// (the same bits on every processor: nothing fuses a multiply with an
/// add). Each loop is a function of its planes as separate slices: the
/// compiler then knows that they do not overlap, and vectorises the loop
/// (reached through one struct, the loops over a dozen planes stayed
/// scalar).
struct SolveRow<'a> {
    row: &'a mut MaskedRow,
    orthogonal: bool,
    rho: f64,
    sigma: f64,
}

impl pulp::WithSimd for SolveRow<'_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let SolveRow { row, orthogonal, rho, sigma } = self;
        let MaskedRow {
            len,
            count,
            c_cii,
            c_cjj,
            c_cij,
            si,
            sj,
            z0,
            zi,
            zj,
            zz,
            moments,
            sin,
            flat,
            lambda,
            scale,
            stepping,
            work,
            normal,
            distances,
            ..
        } = row;
        // The patches pushed: each loop runs over the planes' first `len`.
        let len = *len;
        let (count, c_cii, c_cjj, c_cij) = (&count[..len], &c_cii[..len], &c_cjj[..len], &c_cij[..len]);
        let (si, sj, z0, zi, zj, zz) = (&si[..len], &sj[..len], &z0[..len], &zi[..len], &zj[..len], &zz[..len]);
        let (sin, flat, lambda, scale) = (&mut sin[..len], &mut flat[..len], &mut lambda[..len], &mut scale[..len]);
        let (stepping, distances) = (&mut stepping[..len], &mut distances[..len]);
        let [cuu, cvv, cuv, cuz, cvz, czz] = moments.each_mut().map(|plane| &mut plane[..len]);
        let [nx, ny, nz] = normal.each_mut().map(|plane| &mut plane[..len]);
        centred_moments(
            count, c_cii, c_cjj, c_cij, si, sj, z0, zi, zj, zz, rho, sigma, cuu, cvv, cuv, cuz, cvz, czz, flat,
        );
        if !orthogonal {
            vertical_normals(cuu, cvv, cuv, cuz, cvz, czz, flat, nx, ny, nz, distances);
            return;
        }
        // In place: [Cuu, Cvv, Cuv, Cuz, Cvz] become [a1, a2, cos θ, b1, b2].
        let (a1, a2, cos, b1, b2) = (cuu, cvv, cuv, cuz, cvz);
        rotate(a1, a2, cos, b1, b2, czz, sin, flat, lambda, scale, stepping);
        newton(a1, a2, b1, b2, czz, scale, lambda, stepping, work);
        orthogonal_normals(a1, a2, b1, b2, czz, cos, sin, lambda, flat, nx, ny, nz, distances);
    }
}

// The loops' planes are separate arguments, each cut to the loop's
// length: the compiler then knows that they neither overlap nor end
// early, and vectorises the loops (reached through one struct, a loop over
// a dozen planes stayed scalar, with branches).

/// The centred moments of every patch (lengths in x spacings, u = i,
/// v = ρσj), and whether it is flat. Three loops of a few planes each: as
/// one loop of seventeen it stayed scalar.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn centred_moments(
    count: &[f64],
    c_cii: &[f64],
    c_cjj: &[f64],
    c_cij: &[f64],
    si: &[f64],
    sj: &[f64],
    z0: &[f64],
    zi: &[f64],
    zj: &[f64],
    zz: &[f64],
    rho: f64,
    sigma: f64,
    cuu: &mut [f64],
    cvv: &mut [f64],
    cuv: &mut [f64],
    cuz: &mut [f64],
    cvz: &mut [f64],
    czz: &mut [f64],
    flat: &mut [bool],
) {
    let rs = rho * sigma;
    // Cii, Cjj, rs·Cij; Cvv and Cvz hold Cjj and Cjz until the last loop.
    geometry_moments(count, c_cii, c_cjj, c_cij, rs, cuu, cvv, cuv);
    z_moments(count, si, sj, z0, zi, zj, zz, cuz, cvz, czz);
    let len = flat.len();
    let (cuu, cvv, cuz, cvz, czz) = (&cuu[..len], &mut cvv[..len], &cuz[..len], &mut cvz[..len], &czz[..len]);
    for k in 0..len {
        let (cii, cjj, ciz, cjz, czz) = (cuu[k], cvv[k], cuz[k], cvz[k], czz[k]);
        // Flat as the full patches' rule (their A is Cii = Cjj).
        flat[k] = ciz * ciz + cjz * cjz <= 1e-20 * (cii.max(cjj) + czz) * (cii.max(cjj) + czz);
        (cvv[k], cvz[k]) = (rho * rho * cjj, rs * cjz);
    }
}

/// Cii, Cjj and rs·Cij from the exact c·C.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn geometry_moments(
    count: &[f64],
    c_cii: &[f64],
    c_cjj: &[f64],
    c_cij: &[f64],
    rs: f64,
    cii: &mut [f64],
    cjj: &mut [f64],
    cuv: &mut [f64],
) {
    let len = count.len();
    let (c_cii, c_cjj, c_cij) = (&c_cii[..len], &c_cjj[..len], &c_cij[..len]);
    let (cii, cjj, cuv) = (&mut cii[..len], &mut cjj[..len], &mut cuv[..len]);
    for k in 0..len {
        let cf = count[k];
        (cii[k], cjj[k], cuv[k]) = (c_cii[k] / cf, c_cjj[k] / cf, rs * (c_cij[k] / cf));
    }
}

/// Ciz, Cjz and Czz.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn z_moments(
    count: &[f64],
    si: &[f64],
    sj: &[f64],
    z0: &[f64],
    zi: &[f64],
    zj: &[f64],
    zz: &[f64],
    ciz: &mut [f64],
    cjz: &mut [f64],
    czz: &mut [f64],
) {
    let len = count.len();
    let (si, sj, z0, zi, zj, zz) = (&si[..len], &sj[..len], &z0[..len], &zi[..len], &zj[..len], &zz[..len]);
    let (ciz, cjz, czz) = (&mut ciz[..len], &mut cjz[..len], &mut czz[..len]);
    for k in 0..len {
        let (cf, z0) = (count[k], z0[k]);
        ciz[k] = (cf * zi[k] - si[k] * z0) / cf;
        cjz[k] = (cf * zj[k] - sj[k] * z0) / cf;
        czz[k] = ((cf * zz[k] - z0 * z0) / cf).max(0.0);
    }
}

/// The vertical fit: the 2×2 normal equations' solution, n ∝ (−gx, −gy, 1).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn vertical_normals(
    cuu: &[f64],
    cvv: &[f64],
    cuv: &[f64],
    cuz: &[f64],
    cvz: &[f64],
    czz: &[f64],
    flat: &[bool],
    nx: &mut [f64],
    ny: &mut [f64],
    nz: &mut [f64],
    distances: &mut [f64],
) {
    let len = flat.len();
    let (cuu, cvv, cuv, cuz, cvz, czz) = (&cuu[..len], &cvv[..len], &cuv[..len], &cuz[..len], &cvz[..len], &czz[..len]);
    let (nx, ny, nz, distances) = (&mut nx[..len], &mut ny[..len], &mut nz[..len], &mut distances[..len]);
    for k in 0..len {
        let (cuu, cvv, cuv, cuz, cvz, czz) = (cuu[k], cvv[k], cuv[k], cuz[k], cvz[k], czz[k]);
        let det = cuu * cvv - cuv * cuv;
        let gx = (cvv * cuz - cuv * cvz) / det;
        let gy = (cuu * cvz - cuv * cuz) / det;
        let residual = (czz - gx * cuz - gy * cvz).max(0.0);
        let inv = 1.0 / (gx * gx + gy * gy + 1.0).sqrt();
        let flat = flat[k];
        (nx[k], ny[k], nz[k]) = (select(flat, 0.0, -gx * inv), select(flat, 0.0, -gy * inv), select(flat, 1.0, inv));
        distances[k] = select(flat, czz, residual);
    }
}

/// Rotates (u, v) by θ, tan 2θ = 2Cuv / (Cuu − Cvv), to diagonalise the
/// (u, v) block: a1 = Cuu + t·Cuv, a2 = Cvv − t·Cuv, t = tan θ (in place:
/// [Cuu, Cvv, Cuv, Cuz, Cvz] become [a1, a2, cos θ, b1, b2]); and the
/// Newton start. A flat patch does not step.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn rotate(
    a1: &mut [f64],
    a2: &mut [f64],
    cos: &mut [f64],
    b1: &mut [f64],
    b2: &mut [f64],
    czz: &[f64],
    sin: &mut [f64],
    flat: &[bool],
    lambda: &mut [f64],
    scale: &mut [f64],
    stepping: &mut [bool],
) {
    let len = stepping.len();
    let (a1, a2, cos, b1, b2) = (&mut a1[..len], &mut a2[..len], &mut cos[..len], &mut b1[..len], &mut b2[..len]);
    let (czz, sin, flat) = (&czz[..len], &mut sin[..len], &flat[..len]);
    let (lambda, scale) = (&mut lambda[..len], &mut scale[..len]);
    for k in 0..len {
        let (cuu, cvv, cuv, cuz, cvz) = (a1[k], a2[k], cos[k], b1[k], b2[k]);
        let tau = (cvv - cuu) / (2.0 * cuv);
        let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
        let t = select(tau == 0.0, 1.0, t);
        let cos_t = 1.0 / (1.0 + t * t).sqrt();
        let (c, s) = (select(cuv == 0.0, 1.0, cos_t), select(cuv == 0.0, 0.0, t * cos_t));
        let rotated = [cuu - (s / c) * cuv, cvv + (s / c) * cuv, c * cuz - s * cvz, s * cuz + c * cvz];
        [a1[k], a2[k], b1[k], b2[k]] = rotated;
        (cos[k], sin[k]) = (c, s);
        let settled;
        (lambda[k], scale[k], settled) = eigen_start(rotated[0], rotated[1], rotated[2], rotated[3], czz[k]);
        stepping[k] = !flat[k] & !settled;
    }
}

/// The orthogonal fit's Newton steps, all patches at once: a pass over
/// the planes is one step of every patch still stepping (`stepping`,
/// cleared as each stops). Most patches take three to six steps, some
/// (two close eigenvalues) dozens. The passes run over the planes in
/// place while a quarter or more of the patches still step (a pass over
/// every patch then costs less than moving the steppers together: moving
/// them first took a third of a geographic DEM's fit); then the others
/// are moved together (`work`), and again whenever half of those have
/// stopped, so that a pass costs what the patches still stepping do.
/// Each patch takes the same steps either way, so the same bits.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn newton(
    a1: &[f64],
    a2: &[f64],
    b1: &[f64],
    b2: &[f64],
    czz: &[f64],
    scale: &[f64],
    lambda: &mut [f64],
    stepping: &mut [bool],
    work: &mut NewtonWork,
) {
    let all = stepping.len();
    let (a1, a2, b1, b2, czz, scale, lambda) =
        (&a1[..all], &a2[..all], &b1[..all], &b2[..all], &czz[..all], &scale[..all], &mut lambda[..all]);
    let mut steps = 0;
    while steps < NEWTON_STEPS && stepping_count(stepping) * 4 > all {
        newton_pass(a1, a2, b1, b2, czz, scale, lambda, stepping);
        steps += 1;
    }
    let NewtonWork { index, matrix, scale: work_scale, lambda: work_lambda, stepping: work_stepping } = work;
    index.clear();
    // A few patches in a row still step: runs of 32 without one are
    // passed over by a test that vectorises (one patch at a time, the
    // scan took a tenth of a geographic DEM's solve).
    for (run, flags) in stepping.chunks(32).enumerate() {
        if flags.iter().fold(false, |any, &s| any | s) {
            index.extend(flags.iter().enumerate().filter(|&(_, &s)| s).map(|(k, _)| run * 32 + k));
        }
    }
    let mut len = index.len();
    if len == 0 {
        return;
    }
    // Grown, never shrunk: a row's planes are not filled afresh.
    for plane in matrix.iter_mut().chain([&mut *work_scale, &mut *work_lambda]) {
        plane.resize(plane.len().max(len), 0.0);
    }
    work_stepping.resize(work_stepping.len().max(len), true);
    // Slices, not the `Vec`s: the loops then keep their pointers in
    // registers (through `work`, they reloaded them at every patch).
    let [w1, w2, wb1, wb2, wc] = matrix.each_mut().map(|plane| &mut plane[..len]);
    let (work_scale, work_lambda) = (&mut work_scale[..len], &mut work_lambda[..len]);
    let (work_stepping, index) = (&mut work_stepping[..len], &mut index[..len]);
    work_stepping.fill(true);
    for (j, &k) in index.iter().enumerate() {
        (w1[j], w2[j], wb1[j], wb2[j], wc[j]) = (a1[k], a2[k], b1[k], b2[k], czz[k]);
        (work_scale[j], work_lambda[j]) = (scale[k], lambda[k]);
    }
    while len > 0 && steps < NEWTON_STEPS {
        newton_pass(
            &w1[..len],
            &w2[..len],
            &wb1[..len],
            &wb2[..len],
            &wc[..len],
            &work_scale[..len],
            &mut work_lambda[..len],
            &mut work_stepping[..len],
        );
        steps += 1;
        if stepping_count(&work_stepping[..len]) * 2 > len {
            continue;
        }
        // Half have stopped: their λ is final; the others move down.
        let mut kept = 0;
        for j in 0..len {
            if !work_stepping[j] {
                lambda[index[j]] = work_lambda[j];
                continue;
            }
            index[kept] = index[j];
            (w1[kept], w2[kept], wb1[kept], wb2[kept], wc[kept]) = (w1[j], w2[j], wb1[j], wb2[j], wc[j]);
            (work_scale[kept], work_lambda[kept], work_stepping[kept]) = (work_scale[j], work_lambda[j], true);
            kept += 1;
        }
        len = kept;
    }
    for j in 0..len {
        lambda[index[j]] = work_lambda[j];
    }
}

/// The patches still stepping.
#[inline(always)]
fn stepping_count(stepping: &[bool]) -> usize {
    stepping.iter().map(|&s| usize::from(s)).sum()
}

/// One Newton step of every patch still stepping.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn newton_pass(
    a1: &[f64],
    a2: &[f64],
    b1: &[f64],
    b2: &[f64],
    czz: &[f64],
    scale: &[f64],
    lambda: &mut [f64],
    stepping: &mut [bool],
) {
    let len = stepping.len();
    let (a1, a2, b1, b2, czz) = (&a1[..len], &a2[..len], &b1[..len], &b2[..len], &czz[..len]);
    let (scale, lambda) = (&scale[..len], &mut lambda[..len]);
    for k in 0..len {
        let (next, more) = newton_step([a1[k], a2[k], b1[k], b2[k], czz[k]], scale[k], lambda[k]);
        lambda[k] = select(stepping[k], next, lambda[k]);
        stepping[k] &= more;
    }
}

/// [`newton`]'s planes of the patches still stepping, and each one's
/// place in the row.
#[derive(Default)]
pub(super) struct NewtonWork {
    index: Vec<usize>,
    /// a1, a2, b1, b2, Czz.
    matrix: [Vec<f64>; 5],
    scale: Vec<f64>,
    lambda: Vec<f64>,
    stepping: Vec<bool>,
}

/// The orthogonal fit's normals from the converged λ: the eigenvector,
/// rotated back to (u, v).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn orthogonal_normals(
    a1: &[f64],
    a2: &[f64],
    b1: &[f64],
    b2: &[f64],
    czz: &[f64],
    cos: &[f64],
    sin: &[f64],
    lambda: &[f64],
    flat: &[bool],
    nx: &mut [f64],
    ny: &mut [f64],
    nz: &mut [f64],
    distances: &mut [f64],
) {
    let len = flat.len();
    let (a1, a2, b1, b2, czz) = (&a1[..len], &a2[..len], &b1[..len], &b2[..len], &czz[..len]);
    let (cos, sin, lambda) = (&cos[..len], &sin[..len], &lambda[..len]);
    let (nx, ny, nz, distances) = (&mut nx[..len], &mut ny[..len], &mut nz[..len], &mut distances[..len]);
    for k in 0..len {
        let e = eigenvector([a1[k], a2[k], b1[k], b2[k], czz[k]], lambda[k]);
        let (cos, sin) = (cos[k], sin[k]);
        let n = [cos * e[0] + sin * e[1], -sin * e[0] + cos * e[1], e[2]];
        let inv = 1.0 / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let flat = flat[k];
        (nx[k], ny[k], nz[k]) =
            (select(flat, 0.0, n[0] * inv), select(flat, 0.0, n[1] * inv), select(flat, 1.0, n[2] * inv));
        distances[k] = select(flat, czz[k], lambda[k].max(0.0));
    }
}

/// The valid points' weighted moments of each column's patch, for the
/// output rows of one strip: Σw, Σw·i, Σw·j, Σw·i², Σw·j², Σw·ij (j
/// down, w = w(i)·w(j), over the valid points), each summed outright as
/// the z sums are.
pub(super) struct WeightedMask {
    cols: Range<usize>,
    /// Each source row's Σw·m, Σw·u·m, Σw·u²·m along the window, by row.
    rows: Vec<(isize, [Vec<f64>; 3])>,
    moments: [Vec<f64>; 6],
    valid: Vec<u8>,
}

impl WeightedMask {
    pub(super) fn new(plan: &Plan, cols: Range<usize>) -> WeightedMask {
        let w = cols.len();
        let planes = || [vec![0.0; w], vec![0.0; w], vec![0.0; w]];
        WeightedMask {
            cols,
            rows: (0..plan.n).map(|_| (isize::MIN, planes())).collect(),
            moments: std::array::from_fn(|_| vec![0.0; w]),
            valid: Vec::new(),
        }
    }

    /// Column x's moments, as [`super::masked::Moments::weighted`] takes them.
    pub(super) fn at(&self, x: usize) -> [f64; 6] {
        self.moments.each_ref().map(|plane| plane[x])
    }

    /// Makes the moments those of output row `y`.
    pub(super) fn advance<'a, H: Sample>(&mut self, plan: &Plan, rows: &SourceRows<'_, 'a, H>, y: isize, nodata: f64) {
        let (n, r, w) = (plan.n, plan.r as isize, self.cols.len());
        let [wk, wuk, wuuk] = &plan.axis;
        for v in y - r..=y + r {
            let slot = v.rem_euclid(n as isize) as usize;
            if self.rows[slot].0 == v {
                continue;
            }
            valid_row(plan, self.cols.clone(), rows(v), nodata, &mut self.valid);
            let [m0, m1, m2] = &mut self.rows[slot].1;
            let (m0, m1, m2) = (&mut m0[..w], &mut m1[..w], &mut m2[..w]);
            for q in 0..n {
                let m = &self.valid[q..q + w];
                let (a, b, c) = (wk[q], wuk[q], wuuk[q]);
                if q == 0 {
                    m0.iter_mut().zip(m).for_each(|(o, &m)| *o = a * f64::from(m));
                    m1.iter_mut().zip(m).for_each(|(o, &m)| *o = b * f64::from(m));
                    m2.iter_mut().zip(m).for_each(|(o, &m)| *o = c * f64::from(m));
                } else {
                    m0.iter_mut().zip(m).for_each(|(o, &m)| *o += a * f64::from(m));
                    m1.iter_mut().zip(m).for_each(|(o, &m)| *o += b * f64::from(m));
                    m2.iter_mut().zip(m).for_each(|(o, &m)| *o += c * f64::from(m));
                }
            }
            self.rows[slot].0 = v;
        }
        let [c, si, sj, sii, sjj, sij] = &mut self.moments;
        for j in 0..n {
            let v = y - r + j as isize;
            let [m0, m1, m2] = &self.rows[v.rem_euclid(n as isize) as usize].1;
            let (a, b, cc) = (wk[j], wuk[j], wuuk[j]);
            for x in 0..w {
                let (p0, p1, p2) = (m0[x], m1[x], m2[x]);
                if j == 0 {
                    (c[x], si[x], sj[x], sii[x], sjj[x], sij[x]) = (a * p0, a * p1, b * p0, a * p2, cc * p0, b * p1);
                } else {
                    c[x] += a * p0;
                    si[x] += a * p1;
                    sj[x] += b * p0;
                    sii[x] += a * p2;
                    sjj[x] += cc * p0;
                    sij[x] += b * p1;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The moments of a point list.
    fn moments(points: &[(i64, i64, f64)]) -> Moments {
        let mut m = Moments { c: 0, geometry: [0; 5], z: [0.0; 4], weighted: None };
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

    /// One patch's fit, through a row of one.
    fn masked_normal(m: &Moments, orthogonal: bool, rho: f64, sigma: f64) -> Option<([f64; 3], f64)> {
        let mut row = MaskedRow::default();
        row.clear(1);
        row.push(0, true, m);
        row.solve(orthogonal, rho, sigma);
        let [nx, ny, nz] = &row.normal;
        (row.len == 1).then(|| ([nx[0], ny[0], nz[0]], row.distances[0]))
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
