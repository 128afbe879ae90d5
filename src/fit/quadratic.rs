//! Curvature: the mean curvature of the least-squares quadratic
//! z = a·u² + b·uv + c·v² + d·u + e·v + f fitted over each texel's N × N
//! patch (docs/curvature.md: the formula, its sign, its units, its
//! sources).
//!
//! On the symmetric full patch the normal equations decouple (every odd
//! moment of the offsets vanishes), so the six coefficients come from six
//! sums of the patch, with i, j the column and row offsets in −r..=r and
//! T₂ = Σᵢ i², T₄ = Σᵢ i⁴ over one axis:
//!
//! * d = Σ i·h / (N·T₂), e = Σ j·h / (N·T₂): the plane fit's slopes;
//! * b = Σ i·j·h / T₂²;
//! * a = (N·Σ i²·h − T₂·Σ h) / (N·(N·T₄ − T₂²)), c likewise with j.
//!
//! Each sum is separable (a weight 1, i or i² along the row, then 1, j or
//! j² down the column), so three row filters and six column filters give
//! them all. How they stay exact and flat in N:
//!
//! * stored integers (8, 16 bits: every PNG): running sums of the integers
//!   in i64 along rows and down columns, each step's update exact, so
//!   where a run starts (a band's first row) changes nothing; the
//!   numerators of a and c are formed in i128 and rounded once. Cost
//!   independent of N.
//! * floats: each patch's sums made outright, in a fixed order (the row
//!   filters, then the column filters), so the bits do not depend on bands
//!   or threads; the cost grows with N (linearly: the filters are
//!   separable), not with N².
//!
//! A texel whose patch holds a hole ([`Options::nodata`]) gets NaN: the
//! quadratic of a partial patch is ill-conditioned near its edge, and a
//! curvature map is used as a mask, where a gap is safer than a guess.
//! Geographic spacing (one per row) is refused.

use crate::error::{Error, Result};
use crate::options::{Options, Spacing, Units};
use crate::par::prelude::*;
use crate::samples::{Sample, Samples, first_non_finite, try_filled, with_slice};

use super::checked_len;
use super::masked::is_hole;

/// The curvature's scale factors: the heights' unit times the gain, and
/// the texel spacing along x and y.
#[derive(Clone, Copy, Debug)]
struct Scales {
    gain: f64,
    dx: f64,
    dy: f64,
}

fn scales<H: Sample>(opts: &Options, width: usize) -> Result<Scales> {
    let s = opts.scale_for_width(width);
    match &opts.units {
        Units::Texels => Ok(Scales { gain: s * H::UNIT, dx: 1.0, dy: 1.0 }),
        Units::Map(spacing @ Spacing::Uniform { x, y }) => {
            spacing.validate(None)?;
            Ok(Scales { gain: s, dx: *x, dy: *y })
        }
        Units::Map(Spacing::Rows(_)) => Err(Error::Unsupported(
            "curvature takes one spacing for the whole map: a geographic raster (one spacing a row) needs \
             reprojecting first"
                .into(),
        )),
    }
}

/// The accumulator of the sums: i64 for stored integers (exact running
/// sums), f64 for floats (each patch summed outright).
trait Acc: Copy + Send + Sync + Default + 'static {
    /// The row or column moments Σ 1·p, Σ k·p, Σ k²·p of every window of
    /// N = 2r + 1 values of `p` (padded: window x covers p[x..x + N],
    /// centred at x + r), into `m0`, `m1`, `m2` (`m1`, `m2` may be absent).
    fn moments(p: &[Self], n: usize, m0: &mut [Self], m1: Option<&mut [Self]>, m2: Option<&mut [Self]>);
    /// The moments of one column, `rows` giving the padded rows' values
    /// (row k of the band at `rows[k][x]`), for every column at once.
    fn column_moments(rows: &[&[Self]], n: usize, out: &mut [&mut [Self]], orders: &[usize]);
    fn from_sample<H: Sample>(h: H) -> Self;
    fn zero() -> Self {
        Self::default()
    }
    fn one() -> Self;
    fn is_zero(self) -> bool;
    /// The sums as numbers: (Σh, Σi·h, Σj·h, Σi²·h, Σj²·h, Σij·h) → the
    /// quadratic's coefficients (a, b, c, d, e) in offsets' units.
    fn coefficients(s: [Self; 6], n: usize) -> [f64; 5];
}

/// Σ over one axis of i² and i⁴, i in −r..=r.
fn axis_moments(n: usize) -> (i64, i64) {
    let r = (n / 2) as i64;
    let t2 = r * (r + 1) * (2 * r + 1) / 3;
    let t4 = r * (r + 1) * (2 * r + 1) * (3 * r * r + 3 * r - 1) / 15;
    (t2, t4)
}

impl Acc for i64 {
    fn moments(p: &[i64], n: usize, m0: &mut [i64], mut m1: Option<&mut [i64]>, mut m2: Option<&mut [i64]>) {
        let r = (n / 2) as i64;
        let w = m0.len();
        let (mut s0, mut s1, mut s2) = (0i64, 0i64, 0i64);
        for (k, &v) in p[..n].iter().enumerate() {
            let o = k as i64 - r;
            s0 += v;
            s1 += o * v;
            s2 += o * o * v;
        }
        for x in 0..w {
            if x > 0 {
                // Window x − 1 → x: its first value leaves (offset −r), the
                // value after it enters (offset r + 1); then every offset
                // moves down by one. Exact in integers.
                let (l, e) = (p[x - 1], p[x - 1 + n]);
                let t0 = s0 - l + e;
                let t1 = s1 + r * l + (r + 1) * e;
                let t2 = s2 - r * r * l + (r + 1) * (r + 1) * e;
                s2 = t2 - 2 * t1 + t0;
                s1 = t1 - t0;
                s0 = t0;
            }
            m0[x] = s0;
            if let Some(m1) = m1.as_deref_mut() {
                m1[x] = s1;
            }
            if let Some(m2) = m2.as_deref_mut() {
                m2[x] = s2;
            }
        }
    }

    fn column_moments(rows: &[&[i64]], n: usize, out: &mut [&mut [i64]], orders: &[usize]) {
        // Running sums down the columns, every column at once (loops over
        // the row that vectorise): the same updates as `moments`.
        // Only the orders asked for (and those below, which the updates
        // need) are carried: Σj²·(Σi²·h) of a wide patch would overflow.
        let r = (n / 2) as i64;
        let w = rows[0].len();
        let top = orders.iter().copied().max().unwrap_or(0);
        let (mut s0, mut s1, mut s2) = (vec![0i64; w], vec![0i64; w], vec![0i64; w]);
        for (k, row) in rows[..n].iter().enumerate() {
            let o = k as i64 - r;
            for x in 0..w {
                s0[x] += row[x];
            }
            if top >= 1 {
                for x in 0..w {
                    s1[x] += o * row[x];
                }
            }
            if top >= 2 {
                for x in 0..w {
                    s2[x] += o * o * row[x];
                }
            }
        }
        let outputs = rows.len() + 1 - n;
        for y in 0..outputs {
            if y > 0 {
                let (l, e) = (rows[y - 1], rows[y - 1 + n]);
                match top {
                    0 => {
                        for x in 0..w {
                            s0[x] += e[x] - l[x];
                        }
                    }
                    1 => {
                        for x in 0..w {
                            let t0 = s0[x] - l[x] + e[x];
                            let t1 = s1[x] + r * l[x] + (r + 1) * e[x];
                            s1[x] = t1 - t0;
                            s0[x] = t0;
                        }
                    }
                    _ => {
                        for x in 0..w {
                            let t0 = s0[x] - l[x] + e[x];
                            let t1 = s1[x] + r * l[x] + (r + 1) * e[x];
                            let t2 = s2[x] - r * r * l[x] + (r + 1) * (r + 1) * e[x];
                            s2[x] = t2 - 2 * t1 + t0;
                            s1[x] = t1 - t0;
                            s0[x] = t0;
                        }
                    }
                }
            }
            for (o, &order) in out.iter_mut().zip(orders) {
                let s = [&s0, &s1, &s2][order];
                o[y * w..(y + 1) * w].copy_from_slice(s);
            }
        }
    }

    fn from_sample<H: Sample>(h: H) -> i64 {
        h.to_f64() as i64
    }

    fn one() -> i64 {
        1
    }

    fn is_zero(self) -> bool {
        self == 0
    }

    fn coefficients([m00, m10, m01, m20, m02, m11]: [i64; 6], n: usize) -> [f64; 5] {
        let (t2, t4) = axis_moments(n);
        let nn = n as i128;
        let den = (nn * (nn * t4 as i128 - (t2 as i128) * (t2 as i128))) as f64;
        // The numerators exact, then rounded once.
        let a = (nn * m20 as i128 - t2 as i128 * m00 as i128) as f64 / den;
        let c = (nn * m02 as i128 - t2 as i128 * m00 as i128) as f64 / den;
        let b = m11 as f64 / (t2 as f64 * t2 as f64);
        let nt2 = n as f64 * t2 as f64;
        [a, b, c, m10 as f64 / nt2, m01 as f64 / nt2]
    }
}

impl Acc for f64 {
    fn moments(p: &[f64], n: usize, m0: &mut [f64], mut m1: Option<&mut [f64]>, mut m2: Option<&mut [f64]>) {
        let r = n / 2;
        for x in 0..m0.len() {
            let window = &p[x..x + n];
            // Offsets paired ±k around the centre, nearest first.
            let mut s0 = window[r];
            let (mut s1, mut s2) = (0.0, 0.0);
            for k in 1..=r {
                let (lo, hi) = (window[r - k], window[r + k]);
                let kf = k as f64;
                s0 += lo + hi;
                s1 += kf * (hi - lo);
                s2 += kf * kf * (hi + lo);
            }
            m0[x] = s0;
            if let Some(m1) = m1.as_deref_mut() {
                m1[x] = s1;
            }
            if let Some(m2) = m2.as_deref_mut() {
                m2[x] = s2;
            }
        }
    }

    fn column_moments(rows: &[&[f64]], n: usize, out: &mut [&mut [f64]], orders: &[usize]) {
        let r = n / 2;
        let w = rows[0].len();
        let top = orders.iter().copied().max().unwrap_or(0);
        let outputs = rows.len() + 1 - n;
        let (mut s0, mut s1, mut s2) = (vec![0.0; w], vec![0.0; w], vec![0.0; w]);
        for y in 0..outputs {
            let window = &rows[y..y + n];
            s0.copy_from_slice(window[r]);
            s1.fill(0.0);
            s2.fill(0.0);
            for k in 1..=r {
                let (lo, hi) = (window[r - k], window[r + k]);
                let kf = k as f64;
                for x in 0..w {
                    s0[x] += lo[x] + hi[x];
                }
                if top >= 1 {
                    for x in 0..w {
                        s1[x] += kf * (hi[x] - lo[x]);
                    }
                }
                if top >= 2 {
                    for x in 0..w {
                        s2[x] += kf * kf * (hi[x] + lo[x]);
                    }
                }
            }
            for (o, &order) in out.iter_mut().zip(orders) {
                let s = [&s0, &s1, &s2][order];
                o[y * w..(y + 1) * w].copy_from_slice(s);
            }
        }
    }

    fn from_sample<H: Sample>(h: H) -> f64 {
        h.to_f64()
    }

    fn one() -> f64 {
        1.0
    }

    fn is_zero(self) -> bool {
        self == 0.0
    }

    fn coefficients([m00, m10, m01, m20, m02, m11]: [f64; 6], n: usize) -> [f64; 5] {
        let (t2, t4) = axis_moments(n);
        let (nf, t2, t4) = (n as f64, t2 as f64, t4 as f64);
        let den = nf * (nf * t4 - t2 * t2);
        let a = (nf * m20 - t2 * m00) / den;
        let c = (nf * m02 - t2 * m00) / den;
        [a, m11 / (t2 * t2), c, m10 / (nf * t2), m01 / (nf * t2)]
    }
}

/// The mean curvature, convex positive, of the surface whose quadratic
/// has these coefficients (offsets' units) at its centre, in the units
/// `scales` give: with p = z_u, q = z_v, r = z_uu, s = z_uv, t = z_vv,
/// K = −((1 + q²)·r − 2·p·q·s + (1 + p²)·t) / (2·(1 + p² + q²)^{3/2}).
fn mean_curvature([a, b, c, d, e]: [f64; 5], s: Scales) -> f64 {
    let p = s.gain * d / s.dx;
    let q = s.gain * e / s.dy;
    let rr = 2.0 * s.gain * a / (s.dx * s.dx);
    let tt = 2.0 * s.gain * c / (s.dy * s.dy);
    let ss = s.gain * b / (s.dx * s.dy);
    let g = 1.0 + p * p + q * q;
    -((1.0 + q * q) * rr - 2.0 * p * q * ss + (1.0 + p * p) * tt) / (2.0 * g * g.sqrt())
}

/// Output rows fitted together: each band's row sums are made once for
/// its rows and halo, so a band of at least 2N rows keeps the halo's share
/// of the work at most half.
fn band_rows(n: usize) -> usize {
    (2 * n).max(64)
}

/// The curvature of every texel (see the module docs), row-major, as f32,
/// convex positive; NaN where the patch holds a hole. In texel units
/// (1 / texel width; the heights z = S·h of the contract) or map units
/// (1 / the spacing's unit; z = S · the stored value), as `opts.units`
/// says. [`Options::fit`] plays no part: the quadratic is the least
/// squares of height. Rows are computed in parallel on rayon's current
/// pool; the bits do not depend on it.
///
/// ```
/// use normalfit::{Border, Borders, Options};
/// use normalfit::fit::curvature;
/// // A dome z = −x²/8 − y²/8: curvature 1/4 at its top, in texel units.
/// let (w, h) = (9, 9);
/// let heights: Vec<f64> =
///     (0..w * h).map(|k| { let (x, y) = ((k % w) as f64 - 4.0, (k / w) as f64 - 4.0); -(x * x + y * y) / 8.0 }).collect();
/// let opts = Options::default().with_borders(Borders::both(Border::Clamp));
/// let k = curvature(&heights, w, h, &opts).unwrap();
/// assert!((k[4 * w + 4] - 0.25).abs() < 1e-6);
/// ```
///
/// Errors: [`Error::InvalidOption`] for options [`Options::validate`]
/// refuses, detail at several scales ([`Options::detail`]) and empty images; [`Error::BufferSize`] when `heights` is not
/// `width × height`; [`Error::NonFiniteHeight`] for a NaN or infinite
/// height without a nodata value; [`Error::Unsupported`] for a spacing a
/// row; the memory rule's error.
pub fn curvature<H: Sample>(heights: &[H], width: usize, height: usize, opts: &Options) -> Result<Vec<f32>> {
    opts.validate()?;
    // One quadratic a patch: several sizes (`--detail`) mix the normals'
    // slopes, which a curvature map has none of.
    if opts.detail.is_some() {
        return Err(Error::InvalidOption(
            "a curvature map fits one quadratic over one patch size: give -n (patch=), not detail at several \
             scales, which mixes the normals' slopes"
                .into(),
        ));
    }
    let len = checked_len(width, height)?;
    if heights.len() != len {
        return Err(Error::BufferSize { expected: len, actual: heights.len() });
    }
    let scales = scales::<H>(opts, width)?;
    if opts.nodata.is_none()
        && let Some((x, y)) = first_non_finite(heights, width)
    {
        return Err(Error::NonFiniteHeight { x, y });
    }
    let n = opts.patch;
    let band = band_rows(n).min(height);
    // Per thread: a band's three row planes and six column planes (and a
    // hole plane of each), 8 bytes a value; the output, 4 a texel.
    let per_band = ((band + n) as u64) * (width as u64 + n as u64) * 8 * 11;
    let threads = crate::par::current_num_threads() as u64;
    crate::memory::check_memory("fitting the curvature", 4 * len as u64 + per_band * threads)?;
    let mut out = try_filled(len, 0.0f32)?;
    let integer = H::UNIT != 1.0;
    out.par_chunks_mut(band * width).enumerate().try_for_each(|(k, rows)| -> Result<()> {
        let y0 = k * band;
        if integer {
            band_curvature::<H, i64>(heights, (width, height), opts, scales, y0, rows)
        } else {
            band_curvature::<H, f64>(heights, (width, height), opts, scales, y0, rows)
        }
    })?;
    Ok(out)
}

/// [`curvature`] of heights of any sample type.
///
/// Errors: as [`curvature`].
pub fn curvature_samples(heights: &Samples, width: usize, height: usize, opts: &Options) -> Result<Vec<f32>> {
    with_slice!(heights, h => curvature(h, width, height, opts))
}

/// A plane's rows.
fn rows_of<A>(plane: &[A], width: usize) -> Vec<&[A]> {
    plane.chunks_exact(width).collect()
}

/// The output rows from `y0` (as many as `out` holds).
fn band_curvature<H: Sample, A: Acc>(
    heights: &[H],
    (width, height): (usize, usize),
    opts: &Options,
    scales: Scales,
    y0: usize,
    out: &mut [f32],
) -> Result<()> {
    let n = opts.patch;
    let r = n / 2;
    let rows_out = out.len() / width;
    let src_rows = rows_out + 2 * r;
    let padded_w = width + 2 * r;
    let columns: Vec<usize> = (0..padded_w).map(|k| opts.borders.x.map(k as isize - r as isize, width)).collect();
    let nodata = opts.nodata;
    // The row filters of every source row the band reads: Σ1, Σi, Σi².
    let plane = src_rows * width;
    let (mut h0, mut h1, mut h2) = (vec![A::zero(); plane], vec![A::zero(); plane], vec![A::zero(); plane]);
    let mut holes = nodata.map(|_| vec![A::zero(); plane]);
    let mut padded = vec![A::zero(); padded_w];
    let mut hole_row = vec![A::zero(); padded_w];
    for k in 0..src_rows {
        let y = opts.borders.y.map((y0 + k) as isize - r as isize, height);
        let row = &heights[y * width..(y + 1) * width];
        let mut any_hole = false;
        for (p, (&c, hole)) in padded.iter_mut().zip(columns.iter().zip(hole_row.iter_mut())) {
            let v = row[c];
            let missing = nodata.is_some_and(|nd| is_hole(v.to_f64(), nd));
            any_hole |= missing;
            *p = if missing { A::zero() } else { A::from_sample(v) };
            *hole = if missing { A::one() } else { A::zero() };
        }
        let at = k * width..(k + 1) * width;
        A::moments(&padded, n, &mut h0[at.clone()], Some(&mut h1[at.clone()]), Some(&mut h2[at.clone()]));
        if let Some(holes) = holes.as_mut()
            && any_hole
        {
            A::moments(&hole_row, n, &mut holes[at], None, None);
        }
    }
    let cells = rows_out * width;
    let mut planes: Vec<Vec<A>> = (0..6).map(|_| vec![A::zero(); cells]).collect();
    {
        let [m00, m01, m02, m10, m11, m20] = planes.as_mut_slice() else { unreachable!() };
        A::column_moments(&rows_of(&h0, width), n, &mut [&mut m00[..], &mut m01[..], &mut m02[..]], &[0, 1, 2]);
        A::column_moments(&rows_of(&h1, width), n, &mut [&mut m10[..], &mut m11[..]], &[0, 1]);
        A::column_moments(&rows_of(&h2, width), n, &mut [&mut m20[..]], &[0]);
    }
    let hole_counts = holes.map(|holes| {
        let mut counts = vec![A::zero(); cells];
        A::column_moments(&rows_of(&holes, width), n, &mut [&mut counts[..]], &[0]);
        counts
    });
    let [m00, m01, m02, m10, m11, m20] = planes.as_slice() else { unreachable!() };
    for (i, o) in out.iter_mut().enumerate() {
        let hole = hole_counts.as_ref().is_some_and(|c| !c[i].is_zero());
        *o = if hole {
            f32::NAN
        } else {
            let coefficients = A::coefficients([m00[i], m10[i], m01[i], m20[i], m02[i], m11[i]], n);
            mean_curvature(coefficients, scales) as f32
        };
    }
    Ok(())
}

/// The curvature that maps to white ([`encode`]) unless a caller says:
/// 0.1 a texel width in texel units (a bump of 1/20 of a texel's height
/// over a 3 × 3 patch), or a map unit's inverse.
pub const DEFAULT_RANGE: f64 = 0.1;

/// Checks a caller's curvature range: finite and positive.
///
/// Errors: [`Error::InvalidOption`] naming the value.
pub fn validate_range(range: f64) -> Result<f64> {
    if range.is_finite() && range > 0.0 {
        Ok(range)
    } else {
        Err(Error::InvalidOption(format!(
            "curvature range must be finite and positive, got {}",
            crate::error::Number(range)
        )))
    }
}

/// The artist's map of a curvature `k`: flat at mid-grey, convex above;
/// `k = range` is white, `−range` the darkest code; with `max` 255 (8
/// bits) or 65535 (16 bits): round(m + (m − 1)·clamp(k / range, −1, 1)),
/// m = (max + 1) / 2 (128 or 32768). A hole (NaN) maps to mid-grey.
#[must_use]
pub fn encode(k: f32, range: f64, max: u32) -> u32 {
    let m = f64::from(max.div_ceil(2));
    let t = if k.is_nan() { 0.0 } else { (f64::from(k) / range).clamp(-1.0, 1.0) };
    (m + (m - 1.0) * t).round() as u32
}
