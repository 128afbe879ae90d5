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
//! * floats: a running sum would carry the rounding of wherever it
//!   started, so the windows are summed over blocks of N aligned on the
//!   image (van Herk / Gil–Werman, as the plane fit's, [`crate::fit`]):
//!   window x = kN + t (x the image's column, or row down the columns)
//!   is the suffix of block k from its value t plus the prefix of block
//!   k + 1 up to its value t − 1, each summed in a fixed order, about one
//!   step a texel and order whatever N. The moments of both parts are
//!   taken about their common boundary (offsets q − N in −N..N, small)
//!   and moved to the window's centre, d = t − r − 1 from it:
//!   Σ(k − d)·h = Σk·h − d·Σh, Σ(k − d)²·h = Σk²·h − 2d·Σk·h + d²·Σh.
//!   Every sum a window takes lies inside its own N values, so a band
//!   starting on any row, and any thread count, gives the same bits.
//!   Cancellation: the shift subtracts terms at most (2N)² times the
//!   heights' size, so its error is a few ulps of N²·|h|, the same order
//!   as the error the a and c numerators (N·Σi²h − T₂·Σh, which remove the
//!   mean height) already carry in f64; the heights are not centred. The
//!   tests hold it to the reference at N = 63 on heights 1000 + a relief
//!   of 0.1 (tests/integration/curvature.rs).
//!
//! A texel whose patch holds a hole ([`Options::nodata`]) gets NaN: the
//! quadratic of a partial patch is ill-conditioned near its edge, and a
//! curvature map is used as a mask, where a gap is safer than a guess.
//! Geographic spacing (one per row) is refused.

use std::ops::Range;

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

/// The scales of a fit of heights whose value 1 is `unit` (a sample
/// type's [`Sample::UNIT`], or a streamed source's).
fn scales(opts: &Options, width: usize, unit: f64) -> Result<Scales> {
    let s = opts.scale_for_width(width);
    match &opts.units {
        Units::Texels => Ok(Scales { gain: s * unit, dx: 1.0, dy: 1.0 }),
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
/// sums), f64 for floats (sums over blocks aligned on the image).
trait Acc: Copy + Send + Sync + Default + 'static {
    /// The row or column moments Σ 1·p, Σ k·p, Σ k²·p of every window of
    /// N = 2r + 1 values of `p` (padded: window x covers p[x..x + N],
    /// centred at x + r), into `m0`, `m1`, `m2` (`m1`, `m2` may be absent).
    fn moments(p: &[Self], n: usize, m0: &mut [Self], m1: Option<&mut [Self]>, m2: Option<&mut [Self]>);
    /// The moments of one column, `rows` giving the padded rows' values
    /// (row k of the band at `rows[k][x]`), for every column at once.
    /// `first` is the image's row of the first output (the padded rows'
    /// first is its top row, `first` − r); `orders` are 0, 1, … in turn.
    fn column_moments(rows: &[&[Self]], n: usize, first: usize, out: &mut [&mut [Self]], orders: &[usize]);
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

    fn column_moments(rows: &[&[i64]], n: usize, _first: usize, out: &mut [&mut [i64]], orders: &[usize]) {
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
        // Blocks of N windows aligned on window 0 (the image's column 0,
        // whatever the band): window x = kN + t sums the block's values
        // q = t..N (a suffix) and the next block's q = N..N + t (a prefix),
        // q counted from p[kN], each in a fixed order; moments about q = N,
        // then moved to the window's centre q = t + r (module docs).
        let (w, r) = (m0.len(), n / 2);
        let mut suffix = vec![[0.0f64; 3]; n];
        for start in (0..w).step_by(n) {
            let z = &p[start..];
            let end = (w - start).min(n);
            let (mut a0, mut a1, mut a2) = (0.0, 0.0, 0.0);
            for q in (0..n).rev() {
                let (v, k) = (z[q], q as f64 - n as f64);
                a0 += v;
                a1 += k * v;
                a2 += k * k * v;
                suffix[q] = [a0, a1, a2];
            }
            let (mut b0, mut b1, mut b2) = (0.0, 0.0, 0.0);
            for (t, &[a0, a1, a2]) in suffix[..end].iter().enumerate() {
                if t > 0 {
                    let (v, k) = (z[n + t - 1], (t - 1) as f64);
                    b0 += v;
                    b1 += k * v;
                    b2 += k * k * v;
                }
                let (s0, s1, s2) = (a0 + b0, a1 + b1, a2 + b2);
                let d = t as f64 - r as f64 - 1.0;
                let x = start + t;
                m0[x] = s0;
                if let Some(m1) = m1.as_deref_mut() {
                    m1[x] = s1 - d * s0;
                }
                if let Some(m2) = m2.as_deref_mut() {
                    m2[x] = s2 - 2.0 * d * s1 + d * d * s0;
                }
            }
        }
    }

    fn column_moments(rows: &[&[f64]], n: usize, first: usize, out: &mut [&mut [f64]], orders: &[usize]) {
        // As `moments`, down the columns, every column at once (loops over
        // a row that vectorise), the blocks aligned on the image's row 0:
        // output y is the image's row first + y. The suffixes are written
        // into `out` first, then the prefixes added and the sums moved to
        // the window's centre. Every sum a window reads lies in its own
        // rows, so a band starting anywhere gives the same bits.
        debug_assert!(orders.iter().enumerate().all(|(k, &o)| k == o), "orders 0, 1, … in turn");
        let (r, w) = (n / 2, rows[0].len());
        let top = orders.len() - 1;
        let outputs = rows.len() + 1 - n;
        let mut acc = vec![vec![0.0f64; w]; top + 1];
        let mut pre = vec![vec![0.0f64; w]; top + 1];
        let mut y = 0;
        while y < outputs {
            let t0 = (first + y) % n;
            // The block's value q (q ≥ t0, all a window reads) is rows[y + q − t0].
            let row = |q: usize| rows[y + q - t0];
            let end = n.min(t0 + outputs - y);
            acc.iter_mut().for_each(|a| a.fill(0.0));
            for q in (t0..n).rev() {
                let (v, k) = (row(q), q as f64 - n as f64);
                add_weighted(&mut acc, v, k);
                if q < end {
                    let at = (y + q - t0) * w..(y + q - t0 + 1) * w;
                    for (o, a) in out.iter_mut().zip(&acc) {
                        o[at.clone()].copy_from_slice(a);
                    }
                }
            }
            pre.iter_mut().for_each(|p| p.fill(0.0));
            for q in n..n + t0 {
                add_weighted(&mut pre, row(q), (q - n) as f64);
            }
            for t in t0..end {
                if t > t0 {
                    add_weighted(&mut pre, row(n + t - 1), (t - 1) as f64);
                }
                let d = t as f64 - r as f64 - 1.0;
                let at = (y + t - t0) * w..(y + t - t0 + 1) * w;
                shift_to_centre(out, &pre, at, d);
            }
            y += end - t0;
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

/// Adds the row `v` to the moments of orders 0, 1, … (as many as `acc`
/// holds) at offset `k`.
fn add_weighted(acc: &mut [Vec<f64>], v: &[f64], k: f64) {
    let w = v.len();
    match acc {
        [a0] => a0[..w].iter_mut().zip(v).for_each(|(a, &v)| *a += v),
        [a0, a1] => {
            let (a0, a1) = (&mut a0[..w], &mut a1[..w]);
            for x in 0..w {
                a0[x] += v[x];
                a1[x] += k * v[x];
            }
        }
        [a0, a1, a2, ..] => {
            let (a0, a1, a2) = (&mut a0[..w], &mut a1[..w], &mut a2[..w]);
            let kk = k * k;
            for x in 0..w {
                a0[x] += v[x];
                a1[x] += k * v[x];
                a2[x] += kk * v[x];
            }
        }
        [] => {}
    }
}

/// `out`'s suffix sums (rows `at`) plus the prefix sums `pre`, moved from
/// the block's boundary to the window's centre, `d` rows from it:
/// Σ(k − d)·v = Σk·v − d·Σv, Σ(k − d)²·v = Σk²·v − 2d·Σk·v + d²·Σv.
fn shift_to_centre(out: &mut [&mut [f64]], pre: &[Vec<f64>], at: std::ops::Range<usize>, d: f64) {
    let w = at.len();
    match (out, pre) {
        ([o0], [p0]) => o0[at].iter_mut().zip(&p0[..w]).for_each(|(o, &p)| *o += p),
        ([o0, o1], [p0, p1]) => {
            let (o0, o1, p0, p1) = (&mut o0[at.clone()], &mut o1[at], &p0[..w], &p1[..w]);
            for x in 0..w {
                let s0 = o0[x] + p0[x];
                let s1 = o1[x] + p1[x];
                o0[x] = s0;
                o1[x] = s1 - d * s0;
            }
        }
        ([o0, o1, o2], [p0, p1, p2]) => {
            let (o0, o1, o2) = (&mut o0[at.clone()], &mut o1[at.clone()], &mut o2[at]);
            let (p0, p1, p2) = (&p0[..w], &p1[..w], &p2[..w]);
            for x in 0..w {
                let s0 = o0[x] + p0[x];
                let s1 = o1[x] + p1[x];
                let s2 = o2[x] + p2[x];
                o0[x] = s0;
                o1[x] = s1 - d * s0;
                o2[x] = s2 - 2.0 * d * s1 + d * d * s0;
            }
        }
        _ => unreachable!("one plane of sums an order, orders 0 to 2"),
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

/// Refuses what no curvature map is made of: invalid options, detail at
/// several scales, a spacing a row; gives the scales.
fn checked_scales(opts: &Options, width: usize, unit: f64) -> Result<Scales> {
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
    if opts.weights != crate::options::Weights::Uniform {
        return Err(Error::InvalidOption(format!(
            "a curvature map fits an unweighted quadratic: {} weights are defined for the plane fit (normals, \
             slope, aspect, hillshade) only",
            opts.weights
        )));
    }
    scales(opts, width, unit)
}

/// The bytes a run of bands of `band` output rows holds on every thread:
/// three planes of row sums, six of patch sums and one of hole counts (a
/// hole plane of the row sums besides), 8 bytes a value, over the band's
/// rows and halo.
fn per_band_bytes(n: usize, width: usize, band: usize) -> u64 {
    ((band + n) as u64) * (width as u64 + n as u64) * 8 * 11
}

/// The curvature of every texel (see the module docs), row-major, as f32,
/// convex positive; NaN where the patch holds a hole. In texel units
/// (1 / texel width; the heights z = S·h of the contract) or map units
/// (1 / the spacing's unit; z = S · the stored value), as `opts.units`
/// says. [`Options::fit`] plays no part: the quadratic is the least
/// squares of height. Rows are computed in parallel on rayon's current
/// pool; the bits do not depend on it, nor on how the rows are cut into
/// bands ([`CurvatureBands`] gives the same bits band by band).
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
    let scales = checked_scales(opts, width, H::UNIT)?;
    let len = checked_len(width, height)?;
    if heights.len() != len {
        return Err(Error::BufferSize { expected: len, actual: heights.len() });
    }
    if opts.nodata.is_none()
        && let Some((x, y)) = first_non_finite(heights, width)
    {
        return Err(Error::NonFiniteHeight { x, y });
    }
    let n = opts.patch;
    let band = band_rows(n).min(height);
    // Per thread: a band's sums; the output, 4 bytes a texel.
    let threads = crate::par::current_num_threads() as u64;
    crate::memory::check_memory("fitting the curvature", 4 * len as u64 + per_band_bytes(n, width, band) * threads)?;
    let mut out = try_filled(len, 0.0f32)?;
    let row = |y: usize| &heights[y * width..(y + 1) * width];
    fit_rows(&row, (width, height), opts, scales, H::UNIT != 1.0, 0, &mut out);
    Ok(out)
}

/// [`curvature`] of heights of any sample type.
///
/// Errors: as [`curvature`].
pub fn curvature_samples(heights: &Samples, width: usize, height: usize, opts: &Options) -> Result<Vec<f32>> {
    with_slice!(heights, h => curvature(h, width, height, opts))
}

/// The output rows from `y0`, as many as `out` holds, in parallel bands
/// of [`band_rows`]; `row(y)` gives source row y. Stored integers
/// (`integer`) take the exact running sums, floats the blocked ones.
fn fit_rows<'a, H: Sample>(
    row: &(dyn Fn(usize) -> &'a [H] + Sync),
    size: (usize, usize),
    opts: &Options,
    scales: Scales,
    integer: bool,
    y0: usize,
    out: &mut [f32],
) {
    let width = size.0;
    let band = band_rows(opts.patch);
    out.par_chunks_mut(band * width).enumerate().for_each(|(k, rows)| {
        let y = y0 + k * band;
        if integer {
            band_curvature::<H, i64>(row, size, opts, scales, y, rows);
        } else {
            band_curvature::<H, f64>(row, size, opts, scales, y, rows);
        }
    });
}

/// The curvature of an image whose rows arrive in bands, top to bottom,
/// for callers that stream rows from a decoder to an encoder without
/// holding the image (as [`BandFit`](super::BandFit) does for normals):
/// memory grows with the width and N, not with the height.
///
/// The output rows are cut into [`bands`](Self::bands): first the top r =
/// N / 2 rows, the only ones whose patches reach above row 0 (so with a
/// wrap in y only they need the image's last rows), then bands of
/// [`band_rows`](Self::band_rows). A band of rows y0 … y1 − 1 reads the
/// source rows y0 − r … y1 − 1 + r through the y border. The values are
/// those of [`curvature`] for the whole image, bit for bit: integers' sums
/// are exact wherever they start, floats' are summed over blocks aligned
/// on the image.
///
/// ```
/// use normalfit::fit::quadratic::CurvatureBands;
/// use normalfit::{curvature, Options};
///
/// let (w, h) = (40, 300);
/// let heights: Vec<f32> = (0..w * h).map(|k| ((k % w) as f32 * 0.3).sin() + (k / w) as f32 * 0.01).collect();
/// let opts = Options::new().with_patch(5);
/// let fit = CurvatureBands::new(w, h, &opts)?;
/// let mut streamed = Vec::new();
/// for rows in fit.bands() {
///     let mut band = vec![0.0f32; rows.len() * w];
///     fit.fit_band(rows, &|y| &heights[y * w..][..w], &mut band)?;
///     streamed.extend(band);
/// }
/// let whole = curvature(&heights, w, h, &opts)?;
/// assert!(streamed.iter().zip(&whole).all(|(a, b)| a.to_bits() == b.to_bits()));
/// # Ok::<(), normalfit::Error>(())
/// ```
pub struct CurvatureBands {
    opts: Options,
    width: usize,
    height: usize,
    band_rows: usize,
    /// The height of a row value of 1, when not the sample type's own.
    unit: Option<f64>,
    /// Holes (NaN) in the bands fitted so far.
    missing: std::sync::atomic::AtomicUsize,
}

impl CurvatureBands {
    /// Plans the curvature of a `width` × `height` image.
    ///
    /// Errors: as [`curvature`] for the options; [`Error::InvalidOption`]
    /// for a zero size.
    pub fn new(width: usize, height: usize, opts: &Options) -> Result<CurvatureBands> {
        checked_scales(opts, width, 1.0)?;
        checked_len(width, height)?;
        // A band of rows for every thread, each fitted as the whole image's.
        let threads = crate::par::current_num_threads().max(1);
        let band_rows = band_rows(opts.patch) * threads;
        Ok(CurvatureBands { opts: opts.clone(), width, height, band_rows, unit: None, missing: 0.into() })
    }

    /// The same curvature of rows whose values are heights in units of
    /// `unit` (a height is value × `unit`): for a decoder that gives
    /// 16-bit samples as `f64` values, 1 / 65535; those then take the
    /// integers' exact sums, as the samples in their own type do. Without
    /// it, the sample type's [`Sample::UNIT`].
    #[must_use]
    pub fn with_unit(mut self, unit: f64) -> CurvatureBands {
        self.unit = Some(unit);
        self
    }

    /// Columns.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Rows per band after the top band.
    #[must_use]
    pub fn band_rows(&self) -> usize {
        self.band_rows
    }

    /// The patch radius r = N / 2, the rows of the top band (fewer in an
    /// image of fewer rows).
    #[must_use]
    pub fn radius(&self) -> usize {
        self.opts.patch / 2
    }

    /// Whether the curvature has holes ([`Options::nodata`] is set).
    #[must_use]
    pub fn has_nodata(&self) -> bool {
        self.opts.nodata.is_some()
    }

    /// The holes (NaN) of every band fitted so far.
    #[must_use]
    pub fn missing(&self) -> usize {
        self.missing.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// The bands of output rows, in order: the top r rows, then bands of
    /// [`band_rows`](Self::band_rows).
    pub fn bands(&self) -> impl Iterator<Item = Range<usize>> + use<> {
        let (h, b) = (self.height, self.band_rows);
        let top = self.radius().min(h);
        std::iter::once(0..top).chain((top..h).step_by(b).map(move |y0| y0..(y0 + b).min(h))).filter(|r| !r.is_empty())
    }

    /// The bytes fitting one band allocates on every thread beyond the
    /// caller's buffers.
    pub(crate) fn work_bytes(&self) -> u64 {
        let threads = crate::par::current_num_threads() as u64;
        let band = band_rows(self.opts.patch).min(self.height);
        per_band_bytes(self.opts.patch, self.width, band).saturating_mul(threads)
    }

    /// Fits the band `rows` (one of [`bands`](Self::bands)) into `out`,
    /// which holds its texels: the curvature, NaN where the patch holds a
    /// hole. `row(y)` gives source row y (`width` heights) for every y the
    /// band reads. Rows run in parallel on rayon's current pool. Returns
    /// the band's holes.
    ///
    /// Errors: [`Error::BufferSize`] for a range that is not a band or a
    /// wrong `out` length, [`Error::NonFiniteHeight`] if a row read holds NaN
    /// or ±inf without a nodata value.
    pub fn fit_band<'a, H: Sample>(
        &self,
        rows: Range<usize>,
        row: &(dyn Fn(usize) -> &'a [H] + Sync),
        out: &mut [f32],
    ) -> Result<usize> {
        let (w, h, r) = (self.width, self.height, self.radius());
        let top = r.min(h);
        let is_band = if rows.start < top {
            rows == (0..top)
        } else {
            (rows.start - top).is_multiple_of(self.band_rows)
                && rows.start < h
                && rows.end == (rows.start + self.band_rows).min(h)
        };
        if !is_band || out.len() != rows.len() * w {
            return Err(Error::BufferSize { expected: rows.len() * w, actual: out.len() });
        }
        for p in rows.start..rows.end + 2 * r {
            let y = self.opts.borders.y.map(p as isize - r as isize, h);
            let values = row(y);
            if values.len() != w {
                return Err(Error::BufferSize { expected: w, actual: values.len() });
            }
            if self.opts.nodata.is_none()
                && let Some((x, _)) = first_non_finite(values, w)
            {
                return Err(Error::NonFiniteHeight { x, y });
            }
        }
        let unit = self.unit.unwrap_or(H::UNIT);
        let scales = scales(&self.opts, w, unit)?;
        fit_rows(row, (w, h), &self.opts, scales, unit != 1.0, rows.start, out);
        let missing = if self.has_nodata() { out.iter().filter(|v| v.is_nan()).count() } else { 0 };
        self.missing.fetch_add(missing, std::sync::atomic::Ordering::Relaxed);
        Ok(missing)
    }
}

/// A plane's rows.
fn rows_of<A>(plane: &[A], width: usize) -> Vec<&[A]> {
    plane.chunks_exact(width).collect()
}

/// The output rows from `y0` (as many as `out` holds); `row(y)` gives
/// source row y.
fn band_curvature<'a, H: Sample, A: Acc>(
    row: &(dyn Fn(usize) -> &'a [H] + Sync),
    (width, height): (usize, usize),
    opts: &Options,
    scales: Scales,
    y0: usize,
    out: &mut [f32],
) {
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
        let row = row(y);
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
        A::column_moments(&rows_of(&h0, width), n, y0, &mut [&mut m00[..], &mut m01[..], &mut m02[..]], &[0, 1, 2]);
        A::column_moments(&rows_of(&h1, width), n, y0, &mut [&mut m10[..], &mut m11[..]], &[0, 1]);
        A::column_moments(&rows_of(&h2, width), n, y0, &mut [&mut m20[..]], &[0]);
    }
    let hole_counts = holes.map(|holes| {
        let mut counts = vec![A::zero(); cells];
        A::column_moments(&rows_of(&holes, width), n, y0, &mut [&mut counts[..]], &[0]);
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
