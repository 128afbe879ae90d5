//! Windows of a larger image: a chunk of a Dask array, a tile of a raster
//! too large for one machine's memory. Any partition of an image into
//! windows gives exactly the whole image's output, bit for bit, because
//! the fit makes every texel's sums from its own patch alone, in an order
//! fixed by the image (see the [module docs](super)): a window needs only
//! its heights and a halo of r = N / 2 texels around them, or with
//! binomial weights summed by blocks (`convolve`), the whole blocks'
//! inputs, which [`HaloPlan`] says side by side. [`FitRequest::window`](super::FitRequest::window)
//! fits one.

use std::ops::Range;

use super::convolve::{Layout, block_len};
use super::{Plan, checked_len};
use crate::error::{Error, Result};
use crate::options::{Border, Borders, Options};

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
///
/// `heights` of a windowed fit hold the window and its halo, row-major:
/// [`Window::held_size`] columns and rows, from image column
/// `origin.0 − halo.left` and row `origin.1 − halo.top`. Texels of the halo
/// beyond the image's edge hold what the border gives there (what Dask's
/// `periodic` boundary gives for wrap, `nearest` for clamp); or the halo
/// stops at the edge, and each border maps the patches' reads beyond it
/// into the texels held (enough for clamp and mirror once the window and
/// its halo reach r texels into the image). [`HaloPlan::window`] gives a
/// halo that always suffices.
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
    pub(super) fn held(&self) -> (Range<isize>, Range<isize>) {
        let (w, h) = self.held_size();
        let x0 = self.origin.0 as isize - self.halo.left as isize;
        let y0 = self.origin.1 as isize - self.halo.top as isize;
        (x0..x0 + w as isize, y0..y0 + h as isize)
    }

    /// Refuses a window that is empty or outside its image, or heights of
    /// `held` columns and rows that are not its held size.
    pub(super) fn check_place(&self, held: (usize, usize)) -> Result<()> {
        let ((iw, ih), (ox, oy), (w, h)) = (self.image, self.origin, self.size);
        checked_len(w, h)?;
        if ox + w > iw || oy + h > ih {
            return Err(Error::InvalidOption(format!(
                "window of {w}×{h} at ({ox}, {oy}) is not inside the {iw}×{ih} image"
            )));
        }
        let (hw, hh) = self.held_size();
        if held != (hw, hh) {
            return Err(Error::InvalidOption(format!(
                "heights of {}×{} are not the window's {hw}×{hh} held texels (its size and halo)",
                held.0, held.1
            )));
        }
        Ok(())
    }

    /// Refuses a halo that lacks a texel the window's patches read (with
    /// sums by blocks, a texel its blocks read), naming it.
    pub(super) fn check_reads(&self, plan: &Plan) -> Result<()> {
        let borders = plan.borders;
        let (held_x, held_y) = self.held();
        let r = plan.r;
        let layouts = plan.blocks.as_ref().map(|b| (Layout { len: b.len, first: 0 }, Layout { len: b.len, first: r }));
        let reads = |axis: &str, first: usize, len: usize, held: &Range<isize>, border: Border, n: usize, blocks| {
            let (lo, hi) = match blocks {
                Some(layout) if len > 0 => Layout::cover(&layout, first..first + len, n),
                _ => (first, first + len),
            };
            let wanted = lo as isize - r as isize..(hi + r) as isize;
            let (before, after) = (first - lo + r, hi - first - len + r);
            match wanted.clone().find(|&u| !held.contains(&u) && !held.contains(&(border.map(u, n) as isize))) {
                Some(u) => Err(Error::InvalidOption(format!(
                    "the window's patches read {axis} {u}, which the heights held ({axis}s {} to {}) lack: hold a \
                     halo of {before} before the window and {after} after it wherever the image goes on \
                     (HaloPlan plans it)",
                    held.start,
                    held.end - 1
                ))),
                None => Ok(()),
            }
        };
        reads("column", self.origin.0, self.size.0, &held_x, borders.x, self.image.0, layouts.map(|l| l.0))?;
        reads("row", self.origin.1, self.size.1, &held_y, borders.y, self.image.1, layouts.map(|l| l.1))
    }
}

/// The halo a window of an image needs for given options, planned without
/// a fit: a patch of N reads r = N / 2 texels on each side of its centre,
/// and each axis's border says what a window at the image's edge holds
/// beyond it.
///
/// * Wrap: r texels on each side; beyond the image's edge they hold the
///   far side's (Dask's `periodic` boundary).
/// * Clamp and mirror: r texels where the image goes on (as many as there
///   are up to the edge), none beyond it: the fit maps the reads beyond
///   the edge into the texels held (Dask's boundary `none`).
/// * None on an axis the window spans whole: every read maps into it.
///
/// With binomial weights from N = 37 on the sums are made by FFT in blocks
/// aligned on the image (`convolve`): a window's halo then holds its blocks'
/// inputs, r texels beyond the blocks that hold its first and last
/// texels, up to [`Self::reach`] = r + B − 1 on a side (B, the block,
/// from N alone; along y the top r rows are a block of their own and the
/// rest are cut from row r). A window whose halo lacks one of those
/// inputs is refused, never fitted with other bits.
///
/// ```
/// use normalfit::fit::{Halo, HaloPlan};
/// use normalfit::{Border, Borders, Options};
///
/// let opts = Options::new().with_patch(7).with_borders(Borders { x: Border::Wrap, y: Border::Mirror });
/// let plan = HaloPlan::new(&opts)?;
/// assert_eq!(plan.radius(), 3);
/// assert_eq!(plan.beyond_edges(), (true, false));
/// // Columns 0..10, rows 0..10 of a 100 × 40 image: wrap holds 3 columns
/// // left of column 0, mirror no row above row 0.
/// let window = plan.window((100, 40), (0, 0), (10, 10));
/// assert_eq!(window.halo, Halo { left: 3, right: 3, top: 0, bottom: 3 });
/// // A window of every row: no rows around it.
/// assert_eq!(plan.halo((100, 40), (50, 0), (10, 40)), Halo { left: 3, right: 3, top: 0, bottom: 0 });
/// # Ok::<(), normalfit::Error>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct HaloPlan {
    radius: usize,
    borders: Borders,
    /// The block length B of sums by blocks, or `None`.
    block: Option<usize>,
}

impl HaloPlan {
    /// The plan for `opts` (its patch size and borders), checking the
    /// options as the fit does.
    ///
    /// Errors: [`Error::InvalidOption`] for invalid options.
    pub fn new(opts: &Options) -> Result<HaloPlan> {
        opts.validate()?;
        let n = opts.largest_patch();
        Ok(HaloPlan { radius: n / 2, borders: opts.borders, block: block_len(opts.weights, n) })
    }

    /// The same plan with these borders instead of the options' (as
    /// [`FitRequest::borders`](super::FitRequest::borders)).
    #[must_use]
    pub fn with_borders(self, borders: Borders) -> HaloPlan {
        HaloPlan { borders, ..self }
    }

    /// r = N / 2: the texels a patch reads on each side of its centre,
    /// the most a halo holds on a side.
    #[must_use]
    pub fn radius(&self) -> usize {
        self.radius
    }

    /// The most a halo holds on a side: r, or with sums by blocks of B
    /// (binomial weights from N = 37 on), r + B − 1. What a caller that
    /// holds one depth around every window (Dask's `map_overlap`) holds.
    #[must_use]
    pub fn reach(&self) -> usize {
        self.radius + self.block.map_or(0, |b| b - 1)
    }

    /// The borders planned for.
    #[must_use]
    pub fn borders(&self) -> Borders {
        self.borders
    }

    /// Whether a window at the image's edge holds a halo beyond it, along
    /// x and along y: with wrap, the r texels the wrap gives there; with
    /// clamp and mirror, none.
    #[must_use]
    pub fn beyond_edges(&self) -> (bool, bool) {
        (self.borders.x == Border::Wrap, self.borders.y == Border::Wrap)
    }

    /// The halo of the window of `size` texels at `origin` in an image of
    /// `image` texels (widths first), as the [type's docs](Self) say.
    #[must_use]
    pub fn halo(&self, image: (usize, usize), origin: (usize, usize), size: (usize, usize)) -> Halo {
        let (left, right) = self.axis(image.0, origin.0, size.0, self.borders.x, 0);
        let (top, bottom) = self.axis(image.1, origin.1, size.1, self.borders.y, self.radius);
        Halo { left, right, top, bottom }
    }

    /// The window of `size` texels at `origin` in an image of `image`
    /// texels, with [`Self::halo`].
    #[must_use]
    pub fn window(&self, image: (usize, usize), origin: (usize, usize), size: (usize, usize)) -> Window {
        Window { image, origin, size, halo: self.halo(image, origin, size) }
    }

    /// The halo before and after a run of `len` texels from `start` of an
    /// axis of `n` (with blocks, cut from `first` on).
    fn axis(&self, n: usize, start: usize, len: usize, border: Border, first: usize) -> (usize, usize) {
        let r = self.radius;
        let end = start.saturating_add(len);
        // With blocks, the reads reach r beyond the blocks that hold the
        // run's first and last texels.
        let (before, after) = match self.block {
            Some(len) if end > start && end <= n => {
                let (lo, hi) = Layout { len, first }.cover(start..end, n);
                (start - lo + r, hi - end + r)
            }
            _ => (r, r),
        };
        if start == 0 && end >= n {
            (0, 0)
        } else if border == Border::Wrap {
            (before, after)
        } else {
            (before.min(start), after.min(n.saturating_sub(end)))
        }
    }
}
