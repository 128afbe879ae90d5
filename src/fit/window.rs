//! Normals of a window of a larger image: a chunk of a Dask array, a tile
//! of a raster too large for one machine's memory. Any partition of an
//! image into windows gives exactly the whole image's output, bit for bit,
//! because the fit makes every texel's sums from its own patch alone, in an
//! order fixed by the image (see the [module docs](super)): a window needs
//! only its heights and a halo of r = N / 2 texels around them.

use std::ops::Range;

use super::{FromNormal, Plan, RowRef, checked_len, first_non_finite};
use crate::error::{Error, Result};
use crate::options::Options;
use crate::samples::Sample;

/// Texels held around a window, on each side.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Halo {
    /// Columns left of the window.
    pub left: usize,
    /// Columns right of the window.
    pub right: usize,
    /// Rows above the window.
    pub top: usize,
    /// Rows below the window.
    pub bottom: usize,
}

impl Halo {
    /// The same depth on every side: r = N / 2 is what a patch of N reads.
    #[must_use]
    pub fn uniform(depth: usize) -> Halo {
        Halo { left: depth, right: depth, top: depth, bottom: depth }
    }
}

/// Where a window lies in its image, and what is held around it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Window {
    /// The whole image's width and height. The relief gain
    /// ([`crate::Strength::Relief`]) is the whole image's, never the
    /// window's.
    pub image: (usize, usize),
    /// The window's first column and row in the image.
    pub origin: (usize, usize),
    /// The window's width and height: the texels to compute.
    pub size: (usize, usize),
    /// The texels held around the window.
    pub halo: Halo,
}

impl Window {
    /// Columns and rows of the heights held: the window and its halo.
    #[must_use]
    pub fn held_size(&self) -> (usize, usize) {
        let Halo { left, right, top, bottom } = self.halo;
        (left + self.size.0 + right, top + self.size.1 + bottom)
    }

    /// Image columns (x) and rows (y) of the heights held; before 0 or
    /// from the image's size on, beyond its edges.
    fn held(&self) -> (Range<isize>, Range<isize>) {
        let (w, h) = self.held_size();
        let x0 = self.origin.0 as isize - self.halo.left as isize;
        let y0 = self.origin.1 as isize - self.halo.top as isize;
        (x0..x0 + w as isize, y0..y0 + h as isize)
    }
}

/// The normals of `window`, as [`crate::normals_into`] gives them for those
/// texels of the whole image, bit for bit, in any texel type.
///
/// `heights` holds the window and its halo, row-major:
/// [`Window::held_size`] columns and rows, from image column
/// `origin.0 − halo.left` and row `origin.1 − halo.top`. Texels of the halo
/// beyond the image's edge hold what the border gives there (what Dask's
/// `periodic` boundary gives for wrap, `nearest` for clamp); or the halo
/// stops at the edge, and each border maps the patches' reads beyond it
/// into the texels held (enough for clamp and mirror once the window and
/// its halo reach r texels into the image). A halo of r = N / 2 on every
/// side where the image goes on always suffices.
///
/// ```
/// use normalfit::fit::{Halo, Window, window_normals_into};
/// use normalfit::{normals, Options};
///
/// let (w, h) = (20, 12);
/// let heights: Vec<f32> = (0..w * h).map(|k| ((k % w) as f32 * 0.4).sin() * (k / w) as f32).collect();
/// let opts = Options::new().with_patch(5); // wrap on both axes
/// let whole = normals(&heights, w, h, &opts)?;
/// // Columns 8..13 of rows 4..7, with r = 2 texels around them.
/// let window = Window { image: (w, h), origin: (8, 4), size: (5, 3), halo: Halo::uniform(2) };
/// let image = &heights;
/// let held: Vec<f32> = (2..9).flat_map(|y| (6..15).map(move |x| image[y * w + x])).collect();
/// let mut out = vec![[0.0f32; 3]; 5 * 3];
/// window_normals_into(&held, &window, &opts, &mut out)?;
/// assert_eq!(out[0], whole[4 * w + 8]);
/// # Ok::<(), normalfit::Error>(())
/// ```
///
/// Errors: [`Error::InvalidOption`] for invalid options, a window that is
/// empty or outside the image, or a halo that lacks a texel the patches
/// read (naming it); [`Error::BufferSize`] for buffers of the wrong
/// length; [`Error::NonFiniteHeight`] for a NaN or infinite height held
/// (at its image texel).
pub fn window_normals_into<H: Sample, T: FromNormal>(
    heights: &[H],
    window: &Window,
    opts: &Options,
    out: &mut [T],
) -> Result<()> {
    fit_window(heights, window, opts, out, None)
}

/// Like [`window_normals_into`], and the fit's residual as
/// [`crate::normals_and_residual_into`] gives it.
///
/// Errors: as [`window_normals_into`]; [`Error::BufferSize`] also for a
/// `residual` of the wrong length.
pub fn window_normals_and_residual_into<H: Sample, T: FromNormal>(
    heights: &[H],
    window: &Window,
    opts: &Options,
    out: &mut [T],
    residual: &mut [f32],
) -> Result<()> {
    fit_window(heights, window, opts, out, Some(residual))
}

fn fit_window<H: Sample, T: FromNormal>(
    heights: &[H],
    window: &Window,
    opts: &Options,
    out: &mut [T],
    residual: Option<&mut [f32]>,
) -> Result<()> {
    let (iw, ih) = window.image;
    let plan = Plan::new(iw, ih, opts)?;
    let ((ox, oy), (w, h)) = (window.origin, window.size);
    checked_len(w, h)?;
    if ox + w > iw || oy + h > ih {
        return Err(Error::InvalidOption(format!(
            "window of {w}×{h} at ({ox}, {oy}) is not inside the {iw}×{ih} image"
        )));
    }
    let (hw, hh) = window.held_size();
    let expected = [hw * hh, w * h, w * h];
    let actual = [Some(heights.len()), Some(out.len()), residual.as_ref().map(|r| r.len())];
    for (expected, actual) in expected.into_iter().zip(actual) {
        if let Some(actual) = actual
            && actual != expected
        {
            return Err(Error::BufferSize { expected, actual });
        }
    }
    let (held_x, held_y) = window.held();
    let r = plan.r as isize;
    let reads = |axis: &str, first: usize, len: usize, held: &Range<isize>, map: &dyn Fn(isize) -> usize| {
        let wanted = first as isize - r..(first + len) as isize + r;
        match wanted.clone().find(|&u| !held.contains(&u) && !held.contains(&(map(u) as isize))) {
            Some(u) => Err(Error::InvalidOption(format!(
                "the window's patches read {axis} {u}, which the heights held ({axis}s {} to {}) lack: hold a halo of \
                 {r} beyond the window wherever the image goes on",
                held.start,
                held.end - 1
            ))),
            None => Ok(()),
        }
    };
    reads("column", ox, w, &held_x, &|u| plan.borders.x.map(u, iw))?;
    reads("row", oy, h, &held_y, &|v| plan.borders.y.map(v, ih))?;
    if let Some((x, y)) = first_non_finite(heights, hw) {
        let x = plan.borders.x.map(held_x.start + x as isize, iw);
        let y = plan.borders.y.map(held_y.start + y as isize, ih);
        return Err(Error::NonFiniteHeight { x, y });
    }
    let rows = |v: isize| {
        let at = if held_y.contains(&v) { v } else { plan.borders.y.map(v, ih) as isize };
        RowRef { values: &heights[(at - held_y.start) as usize * hw..][..hw], x0: held_x.start, holes: false }
    };
    plan.fit_rows(&rows, H::UNIT, (oy, ox..ox + w), out, residual, None);
    Ok(())
}
