//! One fit request: the fit's one way in for heights held in memory.

use super::{FromNormal, Plan, RowRef, Texel, Window, checked_len, detail, row_has_hole};
use crate::error::{Error, Result};
use crate::options::{Borders, Options};
use crate::samples::{Sample, Samples, first_non_finite, try_filled, try_vec, with_slice};

/// A fit of heights held in memory: [`Options`], and what else the caller
/// asks for, then [`normals_into`](Self::normals_into) runs it.
///
/// * the whole image, or a [`window`](Self::window) of a larger one from
///   its heights and a halo (a Dask chunk), the whole image's bits;
/// * the fit's [`residual`](Self::residual);
/// * holes: texels whose value is [`Options::nodata`], or NaN or infinite
///   with [`holes`](Self::holes), are missing, and the texels that say
///   which are; a missing texel's normal is [`missing`](Self::missing);
/// * the normals in any texel type ([`FromNormal`]: the normal itself, or
///   the contract's 8- or 16-bit RGB), from heights of any sample type
///   ([`Heights`]).
///
/// Rows are computed in parallel on rayon's current pool; the bits are
/// the same on any pool, in any window, and from any sample type that
/// holds the same heights.
///
/// ```
/// use normalfit::{FitRequest, Options};
///
/// // A ramp of 16-bit samples: heights v / 65535.
/// let (w, h) = (16, 12);
/// let heights: Vec<u16> = (0..w * h).map(|k| (k % w) as u16 * 1000).collect();
/// let mut rgb = vec![[0u8; 3]; w * h];
/// FitRequest::new(&Options::new()).normals_into(&heights, w, h, &mut rgb)?;
/// assert!(rgb[5 * w + 7][0] < 128, "the normal leans towards −x");
/// # Ok::<(), normalfit::Error>(())
/// ```
#[must_use = "a request does nothing until `normals_into` runs it"]
pub struct FitRequest<'a> {
    opts: &'a Options,
    borders: Option<Borders>,
    window: Option<Window>,
    residual: Option<&'a mut [f32]>,
    valid: Option<&'a mut [bool]>,
    missing: [f64; 3],
    /// The raster's axes on the map, for an aspect ([`Self::on_map`]).
    axes: super::MapAxes,
    /// The lamp of a lit view ([`Self::lit`]).
    lamp: Option<super::Lamp>,
}

impl<'a> FitRequest<'a> {
    /// A fit with these options, of the whole image, normals only; holes
    /// only where [`Options::nodata`] is set.
    pub fn new(opts: &'a Options) -> FitRequest<'a> {
        FitRequest {
            opts,
            borders: None,
            window: None,
            residual: None,
            valid: None,
            missing: [0.0, 0.0, 1.0],
            axes: super::MapAxes::NORTH_UP,
            lamp: None,
        }
    }

    /// Fits with these borders instead of the options' (a border settled
    /// after the options were made: `auto`'s tiling check).
    pub fn borders(mut self, borders: Borders) -> FitRequest<'a> {
        self.borders = Some(borders);
        self
    }

    /// The heights are `window` of a larger image and the halo held around
    /// it ([`Window`] says how they are laid out; [`HaloPlan`](super::HaloPlan)
    /// plans a halo that suffices), and the outputs are the window's
    /// texels: those the whole image's fit gives there, bit for bit.
    ///
    /// ```
    /// use normalfit::fit::{HaloPlan, FitRequest};
    /// use normalfit::{normals, Options};
    ///
    /// let (w, h) = (20, 12);
    /// let heights: Vec<f32> = (0..w * h).map(|k| ((k % w) as f32 * 0.4).sin() * (k / w) as f32).collect();
    /// let opts = Options::new().with_patch(5); // wrap on both axes
    /// let whole = normals(&heights, w, h, &opts)?;
    /// // Columns 8..13 of rows 4..7, with r = 2 texels around them.
    /// let window = HaloPlan::new(&opts)?.window((w, h), (8, 4), (5, 3));
    /// let (hw, hh) = window.held_size();
    /// let image = &heights;
    /// let held: Vec<f32> = (2..9).flat_map(|y| (6..15).map(move |x| image[y * w + x])).collect();
    /// let mut out = vec![[0.0f32; 3]; 5 * 3];
    /// FitRequest::new(&opts).window(window).normals_into(&held, hw, hh, &mut out)?;
    /// assert_eq!(out[0], whole[4 * w + 8]);
    /// # Ok::<(), normalfit::Error>(())
    /// ```
    pub fn window(mut self, window: Window) -> FitRequest<'a> {
        self.window = Some(window);
        self
    }

    /// Also the fit's residual, into `residual` (as many texels as the
    /// normals): the root-mean-square distance of each texel's N² patch
    /// points from the plane fitted to them, in texel widths (the units
    /// of the surface z = S · h, so it grows with the gain S); NaN where a
    /// texel is missing.
    ///
    /// The distance is the one the fit minimises: perpendicular to the
    /// plane for [`Fit::Orthogonal`](crate::Fit::Orthogonal) (√(λ / N²), λ
    /// the covariance's smallest eigenvalue), vertical for
    /// [`Fit::Vertical`](crate::Fit::Vertical). A planar patch gives 0;
    /// bumps, pits and grain finer than the patch give more, so the map is
    /// a hint of cavities and roughness at the patch's scale. Where the
    /// normal is the flat (0, 0, 1) of a tilt-free patch, the residual is
    /// the points' distance from that horizontal plane. It comes from the
    /// sums the fit already has, at the cost of a few operations per texel.
    ///
    /// ```
    /// use normalfit::{FitRequest, Options};
    /// // A plane plus a checkerboard of amplitude 0.1: the plane is found, and
    /// // the points lie about 0.1 from it (exactly 0.1 · √(1 − 1/N⁴), N = 3).
    /// let (w, h) = (16, 16);
    /// let heights: Vec<f32> = (0..w * h)
    ///     .map(|k| 0.01 * (k % w) as f32 + if (k % w + k / w) % 2 == 0 { 0.1 } else { -0.1 })
    ///     .collect();
    /// let opts = Options::new().with_fit(normalfit::Fit::Vertical)
    ///     .with_borders(normalfit::Borders::both(normalfit::Border::Mirror));
    /// let mut normals = vec![[0.0f32; 3]; w * h];
    /// let mut residual = vec![0.0f32; w * h];
    /// FitRequest::new(&opts).residual(&mut residual).normals_into(&heights, w, h, &mut normals)?;
    /// let expected = 0.1 * (1.0f32 - 1.0 / 81.0).sqrt();
    /// assert!((residual[5 * w + 7] - expected).abs() < 1e-5);
    /// # Ok::<(), normalfit::Error>(())
    /// ```
    pub fn residual(mut self, residual: &'a mut [f32]) -> FitRequest<'a> {
        self.residual = Some(residual);
        self
    }

    /// Holes, reported: texels whose value is `opts.nodata`, and
    /// non-finite ones (whether or not a nodata value is set), are
    /// missing, and each patch is fitted to its valid points alone.
    /// `valid[k]` (as many texels as the normals) is set to whether texel
    /// k has a normal: it is missing when it is itself a hole, or when its
    /// patch's valid points are fewer than three or collinear. A patch
    /// without a hole gives the same bits as without holes.
    ///
    /// Without this call, a fit has holes only when `opts.nodata` is set
    /// (non-finite heights are then holes too), and a NaN or infinite
    /// height is otherwise [`Error::NonFiniteHeight`].
    ///
    /// ```
    /// use normalfit::{FitRequest, Options};
    /// let (w, h) = (6, 5);
    /// let mut heights: Vec<f32> = (0..w * h).map(|k| 0.1 * (k % w) as f32).collect();
    /// heights[2 * w + 3] = f32::NAN;
    /// let mut normals = vec![[0.0f32; 3]; w * h];
    /// let mut valid = vec![false; w * h];
    /// let missing = FitRequest::new(&Options::new()).holes(&mut valid).normals_into(&heights, w, h, &mut normals)?;
    /// assert_eq!(missing, 1);
    /// assert!(!valid[2 * w + 3] && valid[2 * w + 2]);
    /// # Ok::<(), normalfit::Error>(())
    /// ```
    pub fn holes(mut self, valid: &'a mut [bool]) -> FitRequest<'a> {
        self.valid = Some(valid);
        self
    }

    /// The normal written at a missing texel, through the output's
    /// [`FromNormal`]; by default (0, 0, 1), flat. `[f64::NAN; 3]` makes
    /// a float output NaN there (the Python package's missing texels);
    /// integer texels have no NaN.
    pub fn missing(mut self, normal: [f64; 3]) -> FitRequest<'a> {
        self.missing = normal;
        self
    }

    /// The texels are made on a raster placed on the map by `affine` (its
    /// GDAL geotransform; `None`: north-up): an aspect's axes
    /// ([`super::TexelFrame`]).
    pub(crate) fn on_map(mut self, affine: Option<&crate::io::Affine>) -> FitRequest<'a> {
        self.axes = super::MapAxes::of(affine);
        self
    }

    /// The texels are lit by `lamp` (a hillshade's greys).
    pub(crate) fn lit(mut self, lamp: super::Lamp) -> FitRequest<'a> {
        self.lamp = Some(lamp);
        self
    }

    /// The options' convention: how a caller of the normals reads their y.
    /// The output's width and height for heights of `width` × `height`:
    /// the window's size, or theirs.
    pub(crate) fn output_size(&self, width: usize, height: usize) -> (usize, usize) {
        self.window.map_or((width, height), |w| w.size)
    }

    /// The output's width (see [`Self::output_size`]).
    pub(crate) fn output_width(&self, width: usize) -> usize {
        self.output_size(width, 0).0
    }

    pub(crate) fn convention(&self) -> crate::options::Convention {
        self.opts.convention
    }

    /// Runs the fit of `heights` (`width` × `height`, row-major, any
    /// [`Heights`]: a slice of a [`Sample`] type or [`Samples`]) into
    /// `out`, in any texel type: `[f32; 3]` for the normal itself,
    /// `[u8; 3]` or `[u16; 3]` for the encoded RGB of the contract. The
    /// heights are the whole image, `out` as many texels; with a
    /// [`window`](Self::window), they are the window's held texels
    /// ([`Window::held_size`]), `out` the window's.
    ///
    /// `f32` and `f64` heights are in the contract's units, `u8` and `u16`
    /// stored integer values whose heights are v / 255 and v / 65535 (SPEC
    /// §1): integers are read as they are and 1 / (2^bits − 1) goes into
    /// the gain, in f64, so no rounding comes between the file and the fit.
    ///
    /// Returns the count of missing texels (0 without holes).
    ///
    /// Errors: [`Error::InvalidOption`] for invalid options or a zero or
    /// too large size, a window that is empty, outside its image or not
    /// the heights' layout, or a halo that lacks a texel the patches read
    /// (naming it); [`Error::BufferSize`] for a buffer of the wrong length
    /// (heights, `out`, the residual, `valid`); without holes,
    /// [`Error::NonFiniteHeight`] for the first NaN or infinite height in
    /// row order (at its image texel); [`Error::Limits`] when the fit's
    /// sums (which grow with N: a strip holds up to 2N rows of them, on
    /// every thread) do not fit in the memory the process may still take
    /// under its limits (`ulimit -v`; see [`check_memory`](crate::io::check_memory)).
    pub fn normals_into<S: Heights + ?Sized, T: FromNormal>(
        self,
        heights: &S,
        width: usize,
        height: usize,
        out: &mut [T],
    ) -> Result<usize> {
        self.texels_into(heights, (width, height), out)
    }

    /// [`Self::normals_into`] for any texel the crate makes ([`Texel`]).
    pub(crate) fn texels_into<S: Heights + ?Sized, T: Texel>(
        self,
        heights: &S,
        (width, height): (usize, usize),
        out: &mut [T],
    ) -> Result<usize> {
        heights.fit(self, (width, height), out)
    }

    /// [`Self::normals_into`] a band of output rows at a time: `each` gets
    /// the band's first output row, its normals and (with holes) which of
    /// them are valid, in order from the top. For a caller that turns
    /// normals into something else (a slope map) and need not hold them
    /// all: the normals of about [`BAND_TEXELS`] texels at once. Holes as
    /// [`Self::holes`] makes them (NaN and infinite heights, and the
    /// options' nodata, are missing texels); the same bits as the whole
    /// request gives; no residual, and the request's own `valid` (if any)
    /// is not written. Returns the count of missing texels.
    pub(crate) fn normals_in_bands<S: Heights + ?Sized, T: Texel>(
        self,
        heights: &S,
        (width, height): (usize, usize),
        each: &mut EachBand<'_, T>,
    ) -> Result<usize> {
        heights.fit_bands(self, (width, height), each)
    }

    /// [`Self::normals_into`] for a slice of one sample type, into `sink`.
    fn run<H: Sample, T: Texel>(
        self,
        heights: &[H],
        (width, height): (usize, usize),
        sink: Sink<'_, T>,
    ) -> Result<usize> {
        let FitRequest { opts, borders, window, residual, valid, missing, axes, lamp } = self;
        let image = window.map_or((width, height), |w| w.image);
        let mut plan = Plan::new(image.0, image.1, opts)?;
        if let Some(borders) = borders {
            plan.borders = borders;
        }
        plan.missing = missing;
        plan.frame.axes = axes;
        if let Some(lamp) = lamp {
            plan.frame.lamp = lamp;
        }
        if !plan.detail.is_empty() && residual.is_some() {
            return Err(Error::InvalidOption(DETAIL_RESIDUAL.into()));
        }
        if plan.weights != crate::options::Weights::Uniform && residual.is_some() {
            return Err(Error::InvalidOption(WEIGHTED_RESIDUAL.into()));
        }
        // The image columns and rows the heights hold, and the texels out.
        let (held_x, held_y, (ox, oy), (ow, oh)) = match &window {
            None => (0..width as isize, 0..height as isize, (0, 0), (width, height)),
            Some(window) => {
                window.check_place((width, height))?;
                let (held_x, held_y) = window.held();
                (held_x, held_y, window.origin, window.size)
            }
        };
        let (held_len, out_len) = (checked_len(width, height)?, ow * oh);
        // In bands the caller's `valid` is not written, nor a residual made.
        let (residual, valid) = match sink {
            Sink::Whole(_) => (residual, valid),
            Sink::Bands(_) => (None, None),
        };
        let out_given = match &sink {
            Sink::Whole(out) => Some(out.len()),
            Sink::Bands(_) => None,
        };
        let expected = [held_len, out_len, out_len, out_len];
        let actual =
            [Some(heights.len()), out_given, residual.as_ref().map(|r| r.len()), valid.as_ref().map(|v| v.len())];
        for (expected, actual) in expected.into_iter().zip(actual) {
            if let Some(actual) = actual
                && actual != expected
            {
                return Err(Error::BufferSize { expected, actual });
            }
        }
        if let Some(window) = &window {
            window.check_reads(&plan)?;
        }
        // Bands are fitted with holes, as `holes` asks: NaN and infinite
        // heights are missing texels, not an error.
        let masked = plan.nodata.is_some() || valid.is_some() || matches!(sink, Sink::Bands(_));
        if !masked && let Some((x, y)) = first_non_finite(heights, width) {
            let x = plan.borders.x.map(held_x.start + x as isize, image.0);
            let y = plan.borders.y.map(held_y.start + y as isize, image.1);
            return Err(Error::NonFiniteHeight { x, y });
        }
        // The memory rule, before the fit allocates: its sums grow with N.
        let band_rows = match sink {
            Sink::Whole(_) => oh,
            Sink::Bands(_) => (BAND_TEXELS / ow.max(1)).clamp(1, oh),
        };
        let work = detail::work_bytes(&plan, H::UNIT, (ow, band_rows), masked, residual.is_some());
        let band_normals = match sink {
            Sink::Whole(_) => 0,
            Sink::Bands(_) => (band_rows * ow * std::mem::size_of::<T>()) as u64,
        };
        let own_valid = if masked && valid.is_none() { (band_rows * ow) as u64 } else { 0 };
        let hole_rows = if masked { height as u64 } else { 0 };
        crate::memory::check_memory("fitting the normals", work + own_valid + hole_rows + band_normals)?;
        let nodata = plan.nodata.unwrap_or(f64::NAN);
        let holes: Vec<bool> = if masked {
            let mut holes = try_vec(height)?;
            holes.extend(heights.chunks_exact(width).map(|row| row_has_hole(row, nodata)));
            holes
        } else {
            Vec::new()
        };
        // Source row v of the patches: a row held, or (beyond the rows held)
        // the one the y border gives.
        let rows = |v: isize| {
            let at = if held_y.contains(&v) { v } else { plan.borders.y.map(v, image.1) as isize };
            let k = (at - held_y.start) as usize;
            RowRef { values: &heights[k * width..][..width], x0: held_x.start, holes: masked && holes[k] }
        };
        let cols = ox..ox + ow;
        let each = match sink {
            Sink::Whole(out) => {
                if !masked {
                    detail::fit_rows(&plan, &rows, H::UNIT, (oy, cols), out, residual, None);
                    return Ok(0);
                }
                let mut own = if valid.is_none() { try_filled(out_len, false)? } else { Vec::new() };
                let valid = match valid {
                    Some(valid) => valid,
                    None => &mut own[..],
                };
                detail::fit_rows(&plan, &rows, H::UNIT, (oy, cols), out, residual, Some((&mut *valid, nodata)));
                return Ok(valid.iter().filter(|&&v| !v).count());
            }
            Sink::Bands(each) => each,
        };
        let mut normals = try_filled(band_rows * ow, T::make([0.0, 0.0, 1.0], &plan.frame))?;
        let mut valid = if masked { try_filled(band_rows * ow, false)? } else { Vec::new() };
        let mut missing = 0;
        for first in (0..oh).step_by(band_rows) {
            let texels = (band_rows.min(oh - first)) * ow;
            let (normals, valid) = (&mut normals[..texels], valid.get_mut(..texels));
            let place = (oy + first, cols.clone());
            match valid {
                Some(valid) => {
                    detail::fit_rows(&plan, &rows, H::UNIT, place, normals, None, Some((&mut *valid, nodata)));
                    missing += valid.iter().filter(|&&v| !v).count();
                    each(first, normals, Some(valid));
                }
                None => {
                    detail::fit_rows(&plan, &rows, H::UNIT, place, normals, None, None);
                    each(first, normals, None);
                }
            }
        }
        Ok(missing)
    }
}

/// About how many texels' normals [`FitRequest::normals_in_bands`] holds
/// at once: a few megabytes, enough rows for every thread.
pub(crate) const BAND_TEXELS: usize = 1 << 19;

/// What takes [`FitRequest::normals_in_bands`]'s bands: the band's first
/// output row, its normals and (with holes) which of them are valid.
#[doc(hidden)]
pub type EachBand<'a, T> = dyn FnMut(usize, &[T], Option<&[bool]>) + 'a;

/// Where [`FitRequest::run`] puts the normals: the caller's buffer for the
/// whole output, or bands handed to a consumer in turn.
enum Sink<'s, T> {
    Whole(&'s mut [T]),
    Bands(&'s mut EachBand<'s, T>),
}

/// Why a residual is refused with weights.
pub(crate) const WEIGHTED_RESIDUAL: &str = "a residual is the unweighted fit's RMS distance: with binomial weights it is not defined yet (use uniform weights)";

/// Why a residual is refused with detail at several scales.
pub(crate) const DETAIL_RESIDUAL: &str =
    "detail at several scales has no residual (a residual is one patch size's): ask for it with one patch size";

/// The bytes a fit of a whole `width` × `height` image, of samples whose
/// height is value × `unit` ([`Sample::UNIT`]), allocates beyond its
/// heights and the caller's outputs (normals, residual, validity): what
/// [`FitRequest::normals_into`] checks against the memory rule, for a
/// caller that checks it up front with its own buffers (the engine).
///
/// Errors: those of the options and the size.
pub(crate) fn work_bytes(
    opts: &Options,
    (width, height): (usize, usize),
    unit: f64,
    holes: bool,
    residual: bool,
) -> Result<u64> {
    let plan = Plan::new(width, height, opts)?;
    let holes = holes || plan.nodata.is_some();
    let hole_rows = if holes { height as u64 } else { 0 };
    Ok(detail::work_bytes(&plan, unit, (width, height), holes, residual).saturating_add(hole_rows))
}

mod sealed {
    /// Only the crate's height types are [`Heights`](super::Heights).
    pub trait Sealed {}
}

/// Heights the fit reads as they are stored: a slice, `Vec` or array of a
/// [`Sample`] type (`u8`, `u16`, `f32`, `f64`), or [`Samples`] (whichever
/// type they hold).
pub trait Heights: sealed::Sealed {
    /// Runs `request` on these heights (what
    /// [`FitRequest::normals_into`] calls).
    #[doc(hidden)]
    fn fit<T: Texel>(&self, request: FitRequest<'_>, size: (usize, usize), out: &mut [T]) -> Result<usize>;

    /// Runs `request` a band at a time (what
    /// `FitRequest::normals_in_bands` calls).
    #[doc(hidden)]
    fn fit_bands<T: Texel>(
        &self,
        request: FitRequest<'_>,
        size: (usize, usize),
        each: &mut EachBand<'_, T>,
    ) -> Result<usize>;
}

impl<H: Sample> sealed::Sealed for [H] {}

impl<H: Sample> Heights for [H] {
    fn fit<T: Texel>(&self, request: FitRequest<'_>, size: (usize, usize), out: &mut [T]) -> Result<usize> {
        request.run(self, size, Sink::Whole(out))
    }

    fn fit_bands<T: Texel>(
        &self,
        request: FitRequest<'_>,
        size: (usize, usize),
        each: &mut EachBand<'_, T>,
    ) -> Result<usize> {
        request.run(self, size, Sink::Bands(each))
    }
}

impl<H: Sample> sealed::Sealed for Vec<H> {}

impl<H: Sample> Heights for Vec<H> {
    fn fit<T: Texel>(&self, request: FitRequest<'_>, size: (usize, usize), out: &mut [T]) -> Result<usize> {
        self.as_slice().fit(request, size, out)
    }

    fn fit_bands<T: Texel>(
        &self,
        request: FitRequest<'_>,
        size: (usize, usize),
        each: &mut EachBand<'_, T>,
    ) -> Result<usize> {
        self.as_slice().fit_bands(request, size, each)
    }
}

impl<H: Sample, const N: usize> sealed::Sealed for [H; N] {}

impl<H: Sample, const N: usize> Heights for [H; N] {
    fn fit<T: Texel>(&self, request: FitRequest<'_>, size: (usize, usize), out: &mut [T]) -> Result<usize> {
        self.as_slice().fit(request, size, out)
    }

    fn fit_bands<T: Texel>(
        &self,
        request: FitRequest<'_>,
        size: (usize, usize),
        each: &mut EachBand<'_, T>,
    ) -> Result<usize> {
        self.as_slice().fit_bands(request, size, each)
    }
}

impl sealed::Sealed for Samples {}

impl Heights for Samples {
    fn fit<T: Texel>(&self, request: FitRequest<'_>, size: (usize, usize), out: &mut [T]) -> Result<usize> {
        with_slice!(self, s => s.fit(request, size, out))
    }

    fn fit_bands<T: Texel>(
        &self,
        request: FitRequest<'_>,
        size: (usize, usize),
        each: &mut EachBand<'_, T>,
    ) -> Result<usize> {
        with_slice!(self, s => s.fit_bands(request, size, each))
    }
}
