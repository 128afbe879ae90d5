//! Normal map → height: the exact inverse of the fit.
//!
//! [`heights`] finds the heights whose fitted normals (the same N, fit,
//! borders and gain as [`crate::normals`] takes) are closest, in least
//! squares, to a given normal map's slopes. For a normal map normalfit made
//! from float heights the round trip gives the heights back up to a
//! constant; for other maps it is the least-squares integration of their
//! slopes through the fit's own operator.
//!
//! # The math
//!
//! The fit of SPEC §2 gives, per texel, n ∝ (−Cx, −Cy, A) (vertical) or
//! (−Cx, −Cy, A − λ) (orthogonal), with Cx = Σ i·z and Cy = σ Σ j·z over
//! the N×N patch. So a normal map's slopes are
//!
//! ```text
//! gx = −nx / nz,   gy = −σ · ny / nz      (gy = ∂z/∂y, y down; σ = −1 OpenGL, +1 DirectX)
//! ```
//!
//! and for the vertical fit gx = Dx z = (1/A) Σ i·z(x+i, y+j), gy = Dy z =
//! (1/A) Σ j·z(x+i, y+j): a linear, separable filter. `solve.rs` solves
//! min ‖Dx z − gx‖² + ‖Dy z − gy‖² per frequency (wrap: the FFT; mirror:
//! the type-I cosine transform, as an FFT of the mirrored period; clamp
//! with N = 3: the type-II one), minimum-norm where the operator has a
//! null space. Clamp with N ≥ 5 has no transform: `iterative.rs` solves
//! it by conjugate gradients with the exact operator, from the mirror
//! solution. For mirror, the least squares are over one period of the
//! mirrored texture (its edge rows and columns count once, the others
//! twice), where the fit's operator is exactly periodic.
//!
//! The orthogonal fit's slopes are the vertical ones times A / (A − λ), λ
//! depending on the heights: from the vertical solution, each step solves
//! for the vertical slopes g · (A − λ(z)) / A, until those ratios stop
//! changing ([`HeightOptions::tolerance`]); changes that keep growing stop
//! the iteration with the best heights so far. Where it stopped so, or
//! settled with the fit's equation still off by more than the input's
//! precision (steep slopes, cliffs, or alternating heights that the
//! orthogonal fit sees through the patches' roughness and the vertical
//! fit does not), Gauss–Newton steps with the exact Jacobian finish it
//! (`gauss_newton.rs`), preconditioned by the vertical fit's transform
//! solve; [`HeightReport::converged`] says whether the heights settled.
//!
//! Heights come back as h = z / S, S the gain of the fit's
//! [`Options::strength`](crate::Options::strength) (with its `invert`,
//! [`HeightOptions::fit`]), with mean 0 over the image: `convert
//! -s S` then `height -s S` gives the heights back up to a constant.
//!
//! # Texels without a slope
//!
//! A texel whose nz ≤ 0 or whose components are not all finite has no
//! slope: it counts as flat (slope 0), and [`HeightReport::bad_texels`]
//! counts them.
//!
//! # Holes
//!
//! [`heights_with_holes`] takes a mask of holes (a DEM's nodata, as the
//! forward fit's holes): holes come back NaN, and the other heights are
//! the least-squares solution of the equations whose patches hold no
//! hole, where the map's normals are the full patch's fit (`holes.rs`):
//! of the solutions, the one whose extension over the holes has the
//! least fit energy of the map without holes, which sets each connected
//! piece's constant (a river's banks join as a smooth fill would) and the
//! modes near holes' edges that no kept equation sees; a texel that
//! no kept patch holds is undetermined, NaN too
//! ([`HeightReport::undetermined`]). Without a hole the inverse is the
//! one above, to the bit.
//!
//! # Quantisation
//!
//! Stored normals are rounded: [`HeightOptions::step`] is the step of a
//! stored component (2/255 for 8-bit, 2/65535 for 16-bit, 0 exact). The
//! slopes then carry noise of RMS q = step/√12 per component, and the
//! solve adds λ = q² / (P_x P_y) to every frequency's normal equation: a
//! frequency is damped only where even a mode carrying one texel² of
//! height would drown in that noise (about the exact zeros of the
//! response). [`HeightReport::quantisation_error`] is the RMS height error
//! the noise leaves, through the same solve.
//!
//! # The generic model
//!
//! [`Model::Generic`] is Frankot–Chellappa: the same solve with the ideal
//! derivative iω and no box, for normal maps that normalfit did not make
//! (baked, scanned) or whose N is unknown.

mod banded;
mod cost;
mod dense;
mod gauss_newton;
mod holes;
mod iterative;
mod line;
mod patch;
mod solve;

use crate::error::{Error, Number, Result};
use crate::options::{Border, Borders, Convention, Strength, named_values};
use crate::par::prelude::*;
use crate::samples::try_filled;

pub mod file;
mod memory;

/// Which operator the heights are fitted through.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Model {
    /// normalfit's own fit (its N, fit and borders): the exact inverse of
    /// a map normalfit made. The default.
    #[default]
    Exact,
    /// Frankot–Chellappa: the slopes integrated with the ideal derivative,
    /// for maps of unknown origin (baked, scanned, another tool's filter).
    Generic,
}

named_values!(Model, "model", { Exact => "exact", Generic => "generic" | "frankot-chellappa" | "fc" });

/// The normal map's green convention: as given, or chosen from the map.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ConventionChoice {
    /// Green up (OpenGL). The default.
    #[default]
    OpenGl,
    /// Green down (DirectX).
    DirectX,
    /// The convention whose slope field is more nearly integrable (less
    /// curl): a true slope field has none, and the wrong green sign gives it
    /// as much curl as it has slope variation.
    Auto,
}

named_values!(ConventionChoice, "convention", {
    OpenGl => "opengl" | "gl",
    DirectX => "directx" | "dx",
    Auto => "auto",
});

impl From<Convention> for ConventionChoice {
    fn from(c: Convention) -> Self {
        match c {
            Convention::OpenGl => ConventionChoice::OpenGl,
            Convention::DirectX => ConventionChoice::DirectX,
        }
    }
}

/// Everything [`heights`] needs besides the normals: the fit the normal
/// map was made with, and the solve's own options.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct HeightOptions {
    /// The fit the normal map was made with, as [`crate::normals`] takes
    /// it: its patch size N, fit, borders, green convention, gain and
    /// invert must be those of the map for the exact inverse, and heights
    /// come back in the units of its gain. Its units and nodata are not
    /// used ([`HeightOptions::from_fit`] leaves them out). Default: the
    /// fit's defaults (3×3, orthogonal, wrap, OpenGL, scale 1).
    pub fit: crate::Options,
    /// Choose the green convention from the map instead of taking
    /// `fit`'s: the one whose slope field is more nearly integrable
    /// ([`ConventionChoice::Auto`]). Default: false.
    pub auto_convention: bool,
    /// Exact inverse of the fit, or generic integration. Default: exact.
    pub model: Model,
    /// The step of a stored normal component (2/255 for 8-bit, 2/65535 for
    /// 16-bit, 0 for exact values: [`crate::normal_map::Storage::step`]).
    /// Default: 0.
    pub step: f64,
    /// λ added to every frequency's normal equation; `None`: from
    /// [`step`](Self::step) (q² / texels of the period, q = step/√12).
    /// Default: `None`.
    pub regularisation: Option<f64>,
    /// The orthogonal fit's (and clamp's) iterations at most. Default: 100.
    pub max_iterations: usize,
    /// The orthogonal fit stops when no texel's slope ratio A/(A − λ)
    /// changes by more than this, or than [`step`](Self::step) (the input
    /// knows its slopes no better). Default: 1e-10.
    pub tolerance: f64,
}

impl Default for HeightOptions {
    fn default() -> Self {
        HeightOptions::new()
    }
}

impl HeightOptions {
    /// The defaults: the fit's (3×3, orthogonal, wrap, OpenGL, scale 1),
    /// the exact model, exact input.
    #[must_use]
    pub fn new() -> Self {
        HeightOptions::from_fit(&crate::Options::new())
    }

    /// The inverse of the fit `fit`: its patch, fit, borders, convention,
    /// gain and invert as they are there (not its units or nodata), with
    /// the solve's defaults (the exact model, exact input).
    #[must_use]
    pub fn from_fit(fit: &crate::Options) -> Self {
        HeightOptions {
            fit: fit.clone().with_units(crate::Units::Texels).with_nodata(None),
            auto_convention: false,
            model: Model::Exact,
            step: 0.0,
            regularisation: None,
            max_iterations: 100,
            tolerance: 1e-10,
        }
    }

    /// The green convention: the fit's, or auto.
    #[must_use]
    pub fn convention(&self) -> ConventionChoice {
        if self.auto_convention { ConventionChoice::Auto } else { self.fit.convention.into() }
    }

    /// Sets the convention (the fit's), or auto.
    #[must_use]
    pub fn with_convention(mut self, convention: impl Into<ConventionChoice>) -> Self {
        match convention.into() {
            ConventionChoice::Auto => self.auto_convention = true,
            ConventionChoice::OpenGl => (self.fit.convention, self.auto_convention) = (Convention::OpenGl, false),
            ConventionChoice::DirectX => (self.fit.convention, self.auto_convention) = (Convention::DirectX, false),
        }
        self
    }
    /// Sets the model.
    #[must_use]
    pub fn with_model(mut self, model: Model) -> Self {
        self.model = model;
        self
    }
    /// Sets the step of a stored component (0: exact).
    #[must_use]
    pub fn with_step(mut self, step: f64) -> Self {
        self.step = step;
        self
    }
    /// Sets λ (`None`: from the step).
    #[must_use]
    pub fn with_regularisation(mut self, lambda: Option<f64>) -> Self {
        self.regularisation = lambda;
        self
    }

    /// The gain S for an image `width` texels wide, sign included.
    #[must_use]
    pub fn scale_for_width(&self, width: usize) -> f64 {
        self.fit.scale_for_width(width)
    }

    /// Checks the options on their own: the fit's as
    /// [`Options::validate`](crate::Options::validate) does, then the
    /// solve's.
    ///
    /// Errors: [`Error::InvalidOption`] naming the field.
    pub fn validate(&self) -> Result<()> {
        self.fit.validate()?;
        if self.fit.detail.is_some() {
            let problem = "the height inverse undoes one patch size's fit: detail at several scales has none";
            return Err(Error::InvalidOption(problem.into()));
        }
        if self.fit.weights != crate::options::Weights::Uniform {
            return Err(Error::InvalidOption(format!(
                "the height inverse undoes the unweighted fit: {} weights are not defined for it yet",
                self.fit.weights
            )));
        }
        let gain = match self.fit.strength {
            Strength::Scale(s) | Strength::Relief(s) => s,
        };
        if gain == 0.0 {
            return Err(Error::InvalidOption("a gain of 0 makes every map flat: heights need a non-zero scale".into()));
        }
        if !(self.step.is_finite() && (0.0..=2.0).contains(&self.step)) {
            return Err(Error::InvalidOption(format!("step must be in [0, 2], got {}", Number(self.step))));
        }
        if let Some(l) = self.regularisation
            && !(l.is_finite() && l >= 0.0)
        {
            return Err(Error::InvalidOption(format!("regularisation must be finite and ≥ 0, got {}", Number(l))));
        }
        if self.max_iterations == 0 || !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(Error::InvalidOption("max_iterations must be ≥ 1 and tolerance finite and > 0".into()));
        }
        Ok(())
    }
}

/// A normal's component type: `f32` or `f64`, the normal n itself.
pub trait NormalComponent: Copy + Send + Sync + 'static {
    /// The value in f64.
    fn to_f64(self) -> f64;
}

impl NormalComponent for f32 {
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}

impl NormalComponent for f64 {
    fn to_f64(self) -> f64 {
        self
    }
}

/// What [`heights`] found besides the heights.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct HeightReport {
    /// The convention used (chosen, under auto).
    pub convention: Convention,
    /// Under auto: the curl of the slope field with each convention,
    /// OpenGL then DirectX, relative to its slope variation (0: integrable;
    /// the wrong convention of a true normal map gives about 1).
    pub curl: Option<[f64; 2]>,
    /// Texels with nz ≤ 0 or a non-finite component, taken as flat.
    pub bad_texels: usize,
    /// Solves run (1 for the vertical fit's transforms; the orthogonal
    /// fit's Gauss–Newton steps count one per inner iteration; 0 for a
    /// map without a slope, whose heights are 0 with nothing to solve).
    pub iterations: usize,
    /// Whether the iteration (orthogonal fit, clamp with N ≥ 5) met its
    /// tolerance; always true for a single solve.
    pub converged: bool,
    /// The regularisation λ used.
    pub regularisation: f64,
    /// The RMS height error (in height units) that the input's quantisation
    /// leaves, through the solve; `None` for exact input.
    pub quantisation_error: Option<f64>,
    /// The smallest and largest height (of those not NaN).
    pub range: (f64, f64),
    /// Holes the caller marked, NaN in the heights.
    pub holes: usize,
    /// Texels not holes that no kept equation sees (every patch holding
    /// them holds a hole): NaN in the heights.
    pub undetermined: usize,
}

/// Heights found from a normal map.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct Heights {
    /// Row-major, `width * height`, mean 0 (with holes: about 0, NaN at
    /// holes and undetermined texels), in units of the gain.
    pub values: Vec<f64>,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// What was found besides.
    pub report: HeightReport,
}

/// The heights of a normal map given as unit normals n (row-major `[x, y,
/// z]`, `width * height` of them; their length does not matter, only
/// their direction).
///
/// ```
/// use normalfit::height::{HeightOptions, heights};
/// use normalfit::{Fit, Options, normals};
///
/// let (w, h) = (32, 16);
/// let original: Vec<f64> = (0..w * h)
///     .map(|k| ((k % w) as f64 * 0.4).sin() * ((k / w) as f64 * 0.8).cos())
///     .collect();
/// let opts = Options::new().with_fit(Fit::Vertical);
/// let n = normals(&original, w, h, &opts)?;
/// let back = heights(&n, w, h, &HeightOptions::from_fit(&opts))?;
/// let mean = original.iter().sum::<f64>() / (w * h) as f64;
/// for (a, b) in original.iter().zip(&back.values) {
///     assert!((a - mean - b).abs() < 1e-4);
/// }
/// # Ok::<(), normalfit::Error>(())
/// ```
///
/// Errors: [`Error::InvalidOption`] for invalid options or a zero size,
/// [`Error::BufferSize`] for a buffer that is not `width * height`,
/// [`Error::Limits`] when the memory is not there.
pub fn heights<T: NormalComponent>(
    normals: &[[T; 3]],
    width: usize,
    height: usize,
    opts: &HeightOptions,
) -> Result<Heights> {
    of_normals(normals, width, height, None, opts)
}

/// [`heights`] with holes: `holes[k]` marks texel k a hole (its normal is
/// not read). Holes come back NaN; the other heights are solved from the
/// slopes of the texels whose patches hold no hole, the solution whose
/// extension over the holes is smoothest (`holes.rs`); texels that no such patch holds are NaN
/// too, counted in [`HeightReport::undetermined`]. Without a hole: the
/// same bits as [`heights`].
///
/// ```
/// use normalfit::height::{HeightOptions, heights_with_holes};
/// use normalfit::{Fit, Options, normals};
///
/// let (w, h) = (24, 16);
/// let original: Vec<f64> = (0..w * h).map(|k| ((k % w) as f64 * 0.3).sin() + (k / w) as f64 * 0.1).collect();
/// let opts = Options::new().with_fit(Fit::Vertical);
/// let n = normals(&original, w, h, &opts)?;
/// let holes: Vec<bool> = (0..w * h).map(|k| (k % w) == 11).collect();
/// let back = heights_with_holes(&n, w, h, &holes, &HeightOptions::from_fit(&opts))?;
/// assert!(back.values[11].is_nan() && back.report.holes == h);
/// # Ok::<(), normalfit::Error>(())
/// ```
///
/// Errors: as [`heights`], and [`Error::BufferSize`] for a mask that is not
/// `width * height`, [`Error::InvalidOption`] for the generic model (which
/// has no patches to keep).
pub fn heights_with_holes<T: NormalComponent>(
    normals: &[[T; 3]],
    width: usize,
    height: usize,
    holes: &[bool],
    opts: &HeightOptions,
) -> Result<Heights> {
    of_normals(normals, width, height, Some(holes), opts)
}

/// [`heights`] and [`heights_with_holes`]: the buffer checked, its rows
/// read as f64 normals.
fn of_normals<T: NormalComponent>(
    normals: &[[T; 3]],
    width: usize,
    height: usize,
    holes: Option<&[bool]>,
    opts: &HeightOptions,
) -> Result<Heights> {
    let len = crate::fit::checked_len(width, height)?;
    if normals.len() != len {
        return Err(Error::BufferSize { expected: len, actual: normals.len() });
    }
    let slopes = |y: usize, sx: &mut [f64], sy: &mut [f64], holes: Option<&[bool]>| {
        let row = &normals[y * width..][..width];
        row_slopes(|x| row[x].map(T::to_f64), holes, sx, sy)
    };
    heights_of_planes(&slopes, width, height, holes, opts)
}

/// [`heights_of_rows`] with holes (`None`: none), as [`heights_with_holes`].
///
/// Errors: as [`heights_with_holes`].
pub fn heights_of_rows_with_holes(
    row: &(dyn Fn(usize, &mut [[f64; 3]]) + Sync),
    width: usize,
    height: usize,
    holes: Option<&[bool]>,
    opts: &HeightOptions,
) -> Result<Heights> {
    let slopes = |y: usize, sx: &mut [f64], sy: &mut [f64], holes: Option<&[bool]>| {
        let mut normals = NORMALS.take();
        normals.resize(width, [0.0; 3]);
        row(y, &mut normals);
        let bad = row_slopes(|x| normals[x], holes, sx, sy);
        NORMALS.set(normals);
        bad
    };
    heights_of_planes(&slopes, width, height, holes, opts)
}

thread_local! {
    /// A thread's row of normals for [`heights_of_rows_with_holes`]'s
    /// caller, taken out while in use (see [`Rows`]).
    static NORMALS: std::cell::RefCell<Vec<[f64; 3]>> = std::cell::RefCell::default();
}

/// The inverse of the normals whose slopes `slopes` gives row by row,
/// with holes (`None`: none): every entry point's.
///
/// Errors: as [`heights_with_holes`].
pub(crate) fn heights_of_planes(
    slopes: RowSlopes<'_>,
    width: usize,
    height: usize,
    holes: Option<&[bool]>,
    opts: &HeightOptions,
) -> Result<Heights> {
    opts.validate()?;
    let len = crate::fit::checked_len(width, height)?;
    if let Some(holes) = holes
        && holes.len() != len
    {
        return Err(Error::BufferSize { expected: len, actual: holes.len() });
    }
    match holes.filter(|m| m.iter().any(|&h| h)) {
        None => {
            memory::check(width, height, opts)?;
            heights_of_slopes(&SlopeField::of_planes(slopes, width, height, None)?, opts)
        }
        Some(holes) => {
            check_masked(width, height, opts)?;
            heights_of_slopes_with_holes(&SlopeField::of_planes(slopes, width, height, Some(holes))?, holes, opts)
        }
    }
}

/// [`heights`] of a normal map given row by row: `row(y, out)` fills
/// `out` (`width` normals) with row y's. For callers whose normals are
/// stored otherwise (planes of a decoded file), without a copy of them.
///
/// Errors: as [`heights`].
pub fn heights_of_rows(
    row: &(dyn Fn(usize, &mut [[f64; 3]]) + Sync),
    width: usize,
    height: usize,
    opts: &HeightOptions,
) -> Result<Heights> {
    heights_of_rows_with_holes(row, width, height, None, opts)
}

/// The slopes of a normal map, made from its normals row by row whenever
/// a pass of the solve reads them (the right-hand sides, the re-fits,
/// Gauss–Newton): nothing is held beside the normals themselves. Slopes
/// stored once took 16 bytes a texel (256 MiB at 4096², a third of the
/// inverse's peak) beside the normals the caller or the decoded file
/// holds anyway; made again at each pass, their two divisions a texel
/// cost about what writing and reading back that plane did. Held as the
/// normals' own slopes (−nx/nz, −ny/nz), 0 where there is none or a hole,
/// so either green convention reads them by a sign.
pub(crate) struct SlopeField<'a> {
    width: usize,
    height: usize,
    /// Row y's slopes.
    slopes: RowSlopes<'a>,
    /// Texels left at slope 0 and not counted without one.
    holes: Option<&'a [bool]>,
    /// Texels without a slope (nz ≤ 0 or a component not finite).
    bad: usize,
}

/// `slopes(y, sx, sy, holes)` fills `sx` and `sy` (the width) with row
/// y's slopes by [`row_slopes`], `holes` that row's, and returns its
/// count of texels without a slope: each caller reads its own storage of
/// the normals straight into the slopes, in one loop.
pub(crate) type RowSlopes<'a> = &'a (dyn Fn(usize, &mut [f64], &mut [f64], Option<&[bool]>) -> usize + Sync);

/// A row's slopes (−nx/nz, −ny/nz) of the normals `normal(x)` gives, into
/// `sx` and `sy` (the row's width), 0 at holes and where there is none
/// (nz ≤ 0 or a component not finite); returns the count of texels
/// without one, holes not counted. The one rule of every caller's rows
/// ([`RowSlopes`]), inlined into each so that the normals' reading and
/// the divisions are one loop.
#[inline(always)]
pub(crate) fn row_slopes(
    normal: impl Fn(usize) -> [f64; 3],
    holes: Option<&[bool]>,
    sx: &mut [f64],
    sy: &mut [f64],
) -> usize {
    let w = sx.len();
    let sy = &mut sy[..w];
    match holes {
        None => slopes_where(normal, |_| false, sx, sy),
        Some(holes) => {
            let holes = &holes[..w];
            slopes_where(normal, |x| holes[x], sx, sy)
        }
    }
}

/// [`row_slopes`] with the holes as a function of the column.
#[inline(always)]
fn slopes_where(
    normal: impl Fn(usize) -> [f64; 3],
    hole: impl Fn(usize) -> bool,
    sx: &mut [f64],
    sy: &mut [f64],
) -> usize {
    // Without branches, so that the loop vectorises (it runs at every
    // pass): both divisions made, 0 chosen where there is no slope.
    let mut bad = 0;
    for x in 0..sx.len() {
        let [nx, ny, nz] = normal(x);
        let hole = hole(x);
        let has_slope = nx.is_finite() & ny.is_finite() & nz.is_finite() & (nz > 0.0);
        let taken = has_slope & !hole;
        sx[x] = if taken { -nx / nz } else { 0.0 };
        sy[x] = if taken { -ny / nz } else { 0.0 };
        bad += usize::from(!has_slope & !hole);
    }
    bad
}

impl<'a> SlopeField<'a> {
    /// The slopes `slopes` gives row by row, the texels `holes` marks
    /// left at slope 0, the others without a slope counted (rows in
    /// parallel).
    ///
    /// Errors: [`Error::InvalidOption`] for a zero or overflowing size.
    pub(crate) fn of_planes(
        slopes: RowSlopes<'a>,
        width: usize,
        height: usize,
        holes: Option<&'a [bool]>,
    ) -> Result<SlopeField<'a>> {
        crate::fit::checked_len(width, height)?;
        let mut field = SlopeField { width, height, slopes, holes, bad: 0 };
        field.bad = (0..height).into_par_iter().map(|y| field.with_row(y, |_, _| ()).0).sum();
        Ok(field)
    }

    /// Row `y`'s slopes (−nx/nz, −ny/nz) into `sx` and `sy`, 0 at holes
    /// and texels without one, whose count it returns.
    fn slopes_of(&self, y: usize, sx: &mut [f64], sy: &mut [f64]) -> usize {
        let w = self.width;
        let holes = self.holes.map(|m| &m[y * w..][..w]);
        (self.slopes)(y, &mut sx[..w], &mut sy[..w], holes)
    }

    /// `look(sx, sy)` of row `y`'s slopes, in the thread's own rows
    /// ([`ROWS`]), and the row's count of texels without a slope.
    fn with_row<R>(&self, y: usize, look: impl FnOnce(&[f64], &[f64]) -> R) -> (usize, R) {
        let mut rows = ROWS.take();
        let Rows { sx, sy } = &mut rows;
        sx.resize(self.width, 0.0);
        sy.resize(self.width, 0.0);
        let bad = self.slopes_of(y, sx, sy);
        let seen = look(sx, sy);
        ROWS.set(rows);
        (bad, seen)
    }

    /// Whether every slope is 0 (a flat map, or none with a slope).
    fn is_flat(&self) -> bool {
        (0..self.height).into_par_iter().all(|y| self.with_row(y, |sx, sy| sx.iter().chain(sy).all(|&v| v == 0.0)).1)
    }

    /// Row `y`'s slopes under the convention of sign `sigma`: gx = −nx/nz,
    /// gy = −σ ny/nz.
    fn row(&self, y: usize, sigma: f64, gx: &mut [f64], gy: &mut [f64]) {
        self.slopes_of(y, gx, gy);
        for g in gy.iter_mut() {
            *g *= sigma;
        }
    }
}

/// A thread's rows for [`SlopeField`]: every pass of the solve asks for
/// every row, on every thread. Taken out while in use (not borrowed), so
/// that a row function that waits on the thread pool, which may run
/// another row's task on this thread meanwhile, finds none taken.
#[derive(Default)]
struct Rows {
    sx: Vec<f64>,
    sy: Vec<f64>,
}

thread_local! {
    static ROWS: std::cell::RefCell<Rows> = std::cell::RefCell::default();
}

/// The convention to read the slopes with, and under auto the curls
/// that chose it.
fn choose_convention(field: &SlopeField, opts: &HeightOptions) -> (Convention, Option<[f64; 2]>) {
    match opts.convention() {
        ConventionChoice::OpenGl => (Convention::OpenGl, None),
        ConventionChoice::DirectX => (Convention::DirectX, None),
        ConventionChoice::Auto => {
            let curl = curl(field);
            let choice = if curl[0] <= curl[1] { Convention::OpenGl } else { Convention::DirectX };
            (choice, Some(curl))
        }
    }
}

/// The checks of the inverse with holes before it starts: the exact model
/// (the generic one has no patches to keep) and the memory it holds.
fn check_masked(width: usize, height: usize, opts: &HeightOptions) -> Result<()> {
    if opts.model != Model::Exact {
        return Err(Error::InvalidOption(
            "holes need the exact model: the generic one has no patches whose slopes are whole".into(),
        ));
    }
    let texels = (width as u64).saturating_mul(height as u64);
    let base = texels.saturating_mul(8 + 4);
    crate::memory::check_memory(
        "finding the heights with holes",
        base.saturating_add(holes::bytes(width, height, opts)?),
    )
}

/// [`heights_with_holes`] of a slope field whose holes are `holes` (at least
/// one): see `holes.rs`.
pub(crate) fn heights_of_slopes_with_holes(
    field: &SlopeField,
    holes: &[bool],
    opts: &HeightOptions,
) -> Result<Heights> {
    opts.validate()?;
    check_masked(field.width, field.height, opts)?;
    let (width, height) = (field.width, field.height);
    let (convention, curl) = choose_convention(field, opts);
    let sigma = convention.sigma();
    let slopes = |y: usize, gx: &mut [f64], gy: &mut [f64]| field.row(y, sigma, gx, gy);
    let q = opts.step / 12f64.sqrt();
    let lambda = opts.regularisation.unwrap_or(q * q / period_texels(width, height, opts.fit.borders));
    let patch = patch::Patch::new(width, height, opts);
    let support = holes::Support::new(&patch, height, holes)?;
    drop(patch);
    let mut z = try_filled(width * height, 0.0)?;
    let (iterations, converged) = holes::solve(&slopes, width, height, opts, lambda, &support, &mut z)?;
    // The quantisation's figure is the transform's, without holes: the
    // noise a solve of the whole map lets through.
    let (b, n) = (opts.fit.borders, opts.fit.patch);
    let noise_gain = match solve::Solver::new(width, height, b, n, Model::Exact)
        .or_else(|| solve::Solver::nearest(width, height, b, n, Model::Exact))
    {
        Some(solver) if opts.step > 0.0 => solver.noise_gain(lambda).noise_gain,
        _ => 0.0,
    };
    let scale = opts.scale_for_width(width);
    // The criterion has set the pieces' constants: only the gain and the NaNs.
    let row_ranges: Vec<(f64, f64)> = z
        .par_chunks_mut(width)
        .zip(support.seen.par_chunks(width))
        .map(|(row, seen)| {
            let mut range = (f64::INFINITY, f64::NEG_INFINITY);
            for (v, &seen) in row.iter_mut().zip(seen) {
                if seen {
                    *v /= scale;
                    range = (range.0.min(*v), range.1.max(*v));
                } else {
                    *v = f64::NAN;
                }
            }
            range
        })
        .collect();
    let range = row_ranges.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    let hole_count = holes.par_iter().filter(|&&h| h).count();
    let seen_count = support.seen.par_iter().filter(|&&s| s).count();
    let range = if seen_count == 0 { (0.0, 0.0) } else { range };
    if !(range.0.is_finite() && range.1.is_finite()) {
        return Err(Error::InvalidOption(format!(
            "heights overflow: a gain of {scale:e} makes them larger than 64-bit floats hold; give a larger scale"
        )));
    }
    let report = HeightReport {
        convention,
        curl,
        bad_texels: field.bad,
        iterations,
        converged,
        regularisation: lambda,
        quantisation_error: (opts.step > 0.0).then(|| q * noise_gain / scale.abs()),
        range,
        holes: hole_count,
        undetermined: width * height - hole_count - seen_count,
    };
    Ok(Heights { values: z, width, height, report })
}

/// [`heights`] of a slope field.
pub(crate) fn heights_of_slopes(field: &SlopeField, opts: &HeightOptions) -> Result<Heights> {
    opts.validate()?;
    let (width, height) = (field.width, field.height);
    let len = width * height;
    let (convention, curl) = choose_convention(field, opts);
    let sigma = convention.sigma();
    let bad_texels = field.bad;
    // The slopes of row y: gx = −nx/nz, gy = −σ ny/nz; 0 where there is none.
    let slopes = |y: usize, gx: &mut [f64], gy: &mut [f64]| field.row(y, sigma, gx, gy);

    let periods = period_texels(width, height, opts.fit.borders);
    let q = opts.step / 12f64.sqrt();
    let lambda = opts.regularisation.unwrap_or(q * q / periods);
    let mut z = try_filled(len, 0.0)?;
    // Frankot–Chellappa knows no clamp: its nearest transform is mirror's.
    let generic = || {
        let borders = Borders { x: generic_border(opts.fit.borders.x), y: generic_border(opts.fit.borders.y) };
        solve::Solver::new(width, height, borders, 3, Model::Generic)
            .ok_or_else(|| Error::InvalidOption("no transform for these borders".into()))
    };
    let (iterations, converged, noise_gain) = if field.is_flat() {
        // No slope anywhere: the heights are 0 (the least-squares answer of
        // least norm, for every model, fit and border), with nothing to
        // solve; only the quantisation's figure needs the solve's sums.
        let noise_gain = if opts.step > 0.0 {
            let solver = match opts.model {
                Model::Generic => generic()?,
                Model::Exact => {
                    let (b, n) = (opts.fit.borders, opts.fit.patch);
                    let exact = solve::Solver::new(width, height, b, n, Model::Exact);
                    exact
                        .or_else(|| solve::Solver::nearest(width, height, b, n, Model::Exact))
                        .ok_or_else(|| Error::InvalidOption("no transform for these borders".into()))?
                }
            };
            solver.noise_gain(lambda).noise_gain
        } else {
            0.0
        };
        (0, true, noise_gain)
    } else {
        match opts.model {
            Model::Generic => (1, true, generic()?.solve(&slopes, lambda, &mut z)?.noise_gain),
            Model::Exact => iterative::exact(&slopes, width, height, opts, lambda, &mut z)?,
        }
    };

    let scale = opts.scale_for_width(width);
    // Rows in parallel, their sums added in row order: the same mean
    // whatever the thread count.
    let row_sums: Vec<f64> = z.par_chunks(width).map(|row| row.iter().sum::<f64>()).collect();
    let mean = row_sums.iter().sum::<f64>() / len as f64;
    let row_ranges: Vec<(f64, f64)> = z
        .par_chunks_mut(width)
        .map(|row| {
            let mut range = (f64::INFINITY, f64::NEG_INFINITY);
            for v in row {
                *v = (*v - mean) / scale;
                range = (range.0.min(*v), range.1.max(*v));
            }
            range
        })
        .collect();
    let range = row_ranges.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    // A tiny gain divides the surface into heights past f64's range: an
    // error, not infinite heights.
    if !(range.0.is_finite() && range.1.is_finite()) {
        return Err(Error::InvalidOption(format!(
            "heights overflow: a gain of {scale:e} makes them larger than 64-bit floats hold; give a larger scale"
        )));
    }
    let quantisation_error = (opts.step > 0.0).then(|| q * noise_gain / scale.abs());
    let report = HeightReport {
        convention,
        curl,
        bad_texels,
        iterations,
        converged,
        regularisation: lambda,
        quantisation_error,
        range,
        holes: 0,
        undetermined: 0,
    };
    Ok(Heights { values: z, width, height, report })
}

fn generic_border(b: Border) -> Border {
    match b {
        Border::Clamp => Border::Mirror,
        other => other,
    }
}

/// Texels of the period the solve works on (for λ's scale).
fn period_texels(w: usize, h: usize, borders: Borders) -> f64 {
    let period = |n: usize, b: Border| match b {
        Border::Wrap => n,
        Border::Mirror if n <= 2 => n,
        Border::Mirror => 2 * (n - 1),
        Border::Clamp => 2 * n,
    };
    (period(w, borders.x) * period(h, borders.y)) as f64
}

/// The relative curl of the slope field under OpenGL and DirectX: with
/// ∂y gx and ∂x gy as differences of neighbours inside the image,
/// Σ(∂y gx − ∂x gy)² / Σ((∂y gx)² + (∂x gy)²). A true slope field has
/// none; the wrong green sign gives ∂y gx + ∂x gy, about 1.
fn curl(field: &SlopeField<'_>) -> [f64; 2] {
    let (w, h) = (field.width, field.height);
    let per_row: Vec<[f64; 3]> = (0..h.saturating_sub(1))
        .into_par_iter()
        .map(|y| {
            // Row y's slopes kept while row y + 1's are made.
            let (_, (top_x, top_y)) = field.with_row(y, |sx, sy| (sx.to_vec(), sy.to_vec()));
            let (_, sums) = field.with_row(y + 1, |below_x, _| {
                let mut sums = [0.0; 3];
                for x in 0..w.saturating_sub(1) {
                    let dgx_dy = below_x[x] - top_x[x];
                    // ny/nz, which is gy under OpenGL and −gy under DirectX.
                    let dny_dx = -(top_y[x + 1] - top_y[x]);
                    sums[0] += (dgx_dy - dny_dx) * (dgx_dy - dny_dx);
                    sums[1] += (dgx_dy + dny_dx) * (dgx_dy + dny_dx);
                    sums[2] += dgx_dy * dgx_dy + dny_dx * dny_dx;
                }
                sums
            });
            sums
        })
        .collect();
    let total = per_row.iter().fold([0.0; 3], |a, r| [a[0] + r[0], a[1] + r[1], a[2] + r[2]]);
    if total[2] > 0.0 { [total[0] / total[2], total[1] / total[2]] } else { [0.0, 0.0] }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Fit, Options, Units};

    /// The height options hold the fit's own options: the inverse of a
    /// fit is made from them, without its units and nodata; the
    /// convention is the fit's unless auto.
    #[test]
    fn the_height_options_hold_the_fits() {
        assert_eq!(HeightOptions::new().fit, Options::default());
        assert_eq!(HeightOptions::default().convention(), ConventionChoice::OpenGl);
        let fit = Options::new()
            .with_patch(7)
            .with_fit(Fit::Vertical)
            .with_borders(Borders { x: Border::Clamp, y: Border::Mirror })
            .with_convention(Convention::DirectX)
            .with_strength(Strength::Relief(0.25))
            .with_invert(true)
            .with_units(Units::Map(crate::options::Spacing::square(2.0)))
            .with_nodata(Some(0.0));
        let opts = HeightOptions::from_fit(&fit);
        assert_eq!(opts.fit, fit.clone().with_units(Units::Texels).with_nodata(None));
        assert_eq!(opts.convention(), ConventionChoice::DirectX);
        assert_eq!(opts.scale_for_width(64), -16.0);
        let auto = opts.clone().with_convention(ConventionChoice::Auto);
        assert!(auto.auto_convention && auto.convention() == ConventionChoice::Auto);
        let gl = auto.with_convention(Convention::OpenGl);
        assert_eq!((gl.convention(), gl.fit.convention), (ConventionChoice::OpenGl, Convention::OpenGl));
        // The fit's checks, then the solve's.
        let e = HeightOptions::from_fit(&Options::new().with_patch(4)).validate().unwrap_err();
        assert_eq!(e.to_string(), Options::new().with_patch(4).validate().unwrap_err().to_string());
        let flat = HeightOptions::from_fit(&Options::new().with_strength(Strength::Scale(0.0)));
        assert!(flat.validate().unwrap_err().to_string().contains("a gain of 0"));
    }
}
