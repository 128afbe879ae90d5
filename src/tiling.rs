//! Whether a texture tiles: a seam score and a verdict per axis.
//!
//! Repeating a texture puts its last column next to its first (the *x
//! seam*) and its last row above its first (the *y seam*). The texture
//! tiles along an axis when that wrap pair looks like the pairs of
//! neighbouring columns (rows) inside the image. [`check`] measures exactly
//! that, with no knowledge of files: planes in, [`TilingReport`] out.
//! [`HeightSeams`] does the same for a height map fed row by row, in
//! memory O(W + H), for images too large to hold.
//!
//! # The measure
//!
//! For the x axis (the y axis is the same with rows for columns), with h the
//! judged signal (see [what is judged](#what-is-judged)) and the sums over
//! all rows y:
//!
//! ```text
//! value pair k:  V[k] = Σ_y |h(k+1, y) − h(k, y)|                      k = 0 … W−1
//! crease at k:   C[k] = Σ_y |(h(k+2, y) − h(k+1, y)) − (h(k, y) − h(k−1, y))|
//! ```
//!
//! with indices mod W. `V[W−1]` is the value jump across the wrap; `C[W−1]`,
//! from h(W−2), h(W−1), h(0), h(1), is the change of slope across it: a
//! crease that the normal map would show even where the values meet. It
//! does not contain the jump h(0) − h(W−1) itself, so the two measures see
//! different things. Each is compared with the same quantity over the
//! *interior* pairs, those whose stencil does not cross the wrap
//! (V: k = 0 … W−2; C: k = 1 … W−3):
//!
//! ```text
//! score_V = (V[W−1] + ε) / (R(V interior) + ε)
//! score_C = (C[W−1] + ε) / (R(C interior) + ε)
//! score   = max(score_V, score_C)       (height maps; normal maps: score_V)
//! seamless  ⇔  score ≤ threshold
//! ```
//!
//! **The reference R is a high rank of the interior distribution**, the
//! k-th largest interior value with k = max(4, ⌈1 % of the pairs⌉) (at most
//! half of them), not its median or mean. That is what makes structured
//! textures pass: in a brick wall whose wrap falls on a mortar line, the
//! seam pair *is* an edge pair, many times the median pair (17.8× in the
//! MaterialX bricks), but every mortar line inside the image gives pairs
//! like it, so the seam ranks inside the interior's distribution (86th
//! percentile there) and scores below 1. A seam of a photo or a crop is a
//! jump between unrelated lines: its sum over the whole line is larger than
//! any interior pair's, where an edge of the picture only spans part of the
//! line, and it scores several times above the reference. Taking the
//! k-th largest rather than the largest keeps one odd interior pair (the
//! denim map has two columns 25× the median) from excusing a real seam, and
//! asks a structure to recur: a kink seen once in the middle and once at
//! the wrap (a triangle wave |x − W/2|) fails, as a crease the eye would
//! catch at the repeat.
//!
//! ## The reference lies near the seam
//!
//! On an axis longer than 512 lines, the interior pairs are those within
//! its first and its last [`EDGE_LINES`] = 256 lines: the seam is compared
//! with what lies on either side of it once the texture repeats, and the
//! check reads those strips and nothing else, 2 × 256 columns of every row
//! and 2 × 256 whole rows at any size. A caller holding a large raster in
//! pieces (a Dask array, the tiles of a file) then reads only its edges
//! ([`HeightSeams::push_edge_columns`], [`HeightSeams::push_edge_rows`]),
//! and the whole-image check measures a quarter of a 4096² image. Up to
//! 512 lines along an axis, every size the threshold was chosen on
//! ([below](#default-threshold-15)), every pair is interior. The kept
//! lines, in order, make an image whose wrap is the seam; the pair across
//! the cut (value pair 255, creases 254 to 256 of the kept lines) joins
//! lines that are not neighbours and is judged by nothing. Scale is the
//! limit: a structure that recurs less than about 3 times within 256 lines
//! (bricks 100 texels tall or more) gives the strips fewer pairs like it
//! than the rank asks for, so a seam on such a line scores higher than on
//! the whole image (figures in `docs/tiling.md`).
//!
//! ε = 10⁻³ × the mean |Δ| of neighbouring texels over both axes (over
//! the pairs judged and the seams; plus 10⁻³⁰) keeps rounding and
//! quantisation noise from making a ratio: an axis whose pairs are all
//! zero (a constant image, the y axis of a ramp along x) scores exactly 1.
//!
//! Why sums over whole lines: a seam spans the whole line, structure inside
//! a photo rarely does; a per-line sum also averages the noise of stochastic
//! textures, so the interior pairs of a tileable noise cluster tightly and
//! a crop's seam stands out.
//!
//! ## Levels: the seam smoothed along itself
//!
//! A photo of a brick wall at an angle has mortar lines that reach the
//! right border at heights that do not match where the lines leave the
//! left one: repeated, the lines break at the seam. Texel by texel that
//! break can be no larger than the wall's own jumps (the grain of the
//! bricks, the sensor noise, the edges of the head joints), so the seam
//! pair ranks among the interior pairs. What sets it apart is that it is
//! *coherent along the seam*: a line arriving at a wrong height makes a
//! jump of one sign over the line's width, where grain and noise change
//! sign from texel to texel. So the same profiles are also taken with the
//! texels first summed in runs along the lines being compared: for the x
//! axis, h is replaced by
//!
//! ```text
//! h_l(x, J) = Σ h(x, y)  over the run  y = J·2^l … (J+1)·2^l − 1   (the last run shorter)
//! ```
//!
//! and V, C, the interior reference and the score are computed on h_l
//! exactly as on h (the y axis sums runs along rows). Level l = 0 is h
//! itself; levels 1 … 5 sum runs of 2 to 32 texels. Summing s texels adds
//! the noise's jumps as √s and a coherent mismatch as s, so the levels
//! bring out breaks the length of a run or longer, while an ordinary
//! interior line, continuing structure and noise alike, stays an ordinary
//! draw of the interior distribution at every level: a tileable texture's
//! seam still scores about 1. The axis's score is the largest of its
//! levels' scores; a level is judged only when the seam holds at least 8
//! runs (l ≤ log₂(line length / 8)), since fewer per-line terms rank
//! poorly. Only the runs change: pairs are still neighbouring columns
//! (rows), so a level measures the same jump, not a blurred one.
//!
//! Chosen over the alternatives a sweep tried (`examples/tiling_sweep.rs`;
//! the figures [below](#default-threshold-15)): square blocks (summing
//! across the seam as well) smear the line's break over neighbouring pairs
//! and gained nothing; matching each pair under a local shift along the
//! seam (to follow lines at an angle) helped less than the runs and costs
//! a search per texel. What the levels cannot see is a line that meets
//! the seam at a glancing angle (mostly within 15° of it): inside the
//! image such a line already makes long one-sided jumps between
//! neighbouring lines, as long as the break it makes at the seam. A photo
//! at a small angle is then caught on its other axis, which the lines
//! cross steeply.
//!
//! # What is judged
//!
//! * [`ImageKind::Height`]: one signal, the height: the single plane of a
//!   gray image (a second plane is alpha and is ignored), or the luma
//!   0.2126 R + 0.7152 G + 0.0722 B of a colour image (a fourth plane is
//!   alpha, ignored). Value and crease seams are both sought.
//! * [`ImageKind::Normal`]: the R, G and B planes, the |Δ| summed over the
//!   three; only value seams are sought (a crease in a normal map is a jump
//!   of curvature, which shading hardly shows). A one- or two-plane image
//!   forced to `Normal` is judged on its first plane.
//!
//! [`KindChoice::Auto`] (the default) tells the two apart by
//! [`ImageKind::detect`], the normal-map reader's rule (see
//! [`normal_map`](crate::normal_map#height-map-or-normal-map)): a gray image
//! or a colour photo is a height map.
//!
//! # Default threshold: 1.5
//!
//! Figures from `cargo run --release --example tiling_table` (score x / y;
//! in brackets, the measure at level 0 alone, as it was before the levels;
//! the 1024² sets against the pairs within 256 lines of the seam, which
//! moved them by at most 0.26: Bricks061 0.70 / 0.29 and its normal maps
//! 1.06 / 0.59 against the whole image, denim 0.24 / 0.77):
//!
//! | image | x | y | must |
//! |---|---|---|---|
//! | ambientCG Bricks061 height (JPEG, 1024², y wrap in a mortar line) | 0.65 | 0.28 | tile |
//! | its NormalGL / NormalDX maps | 0.99 / 0.99 | 0.58 | tile |
//! | Poly Haven denim height (16-bit) / normal map | 0.50 / 0.33 | 0.80 / 0.89 | tile |
//! | MaterialX bricks_02 height (half EXR, y wrap beside a mortar edge) | 0.32 | 0.54 | tile |
//! | its normal map, EXR / PNG | 0.41 / 0.42 | 0.55 / 0.55 | tile |
//! | scikit-image camera (gray photo) | 3.92 (3.30) | 10.21 (5.12) | fail |
//! | scikit-image coffee (RGB photo) | 11.26 (4.53) | 13.57 (6.40) | fail |
//! | SPEC sine, 96² 16-bit | 1.00 | 1.00 | tile |
//! | SPEC ramp along x, 96² 16-bit | 94.9 | 1.00 | x fails |
//! | periodic value noise, 64² … 256², 1–3 octaves (8 cases) | 0.21 – 1.11 | | tile |
//! | the same noises cropped off-period (8 cases) | 4.4 – 64 | | fail |
//! | noise periodic in x only, 64² / 256² | 1.06 / 0.70 | 4.5 / 30 | y fails |
//! | half sine, parabola, triangle crease at the x wrap + noise, 64² | 8.0, 8.9, 5.3 | 0.66 | x fails |
//! | the same at 256² | 33, 36, 22 | 0.35 | x fails |
//! | normal map fitted from a tileable noise, 64² / 256² | 0.78 / 0.42 | 0.52 / 0.85 | tile |
//! | normal map fitted (clamp borders) from a crop, 64² / 256² | 2.34 / 7.17 | 1.86 / 8.01 | fail |
//! | structured photos at 12° to 33° (bricks, planks, tiles, cables; 256², 512²; 10 cases) | 3.1 – 6.9 | 2.1 – 4.1 (1.32 – 2.8) | fail |
//! | photos of rough planks at −38°, 38°, 25°, 512² | 2.44, 1.97, 2.44 (1.48, 1.37, 1.78) | 2.10, 1.80, 1.77 (1.38, 1.25, 1.15) | fail |
//! | periodic bricks, planks, tiles, cables: square, rotated atan(1/2), atan(1/3), lines at atan(k·H/W) (12 cases) | 0.18 – 0.97 | 0.09 – 0.95 | tile |
//!
//! The sweep, `cargo run --release --example tiling_sweep -- --per 24`
//! (24 images of each kind at each of 64², 96², 128², 256², 512²,
//! 512×256, 256×512: 168 periodic noises, 168 off-period crops of noise,
//! 672 exactly periodic structured textures, 672 structured photos at 3°
//! to 43° with random keystone, zoom, light, grain and sensor noise; in
//! brackets, level 0 alone):
//!
//! | group | highest score of an axis that tiles | lowest of one that does not | axes judged wrong at 1.5 |
//! |---|---|---|---|
//! | periodic noise | 1.28 (1.27) | | 0 (0) |
//! | periodic structured textures | 1.40 (1.39) | | 0 (0) |
//! | noise crops | | 2.11 (2.07) | 0 (0) |
//! | structured photos | | 0.30 (0.30) | 123 of 1344 (261); 5 of the 672 photos pass on both axes (36) |
//!
//! Everything that tiles scores at most 1.40, below 1.5, at any size from
//! 64 texels; the levels moved that by 0.01 while halving the photos'
//! wrong axes and catching 31 of the 36 photos that passed whole. The
//! axes still judged wrong are, but for some at 64² and 96² (54 of the
//! 123), the axis whose seam the lines meet at a glancing angle (the
//! limit in [Levels](#levels-the-seam-smoothed-along-itself)); their other
//! axis fails, so the image does not tile. A grid at a small angle (tiles
//! at 4°) meets both seams at a glancing angle and can pass whole: of the
//! 5 photos that do, one is such a 512² grid, the others 64² and 96²
//! crops. An earlier sweep of 576 noise
//! images (64² to 512²) gave at most 1.40 for a tileable noise and at
//! least 1.71 for a crop at level 0; below 64 texels the two overlap (at
//! 32²–48²: tileable up to 1.66, crops down to 1.33): a short axis gives
//! the interior distribution few samples. The real textures are no part
//! of the choice beyond staying below it: their worst is 1.06.
//!
//! # Edge cases
//!
//! * An axis of 1 texel tiles (score 1): its only pair is a texel with
//!   itself. An axis of 2 to 3 texels has value pairs but no interior
//!   crease pair, so only the value is judged; R is then the interior's
//!   median-or-above, never a rank that does not exist.
//! * A zero-sized image tiles on both axes, score 1.
//! * Non-finite texels are taken as 0 (a NaN must not make the verdict
//!   NaN); callers that care reject them before, as `normalfit::io` does.
//! * Finite heights anywhere in f32's range give finite scores: the sums
//!   run on the heights times 2⁻³², exactly, and are scaled back in f64,
//!   so that the difference of ±3.4·10³⁸ and its sums do not overflow f32.
//!
//! # Cost
//!
//! One pass over the texels, rows in parallel (rayon), each row read once
//! for both axes; the colour-to-luma conversion happens on the fly per
//! block of rows, so no full-size copy is made. The levels add, per row,
//! its runs along x (W/2 + W/4 + … sums) and the y pairs of those, and
//! per 2^l rows one row of runs along y and its x pairs: about twice the
//! work of level 0 alone. [`HeightSeams`] runs the same kernels on the
//! caller's thread, on blocks of up to 32 rows 1024 columns at a time (so
//! that the rows and sums of a pass stay in cache at any width), keeping
//! 6 rows and the profiles at every level. `cargo bench --bench fit -- seams` (4096², 2 cores): see
//! docs/tiling.md for the figures.

use crate::par::prelude::*;

use crate::Samples;
use crate::options::{Border, Borders};
use crate::samples::{check_planes, image_len, try_vec};
use crate::{Error, Result};

/// What the planes hold and how it is decided: the normal-map reader's
/// ([`crate::normal_map`]), named here too for callers of earlier versions.
#[doc(no_inline)]
pub use crate::normal_map::{ImageKind, KindChoice};

/// The default [`TilingOptions::threshold`]; see the [module docs](self)
/// for the figures it was chosen from.
pub const DEFAULT_THRESHOLD: f64 = 1.5;

/// Rows per parallel task: large enough that the four halo rows each task
/// reads twice cost little, small enough to spread over threads.
const CHUNK: usize = 32;

/// The reference is at least the `MIN_RANK`-th largest interior pair…
const MIN_RANK: usize = 4;

/// …and at least the top `RANK_FRACTION` of the interior pairs.
const RANK_FRACTION: f64 = 0.01;

/// Levels of smoothing along the seam: level l compares lines whose
/// texels are summed in runs of 2^l along them, l = 0 … 5 (runs of 1 to
/// 32). [`CHUNK`] is a multiple of the longest run.
const LEVELS: usize = 6;

/// A level is judged only when the seam holds at least this many of its
/// runs: fewer, and its per-line sums are too few draws to rank well.
const MIN_RUNS: usize = 8;

/// Lines of an axis read at each of its ends when the axis is longer than
/// twice this: the seam is compared with the pairs within them (see the
/// [module docs](self#the-reference-lies-near-the-seam)). 256 keeps every
/// image up to 512 texels along an axis whole, the sizes the threshold was
/// chosen on.
pub const EDGE_LINES: usize = 256;

/// ε relative to the mean neighbour difference: above f32 rounding and
/// 16-bit quantisation noise, far below any visible seam.
const FLOOR_FRACTION: f64 = 1e-3;

/// The f32 kernels measure the heights times this, and the profiles are
/// scaled back in f64. Without it, finite heights near f32's range (an HDR
/// or float file of ±3.4·10³⁸, found by fuzzing) overflow to infinite
/// differences and sums, and the score to NaN. A power of two, so the
/// scaling is exact and the scores are the same bit for bit, except for
/// heights within about 10⁻²⁸ of zero whose differences become subnormal:
/// they lose what lies below 10⁻³⁵, far below the ε floor (10⁻³⁰) that
/// decides such scores anyway. With it, |Δ| ≤ 2⁹⁷ and a crease ≤ 2⁹⁸: the
/// x sums of 32 rows, and a y lane of up to 2²⁹ texels (rows of 2³² texels,
/// 16 GiB of f32), stay below f32's largest value, 2¹²⁸. The runs of the
/// levels hold it too: a run of 2^l texels or rows is up to 2^l times
/// larger, and a sum holds 2^l times fewer of them.
const JUDGE_SCALE: f32 = 1.0 / 4_294_967_296.0;

/// 1 / [`JUDGE_SCALE`], to bring the sums back to height units.
const UNSCALE: f64 = 4_294_967_296.0;

/// What [`check`] is asked to do.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct TilingOptions {
    /// An axis is seamless when its score is at most this. Default:
    /// [`DEFAULT_THRESHOLD`] (1.5). A NaN threshold passes nothing.
    pub threshold: f64,
    /// What the planes hold. Default: [`KindChoice::Auto`].
    pub kind: KindChoice,
}

impl Default for TilingOptions {
    fn default() -> Self {
        TilingOptions { threshold: DEFAULT_THRESHOLD, kind: KindChoice::Auto }
    }
}

impl TilingOptions {
    /// The defaults: threshold 1.5, kind detected.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets [`threshold`](Self::threshold).
    #[must_use]
    pub fn with_threshold(mut self, threshold: f64) -> Self {
        self.threshold = threshold;
        self
    }

    /// Sets [`kind`](Self::kind).
    #[must_use]
    pub fn with_kind(mut self, kind: KindChoice) -> Self {
        self.kind = kind;
        self
    }

    /// Checks the options as a caller gave them: the threshold must be a
    /// positive number (the library itself judges with any value; a NaN
    /// passes nothing).
    ///
    /// Errors: [`Error::InvalidOption`] naming the threshold.
    pub fn validate(&self) -> Result<()> {
        if self.threshold.is_nan() || self.threshold <= 0.0 {
            return Err(Error::InvalidOption(format!("threshold must be positive, got {}", self.threshold)));
        }
        Ok(())
    }
}

/// The verdict on one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct AxisReport {
    /// How the wrap pair compares with the interior pairs: about 1 or less
    /// when it looks like them, larger for a more visible seam. Finite and
    /// positive.
    pub score: f64,
    /// `score <= threshold`.
    pub seamless: bool,
}

/// The verdict on an image: the kind judged, and each axis.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct TilingReport {
    /// What the image was judged as (given, or detected).
    pub kind: ImageKind,
    /// The x seam: last column against first.
    pub x: AxisReport,
    /// The y seam: last row against first.
    pub y: AxisReport,
}

impl TilingReport {
    /// Whether the image tiles on both axes.
    #[must_use]
    pub fn seamless(&self) -> bool {
        self.x.seamless && self.y.seamless
    }

    /// Wrap on the axes that tile, mirror on the others: borders that add
    /// no seam of their own (what `normalfit convert --border auto` uses).
    /// Mirror rather than clamp, because clamping flattens the slope at the
    /// edge while mirroring keeps the texels' own neighbourhood.
    #[must_use]
    pub fn suggested_borders(&self) -> Borders {
        let pick = |axis: &AxisReport| if axis.seamless { Border::Wrap } else { Border::Mirror };
        Borders { x: pick(&self.x), y: pick(&self.y) }
    }
}

/// The image moved circularly by half its width and height, so both wrap
/// seams cross its middle: the picture an artist looks at to judge tiling.
/// Texel (x, y) of the result is texel ((x + W/2) mod W, (y + H/2) mod H).
///
/// Errors: [`Error::BufferSize`] when `texels` does not hold
/// `width * height` values, [`Error::Limits`] when the copy cannot be
/// allocated.
pub fn shift_half<T: Copy>(texels: &[T], width: usize, height: usize) -> Result<Vec<T>> {
    let len = image_len(width, height)?;
    if texels.len() != len {
        return Err(Error::BufferSize { expected: len, actual: texels.len() });
    }
    let (dx, dy) = (width / 2, height / 2);
    let mut out = try_vec(len)?;
    for y in 0..height {
        let row = &texels[((y + dy) % height) * width..][..width];
        out.extend_from_slice(&row[dx..]);
        out.extend_from_slice(&row[..dx]);
    }
    Ok(out)
}

/// Scores the x and y seams of an image given as f32 planes.
///
/// `planes` are the channels, row-major, `width * height` each, in the
/// contract's units (integer images divided by 2^bits − 1, floats as
/// stored): 1 for gray, 2 for gray + alpha, 3 for RGB, 4 for RGBA. How they
/// are judged, and the measure, are in the [module docs](self).
///
/// ```
/// use normalfit::tiling::{check, TilingOptions};
/// // A ramp along x: a jump at the x wrap; every row the same, so y tiles.
/// let (w, h) = (64, 32);
/// let ramp: Vec<f32> = (0..w * h).map(|k| (k % w) as f32 / (w - 1) as f32).collect();
/// let report = check(&[&ramp], w, h, &TilingOptions::default())?;
/// assert!(!report.x.seamless && report.x.score > 10.0);
/// assert!(report.y.seamless && report.y.score == 1.0);
/// assert!(!report.seamless());
/// # Ok::<(), normalfit::Error>(())
/// ```
///
/// Errors: [`Error::InvalidOption`] when `planes` is empty,
/// [`Error::BufferSize`] when a plane is shorter than `width * height`,
/// [`Error::Limits`] when the profiles need more memory than the process
/// may take.
pub fn check(planes: &[&[f32]], width: usize, height: usize, opts: &TilingOptions) -> Result<TilingReport> {
    if planes.is_empty() {
        return Err(Error::InvalidOption("the tiling check needs at least one plane".into()));
    }
    let len = image_len(width, height)?;
    check_planes(planes, len)?;
    let kind = match opts.kind {
        KindChoice::Auto => ImageKind::detect(planes, width, height)?,
        KindChoice::Height => ImageKind::Height,
        KindChoice::Normal => ImageKind::Normal,
    };
    if len == 0 {
        return Ok(Profiles::empty_report(kind, opts));
    }
    let (cols, rows) = (Cut::of(width), Cut::of(height));
    let all_rows = Cut::whole(height);
    if cols.is_whole() {
        // Every column is read: one pass over the image gives the x
        // profiles, and the y ones of every row, of which the kept are used.
        crate::io::check_memory("the tiling check", Profiles::bytes_needed(width, height))?;
        let p = Profiles::measure(planes, cols, all_rows, kind);
        return Ok(report(&p.x_axis(height, cols), &p.y_axis(width, all_rows, rows), kind, opts));
    }
    // The kept columns of every row for x, the kept rows whole for y.
    let bytes = Profiles::bytes_needed(cols.kept(), height) + Profiles::bytes_needed(width, rows.kept());
    crate::io::check_memory("the tiling check", bytes)?;
    let x = Profiles::measure(planes, cols, all_rows, kind).x_axis(height, cols);
    let y = Profiles::measure(planes, Cut::whole(width), rows, kind).y_axis(width, rows, rows);
    Ok(report(&x, &y, kind, opts))
}

/// The tiling check of a height map fed one row at a time, top to bottom:
/// [`check`] for an image too large to hold, such as one streamed from a
/// decoder, or held in pieces (a chunked array) of which only the edges
/// need be read.
///
/// Gives the report of
/// `check(&[&heights], width, height, &opts.with_kind(KindChoice::Height))`:
/// the same profiles and scores (see [below](#same-as-check)), judged as
/// [`ImageKind::Height`] whatever `opts.kind` says. For a colour image, push
/// rows of its luma (0.2126 R + 0.7152 G + 0.0722 B, as `check` takes it).
///
/// Two ways to feed it:
/// * whole rows, top to bottom: [`push_row`](Self::push_row),
///   [`push_heights`](Self::push_heights), [`push_samples`](Self::push_samples);
/// * only the lines the check reads (see the
///   [module docs](self#the-reference-lies-near-the-seam)): every row's
///   [`edge_columns`](Self::edge_columns), top to bottom, through
///   [`push_edge_columns`](Self::push_edge_columns), and the
///   [`edge_rows`](Self::edge_rows) whole, in order, through
///   [`push_edge_rows`](Self::push_edge_rows) (in any interleaving with
///   the columns). On an image more than 512 texels wide and tall, that is
///   the 256 columns and 256 rows at each edge: a caller holding the image
///   in pieces reads those strips and nothing else.
///
/// Memory is O(W + H), never the image: at each of the 6 levels of the
/// [module docs](self#levels-the-seam-smoothed-along-itself), the x
/// profiles (4 values a kept column) and the y profiles (2 a kept row);
/// the first 2 rows and the last 4 with their runs along x (about 2 W
/// each; the pairs that cross the y wrap, value H−1 → 0 and crease H−2,
/// H−1, 0, 1, need rows H−2, H−1, 0 and 1); one run of rows in progress per
/// level (W each); and the rows pushed but not yet measured, up to 32
/// (fewer when 32 rows would take more than 4 MiB). Every 32nd row measures
/// the rows that wait, O(W) work a row on the caller's thread, in
/// branch-free loops over slices that vectorise, 1024 columns at a time;
/// [`finish`](Self::finish) measures the rest, adds the pairs across the
/// wrap and selects the references, O(W + H).
///
/// # Same as check
///
/// The per-line sums are computed by the same kernels as in `check`, in the
/// same order, at every level (the runs of rows and of texels are added in
/// the same order too): the y sums and the x sums of each block of 32 rows
/// (kept in f32 by `check`, and so here) are bit for bit the same; only the
/// f64 total over the blocks is added in another order (`check` adds them
/// per thread). Those f64 sums of f32 values are exact unless the block
/// sums span about 2²⁹ in size, so the scores are in practice identical
/// (they were in every test) and at worst about 10⁻¹⁵ apart relative;
/// verdicts can then differ only for a score that close to the threshold.
/// The two ways of feeding give the same bits.
///
/// ```
/// use normalfit::normal_map::KindChoice;
/// use normalfit::tiling::{check, HeightSeams, TilingOptions};
/// // A ramp along x, fed row by row.
/// let (w, h) = (64, 32);
/// let ramp: Vec<f32> = (0..w * h).map(|k| (k % w) as f32 / (w - 1) as f32).collect();
/// let mut seams = HeightSeams::new(w, h)?;
/// for row in ramp.chunks_exact(w) {
///     seams.push_row(row)?;
/// }
/// let opts = TilingOptions::new();
/// let report = seams.finish(&opts)?;
/// assert!(!report.x.seamless && report.y.seamless);
/// let whole = check(&[&ramp], w, h, &opts.with_kind(KindChoice::Height))?;
/// assert!((report.x.score / whole.x.score - 1.0).abs() < 1e-12);
/// # Ok::<(), normalfit::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct HeightSeams {
    width: usize,
    height: usize,
    /// The columns and rows the check reads.
    cols: Cut,
    rows: Cut,
    /// The x profiles, fed the kept columns of every row. When every
    /// column is kept, it is fed whole rows and gives the y profiles too.
    x: RowSeams,
    /// The y profiles, fed the kept rows whole: when some columns are not
    /// kept.
    y: Option<RowSeams>,
    /// Rows fed to `y`.
    y_rows: usize,
    /// A row's kept columns, converted.
    kept: Vec<f32>,
}

impl HeightSeams {
    /// A check of a `width` × `height` height map, no rows in yet.
    ///
    /// Refused when the check's memory ([`bytes_needed`](Self::bytes_needed))
    /// is more than the process may still take (under `ulimit -v` and the
    /// like), instead of aborting on a failed allocation: an image 2^24
    /// texels wide or tall needs 1.6 to 3.7 GB for it.
    ///
    /// Errors: [`Error::Limits`] saying how much is needed,
    /// [`Error::InvalidOption`] when `width * height` overflows.
    pub fn new(width: usize, height: usize) -> Result<Self> {
        image_len(width, height)?;
        crate::io::check_memory("the tiling check", Self::bytes_needed(width, height))?;
        let (cols, rows) = (Cut::of(width), Cut::of(height));
        let y = (!cols.is_whole()).then(|| RowSeams::new(width, rows.kept()));
        Ok(HeightSeams {
            width,
            height,
            cols,
            rows,
            x: RowSeams::new(cols.kept(), height),
            y,
            y_rows: 0,
            kept: Vec::with_capacity(cols.kept()),
        })
    }

    /// The bytes a check of a `width` × `height` image holds (its profiles,
    /// row buffers and pending rows, at every level): about 350 a column
    /// and 96 a row.
    #[must_use]
    pub fn bytes_needed(width: usize, height: usize) -> u64 {
        let (cols, rows) = (Cut::of(width), Cut::of(height));
        let y = if cols.is_whole() { 0 } else { RowSeams::bytes_needed(width, rows.kept()) };
        RowSeams::bytes_needed(cols.kept(), height) + y + 4 * cols.kept() as u64
    }

    /// The columns of every row that the check reads, as two ranges (the
    /// second empty when the first is the whole row): what
    /// [`push_edge_columns`](Self::push_edge_columns) takes, in this order.
    #[must_use]
    pub fn edge_columns(&self) -> [std::ops::Range<usize>; 2] {
        self.cols.ranges()
    }

    /// The rows that [`push_edge_rows`](Self::push_edge_rows) takes whole,
    /// as two ranges: the first and last 256 rows of a tall image, all
    /// rows of a short one, none when [`edge_columns`](Self::edge_columns)
    /// is every column (the whole rows pushed as columns serve the y axis
    /// too).
    #[must_use]
    pub fn edge_rows(&self) -> [std::ops::Range<usize>; 2] {
        if self.y.is_some() { self.rows.ranges() } else { [0..0, 0..0] }
    }

    /// The rows pushed so far: whole rows, or rows of edge columns.
    #[must_use]
    pub fn rows(&self) -> usize {
        self.x.rows
    }

    /// Adds the next row, `width` heights. Non-finite values count as 0, as
    /// in [`check`].
    ///
    /// Errors: [`Error::BufferSize`] when `row.len() != width`,
    /// [`Error::InvalidOption`] when all `height` rows are in already, or
    /// rows came through [`push_edge_rows`](Self::push_edge_rows) too; the
    /// check is unchanged then.
    pub fn push_row(&mut self, row: &[f32]) -> Result<()> {
        let w = self.width;
        if row.len() != w {
            return Err(Error::BufferSize { expected: w, actual: row.len() });
        }
        self.check_room(1)?;
        let y = self.x.rows;
        let is_kept = |y: usize| self.rows.ranges().iter().any(|r| r.contains(&y));
        if self.y.is_some() && is_kept(y) && self.rows.line(self.y_rows) != y {
            return Err(Error::InvalidOption("the tiling check was given edge rows and whole rows both".into()));
        }
        if let Some(seams) = self.y.as_mut().filter(|_| is_kept(y)) {
            seams.push_row(row);
            self.y_rows += 1;
        }
        if self.cols.is_whole() {
            self.x.push_row(row);
        } else {
            self.kept.clear();
            for part in self.cols.ranges() {
                self.kept.extend_from_slice(&row[part]);
            }
            self.x.push_row(&self.kept);
        }
        Ok(())
    }

    /// Pushes every row of `heights`, an image of this check's width held
    /// whole in the samples' own type, converting one row at a time (no
    /// `f32` copy of the image).
    ///
    /// Errors: [`Error::BufferSize`] when `heights` is not whole rows of
    /// this width, or holds more rows than are still to come (nothing is
    /// pushed then).
    pub fn push_samples(&mut self, heights: &Samples) -> Result<()> {
        crate::samples::with_slice!(heights, s => self.push_heights(s))
    }

    /// Pushes every row of `heights`, whole rows of this check's width in
    /// any [`Sample`](crate::Sample) type (a caller's array, such as the
    /// Python package's), converting one row at a time.
    ///
    /// Errors: as [`push_samples`](Self::push_samples).
    pub fn push_heights<H: crate::Sample>(&mut self, heights: &[H]) -> Result<()> {
        let w = self.width;
        let count = whole_rows(heights.len(), w, self.height - self.x.rows)?;
        let mut row = try_vec(w)?;
        row.resize(w, 0.0f32);
        for rows in heights.chunks_exact(w.max(1)).take(count) {
            convert_row(rows, &mut row);
            self.push_row(&row)?;
        }
        Ok(())
    }

    /// Pushes the [`edge_columns`](Self::edge_columns) of the next rows:
    /// rows of that many values (the first range's columns, then the
    /// second's), top to bottom, in any [`Sample`](crate::Sample) type.
    ///
    /// Errors: [`Error::BufferSize`] when `texels` is not whole rows of
    /// edge columns, or holds more rows than are still to come (nothing is
    /// pushed then).
    pub fn push_edge_columns<H: crate::Sample>(&mut self, texels: &[H]) -> Result<()> {
        let n = self.cols.kept();
        let count = whole_rows(texels.len(), n, self.height - self.x.rows)?;
        let mut row = std::mem::take(&mut self.kept);
        row.resize(n, 0.0);
        for part in texels.chunks_exact(n.max(1)).take(count) {
            convert_row(part, &mut row);
            self.x.push_row(&row);
        }
        self.kept = row;
        Ok(())
    }

    /// Pushes the next of the [`edge_rows`](Self::edge_rows), whole rows of
    /// this check's width in order, in any [`Sample`](crate::Sample) type.
    ///
    /// Errors: [`Error::BufferSize`] when `heights` is not whole rows, or
    /// holds more than the edge rows still to come (nothing is pushed
    /// then).
    pub fn push_edge_rows<H: crate::Sample>(&mut self, heights: &[H]) -> Result<()> {
        let w = self.width;
        let Some(y) = self.y.as_mut() else {
            return match heights.is_empty() {
                true => Ok(()),
                false => Err(Error::BufferSize { expected: 0, actual: heights.len() }),
            };
        };
        let count = whole_rows(heights.len(), w, y.height - y.rows)?;
        let mut row = try_vec(w)?;
        row.resize(w, 0.0f32);
        for rows in heights.chunks_exact(w.max(1)).take(count) {
            convert_row(rows, &mut row);
            y.push_row(&row);
        }
        self.y_rows += count;
        Ok(())
    }

    /// Fails unless `n` more rows may come.
    fn check_room(&self, n: usize) -> Result<()> {
        if self.x.rows + n > self.height {
            return Err(Error::InvalidOption(format!("all {} rows of the tiling check are in already", self.height)));
        }
        Ok(())
    }

    /// The report, judged as [`ImageKind::Height`] under `opts.threshold`,
    /// once every row (or every row's edge columns, and the edge rows) is
    /// in. An image of height or width 0: score 1 on both axes, as `check`
    /// of an empty image.
    ///
    /// Errors: [`Error::InvalidOption`] saying how many rows are in, when
    /// some are missing (a stream cut short is not the image).
    pub fn finish(self, opts: &TilingOptions) -> Result<TilingReport> {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return Ok(Profiles::empty_report(ImageKind::Height, opts));
        }
        let y_needed = self.y.as_ref().map_or(0, |y| y.height);
        if self.x.rows < h || self.y_rows < y_needed {
            let got = if self.x.rows < h { self.x.rows } else { self.y_rows };
            let of = if self.x.rows < h { h } else { y_needed };
            let what = if self.x.rows < h { "rows" } else { "edge rows" };
            return Err(Error::InvalidOption(format!("the tiling check has {got} of its {of} {what}")));
        }
        let all_rows = Cut::whole(h);
        let px = self.x.profiles().expect("texels, so profiles");
        let x = px.x_axis(h, self.cols);
        let y = match self.y {
            Some(y) => y.profiles().expect("texels, so profiles").y_axis(w, self.rows, self.rows),
            None => px.y_axis(w, all_rows, self.rows),
        };
        Ok(report(&x, &y, ImageKind::Height, opts))
    }
}

/// How many rows of `per_row` values `len` values make, refused when not
/// whole or more than `left`.
fn whole_rows(len: usize, per_row: usize, left: usize) -> Result<usize> {
    // Rows of no values: none, unless values came.
    let count = len.checked_div(per_row).unwrap_or(if len == 0 { 0 } else { usize::MAX });
    if (per_row > 0 && !len.is_multiple_of(per_row)) || count > left {
        return Err(Error::BufferSize { expected: left * per_row, actual: len });
    }
    Ok(count)
}

/// Converts a row of samples into the contract's f32 units.
fn convert_row<H: crate::Sample>(from: &[H], to: &mut [f32]) {
    for (o, &v) in to.iter_mut().zip(from) {
        *o = crate::samples::contract(v) as f32;
    }
}

/// The profiles of a height map fed one row at a time, top to bottom, in
/// memory O(W + H): the engine of [`HeightSeams`], which feeds it the
/// lines the check reads (see [`HeightSeams`] for the memory and the order
/// of the sums).
#[derive(Clone, Debug)]
struct RowSeams {
    width: usize,
    height: usize,
    /// Rows pushed so far, the pending ones included.
    rows: usize,
    /// Rows pushed and not yet measured, judged (times [`JUDGE_SCALE`],
    /// non-finite values as 0): `pending_rows` of `width` values. They are
    /// measured [`TILE_COLS`] columns at a time, so that each pass's rows
    /// and sums stay in a core's cache however wide the image.
    pending: Vec<f32>,
    pending_rows: usize,
    /// Rows measured at once: up to [`CHUNK`], fewer for very wide images.
    block_rows: usize,
    /// Columns per pass: [`TILE_COLS`] (tests change it).
    tile_cols: usize,
    /// Whether the kernels use the processor's widest vectors (tests turn
    /// it off to compare with the baseline build).
    widest: bool,
    /// Rows 0 and 1 as far as pushed (non-finite values as 0), at every
    /// level.
    first: Runs,
    /// The last 4 rows measured, at every level: row y in slot y mod 4.
    ring: Runs,
    /// The runs of rows that the x pairs of the coarser levels compare.
    stack: RowStack,
    /// What a pass over some columns leaves to the passes over the others.
    edges: EdgeLog,
    /// The y sums of the pending rows in progress, row after row, level
    /// after level: value then crease.
    lanes: Vec<[Lanes; 2]>,
    /// The x sums of the current block of [`CHUNK`] rows, in f32 as in
    /// [`Block`], level after level.
    vx_block: Vec<f32>,
    cx_block: Vec<f32>,
    /// The profiles of the [module docs](self), laid out as in
    /// [`Profiles`]; x over the finished blocks. The crease pairs 0 and
    /// H − 2 stay 0: their stencils cross the wrap, but they are neither
    /// the seam nor interior pairs, so no score reads them.
    vx: Vec<f64>,
    cx: Vec<f64>,
    vy: Vec<f64>,
    cy: Vec<f64>,
}

impl RowSeams {
    /// The profiles of a `width` × `height` image, no rows in yet (the
    /// caller has checked the memory, [`bytes_needed`](Self::bytes_needed)).
    fn new(width: usize, height: usize) -> Self {
        let block_rows = pending_rows_for(width, height);
        RowSeams {
            width,
            height,
            rows: 0,
            pending: vec![0.0; block_rows * width],
            pending_rows: 0,
            block_rows,
            tile_cols: TILE_COLS,
            widest: true,
            first: Runs::new(width, 2.min(height)),
            ring: Runs::new(width, 4.min(height)),
            stack: RowStack::new(width),
            edges: EdgeLog::default(),
            lanes: vec![[Lanes::default(); 2]; block_rows * LEVELS],
            vx_block: vec![0.0; LEVELS * width],
            cx_block: vec![0.0; LEVELS * width],
            vx: vec![0.0; LEVELS * width],
            cx: vec![0.0; LEVELS * width],
            vy: vec![0.0; LEVELS * height],
            cy: vec![0.0; LEVELS * height],
        }
    }

    /// The bytes a check of a `width` × `height` image holds (its profiles,
    /// row buffers and pending rows, at every level): about 350 a column
    /// and 96 a row.
    fn bytes_needed(width: usize, height: usize) -> u64 {
        let (w, h, levels) = (width as u64, height as u64, LEVELS as u64);
        // One row at every level: ⌈W / 2^l⌉ values each.
        let row_levels: u64 = (0..LEVELS).map(|l| w.div_ceil(1 << l)).sum();
        let runs = (2.min(h) + 4.min(h)) * row_levels * 4;
        let x_sums = levels * w * 4 + 2 * levels * w * 4 + 2 * levels * w * 8;
        let pending = pending_rows_for(width, height) as u64 * w * 4;
        runs + x_sums + pending + 2 * levels * h * 8
    }

    /// Adds the next row, `width` heights (the caller has checked its
    /// length and that rows are still to come). Non-finite values count as
    /// 0, as in [`check`].
    fn push_row(&mut self, row: &[f32]) {
        let w = self.width;
        debug_assert!(row.len() == w && self.rows < self.height);
        self.rows += 1;
        if w == 0 {
            return;
        }
        for (o, &v) in self.pending[self.pending_rows * w..][..w].iter_mut().zip(row) {
            *o = judged(v);
        }
        self.pending_rows += 1;
        if self.pending_rows == self.block_rows {
            self.measure_pending(false);
        }
    }

    /// Measures the pending rows, [`TILE_COLS`] columns at a time: each
    /// pass runs every row's kernels over its columns, so the kernels add
    /// into every sum in the order of the rows, as a pass over whole rows
    /// would, and give the same bits. With `last`, the runs of rows cut
    /// short by the end are closed too, as [`check`] ends them.
    fn measure_pending(&mut self, last: bool) {
        if self.widest {
            pulp::Arch::new().dispatch(MeasurePending { seams: self, last });
        } else {
            pulp::WithSimd::with_simd(MeasurePending { seams: self, last }, pulp::Scalar::new());
        }
    }

    /// [`measure_pending`](Self::measure_pending), inlined into the
    /// dispatch so that it is compiled for each instruction set.
    #[inline(always)]
    fn measure_pending_here(&mut self, last: bool) {
        let (w, n) = (self.width, self.pending_rows);
        let y0 = self.rows - n;
        let counts = self.stack.count;
        self.lanes[..n * LEVELS].fill([Lanes::default(); 2]);
        for x0 in (0..w).step_by(self.tile_cols) {
            let cols = Cols { x0, x1: (x0 + self.tile_cols).min(w), w };
            // Every pass replays the same runs of rows.
            self.stack.count = counts;
            self.edges.next = 0;
            for i in 0..n {
                let y = y0 + i;
                let slot = y % 4;
                self.ring.slot_mut(slot)[cols.range()].copy_from_slice(&self.pending[i * w..][cols.range()]);
                self.ring.coarsen(slot, &cols);
                if y < 2 {
                    self.first.copy_slot(y, &self.ring, slot, &cols);
                }
                let mut sums =
                    XSums { vx: &mut self.vx_block, cx: &mut self.cx_block, crease: true, edges: &mut self.edges };
                self.stack.push(self.ring.row(0, slot), &cols, &mut sums);
                if (y + 1).is_multiple_of(CHUNK) {
                    flush_cols(&mut self.vx, &mut self.vx_block, &mut self.cx, &mut self.cx_block, &cols);
                }
                // The y pairs whose stencils end at this row and do not wrap.
                let ring = &self.ring;
                for (level, lanes) in self.lanes[i * LEVELS..][..LEVELS].iter_mut().enumerate() {
                    let r = |j: usize| ring.row(level, j % 4);
                    let part = cols.at_level(level, ring.widths[level]);
                    if y >= 3 {
                        // Both sums in one loop: two chains of additions
                        // that do not wait for each other.
                        let [value, crease] = lanes;
                        Lanes::add_both(value, crease, part, [r(y - 3), r(y - 2), r(y - 1), r(y)]);
                    } else if y >= 1 {
                        lanes[0].add(part, [r(y - 1), r(y)], |[b, c]| (c - b).abs());
                    }
                }
            }
            if last {
                let mut sums =
                    XSums { vx: &mut self.vx_block, cx: &mut self.cx_block, crease: true, edges: &mut self.edges };
                self.stack.finish(&cols, &mut sums);
                flush_cols(&mut self.vx, &mut self.vx_block, &mut self.cx, &mut self.cx_block, &cols);
            }
        }
        for (i, lanes) in self.lanes[..n * LEVELS].chunks_exact(LEVELS).enumerate() {
            let y = y0 + i;
            for (level, [value, crease]) in lanes.iter().enumerate() {
                if y >= 1 {
                    self.vy[(y - 1) * LEVELS + level] = value.total();
                }
                if y >= 3 {
                    self.cy[(y - 2) * LEVELS + level] = crease.total();
                }
            }
        }
        self.pending_rows = 0;
    }

    /// The profiles of the image of the rows pushed (its last row wraps
    /// to its first), or none for an image without texels.
    fn profiles(mut self) -> Option<Profiles> {
        let (w, h) = (self.width, self.rows);
        if w == 0 || h == 0 {
            return None;
        }
        // The pending rows, and the runs of rows cut short by the last row.
        self.measure_pending(true);
        let (first, ring) = (&self.first, &self.ring);
        let (mut vy, mut cy) = (self.vy, self.cy);
        vy.truncate(h * LEVELS);
        cy.truncate(h * LEVELS);
        // The seams; the passes did the interior pairs. Row j mod H: the
        // seam stencils only reach rows H − 2, H − 1, 0, 1.
        for level in 0..LEVELS {
            let row = |j: usize| {
                let j = j % h;
                if j < 2 { first.row(level, j) } else { ring.row(level, j % 4) }
            };
            vy[(h - 1) * LEVELS + level] = y_value(row(h - 1), row(h));
            cy[(h - 1) * LEVELS + level] = y_crease(row(2 * h - 2), row(h - 1), row(h), row(h + 1));
        }
        Some(Profiles { vx: self.vx, cx: self.cx, vy, cy })
    }
}

/// [`RowSeams::measure_pending`] for [`pulp::Arch::dispatch`]: the
/// kernels built for the widest vectors the processor has (AVX2 on most
/// x86-64 of the last decade; baseline x86-64 has only SSE2's 4 lanes),
/// chosen at run time. The kernels add, subtract and take absolute values
/// lane by lane, in the same order in every build, and nothing fuses a
/// multiply with an add: the same bits on every processor
/// (`tests::every_instruction_set_gives_the_same_bits`).
struct MeasurePending<'a> {
    seams: &'a mut RowSeams,
    last: bool,
}

impl pulp::WithSimd for MeasurePending<'_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        self.seams.measure_pending_here(self.last);
    }
}

/// Columns of one pass of [`RowSeams`] over its pending rows: a
/// multiple of 8 · 2^(LEVELS − 1), so that every pass starts on whole runs
/// at every level and on lane 0 of the y sums. The pass's rows and sums,
/// about 330 bytes a column with 32 pending rows, then stay in a core's
/// cache (at 32768 columns, whole rows took 3 MB and did not).
const TILE_COLS: usize = 1024;

/// Bytes of pending rows [`RowSeams`] holds at most (unless one row is
/// longer).
const PENDING_BYTES: usize = 4 << 20;

/// Rows [`RowSeams`] measures at once for an image `width` wide: as many
/// as [`CHUNK`] (more add nothing: the x sums are flushed every CHUNK rows
/// anyway), fewer when they would take more than [`PENDING_BYTES`].
fn pending_rows_for(width: usize, height: usize) -> usize {
    (PENDING_BYTES / (4 * width.max(1))).clamp(1, CHUNK).min(height.max(1))
}

/// The columns `x0 .. x1` of a row `w` wide that a pass measures.
#[derive(Clone, Copy, Debug)]
struct Cols {
    x0: usize,
    x1: usize,
    w: usize,
}

impl Cols {
    /// The whole row.
    fn whole(w: usize) -> Self {
        Cols { x0: 0, x1: w, w }
    }

    fn range(&self) -> std::ops::Range<usize> {
        self.x0..self.x1
    }

    fn is_first(&self) -> bool {
        self.x0 == 0
    }

    fn is_last(&self) -> bool {
        self.x1 == self.w
    }

    /// The values of a level-`level` row (`width` of them) made from these
    /// columns' texels.
    fn at_level(&self, level: usize, width: usize) -> std::ops::Range<usize> {
        let end = if self.is_last() { width } else { self.x1 >> level };
        (self.x0 >> level)..end
    }
}

/// What the x kernels of a pass over some columns leave to the passes over
/// the others, per event (a row measured, or a run of rows closed), in the
/// order the events come: the last 3 values of the row, for the pairs that
/// straddle the next pass's first column, and the first 3, for the pairs
/// across the wrap, which the last pass adds.
#[derive(Clone, Debug, Default)]
struct EdgeLog {
    /// The event being measured.
    next: usize,
    ends: Vec<[f32; 3]>,
    starts: Vec<[f32; 3]>,
}

/// Where the x kernels add their sums (level-major, as in [`Profiles`]),
/// and what they need from the other passes.
struct XSums<'a> {
    vx: &'a mut [f32],
    cx: &'a mut [f32],
    crease: bool,
    edges: &'a mut EdgeLog,
}

/// Adds the f32 block sums that a pass over `cols` adds to into the f64
/// totals, and clears them: the columns each pass's x kernels own (see
/// [`add_row_x`]), so that each column is flushed after all its rows'
/// additions, as with whole rows.
#[inline(always)]
fn flush_cols(vx: &mut [f64], vx_block: &mut [f32], cx: &mut [f64], cx_block: &mut [f32], cols: &Cols) {
    let w = cols.w;
    let (first, last) = (cols.is_first(), cols.is_last());
    let value = if first { 0 } else { cols.x0 - 1 }..if last { w } else { cols.x1 - 1 };
    // Crease 0 crosses the wrap: the last pass adds it.
    let crease = match (first, last) {
        (true, true) => [0..w, 0..0],
        (true, false) => [1..cols.x1 - 2, 0..0],
        (false, true) => [cols.x0 - 2..w, 0..1],
        (false, false) => [cols.x0 - 2..cols.x1 - 2, 0..0],
    };
    for level in 0..LEVELS {
        let at = |r: &std::ops::Range<usize>| level * w + r.start..level * w + r.end;
        flush(&mut vx[at(&value)], &mut vx_block[at(&value)]);
        for part in &crease {
            flush(&mut cx[at(part)], &mut cx_block[at(part)]);
        }
    }
}

/// Adds the f32 block sums into the f64 totals and clears them.
#[inline(always)]
fn flush(total: &mut [f64], block: &mut [f32]) {
    for (t, b) in total.iter_mut().zip(block.iter_mut()) {
        *t += unscaled(*b);
        *b = 0.0;
    }
}

/// The report from complete profiles of both axes (W, H ≥ 1): ε from the
/// mean |Δ| of level 0 over the pairs judged, then [`axis_score`] per axis.
fn report(x: &Axis, y: &Axis, kind: ImageKind, opts: &TilingOptions) -> TilingReport {
    // ε from the mean |Δ| per texel over both axes (every pair's texels,
    // the seam's included: 2·W·H differences when all lines are kept),
    // times the line length each axis's profile sums over.
    let total: f64 = x.own_pairs().map(|k| x.value[k]).chain(y.own_pairs().map(|k| y.value[k])).sum();
    let count = x.own_pairs().count() * x.line + y.own_pairs().count() * y.line;
    let mean = total / count as f64;
    let eps_x = FLOOR_FRACTION * mean * x.line as f64 + 1e-30;
    let eps_y = FLOOR_FRACTION * mean * y.line as f64 + 1e-30;
    let crease = kind == ImageKind::Height;
    TilingReport {
        kind,
        x: axis_report(axis_score(x, crease, eps_x), opts),
        y: axis_report(axis_score(y, crease, eps_y), opts),
    }
}

/// The score of one axis: the largest of its levels' scores.
fn axis_score(axis: &Axis, with_crease: bool, eps: f64) -> f64 {
    let n = axis.pairs;
    (0..LEVELS)
        .filter(|&level| level == 0 || axis.line >= MIN_RUNS << level)
        .map(|level| {
            let (v, c) = (&axis.value[level * n..][..n], &axis.crease[level * n..][..n]);
            level_score(v, c, axis.joint, with_crease, eps)
        })
        .fold(0.0, f64::max)
}

/// The score of one level from its value and crease profiles (seam last):
/// the seam against the interior pairs, those whose stencils neither
/// cross the seam nor the `joint` of a cut.
fn level_score(value: &[f64], crease: &[f64], joint: Option<usize>, with_crease: bool, eps: f64) -> f64 {
    let n = value.len();
    if n < 2 {
        return 1.0;
    }
    // A value pair reads lines k, k + 1; a crease k − 1 … k + 2, so the
    // creases k = joint − 1 … joint + 1 reach across the cut.
    let apart = |k: usize, reach: usize| joint.is_none_or(|j| k + reach < j || k > j + reach);
    let interior = |p: &[f64], ks: std::ops::Range<usize>, reach| -> Vec<f64> {
        ks.filter(|&k| apart(k, reach)).map(|k| p[k]).collect()
    };
    let mut score = seam_ratio(value[n - 1], interior(value, 0..n - 1, 0), eps);
    if with_crease && n >= 4 {
        score = score.max(seam_ratio(crease[n - 1], interior(crease, 1..n - 2, 1), eps));
    }
    score
}

/// (seam + ε) / (R + ε), R the k-th largest of `interior` (see module docs).
fn seam_ratio(seam: f64, mut interior: Vec<f64>, eps: f64) -> f64 {
    let n = interior.len();
    let k = MIN_RANK.max((n as f64 * RANK_FRACTION).ceil() as usize).min(n.div_ceil(2)).max(1);
    // The k-th largest is the (n − k)-th smallest: linear-time selection.
    let (_, reference, _) = interior.select_nth_unstable_by(n - k, f64::total_cmp);
    (seam + eps) / (*reference + eps)
}

/// What is measured of one signal, before it is compared.
enum Signal<'a> {
    /// A plane as it is.
    Plane(&'a [f32]),
    /// The luma of three planes.
    Luma(&'a [f32], &'a [f32], &'a [f32]),
}

impl Signal<'_> {
    /// Writes the kept columns `cols` of image row `y` into `out`
    /// (`cols.kept()` values), times [`JUDGE_SCALE`], non-finite values
    /// as 0.
    fn fill(&self, y: usize, cols: Cut, out: &mut [f32]) {
        let w = cols.len;
        let mut at = 0;
        for part in cols.ranges() {
            let out = &mut out[at..][..part.len()];
            at += part.len();
            let part = y * w + part.start..y * w + part.end;
            match *self {
                Signal::Plane(p) => {
                    for (o, &v) in out.iter_mut().zip(&p[part]) {
                        *o = judged(v);
                    }
                }
                Signal::Luma(r, g, b) => {
                    let rows = r[part.clone()].iter().zip(&g[part.clone()]).zip(&b[part]);
                    // The weights carry the scale: w·S·r is S·(w·r) exactly.
                    let [wr, wg, wb] = [0.2126, 0.7152, 0.0722].map(|w: f32| w * JUDGE_SCALE);
                    for (o, ((&r, &g), &b)) in out.iter_mut().zip(rows) {
                        *o = finite(wr * r + wg * g + wb * b);
                    }
                }
            }
        }
    }
}

/// The lines of one axis that the check reads: all of them, or, on an axis
/// longer than 2 · [`EDGE_LINES`], the first and the last `EDGE_LINES`
/// (the reference pairs lie within them; see the
/// [module docs](self#the-reference-lies-near-the-seam)). Read in order,
/// the kept lines make an image whose wrap is the image's own seam and
/// whose pair across the cut, the *joint*, joins two lines that are not
/// neighbours and is judged by nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Cut {
    /// Lines of the axis.
    len: usize,
    /// Lines kept at each end: `len` when all are kept.
    edge: usize,
}

impl Cut {
    /// The lines a check of an axis `len` long reads.
    fn of(len: usize) -> Cut {
        Cut { len, edge: if len > 2 * EDGE_LINES { EDGE_LINES } else { len } }
    }

    /// Every line.
    fn whole(len: usize) -> Cut {
        Cut { len, edge: len }
    }

    fn is_whole(self) -> bool {
        self.edge == self.len
    }

    /// How many lines are kept.
    fn kept(self) -> usize {
        if self.is_whole() { self.len } else { 2 * self.edge }
    }

    /// The image line of kept line `i`.
    fn line(self, i: usize) -> usize {
        if i < self.edge { i } else { i + self.len - 2 * self.edge }
    }

    /// The kept lines, first end then last.
    fn ranges(self) -> [std::ops::Range<usize>; 2] {
        if self.is_whole() { [0..self.len, self.len..self.len] } else { [0..self.edge, self.len - self.edge..self.len] }
    }

    /// The kept pair across the cut, which is no pair of the image.
    fn joint(self) -> Option<usize> {
        (!self.is_whole()).then(|| self.edge - 1)
    }
}

/// The per-pair sums of one axis, level after level, over the kept lines
/// of a [`Cut`]: pair i joins kept line i to i + 1, the last pair is the
/// seam; `line` texels are summed along each line.
struct Axis {
    value: Vec<f64>,
    crease: Vec<f64>,
    /// Pairs per level.
    pairs: usize,
    line: usize,
    /// The pair across the cut, judged by nothing.
    joint: Option<usize>,
}

impl Axis {
    /// The profile of every line of an axis (`pairs` per level) reduced to
    /// the lines `cut` keeps.
    fn kept(value: Vec<f64>, crease: Vec<f64>, line: usize, cut: Cut) -> Axis {
        let pairs = value.len() / LEVELS;
        if cut.is_whole() {
            return Axis { value, crease, pairs, line, joint: None };
        }
        // The pairs between kept lines are the image's pairs of the same
        // lines; those across the cut are taken from anywhere, unread.
        let gather = |p: &[f64]| -> Vec<f64> {
            (0..LEVELS).flat_map(|level| (0..cut.kept()).map(move |i| p[level * pairs + cut.line(i)])).collect()
        };
        Axis { value: gather(&value), crease: gather(&crease), pairs: cut.kept(), line, joint: cut.joint() }
    }

    /// The pairs that are the image's own (all but the joint).
    fn own_pairs(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.pairs).filter(|&k| Some(k) != self.joint)
    }
}

/// The per-pair sums of the [module docs](self), summed over the signals,
/// at every level: `vx[l·W + k]`, `cx[l·W + k]` for the column pair
/// k → k+1 at level l (k = W−1 the wrap), `vy[y·LEVELS + l]`,
/// `cy[y·LEVELS + l]` for the row pair y → y+1 (row after row, so that
/// the parallel tasks own whole chunks of it). The crease sums stay 0 when
/// not asked for.
struct Profiles {
    vx: Vec<f64>,
    cx: Vec<f64>,
    vy: Vec<f64>,
    cy: Vec<f64>,
}

impl Profiles {
    /// The report on an image without texels: both axes tile, score 1.
    fn empty_report(kind: ImageKind, opts: &TilingOptions) -> TilingReport {
        TilingReport { kind, x: axis_report(1.0, opts), y: axis_report(1.0, opts) }
    }

    /// The x axis's profiles, measured over the columns `cols` keeps of
    /// every row (lines `line` rows long).
    fn x_axis(&self, line: usize, cols: Cut) -> Axis {
        Axis {
            value: self.vx.clone(),
            crease: self.cx.clone(),
            pairs: self.vx.len() / LEVELS,
            line,
            joint: cols.joint(),
        }
    }

    /// The y axis's profiles, level after level, measured over the rows
    /// `measured` keeps (lines `line` columns long), reduced to the rows
    /// `kept` keeps (the same cut, or every row reduced).
    fn y_axis(&self, line: usize, measured: Cut, kept: Cut) -> Axis {
        // The y profiles level after level, as the x ones are.
        let by_level = |p: &[f64]| -> Vec<f64> {
            (0..LEVELS).flat_map(|level| p.iter().skip(level).step_by(LEVELS).copied()).collect()
        };
        let (value, crease) = (by_level(&self.vy), by_level(&self.cy));
        if measured == kept {
            let pairs = value.len() / LEVELS;
            Axis { value, crease, pairs, line, joint: kept.joint() }
        } else {
            Axis::kept(value, crease, line, kept)
        }
    }

    /// The bytes [`measure`](Self::measure) holds at most: the y profiles,
    /// and per thread (and once more while they are summed) two x
    /// profiles and a [`Block`].
    fn bytes_needed(width: usize, height: usize) -> u64 {
        let (w, h, levels) = (width as u64, height as u64, LEVELS as u64);
        let block = 4 * 2 * w * 4 + levels * w * 4 + 2 * levels * w * 4;
        let per_thread = 2 * levels * w * 8 + block;
        2 * levels * h * 8 + (crate::par::current_num_threads() as u64 + 1) * per_thread
    }

    /// The profiles of the image made of the columns `cols` keeps of the
    /// rows `rows` keeps, in their order.
    fn measure(planes: &[&[f32]], cols: Cut, rows: Cut, kind: ImageKind) -> Profiles {
        let (w, h) = (cols.kept(), rows.kept());
        let signals: Vec<Signal> = match kind {
            ImageKind::Height if planes.len() >= 3 => {
                vec![Signal::Luma(planes[0], planes[1], planes[2])]
            }
            ImageKind::Normal if planes.len() >= 3 => planes[..3].iter().map(|p| Signal::Plane(p)).collect(),
            _ => vec![Signal::Plane(planes[0])],
        };
        let crease = kind == ImageKind::Height;
        let mut vy = vec![0.0f64; LEVELS * h];
        let mut cy = vec![0.0f64; LEVELS * h];
        let zeros = || vec![0.0f64; LEVELS * w];
        // Each task owns CHUNK row pairs of the y profiles and adds its rows
        // to a per-thread x profile; the x profiles are summed at the end.
        let (vx, cx, _) = crate::par::fold_reduce(
            vy.par_chunks_mut(CHUNK * LEVELS).zip(cy.par_chunks_mut(CHUNK * LEVELS)).enumerate(),
            || (zeros(), zeros(), Block::new(w)),
            |(mut vx, mut cx, mut block), (c, (vy, cy))| {
                for signal in &signals {
                    block.measure(signal, cols, rows, c * CHUNK, vy.len() / LEVELS, crease);
                    for (acc, s) in vy.iter_mut().zip(&block.vy) {
                        *acc += s;
                    }
                    for (acc, s) in cy.iter_mut().zip(&block.cy) {
                        *acc += s;
                    }
                    for (acc, &s) in vx.iter_mut().zip(&block.vx) {
                        *acc += unscaled(s);
                    }
                    for (acc, &s) in cx.iter_mut().zip(&block.cx) {
                        *acc += unscaled(s);
                    }
                }
                (vx, cx, block)
            },
            |(mut vx, mut cx, block), (vx2, cx2, _)| {
                for (a, b) in vx.iter_mut().zip(vx2) {
                    *a += b;
                }
                for (a, b) in cx.iter_mut().zip(cx2) {
                    *a += b;
                }
                (vx, cx, block)
            },
        );
        Profiles { vx, cx, vy, cy }
    }
}

/// Rows of one signal at every level: level l of a row holds its texels
/// summed in runs of 2^l along the row (the last run shorter when 2^l does
/// not divide W), `slots` rows per level.
#[derive(Clone, Debug)]
struct Runs {
    /// Values per row at each level: ⌈W / 2^l⌉.
    widths: [usize; LEVELS],
    /// Level l: `slots` rows of `widths[l]` values.
    levels: [Vec<f32>; LEVELS],
}

impl Runs {
    fn new(w: usize, slots: usize) -> Self {
        let widths: [usize; LEVELS] = std::array::from_fn(|level| w.div_ceil(1 << level));
        Runs { widths, levels: std::array::from_fn(|level| vec![0.0; slots * widths[level]]) }
    }

    /// Level `level` of the row in `slot`.
    fn row(&self, level: usize, slot: usize) -> &[f32] {
        let n = self.widths[level];
        &self.levels[level][slot * n..][..n]
    }

    /// The texels of the row in `slot`, to be written before [`coarsen`](Self::coarsen).
    fn slot_mut(&mut self, slot: usize) -> &mut [f32] {
        let n = self.widths[0];
        &mut self.levels[0][slot * n..][..n]
    }

    /// Levels 1 … of the row in `slot` from its texels in `cols`: each
    /// level sums pairs of the one below.
    #[inline(always)]
    fn coarsen(&mut self, slot: usize, cols: &Cols) {
        for level in 1..LEVELS {
            let (below, above) = self.levels.split_at_mut(level);
            let (nb, na) = (self.widths[level - 1], self.widths[level]);
            let src = &below[level - 1][slot * nb..][cols.at_level(level - 1, nb)];
            let dst = &mut above[0][slot * na..][cols.at_level(level, na)];
            for (d, s) in dst.iter_mut().zip(src.chunks_exact(2)) {
                *d = s[0] + s[1];
            }
            if src.len() % 2 == 1 {
                dst[src.len() / 2] = src[src.len() - 1];
            }
        }
    }

    /// Copies every level of `from`'s row in `from_slot` into `slot`, the
    /// values made from `cols`.
    #[inline(always)]
    fn copy_slot(&mut self, slot: usize, from: &Runs, from_slot: usize, cols: &Cols) {
        for level in 0..LEVELS {
            let n = self.widths[level];
            let part = cols.at_level(level, n);
            self.levels[level][slot * n..][part.clone()].copy_from_slice(&from.row(level, from_slot)[part]);
        }
    }
}

/// Rows summed in runs of 2^l rows (aligned on multiples of 2^l from row 0),
/// whose x pairs are level l's: each row pushed is level 0; two finished
/// runs of a level make one of the next. A pass over some columns keeps
/// those columns of the runs.
#[derive(Clone, Debug)]
struct RowStack {
    /// Level l's run in progress (level 0 unused).
    sums: [Vec<f32>; LEVELS],
    /// How many runs of level l − 1 (rows for l = 1) `sums[l]` holds.
    count: [usize; LEVELS],
}

impl RowStack {
    fn new(w: usize) -> Self {
        RowStack { sums: std::array::from_fn(|_| vec![0.0; w]), count: [0; LEVELS] }
    }

    /// Adds the x pairs of row `r` (level 0) to the sums, and those of
    /// every run it completes, over `cols`.
    #[inline(always)]
    fn push(&mut self, r: &[f32], cols: &Cols, sums: &mut XSums) {
        add_row_x(r, cols, 0, sums);
        self.add_into(1, r, cols);
        let mut level = 1;
        while level < LEVELS && self.count[level] == 2 {
            self.close(level, cols, sums);
            level += 1;
        }
    }

    /// Closes the runs cut short by the end of the rows, finest first (each
    /// then counts as one run of the next level).
    #[inline(always)]
    fn finish(&mut self, cols: &Cols, sums: &mut XSums) {
        for level in 1..LEVELS {
            if self.count[level] > 0 {
                self.close(level, cols, sums);
            }
        }
    }

    #[inline(always)]
    fn add_into(&mut self, level: usize, r: &[f32], cols: &Cols) {
        // The first run of a level is copied, not added to zeros: no pass
        // to clear the sums when a run closes.
        let (sums, r) = (&mut self.sums[level][cols.range()], &r[cols.range()]);
        if self.count[level] == 0 {
            sums.copy_from_slice(r);
        } else {
            for (s, &v) in sums.iter_mut().zip(r) {
                *s += v;
            }
        }
        self.count[level] += 1;
    }

    /// Measures level `level`'s run, hands it to the next level, clears it.
    #[inline(always)]
    fn close(&mut self, level: usize, cols: &Cols, sums: &mut XSums) {
        let run = std::mem::take(&mut self.sums[level]);
        add_row_x(&run, cols, level, sums);
        if level + 1 < LEVELS {
            self.add_into(level + 1, &run, cols);
        }
        self.sums[level] = run;
        self.count[level] = 0;
    }
}

/// One task's rows and its partial sums.
///
/// Rule of the loops: every row of the block is read for both axes while it
/// is in cache; x sums of up to CHUNK rows are kept in f32 (error ≲ 10⁻⁵
/// relative), then added into f64; y sums run in 8 f32 lanes so they
/// vectorise, each lane then added in f64.
struct Block {
    /// The last 4 of rows y0 − 1 … y0 + n + 1 (mod H) of one signal at
    /// every level (block row i in slot i mod 4): the n rows of the task
    /// and the halo its crease stencils need, as they come.
    rows: Runs,
    /// The runs of rows of the task's rows (CHUNK is a multiple of the
    /// longest run, so a task's runs are whole but at the image's end).
    stack: RowStack,
    /// Level-major, as in [`Profiles`].
    vx: Vec<f32>,
    cx: Vec<f32>,
    /// Row after row, as in [`Profiles`].
    vy: Vec<f64>,
    cy: Vec<f64>,
    /// Unused: a block's rows are measured whole.
    edges: EdgeLog,
}

impl Block {
    fn new(w: usize) -> Self {
        Block {
            rows: Runs::new(w, 4),
            stack: RowStack::new(w),
            vx: vec![0.0; LEVELS * w],
            cx: vec![0.0; LEVELS * w],
            vy: Vec::with_capacity(CHUNK * LEVELS),
            cy: Vec::with_capacity(CHUNK * LEVELS),
            edges: EdgeLog::default(),
        }
    }

    /// The sums of rows y0 … y0 + n − 1 (x pairs) and of row pairs
    /// y0 … y0 + n − 1 → next (y pairs) of the image made of the columns
    /// `kept_cols` keeps of the rows `kept_rows` keeps.
    fn measure(&mut self, signal: &Signal, kept_cols: Cut, kept_rows: Cut, y0: usize, n: usize, crease: bool) {
        let h = kept_rows.kept();
        self.vx.fill(0.0);
        self.cx.fill(0.0);
        self.vy.clear();
        self.cy.clear();
        // Block row i is image row (y0 − 1 + i) mod H. Each row is measured
        // as soon as it is made, while it and the three before it are in
        // cache: its x pairs (rows 1 … n), and the y pair whose stencil it
        // ends (pair i − 2, over rows i − 3 … i).
        let whole = Cols::whole(self.vx.len() / LEVELS);
        self.edges.next = 0;
        for i in 0..n + 3 {
            signal.fill(kept_rows.line((y0 + h - 1 + i) % h), kept_cols, self.rows.slot_mut(i % 4));
            self.rows.coarsen(i % 4, &whole);
            let rows = &self.rows;
            if (1..=n).contains(&i) {
                let mut sums = XSums { vx: &mut self.vx, cx: &mut self.cx, crease, edges: &mut self.edges };
                self.stack.push(rows.row(0, i % 4), &whole, &mut sums);
            }
            if i >= 3 {
                for level in 0..LEVELS {
                    // Rows y − 1, y, y + 1, y + 2 for the pair y → y + 1.
                    let r = |j: usize| rows.row(level, j % 4);
                    self.vy.push(y_value(r(i - 2), r(i - 1)));
                    self.cy.push(if crease { y_crease(r(i - 3), r(i - 2), r(i - 1), r(i)) } else { 0.0 });
                }
            }
        }
        let mut sums = XSums { vx: &mut self.vx, cx: &mut self.cx, crease, edges: &mut self.edges };
        self.stack.finish(&whole, &mut sums);
    }
}

/// The [`AxisReport`] of a score under `opts.threshold`.
fn axis_report(score: f64, opts: &TilingOptions) -> AxisReport {
    AxisReport { score, seamless: score <= opts.threshold }
}

/// A texel as judged: non-finite values as 0.
#[inline]
fn finite(v: f32) -> f32 {
    if v.is_finite() { v } else { 0.0 }
}

/// A height as the kernels measure it: times [`JUDGE_SCALE`], non-finite
/// values as 0.
#[inline]
fn judged(v: f32) -> f32 {
    finite(v * JUDGE_SCALE)
}

/// A kernel's f32 sum back in height units, exactly.
#[inline]
fn unscaled(s: f32) -> f64 {
    f64::from(s) * UNSCALE
}

/// Adds the x pairs of row `r` at `level` (W ≥ 1 values, of which a pass
/// over `cols` holds those columns) to the f32 sums and, with
/// `sums.crease`, its x creases. The one x kernel of [`check`] and
/// [`HeightSeams`].
///
/// A pass adds the pairs whose stencils end in its columns: value pair k
/// (texels k, k + 1) for k = x0 − 1 … x1 − 2 and crease k (k − 1 … k + 2)
/// for k = x0 − 2 … x1 − 3, with the last 3 texels of the same event from
/// the pass before; the last pass adds the pairs across the wrap too, with
/// the first 3 texels from the first pass. A pass over the whole row does
/// it all with its own texels.
#[inline(always)]
fn add_row_x(r: &[f32], cols: &Cols, level: usize, sums: &mut XSums) {
    let Cols { x0, x1, w } = *cols;
    let (first, last) = (cols.is_first(), cols.is_last());
    let vx = &mut sums.vx[level * w..][..w];
    let cx = &mut sums.cx[level * w..][..w];
    let log = &mut *sums.edges;
    let event = log.next;
    log.next += 1;
    let (before, start) = if first { ([0.0; 3], [0.0; 3]) } else { (log.ends[event], log.starts[event]) };
    if !last {
        let end = [r[x1 - 3], r[x1 - 2], r[x1 - 1]];
        if first {
            set_or_push(&mut log.ends, event, end);
            set_or_push(&mut log.starts, event, [r[0], r[1], r[2]]);
        } else {
            log.ends[event] = end;
        }
    }
    // h(k) for any k a stencil of this pass reaches (mod W): its own
    // columns, the 3 before them, and across the wrap the row's first 3.
    // Only for the few columns at the pass's edges or across the wrap, so
    // the loops over the rest read `r` in place.
    let h = |k: usize| {
        let k = k % w;
        if k >= x0 {
            r[k]
        } else if k + 3 >= x0 {
            before[k + 3 - x0]
        } else {
            start[k]
        }
    };
    let crease_at = |k: usize| ((h(k + 2) - h(k + 1)) - (h(k) - h(k + w - 1))).abs();
    // Values: pair k → k + 1, the last one the wrap.
    for ((v, &b), &c) in vx[x0..x1 - 1].iter_mut().zip(&r[x0..x1]).zip(&r[x0 + 1..x1]) {
        *v += (c - b).abs();
    }
    if !first {
        vx[x0 - 1] += (r[x0] - before[2]).abs();
    }
    if last {
        vx[w - 1] += (h(0) - r[w - 1]).abs();
    }
    if !sums.crease {
        return;
    }
    if w >= 4 {
        // Creases: a, b, c, d = h(k−1), h(k), h(k+1), h(k+2); in place for
        // k = x0 + 1 … x1 − 3, from the pass before for k = x0 − 2 … x0,
        // through the wrap for k = 0, W−2 and W−1.
        let inside = (x0 + 1).min(x1.saturating_sub(2));
        let lo = if first { 1 } else { x0 - 2 };
        for (k, s) in cx.iter_mut().enumerate().take(inside).skip(lo) {
            *s += crease_at(k);
        }
        if x1 >= inside + 3 {
            let (a, b, c, d) = (&r[inside - 1..x1 - 3], &r[inside..x1 - 2], &r[inside + 1..x1 - 1], &r[inside + 2..x1]);
            for (k, s) in cx[inside..x1 - 2].iter_mut().enumerate() {
                *s += ((d[k] - c[k]) - (b[k] - a[k])).abs();
            }
        }
        if last {
            for k in [0, w - 2, w - 1] {
                cx[k] += crease_at(k);
            }
        }
    } else {
        for (k, s) in cx[..w].iter_mut().enumerate() {
            *s += crease_at(k);
        }
    }
}

/// Sets `log[at]`, growing it by one when `at` is its length.
fn set_or_push(log: &mut Vec<[f32; 3]>, at: usize, value: [f32; 3]) {
    if at < log.len() {
        log[at] = value;
    } else {
        log.push(value);
    }
}

/// The y value sum of the row pair `b` → `c`.
#[inline]
fn y_value(b: &[f32], c: &[f32]) -> f64 {
    lane_sum([b, c], |[b, c]| (c - b).abs())
}

/// The y crease sum of the row pair `b` → `c`, `a` the row before `b` and
/// `d` the row after `c`.
#[inline]
fn y_crease(a: &[f32], b: &[f32], c: &[f32], d: &[f32]) -> f64 {
    lane_sum([a, b, c, d], |[a, b, c, d]| ((d - c) - (b - a)).abs())
}

/// Σ f(rows at x) for x in 0 … n − 1 (n the first row's length): see
/// [`Lanes`].
#[inline(always)]
fn lane_sum<const K: usize>(rows: [&[f32]; K], f: impl Fn([f32; K]) -> f32) -> f64 {
    let mut lanes = Lanes::default();
    lanes.add(0..rows[0].len(), rows, f);
    lanes.total()
}

/// A y sum over the texels of rows, some columns at a time: in 8 f32
/// lanes (lane l takes x ≡ l mod 8; the loop over fixed chunks
/// vectorises), the texels past the rows' last multiple of 8 in f64, all
/// added in f64 at the end and scaled back to height units. Parts added
/// left to right, each starting on a multiple of 8, give the bits of one
/// part over the whole rows.
#[derive(Clone, Copy, Debug, Default)]
struct Lanes {
    lanes: [f32; 8],
    tail: f64,
}

impl Lanes {
    /// Adds f(rows at x) for x in `part` (starting on a multiple of 8).
    #[inline(always)]
    fn add<const K: usize>(&mut self, part: std::ops::Range<usize>, rows: [&[f32]; K], f: impl Fn([f32; K]) -> f32) {
        let n = rows[0].len();
        let whole = (n - n % 8).min(part.end);
        let rows_whole = rows.map(|r| &r[part.start..whole]);
        // A local copy: through `self` the lanes were stored at every step.
        let mut lanes = self.lanes;
        for x0 in (0..whole - part.start).step_by(8) {
            let at: [&[f32; 8]; K] = rows_whole.map(|r| r[x0..x0 + 8].try_into().expect("8 values"));
            for (l, lane) in lanes.iter_mut().enumerate() {
                *lane += f(at.map(|c| c[l]));
            }
        }
        self.lanes = lanes;
        if part.end > whole {
            self.tail = (whole..part.end).map(|x| f64::from(f(rows.map(|r| r[x])))).sum();
        }
    }

    /// Adds to `value` the y value sum of the row pair `b` → `c` and to
    /// `crease` its crease sum, over `part`, as [`add`](Self::add) does
    /// each (the same additions in the same order), in one loop.
    #[inline(always)]
    fn add_both(value: &mut Lanes, crease: &mut Lanes, part: std::ops::Range<usize>, rows: [&[f32]; 4]) {
        let n = rows[0].len();
        let whole = (n - n % 8).min(part.end);
        let [a, b, c, d] = rows.map(|r| &r[part.start..whole]);
        let (mut v, mut k) = (value.lanes, crease.lanes);
        for x0 in (0..whole - part.start).step_by(8) {
            let at = |r: &[f32]| -> [f32; 8] { r[x0..x0 + 8].try_into().expect("8 values") };
            let (a, b, c, d) = (at(a), at(b), at(c), at(d));
            for l in 0..8 {
                v[l] += (d[l] - c[l]).abs();
                k[l] += ((d[l] - c[l]) - (b[l] - a[l])).abs();
            }
        }
        (value.lanes, crease.lanes) = (v, k);
        if part.end > whole {
            let [a, b, c, d] = rows;
            value.tail = (whole..part.end).map(|x| f64::from((d[x] - c[x]).abs())).sum();
            crease.tail = (whole..part.end).map(|x| f64::from(((d[x] - c[x]) - (b[x] - a[x])).abs())).sum();
        }
    }

    /// The sum, in height units.
    fn total(&self) -> f64 {
        (self.tail + self.lanes.iter().map(|&l| f64::from(l)).sum::<f64>()) * UNSCALE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_x_kernel_is_the_wrapped_stencil_at_every_width() {
        // Each column's pair and crease, written with plain modular
        // indices, against the kernel's in-place loops and edge columns;
        // added onto earlier sums, as rows are.
        for w in 1..=11usize {
            let r: Vec<f32> = (0..w).map(|k| ((k * 7919 + 13) % 101) as f32 * 0.37 - 9.0).collect();
            let h = |k: usize| r[k % w];
            let earlier: Vec<f32> = (0..w).map(|k| k as f32 * 0.5).collect();
            // Whole, then in passes of 3 … W − 1 columns (a pass before
            // the last holds at least the 3 texels the next one needs).
            for pass in std::iter::once(w).chain(3..w) {
                let (mut vx, mut cx) = (earlier.clone(), earlier.clone());
                let mut edges = EdgeLog::default();
                for x0 in (0..w).step_by(pass) {
                    edges.next = 0;
                    let mut sums = XSums { vx: &mut vx, cx: &mut cx, crease: true, edges: &mut edges };
                    add_row_x(&r, &Cols { x0, x1: (x0 + pass).min(w), w }, 0, &mut sums);
                }
                for k in 0..w {
                    let value = (h(k + 1) - h(k)).abs();
                    let crease = ((h(k + 2) - h(k + 1)) - (h(k) - h(k + w - 1))).abs();
                    assert_eq!(vx[k], earlier[k] + value, "value of column {k}, W = {w}, passes of {pass}");
                    assert_eq!(cx[k], earlier[k] + crease, "crease of column {k}, W = {w}, passes of {pass}");
                }
            }
            let (mut vx, mut untouched) = (earlier.clone(), earlier.clone());
            let mut edges = EdgeLog::default();
            let mut sums = XSums { vx: &mut vx, cx: &mut untouched, crease: false, edges: &mut edges };
            add_row_x(&r, &Cols::whole(w), 0, &mut sums);
            assert_eq!(untouched, earlier, "no creases asked for, W = {w}");
        }
    }

    /// The profiles of a [`RowSeams`] fed `rows` (`w` wide), measured
    /// `tile_cols` columns at a time.
    fn streamed_profiles(rows: &[f32], w: usize, h: usize, tile_cols: usize) -> Vec<Vec<u64>> {
        profiles_of(rows, w, h, tile_cols, true)
    }

    /// The same, with the kernels built for the widest vectors or not.
    fn profiles_of(rows: &[f32], w: usize, h: usize, tile_cols: usize, widest: bool) -> Vec<Vec<u64>> {
        let mut seams = RowSeams::new(w, h);
        seams.tile_cols = tile_cols;
        seams.widest = widest;
        for row in rows.chunks_exact(w) {
            seams.push_row(row);
        }
        seams.measure_pending(true);
        [&seams.vx, &seams.cx, &seams.vy, &seams.cy].map(|p| p.iter().map(|v| v.to_bits()).collect()).to_vec()
    }

    #[test]
    fn passes_over_some_columns_give_the_bits_of_whole_rows() {
        // Passes of 256 columns (the narrowest that keeps every level's
        // runs and the 8 lanes whole) against one pass over the whole row:
        // pass edges after 1, 2 and 3 columns of the last pass, wide and
        // narrow last passes, heights that end blocks and runs early.
        let mut state = 7u64;
        let mut random = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        for w in [257, 258, 259, 260, 300, 511, 512, 513, 700, 1029] {
            for h in [1, 2, 3, 4, 5, 33, 70] {
                // Structure along both axes, so every level's sums differ.
                let rows: Vec<f32> = (0..w * h)
                    .map(|k| ((k % w) / 7 % 3) as f32 * 5.0 + ((k / w) / 3 % 2) as f32 * 3.0 + random())
                    .collect();
                let whole = streamed_profiles(&rows, w, h, w.next_multiple_of(256));
                assert_eq!(streamed_profiles(&rows, w, h, 256), whole, "{w}×{h}");
                assert!(whole[0].iter().any(|&v| f64::from_bits(v) > 0.0), "{w}×{h}: zero sums");
            }
        }
    }

    #[test]
    fn every_instruction_set_gives_the_same_bits() {
        // The kernels as built for this processor's widest vectors, and for
        // baseline x86-64 (or the target's baseline elsewhere): the same
        // sums, to the bit, on values of every size the judge sees.
        let (w, h) = (1000, 75);
        let rows: Vec<f32> = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f32, (k / w) as f32);
                (x * 0.37).sin() * 1e3 + (y * 0.11).cos() * 7.0 + ((k * 7919) % 101) as f32 * 1e-3
            })
            .collect();
        let widest = profiles_of(&rows, w, h, 256, true);
        assert_eq!(profiles_of(&rows, w, h, 256, false), widest);
        assert!(widest[1].iter().any(|&v| f64::from_bits(v) > 0.0), "zero creases");
    }

    #[test]
    fn shift_half_moves_the_seams_to_the_middle() {
        // 4×3: rows shift by 1, columns by 2.
        let t: Vec<u8> = (0..12).collect();
        assert_eq!(shift_half(&t, 4, 3).unwrap(), [6, 7, 4, 5, 10, 11, 8, 9, 2, 3, 0, 1]);
        assert_eq!(shift_half(&[7u8], 1, 1).unwrap(), [7]);
    }

    #[test]
    fn suggested_borders_wrap_only_what_tiles() {
        let axis = |seamless| AxisReport { score: if seamless { 1.0 } else { 9.0 }, seamless };
        let r = TilingReport { kind: ImageKind::Height, x: axis(true), y: axis(false) };
        assert_eq!(r.suggested_borders(), Borders { x: Border::Wrap, y: Border::Mirror });
    }

    #[test]
    fn reference_rank_is_clamped_for_short_axes() {
        // Three interior pairs: the rank is the median-or-above (2nd largest).
        assert_eq!(seam_ratio(2.0, vec![1.0, 2.0, 4.0], 0.0), 1.0);
        // One pair: itself.
        assert_eq!(seam_ratio(3.0, vec![1.5], 0.0), 2.0);
        // Many: the 4th largest while 1 % is fewer than 4.
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(seam_ratio(97.0, v, 0.0), 1.0);
        let v: Vec<f64> = (1..=1000).map(f64::from).collect();
        assert_eq!(seam_ratio(991.0, v, 0.0), 1.0);
    }

    #[test]
    fn a_level_counts_only_when_the_seam_holds_8_of_its_runs() {
        let axis = |value: Vec<f64>, crease: &[f64], line| Axis {
            pairs: value.len() / LEVELS,
            value,
            crease: crease.to_vec(),
            line,
            joint: None,
        };
        // 8 pairs per level, all 1 but level 1's seam, 5 times larger.
        let n = 8;
        let mut value = vec![1.0; LEVELS * n];
        value[n + n - 1] = 5.0;
        let crease = vec![0.0; LEVELS * n];
        // Level 1 sums runs of 2: a seam of 15 texels holds 7, of 16 holds 8.
        assert_eq!(axis_score(&axis(value.clone(), &crease, 15), true, 0.0), 1.0);
        assert_eq!(axis_score(&axis(value, &crease, 16), true, 0.0), 5.0);
        // The crease counts at every level too (interior creases 1 … n − 3).
        let mut crease = vec![1.0; LEVELS * n];
        crease[5 * n + n - 1] = 3.0;
        assert_eq!(axis_score(&axis(vec![1.0; LEVELS * n], &crease, 256), true, 0.0), 3.0);
        assert_eq!(axis_score(&axis(vec![1.0; LEVELS * n], &crease, 255), true, 0.0), 1.0);
        assert_eq!(axis_score(&axis(vec![1.0; LEVELS * n], &crease, 256), false, 0.0), 1.0);
    }

    #[test]
    fn profiles_match_the_formulas() {
        // 4×3 image, hand-checked sums.
        let h = [0.0, 1.0, 3.0, 6.0, 0.0, 1.0, 3.0, 6.0, 1.0, 1.0, 1.0, 1.0];
        let p = Profiles::measure(&[&h], Cut::whole(4), Cut::whole(3), ImageKind::Height);
        let y_level = |p: &[f64], level: usize| -> Vec<f64> { p.iter().skip(level).step_by(LEVELS).copied().collect() };
        // x pairs: rows 0, 1 give |1|, |2|, |3|, |−6|; row 2 gives 0.
        assert_eq!(p.vx[..4], [2.0, 4.0, 6.0, 12.0]);
        // Crease at k: (h(k+2) − h(k+1)) − (h(k) − h(k−1)); row 0 at k = 0:
        // (3 − 1) − (0 − 6) = 8; k = 1: 3 − 1 = 2; k = 2: −6 − 2 = −8;
        // k = 3: (1 − 0) − (6 − 3) = −2.
        assert_eq!(p.cx[..4], [16.0, 4.0, 16.0, 4.0]);
        // y pairs: row 0 → 1 equal; 1 → 2: |1|+0+|2|+|5|; 2 → 0 the same.
        assert_eq!(y_level(&p.vy, 0), [0.0, 8.0, 8.0]);
        // Level 1: rows 0 + 1 and row 2 alone are the runs along y for the
        // x pairs: 0 1 3 6 doubled, then 1 1 1 1; pairs |2|+0, |4|+0,
        // |6|+0, |−12|+0.
        assert_eq!(p.vx[4..8], [2.0, 4.0, 6.0, 12.0]);
        // Level 1 along x for the y pairs: runs (0 + 1, 3 + 6) = (1, 9)
        // twice, then (2, 2): row 1 → 2 gives |1| + |7| = 8, 2 → 0 too.
        assert_eq!(y_level(&p.vy, 1), [0.0, 8.0, 8.0]);
        // Level 2: the runs of 4 along x: 10, 10, 4: row 1 → 2 gives 6.
        assert_eq!(y_level(&p.vy, 2), [0.0, 6.0, 6.0]);
    }
}
