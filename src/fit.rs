//! The plane fit: heights in, unit normals out. Knows nothing of files.
//!
//! For texel (x, y), patch size N = 2r + 1, the points are
//! p(i, j) = (i, σ·j, z(x + i, y + j)) for i, j ∈ [−r, r], z = S · h, with
//! σ = −1 for OpenGL and +1 for DirectX. With the mean removed only these
//! sums remain (Σi = Σj = Σij = 0 on the square grid):
//!
//! ```text
//! A   = Σ i²  (= Σ j²)  = N · r(r + 1)(2r + 1) / 3
//! Cx  = Σ i · z         Cy = σ · Σ j · z
//! Czz = Σ z² − (Σ z)² / N²
//! ```
//!
//! * vertical fit: n ∝ (−Cx, −Cy, A);
//! * orthogonal fit: n ∝ (−Cx, −Cy, A − λ), λ the covariance's smallest
//!   eigenvalue; with d = (A − Czz)/2, q = √(d² + Cx² + Cy²),
//!   A − λ = d + q if d ≥ 0, else (Cx² + Cy²)/(q − d) (the same value,
//!   written so that it does not cancel);
//! * a patch with Cx² + Cy² ≤ 1e-20 · (A + Czz)² is flat: n = (0, 0, 1).
//!
//! In map units ([`Units::Map`](crate::options::Units::Map)) texel centres are sx apart along a row
//! and sy down a column (per row for a geographic raster: the patch takes
//! its centre row's). Lengths are then counted in x spacings: z / sx, and
//! the rows ρ = sy / sx apart. Where ρ = 1 the formulas above run as they
//! are (on z / sx); otherwise (`unequal`) the vertical fit
//! n ∝ (−Cx, −Cy/ρ, A), the orthogonal fit the smallest eigenvector of
//! [[A, 0, Cx], [0, ρ²A, ρCy], [Cx, ρCy, Czz]] (docs/spec.md). The sums
//! do not change; only the last step does, and it too runs as loops over
//! a row's planes, without branches.
//!
//! # How the sums are found
//!
//! The four patch sums Σz, Σiz, Σjz, Σz² are separable: each is a sum
//! along a row's window, then a sum of those down the patch's rows. The
//! cost per texel is the same for N = 3 and N = 63, and every texel's sums
//! are made from its own patch alone, by operations fixed by the image and
//! N: so threads, the tiles a streaming caller asks for, and windows of the
//! image computed apart ([`FitRequest::window`], a Dask chunk) all give
//! the same bits.
//!
//! * Stored integers (8 and 16 bits) are summed as they are, unscaled:
//!   every sum is an integer below 2^53, exact in f64, so running sums
//!   (add the entering texel, remove the leaving one: two steps a texel)
//!   give each texel exactly its patch's sums wherever the run started.
//!   The gain S / (2^bits − 1) comes after, in f64, and Czz is formed as
//!   (N²·Σz² − (Σz)²)/N², whose numerator is exact too.
//! * Floats (z = S · h) would carry the rounding of wherever a running sum
//!   started, so their windows are summed over blocks aligned on the image
//!   (van Herk / Gil–Werman): texel t of block k (x = kN + t) has the
//!   suffix of the values [kN − r, kN + r] from x − r plus the prefix of
//!   the next N values up to x + r, each summed in a fixed order from the
//!   patch's values; the same down the rows. About three steps a texel,
//!   and no sum runs over more than 2N values, so rounding stays that of a
//!   few additions (no reference value needs subtracting: within SPEC's
//!   |S·h| ≤ 1000, Σz² − (Σz)²/N² keeps its digits).
//! * The first row tile is the top r rows, the only rows whose patches
//!   reach above row 0; the others start at row r. With a wrap in y, only
//!   that tile reads the image's last rows, so a streaming caller
//!   ([`BandFit`]) can fit the rest before it has them.
//! * A block of rows holds between 2^14 and 2^24 texels, whatever the
//!   image's shape: a narrow image (one column, 2^24 rows) gets blocks tall
//!   enough that the work of a block outweighs its setup, and a very wide one
//!   (2^26 columns) blocks of fewer rows, so that a band of blocks, which a
//!   streaming caller holds, stays a bounded number of texels. Each task's
//!   own sums are a strip of ~512 columns (at least 8·N, so starting a
//!   strip's sums costs at most an eighth of its work), and borders are
//!   mapped as they are read, so the fit's working memory does not grow
//!   with the image's width or height.

use crate::error::{Error, Result};
use crate::options::Options;
use crate::samples::Sample;

mod band;
mod convolve;
mod detail;
mod eigen;
mod emit;
mod masked;
mod plan;
pub mod quadratic;
mod request;
mod sums;
mod texel;
mod unequal;
mod weighted;
mod window;
pub use band::BandFit;
use emit::store_normals;
use masked::row_has_hole;
use plan::Plan;
pub use quadratic::{curvature, curvature_samples};
pub(crate) use request::work_bytes;
pub use request::{FitRequest, Heights};
use sums::{RowRef, SourceRows, WindowSums};
pub(crate) use texel::{Lamp, MapAxes, Texel, TexelFrame};
pub use window::{Halo, HaloPlan, Window};
// The texel types the fit writes are the encoding's (io): re-exported
// where a caller of the fit looks for them.
pub use crate::io::from_normal::FromNormal;

/// Unit normals of a `width` × `height` height map, as `[x, y, z]` in
/// [−1, 1], row-major: a convenience over [`FitRequest`], the fit's one
/// way in, for the plainest request (the whole image, no residual, a new
/// buffer of `[f32; 3]`).
///
/// `heights` is row-major, `width * height` long, of any [`Sample`] type:
/// `f32` and `f64` are heights in the contract's units, `u8` and `u16`
/// stored integer values whose heights are v / 255 and v / 65535 (SPEC
/// §1). Integers are read as they are and 1 / (2^bits − 1) goes into the
/// gain, in f64, so no rounding comes between the file and the fit. Rows
/// are computed in parallel on rayon's current pool.
///
/// ```
/// use normalfit::{normals, Options};
/// // A ramp rising to the right: normals lean left (−x), green stays 0.
/// let (w, h) = (8, 4);
/// let heights: Vec<f32> = (0..w * h).map(|k| (k % w) as f32 * 0.25).collect();
/// let opts = Options::default().with_borders(normalfit::Borders::both(normalfit::Border::Clamp));
/// let n = normals(&heights, w, h, &opts).unwrap();
/// let [nx, ny, nz] = n[w + 3];
/// assert!(nx < 0.0 && ny.abs() < 1e-6 && nz > 0.0);
/// ```
///
/// Errors: as [`FitRequest::normals_into`].
pub fn normals<H: Sample>(heights: &[H], width: usize, height: usize, opts: &Options) -> Result<Vec<[f32; 3]>> {
    let mut out = vec![[0.0f32; 3]; checked_len(width, height)?];
    FitRequest::new(opts).normals_into(heights, width, height, &mut out)?;
    Ok(out)
}

/// `width * height`, refusing zero sizes and overflow: the rule every fit
/// and check holds an image to (a caller planning work on an image it
/// does not hold yet, such as `normalfit.dask`, asks it first).
///
/// Errors: [`Error::InvalidOption`] naming the size.
pub fn checked_len(width: usize, height: usize) -> Result<usize> {
    if width == 0 || height == 0 {
        return Err(Error::InvalidOption(format!("image is {width}×{height}: both sides must be at least 1")));
    }
    width
        .checked_mul(height)
        .ok_or_else(|| Error::InvalidOption(format!("image of {width}×{height} texels is too large")))
}

#[cfg(test)]
mod tests {
    use super::emit::normal_from_sums;
    use super::plan::{EMIT_CHUNK, MAX_BLOCK_TEXELS};
    use super::*;
    use crate::options::Border;
    use crate::options::{Borders, Fit};

    /// The whole-image fit with blocks of `block_rows` rows.
    fn fitted_with_blocks(heights: &[f32], w: usize, h: usize, opts: &Options, block_rows: usize) -> Vec<[f32; 3]> {
        let mut plan = Plan::new(w, h, opts).unwrap();
        plan.block_rows = block_rows;
        let mut out = vec![[0.0f32; 3]; w * h];
        let rows = |v: isize| RowRef { values: &heights[plan.borders.y.map(v, h) * w..][..w], x0: 0, holes: false };
        plan.fit_rows(&rows, 1.0, (0, 0..w), &mut out, None, None);
        out
    }

    /// Stored integers at N = 3 are summed outright, as floats are
    /// ([`Plan::kernel`]), not by the running sums larger patches take:
    /// the sums are exact either way, so the texels (f64 normals, which
    /// show a sum's last bit, and the residual) must be the running sums'
    /// bits, with and without holes, in the one-pass emit and the planes'.
    #[test]
    fn stored_integers_summed_outright_give_the_bits_of_running_sums() {
        use crate::samples::Sample;
        let (w, h) = (41, 29);
        let heights: Vec<u16> = (0..w * h).map(|k| ((k * 7919 + (k / w) * 104_729) % 65_536) as u16).collect();
        let hole = f64::from(heights[5 * w + 7]);
        let mut compared = 0;
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            for borders in [Borders::both(Border::Wrap), Borders { x: Border::Mirror, y: Border::Clamp }] {
                for (nodata, with_residual) in [(None, false), (None, true), (Some(hole), false)] {
                    let opts = Options::new()
                        .with_patch(3)
                        .with_fit(fit)
                        .with_borders(borders)
                        .with_strength(crate::Strength::Scale(40.0))
                        .with_nodata(nodata);
                    let plan = Plan::new(w, h, &opts).unwrap();
                    assert_eq!(plan.kernel(u16::UNIT), plan::Kernel::Direct);
                    let gain = plan.scale * u16::UNIT;
                    let rows = |v: isize| RowRef {
                        values: &heights[plan.borders.y.map(v, h) * w..][..w],
                        x0: 0,
                        holes: nodata.is_some(),
                    };
                    let run = |outright: bool| {
                        let mut out = vec![[0.0f64; 3]; w * h];
                        let mut residual = vec![0.0f32; w * h];
                        let mut valid = vec![false; w * h];
                        let strip = plan::Strip {
                            y0: 0,
                            x0: 0,
                            out: out.chunks_mut(w).collect(),
                            residual: with_residual.then(|| residual.chunks_mut(w).collect()),
                            valid: nodata.map(|v| (valid.chunks_mut(w).collect(), v)),
                        };
                        match outright {
                            true => plan.fit_strip_direct::<u16, [f64; 3], 3>(&rows, (1.0, gain), strip),
                            false => plan.fit_strip_sliding(&rows, gain, strip),
                        }
                        let normals: Vec<[u64; 3]> = out.iter().map(|n| n.map(f64::to_bits)).collect();
                        (normals, residual.iter().map(|r| r.to_bits()).collect::<Vec<_>>(), valid)
                    };
                    let (outright, running) = (run(true), run(false));
                    assert!(outright.0.iter().any(|n| n[0] != 0), "non-zero slopes");
                    assert_eq!(outright, running, "{opts:?}, residual {with_residual}");
                    compared += 1;
                }
            }
        }
        assert_eq!(compared, 12);
    }

    /// The patch moments of the sliding sums against the sums written out
    /// over each N×N patch, through the borders' index maps.
    #[test]
    fn moments_are_the_patch_sums() {
        let (w, h) = (37, 23);
        let z: Vec<f64> = (0..w * h).map(|k| ((k * 7919) % 1009) as f64 * 0.013 + (k % w) as f64 * 0.5).collect();
        for (n, bx, by) in
            [(3, Border::Wrap, Border::Mirror), (5, Border::Mirror, Border::Clamp), (7, Border::Clamp, Border::Wrap)]
        {
            let opts = Options::new()
                .with_patch(n)
                .with_fit(Fit::Vertical)
                .with_borders(Borders { x: bx, y: by })
                .with_strength(crate::Strength::Scale(1.0));
            let mut fit = BandFit::new(w, h, &opts).unwrap().with_unit(1.0);
            let mut got = Vec::new();
            for rows in fit.bands().collect::<Vec<_>>() {
                let mut band = vec![[0.0; 3]; rows.len() * w];
                fit.moments(rows, &|y| &z[y * w..][..w], &mut band).unwrap();
                got.extend(band);
            }
            let r = (n / 2) as isize;
            for y in 0..h {
                for x in 0..w {
                    let mut values = Vec::new();
                    let (mut cx, mut cy) = (0.0, 0.0);
                    for j in -r..=r {
                        for i in -r..=r {
                            let v = z[by.map(y as isize + j, h) * w + bx.map(x as isize + i, w)];
                            cx += i as f64 * v;
                            cy += j as f64 * v;
                            values.push(v);
                        }
                    }
                    let mean = values.iter().sum::<f64>() / values.len() as f64;
                    let czz: f64 = values.iter().map(|v| (v - mean) * (v - mean)).sum();
                    let [gx, gy, gzz] = got[y * w + x];
                    let scale = 1.0 + czz;
                    assert!((gx - cx).abs() < 1e-9 * scale && (gy - cy).abs() < 1e-9 * scale, "{n} {x},{y}");
                    assert!((gzz - czz).abs() < 1e-9 * scale, "{n} {x},{y}: {gzz} against {czz}");
                }
            }
        }
    }

    /// Blocks of a few rows, as a very wide image gets, and taller ones, as
    /// a narrow image gets: the sums restart at other rows, the normals are
    /// the same up to rounding.
    #[test]
    fn blocks_of_any_height_give_the_same_normals() {
        let (w, h) = (150, 70);
        let heights: Vec<f32> =
            (0..w * h).map(|k| (((k * 7919) % 1013) as f32 / 1013.0) + (k % w) as f32 * 0.01).collect();
        for n in [3, 9] {
            for borders in [Borders::both(Border::Wrap), Borders::both(Border::Mirror), Borders::both(Border::Clamp)] {
                let opts =
                    Options::new().with_patch(n).with_borders(borders).with_strength(crate::Strength::Scale(3.0));
                let default = fitted_with_blocks(&heights, w, h, &opts, Plan::new(w, h, &opts).unwrap().block_rows);
                for rows in [1, 2, 3, 7, 200] {
                    let other = fitted_with_blocks(&heights, w, h, &opts, rows);
                    for (k, (a, b)) in default.iter().zip(&other).enumerate() {
                        for c in 0..3 {
                            assert!(
                                (a[c] - b[c]).abs() < 1e-6,
                                "N {n} {borders:?} blocks of {rows}: texel {k} {a:?} {b:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// The rows of a block for the shapes of the module docs.
    #[test]
    fn blocks_hold_a_bounded_number_of_texels() {
        let rows = |w: usize, h: usize, n: usize| Plan::new(w, h, &Options::new().with_patch(n)).unwrap().block_rows;
        assert_eq!(rows(4096, 4096, 3), 64);
        assert_eq!(rows(4096, 4096, 63), 504);
        assert_eq!(rows(32768, 32768, 63), 504, "flat in N up to 2^24 / 504 columns");
        assert_eq!(rows(1, 1 << 24, 3), 1 << 14);
        assert_eq!(rows(100, 100, 3), 164);
        assert_eq!(rows(1 << 24, 1, 3), 1);
        assert_eq!(rows(1 << 26, 16, 3), 1);
        assert_eq!(rows(1 << 20, 16, 63), 16);
        let band = |w: usize, h: usize| BandFit::new(w, h, &Options::new()).unwrap().band_rows() * w;
        assert!(band(1 << 20, 64) <= MAX_BLOCK_TEXELS);
        assert!(band(1 << 26, 16) == 1 << 26, "one row when a row is more than the bound");
    }

    /// The orthogonal fit's normals, a chunk of texels at a time: chunks
    /// without a steep patch (Czz ≤ A) leave the division out, and get the
    /// same bits as the formula with it; a chunk with one divides.
    #[test]
    #[allow(clippy::needless_range_loop)] // x indexes the sums and the three planes
    fn chunks_with_and_without_steep_patches_give_the_formula_bit_for_bit() {
        let w = 3 * EMIT_CHUNK + 5;
        let plan = Plan::new(w, 4, &Options::new().with_patch(3)).unwrap();
        let steep = |x: usize| (EMIT_CHUNK + 3..EMIT_CHUNK + 9).contains(&x) || x == w - 2;
        let mut v = WindowSums::zeros(w);
        for x in 0..w {
            let t = x as f64;
            v.s0[x] = 0.37 * t - 3.0;
            v.si[x] = 0.9 - 0.031 * t;
            v.sj[x] = 0.2 + 0.017 * t;
            let czz = if steep(x) { 40.0 + t } else { 0.05 * t };
            v.szz[x] = czz + v.s0[x] * v.s0[x] / 9.0;
        }
        let mut normal = [vec![0.0; w], vec![0.0; w], vec![0.0; w]];
        plan.emit_with::<true>(&v, 1.0, true, &mut normal);
        let mut cancelling = 0;
        for x in 0..w {
            let czz = ((9.0 * v.szz[x] - v.s0[x] * v.s0[x]) * (1.0 / 9.0)).max(0.0);
            assert_eq!(czz > plan.a, steep(x), "texel {x}: czz {czz}");
            let with_division = normal_from_sums::<true, true>(plan.a, v.si[x], plan.sigma * v.sj[x], czz, true);
            let got = [normal[0][x], normal[1][x], normal[2][x]];
            assert_eq!(got.map(f64::to_bits), with_division.map(f64::to_bits), "texel {x}");
            let without = normal_from_sums::<true, false>(plan.a, v.si[x], plan.sigma * v.sj[x], czz, true);
            if without.map(f64::to_bits) != with_division.map(f64::to_bits) {
                assert!(steep(x), "texel {x}: gentle, but the formulas differ");
                cancelling += 1;
            }
        }
        // The steep texels are ones where leaving the division out would show.
        assert!(cancelling >= 4, "{cancelling}");
    }
}
