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
//! * Non-finite texels are holes (below); [`check`] refuses them unless
//!   [`TilingOptions::nodata`] is given.
//! * Finite heights anywhere in f32's range give finite scores: the sums
//!   run on the heights times 2⁻³², exactly, and are scaled back in f64,
//!   so that the difference of ±3.4·10³⁸ and its sums do not overflow f32.
//!
//! # Holes
//!
//! A nodata value ([`TilingOptions::nodata`], [`HeightSeams::with_nodata`];
//! `--nodata` and a GeoTIFF's nodata behind `--border auto`) or a NaN or
//! infinite texel is not a height. Every pair or crease whose stencil
//! reads a hole is skipped, in the seam's sum and in the interior ones, and
//! each sum keeps the count of the pairs it holds; a run of a level that
//! holds a hole is a hole. Before ranking, a level's sums are scaled to
//! the count of its fullest pair (sum × fullest / count: a line with half
//! its pairs in holes weighs as a whole one; a sum over every pair is left
//! as it is, so an image without holes keeps its scores bit for bit), and
//! a sum of no valid pair is no sample. ε is the mean over the valid pairs.
//! When no pair across the seam at level 0 is valid, or none inside, the
//! axis cannot be judged: its score is infinite and it is not seamless (a
//! nodata collar along an edge: `--border auto` mirrors it); a coarser
//! level that cannot be judged is left out.
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

// What the check is asked and answers.
mod report;
// The lines read, the per-pair sums of each axis, and the score.
mod score;
// The row kernels the two ways of measuring share.
mod kernels;
// The whole-image measure: planes, rows in parallel.
mod whole;
// The row-by-row check, `HeightSeams`.
mod streamed;

use crate::samples::{check_planes, image_len, try_vec};
use crate::{Error, Result};

/// What the planes hold and how it is decided: the normal-map reader's
/// ([`crate::normal_map`]), named here too for callers of earlier versions.
#[doc(no_inline)]
pub use crate::normal_map::{ImageKind, KindChoice};
pub use report::{AxisReport, DEFAULT_THRESHOLD, TilingOptions, TilingReport};
pub use score::EDGE_LINES;
pub use streamed::HeightSeams;

use score::{Cut, Profiles, report};

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
/// Errors: [`Error::InvalidOption`] when `planes` is empty or a side is 0
/// (an image without texels has no seams to judge, and no decoder gives
/// one; the fit's rule),
/// [`Error::BufferSize`] when a plane is shorter than `width * height`,
/// [`Error::NonFiniteHeight`] naming the first texel in row order whose
/// height is NaN or infinite when the planes are judged as a height map,
/// [`Error::NonFiniteNormal`] the first whose normal has a NaN or infinite
/// component when they are judged as a normal map (a score from samples
/// some of which are not numbers would be a verdict on nothing), unless
/// `opts.nodata` says there are holes ([module docs](self#holes)),
/// [`Error::Limits`] when the profiles need more memory than the process
/// may take.
pub fn check(planes: &[&[f32]], width: usize, height: usize, opts: &TilingOptions) -> Result<TilingReport> {
    if planes.is_empty() {
        return Err(Error::InvalidOption("the tiling check needs at least one plane".into()));
    }
    let len = crate::fit::checked_len(width, height)?;
    check_planes(planes, len)?;
    let kind = match opts.kind {
        KindChoice::Auto => ImageKind::detect(planes, width, height)?,
        KindChoice::Height => ImageKind::Height,
        KindChoice::Normal => ImageKind::Normal,
    };
    let nodata = opts.nodata.unwrap_or(f64::NAN);
    if let Some((x, y)) = Profiles::first_non_finite(planes, len, width).filter(|_| opts.nodata.is_none()) {
        return Err(match kind {
            ImageKind::Height => Error::NonFiniteHeight { x, y },
            ImageKind::Normal => Error::NonFiniteNormal { x, y },
        });
    }
    let (cols, rows) = (Cut::of(width), Cut::of(height));
    let all_rows = Cut::whole(height);
    if cols.is_whole() {
        // Every column is read: one pass over the image gives the x
        // profiles, and the y ones of every row, of which the kept are used.
        crate::io::check_memory("the tiling check", Profiles::bytes_needed(width, height))?;
        let p = Profiles::measure(planes, cols, all_rows, kind, nodata);
        return Ok(report(&p.x_axis(height, cols), &p.y_axis(width, all_rows, rows), kind, opts));
    }
    // The kept columns of every row for x, the kept rows whole for y.
    let bytes = Profiles::bytes_needed(cols.kept(), height) + Profiles::bytes_needed(width, rows.kept());
    crate::io::check_memory("the tiling check", bytes)?;
    let x = Profiles::measure(planes, cols, all_rows, kind, nodata).x_axis(height, cols);
    let y = Profiles::measure(planes, Cut::whole(width), rows, kind, nodata).y_axis(width, rows, rows);
    Ok(report(&x, &y, kind, opts))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_half_moves_the_seams_to_the_middle() {
        // 4×3: rows shift by 1, columns by 2.
        let t: Vec<u8> = (0..12).collect();
        assert_eq!(shift_half(&t, 4, 3).unwrap(), [6, 7, 4, 5, 10, 11, 8, 9, 2, 3, 0, 1]);
        assert_eq!(shift_half(&[7u8], 1, 1).unwrap(), [7]);
    }
}
