//! Mip chains of normal maps: every level down to 1 × 1, made two ways.
//!
//! * **fit** ([`fit_chain`]): each level's normals are the plane fit of
//!   that level's heights. The heights of level k are the box filter of the
//!   finest heights over the level's texel (its footprint, [`box_reduce`]);
//!   the fit runs with the same options (N, fit, borders: wrap stays wrap,
//!   so every level tiles), its texels spaced as far apart as their
//!   footprints (W / w_k by H / h_k finest texels) and the finest level's
//!   gain, so a slope keeps its meaning at every level.
//! * **average** ([`average_chain`]): each level's normal is the
//!   renormalised mean of the finer level's unit normals its footprint
//!   covers (four at even sizes), the way mip chains of normal maps given
//!   as images are made.
//!
//! Sizes follow Direct3D and Vulkan ([`level_sizes`]): each side
//! max(1, ⌊n / 2⌋) until both are 1.
//!
//! [`mean_lengths`] measures what a level loses: the length |n̄| of the
//! mean of the finest unit normals under each of its texels, 1 where they
//! agree and less where detail cancels out (Toksvig's measure).

use crate::error::{Error, Result};
use crate::fit::FitRequest;
// A chain's shape is the GPU files': their levels and the sizes they take.
pub use crate::io::gpu::{MipLevel, level_sizes};
use crate::options::{Options, Spacing, Strength, Units, named_values};
use crate::samples::{Sample, try_vec};

/// How a chain of normals is made: by the fit of each level's heights
/// ([`fit_chain`]: a height map's), by renormalised means
/// ([`average_chain`]: a normal map's), or as the input says (`auto`:
/// fit for a height map, average for a normal map).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum MipChoice {
    /// Fit for a height map, average for a normal map. The default.
    #[default]
    Auto,
    /// Each level the fit of its box-filtered heights (height maps only).
    Fit,
    /// Each level the renormalised mean of the finer level's normals.
    Average,
}

named_values!(MipChoice, "mip chain", { Auto => "auto", Fit => "fit", Average => "average" | "mean" });

/// The weights of a box filter from `n` texels to `m` (m ≤ n) along one
/// axis: texel i of `m` covers [i·n/m, (i + 1)·n/m) of the `n`, and each
/// texel j of those takes its overlap with that span, over the span's
/// length. Returned per texel of `m`: the first texel covered and the
/// weights, which sum to 1. The overlaps are whole multiples of 1/m, so
/// each weight is an integer over n, exact where n is a power of two.
fn box_weights(n: usize, m: usize) -> Vec<(usize, Vec<f64>)> {
    (0..m)
        .map(|i| {
            // In units of 1/m of a texel: the span is [i·n, (i + 1)·n),
            // texel j is [j·m, (j + 1)·m).
            let (start, end) = (i * n, (i + 1) * n);
            let (first, last) = (start / m, (end - 1) / m);
            let weights = (first..=last)
                .map(|j| {
                    let overlap = end.min((j + 1) * m) - start.max(j * m);
                    overlap as f64 / n as f64
                })
                .collect();
            (first, weights)
        })
        .collect()
}

/// The box filter of `values` (`width × height`, row-major) to
/// `(w, h)` texels (each at most the input's): each output texel the mean
/// of the input over its footprint, texels partly covered weighted by the
/// part. NaN values are missing: a texel's mean is over the valid part of
/// its footprint, and NaN where none of it is valid.
///
/// Errors: [`Error::InvalidOption`] for a size of zero or larger than the
/// input's; [`Error::BufferSize`] when `values` does not hold the input.
pub fn box_reduce(values: &[f64], (width, height): (usize, usize), (w, h): (usize, usize)) -> Result<Vec<f64>> {
    if w == 0 || h == 0 || w > width || h > height {
        return Err(Error::InvalidOption(format!("cannot reduce {width} × {height} texels to {w} × {h}")));
    }
    if values.len() != width * height {
        return Err(Error::BufferSize { expected: width * height, actual: values.len() });
    }
    let (along_x, along_y) = (box_weights(width, w), box_weights(height, h));
    // Sums of weight × value and of the weights of valid values: rows
    // first (w × height), then columns.
    let mut sums: Vec<f64> = try_vec(w * height)?;
    let mut cover: Vec<f64> = try_vec(w * height)?;
    for row in values.chunks_exact(width) {
        for (first, weights) in &along_x {
            let (mut sum, mut weight) = (0.0, 0.0);
            for (value, k) in row[*first..].iter().zip(weights) {
                if !value.is_nan() {
                    sum += k * value;
                    weight += k;
                }
            }
            sums.push(sum);
            cover.push(weight);
        }
    }
    let mut out: Vec<f64> = try_vec(w * h)?;
    for (first, weights) in &along_y {
        for x in 0..w {
            let (mut sum, mut weight) = (0.0, 0.0);
            for (j, k) in weights.iter().enumerate() {
                let at = (first + j) * w + x;
                sum += k * sums[at];
                weight += k * cover[at];
            }
            out.push(if weight > 0.0 { sum / weight } else { f64::NAN });
        }
    }
    Ok(out)
}

/// The mip chain of the normals of `heights` (`width × height`, row-major,
/// any [`Sample`] type, read as [`FitRequest`] reads them) by the fit of
/// each level's heights (the module's docs): level 0 is the fit of the
/// heights themselves, bit for bit what [`FitRequest::normals_into`]
/// gives; level k the fit of their box filter to the level's size, its
/// texels spaced W / w_k by H / h_k finest texels apart (the spacing of
/// [`Units::Map`] times that), with the finest level's gain. Texels the
/// options call missing ([`Options::nodata`], NaN) are left out of the
/// box filter; a level texel with none under it is missing too, and its
/// normal is (0, 0, 1).
///
/// Errors: those of [`FitRequest::normals_into`] for any level.
pub fn fit_chain<H: Sample>(
    heights: &[H],
    (width, height): (usize, usize),
    opts: &Options,
) -> Result<Vec<MipLevel<[f32; 3]>>> {
    let mut finest = MipLevel { width, height, texels: try_vec(width * height)? };
    finest.texels.resize(width * height, [0.0; 3]);
    FitRequest::new(opts).normals_into(heights, width, height, &mut finest.texels)?;
    let sizes = level_sizes(width, height);
    let mut chain = try_vec(sizes.len())?;
    chain.push(finest);
    if sizes.len() == 1 {
        return Ok(chain);
    }
    // The heights in the fit's units, missing ones NaN.
    let unit = match opts.units {
        Units::Texels => H::UNIT,
        Units::Map(_) => 1.0,
    };
    let nodata = opts.nodata;
    let mut values: Vec<f64> = try_vec(heights.len())?;
    values.extend(heights.iter().map(|&v| {
        let stored = v.to_f64();
        let missing = !v.is_finite() || nodata.is_some_and(|n| stored == n);
        if missing { f64::NAN } else { stored * unit }
    }));
    let gain = opts.scale_for_width(width);
    for &(w, h) in &sizes[1..] {
        let reduced = box_reduce(&values, (width, height), (w, h))?;
        let (fx, fy) = (width as f64 / w as f64, height as f64 / h as f64);
        let spacing = match &opts.units {
            Units::Texels => Spacing::Uniform { x: fx, y: fy },
            Units::Map(Spacing::Uniform { x, y }) => Spacing::Uniform { x: x * fx, y: y * fy },
            Units::Map(Spacing::Rows(rows)) => {
                // Each level row's spacing is the mean of the rows it covers.
                let (xs, ys): (Vec<f64>, Vec<f64>) = rows.iter().map(|&[x, y]| (x, y)).unzip();
                let (xs, ys) = (box_reduce(&xs, (1, height), (1, h))?, box_reduce(&ys, (1, height), (1, h))?);
                Spacing::Rows(xs.iter().zip(&ys).map(|(x, y)| [x * fx, y * fy]).collect())
            }
        };
        let level_opts = opts
            .clone()
            .with_units(Units::Map(spacing))
            .with_strength(Strength::Scale(gain))
            .with_invert(false)
            .with_nodata(Some(f64::NAN));
        let mut texels: Vec<[f32; 3]> = try_vec(w * h)?;
        texels.resize(w * h, [0.0; 3]);
        FitRequest::new(&level_opts).normals_into(&reduced, w, h, &mut texels)?;
        chain.push(MipLevel { width: w, height: h, texels });
    }
    Ok(chain)
}

/// The mip chain of a normal map (`width × height` unit normals, row-major)
/// by averaging: level 0 is the map; each next level's normal is the mean
/// of the finer level's normals over its footprint (the box filter of
/// [`box_reduce`]: four at even sizes), renormalised; (0, 0, 1) where the
/// mean has no length.
///
/// Errors: [`Error::BufferSize`] when `normals` does not hold the map;
/// [`Error::InvalidOption`] for a size of zero.
pub fn average_chain(normals: &[[f32; 3]], (width, height): (usize, usize)) -> Result<Vec<MipLevel<[f32; 3]>>> {
    check_map(normals.len(), (width, height))?;
    let sizes = level_sizes(width, height);
    let mut chain: Vec<MipLevel<[f32; 3]>> = try_vec(sizes.len())?;
    chain.push(MipLevel { width, height, texels: normals.to_vec() });
    for &(w, h) in &sizes[1..] {
        let finer = chain.last().expect("level 0 is in");
        let mean = mean_of(&finer.texels, (finer.width, finer.height), (w, h))?;
        let texels = mean
            .into_iter()
            .map(|n| {
                let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if length > 0.0 { n.map(|c| (c / length) as f32) } else { [0.0, 0.0, 1.0] }
            })
            .collect();
        chain.push(MipLevel { width: w, height: h, texels });
    }
    Ok(chain)
}

/// For each level of the chain of a `width × height` normal map, the
/// length |n̄| of the mean of the map's unit normals under each of its
/// texels (level 0: the lengths of the normals themselves): 1 where they
/// agree, less where detail cancels out. The input to a Toksvig-style
/// roughness.
///
/// The mean is the box filter of the finest normals over the texel's
/// footprint ([`box_reduce`]'s, texels partly covered weighted by the
/// part), made for every level in one pass over the map ([`box_levels`]).
///
/// Errors: as [`average_chain`].
pub fn mean_lengths(normals: &[[f32; 3]], (width, height): (usize, usize)) -> Result<Vec<MipLevel<f32>>> {
    check_map(normals.len(), (width, height))?;
    let sizes = level_sizes(width, height);
    let length = |n: [f64; 3]| (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() as f32;
    let mut chain = try_vec(sizes.len())?;
    let mut finest: Vec<f32> = try_vec(normals.len())?;
    finest.extend(normals.iter().map(|n| length(n.map(f64::from))));
    chain.push(MipLevel { width, height, texels: finest });
    let means = reduce_levels(|i| normals[i].map(f64::from), (width, height), &sizes[1..])?;
    for (&(w, h), mean) in sizes[1..].iter().zip(means) {
        chain.push(MipLevel { width: w, height: h, texels: mean.into_iter().map(length).collect() });
    }
    Ok(chain)
}

/// The first `count` levels of the chain of a `width × height` map of
/// values (row-major): level 0 the values themselves, level k their box
/// filter to the level's size, as [`box_reduce`] makes it (within
/// rounding: NaN values are missing, a texel with none valid under it is
/// NaN), every level in one pass over the map. The heights of a chain
/// (an alpha of heights), a base roughness's α².
///
/// Errors: as [`average_chain`].
pub fn box_levels(values: &[f64], (width, height): (usize, usize), count: usize) -> Result<Vec<MipLevel<f64>>> {
    check_map(values.len(), (width, height))?;
    let mut sizes = level_sizes(width, height);
    sizes.truncate(count.max(1));
    let mut chain = try_vec(sizes.len())?;
    let mut finest = try_vec(values.len())?;
    finest.extend_from_slice(values);
    chain.push(MipLevel { width, height, texels: finest });
    let means = reduce_levels(|i| [values[i]], (width, height), &sizes[1..])?;
    for (&(w, h), mean) in sizes[1..].iter().zip(means) {
        chain.push(MipLevel { width: w, height: h, texels: mean.into_iter().map(|[v]| v).collect() });
    }
    Ok(chain)
}

/// The heights of the first `count` levels of a chain, for an alpha of
/// heights ([`crate::io::Layout::RgbHeight`]) at every level: level 0 the
/// heights in contract units as f32, as a single image's alpha holds
/// them (SPEC §1: an integer sample over its maximum, a float as it is;
/// [`crate::Samples::to_f32`]); level k their box filter to its size
/// ([`box_levels`]), texels the fit calls missing (`nodata`, NaN) left
/// out, and 0 where none under a texel is valid (a NaN or infinite height
/// of level 0 is 0 too).
///
/// Errors: as [`average_chain`].
pub fn height_levels<H: Sample>(
    heights: &[H],
    (width, height): (usize, usize),
    nodata: Option<f64>,
    count: usize,
) -> Result<Vec<MipLevel<f32>>> {
    check_map(heights.len(), (width, height))?;
    let mut values: Vec<f64> = try_vec(heights.len())?;
    values.extend(heights.iter().map(|&v| {
        let stored = v.to_f64();
        let missing = !v.is_finite() || nodata.is_some_and(|n| stored == n);
        if missing { f64::NAN } else { stored * H::UNIT }
    }));
    let mut levels = box_levels(&values, (width, height), count)?.into_iter();
    let mut chain = try_vec(count.clamp(1, 64))?;
    // Level 0 as the single image's alpha: every sample as stored.
    let finest = levels.next().expect("a level at least");
    let mut texels: Vec<f32> = try_vec(heights.len())?;
    texels.extend(heights.iter().map(|&v| {
        let h = (v.to_f64() * H::UNIT) as f32;
        if h.is_finite() { h } else { 0.0 }
    }));
    chain.push(MipLevel { width: finest.width, height: finest.height, texels });
    drop(finest);
    chain.extend(levels.map(|level| MipLevel {
        width: level.width,
        height: level.height,
        texels: level.texels.into_iter().map(|v| if v.is_nan() { 0.0 } else { v as f32 }).collect(),
    }));
    Ok(chain)
}

/// Refuses a map of no texels, or a buffer of `len` texels that is not
/// `width × height`.
fn check_map(len: usize, (width, height): (usize, usize)) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::InvalidOption(format!("a map of {width} × {height} texels has no levels")));
    }
    let expected = width.checked_mul(height).ok_or(Error::BufferSize { expected: usize::MAX, actual: len })?;
    if len != expected {
        return Err(Error::BufferSize { expected, actual: len });
    }
    Ok(())
}

/// One texel of a coarser grid along an axis, as [`box_weights`] weighs
/// the finer texels it covers: the first and the last (their parts
/// covered) and those between (whole, each m / n).
#[derive(Clone, Copy)]
struct Span {
    first: usize,
    last: usize,
    first_weight: f64,
    inner_weight: f64,
    last_weight: f64,
}

/// The spans of `m` texels over `n` (m ≤ n): [`box_weights`]' weights,
/// the same values, without a list per texel.
fn spans(n: usize, m: usize) -> Vec<Span> {
    (0..m)
        .map(|i| {
            let (start, end) = (i * n, (i + 1) * n);
            let (first, last) = (start / m, (end - 1) / m);
            let overlap = |j: usize| (end.min((j + 1) * m) - start.max(j * m)) as f64 / n as f64;
            Span {
                first,
                last,
                first_weight: overlap(first),
                inner_weight: m as f64 / n as f64,
                last_weight: overlap(last),
            }
        })
        .collect()
}

/// The box filter ([`box_reduce`]'s: each texel the mean over its
/// footprint, texels partly covered weighted by the part, NaN values
/// missing) of a `width × height` map of `C` values a texel (`texel(i)`,
/// row-major; a texel with a NaN value is missing) to each of `sizes`, in
/// one pass over the map's rows, whatever the number of levels:
///
/// * along x, each row's running sums (of the valid values, and of their
///   count) give a span's whole texels at once, and its two ends are
///   added by the part they cover: each level's row costs its own width,
///   not the map's;
/// * along y, each finer row is added, weighted by the part covered, to
///   the one or two rows of each level whose footprint it crosses.
///
/// So a level's mean is the mean of the finest texels under it (in f64,
/// equal to [`box_reduce`]'s within rounding), at every size, odd ones
/// included, where a mean of the level before's means would not be (a
/// texel of 75 covers parts of three texels of 150 whose footprints
/// overlap its neighbours'). Cost: the map's texels a few times over, and
/// (C + 1) f64 per texel of the coarser levels (a third of the map's).
fn reduce_levels<const C: usize>(
    texel: impl Fn(usize) -> [f64; C],
    (width, height): (usize, usize),
    sizes: &[(usize, usize)],
) -> Result<Vec<Vec<[f64; C]>>> {
    let along_x: Vec<Vec<Span>> = sizes.iter().map(|&(w, _)| spans(width, w)).collect();
    // For each level, the level rows (and weights) each finer row adds to.
    let mut rows_of: Vec<Vec<Vec<(usize, f64)>>> = try_vec(sizes.len())?;
    for &(_, h) in sizes {
        let mut rows = vec![Vec::new(); height];
        for (i, span) in spans(height, h).into_iter().enumerate() {
            for (r, targets) in rows.iter_mut().enumerate().take(span.last + 1).skip(span.first) {
                let weight = match r {
                    r if r == span.first => span.first_weight,
                    r if r == span.last => span.last_weight,
                    _ => span.inner_weight,
                };
                targets.push((i, weight));
            }
        }
        rows_of.push(rows);
    }
    let mut sums: Vec<Vec<[f64; C]>> = try_vec(sizes.len())?;
    let mut covers: Vec<Vec<f64>> = try_vec(sizes.len())?;
    for &(w, h) in sizes {
        let mut sum = try_vec(w * h)?;
        sum.resize(w * h, [0.0; C]);
        let mut cover = try_vec(w * h)?;
        cover.resize(w * h, 0.0);
        sums.push(sum);
        covers.push(cover);
    }
    // A row's values (missing ones 0) and validity, and their running sums.
    let mut row: Vec<([f64; C], f64)> = try_vec(width)?;
    let mut running: Vec<([f64; C], f64)> = try_vec(width + 1)?;
    for y in 0..height {
        // The level rows each level's row of this one adds to.
        let targets_of = rows_of.iter().map(|rows| &rows[y]);
        row.clear();
        row.extend((0..width).map(|x| {
            let v = texel(y * width + x);
            if v.iter().any(|c| c.is_nan()) { ([0.0; C], 0.0) } else { (v, 1.0) }
        }));
        running.clear();
        running.push(([0.0; C], 0.0));
        let mut total = ([0.0; C], 0.0);
        for (v, valid) in &row {
            for (t, c) in total.0.iter_mut().zip(v) {
                *t += c;
            }
            total.1 += valid;
            running.push(total);
        }
        for ((k, spans), targets) in along_x.iter().enumerate().zip(targets_of) {
            let w = spans.len();
            for (x, span) in spans.iter().enumerate() {
                let (v, valid) = row[span.first];
                let mut sum = v.map(|c| span.first_weight * c);
                let mut cover = span.first_weight * valid;
                if span.last > span.first {
                    let (inner, ends) = (&running[span.first + 1], &running[span.last]);
                    let (v, valid) = row[span.last];
                    for c in 0..C {
                        sum[c] += span.inner_weight * (ends.0[c] - inner.0[c]) + span.last_weight * v[c];
                    }
                    cover += span.inner_weight * (ends.1 - inner.1) + span.last_weight * valid;
                }
                for &(i, weight) in targets {
                    let at = i * w + x;
                    for c in 0..C {
                        sums[k][at][c] += weight * sum[c];
                    }
                    covers[k][at] += weight * cover;
                }
            }
        }
    }
    for (sum, cover) in sums.iter_mut().zip(&covers) {
        for (s, &weight) in sum.iter_mut().zip(cover) {
            *s = if weight > 0.0 { s.map(|c| c / weight) } else { [f64::NAN; C] };
        }
    }
    Ok(sums)
}

/// Toksvig's variance of the normals under a texel from the length |n̄|
/// of their mean: σ² = (1 − |n̄|) / |n̄| (0 for |n̄| ≥ 1; |n̄| taken at
/// least 10⁻⁶).
#[must_use]
pub fn toksvig_variance(length: f32) -> f64 {
    let length = f64::from(length).clamp(1e-6, 1.0);
    (1.0 - length) / length
}

/// The perceptual roughness r of a texel whose surface has GGX roughness
/// α_base (α_base² given) and whose normals vary by σ² (Toksvig):
/// α² = α_base² + σ², clamped to [0, 1], and r = √α (α = r²).
#[must_use]
pub fn perceptual_roughness(base_alpha2: f64, variance: f64) -> f32 {
    let alpha2 = (base_alpha2 + variance).clamp(0.0, 1.0);
    alpha2.sqrt().sqrt() as f32
}

/// The roughness chain of a normal map from the mean lengths of its
/// finest normals ([`mean_lengths`]), each texel's perceptual roughness
/// r = √α with α² = α_base² + σ², σ² Toksvig's variance
/// ([`toksvig_variance`]) and α_base = r_base² the base's roughness,
/// clamped to [0, 1]. Level 0 holds the finest normals themselves: its σ²
/// is 0. `base` (the finest level's size, perceptual roughness in [0, 1];
/// none: 0) is box-filtered to each level as α² = r_base⁴, the quantity
/// the lobes add up in, not as r.
///
/// Errors: [`Error::BufferSize`] for a base that is not the finest
/// level's size; [`Error::InvalidOption`] for a base value outside
/// [0, 1] or NaN, or no levels.
pub fn roughness_chain(lengths: &[MipLevel<f32>], base: Option<&[f32]>) -> Result<Vec<MipLevel<f32>>> {
    let Some(finest) = lengths.first() else {
        return Err(Error::InvalidOption("a roughness chain needs at least one level".into()));
    };
    let (width, height) = (finest.width, finest.height);
    let base_alpha2: Option<Vec<MipLevel<f64>>> = match base {
        None => None,
        Some(base) if base.len() != width * height => {
            return Err(Error::BufferSize { expected: width * height, actual: base.len() });
        }
        Some(base) => {
            if let Some(at) = base.iter().position(|r| !(0.0..=1.0).contains(r)) {
                let (x, y) = (at % width, at / width);
                return Err(Error::InvalidOption(format!(
                    "the base roughness at texel (x {x}, y {y}) is {}: perceptual roughness is in [0, 1]",
                    base[at]
                )));
            }
            let mut alpha2 = try_vec(base.len())?;
            alpha2.extend(base.iter().map(|&r| f64::from(r).powi(4)));
            Some(box_levels(&alpha2, (width, height), lengths.len())?)
        }
    };
    let mut chain = try_vec(lengths.len())?;
    for (k, level) in lengths.iter().enumerate() {
        let (w, h) = (level.width, level.height);
        let base = base_alpha2.as_ref().and_then(|levels| levels.get(k)).map_or(&[][..], |level| &level.texels[..]);
        let mut texels: Vec<f32> = try_vec(w * h)?;
        texels.extend(level.texels.iter().enumerate().map(|(i, &length)| {
            let variance = if k == 0 { 0.0 } else { toksvig_variance(length) };
            perceptual_roughness(base.get(i).copied().unwrap_or(0.0), variance)
        }));
        chain.push(MipLevel { width: w, height: h, texels });
    }
    Ok(chain)
}

/// The box filter of each component of `normals` to `(w, h)`.
fn mean_of(normals: &[[f32; 3]], size: (usize, usize), (w, h): (usize, usize)) -> Result<Vec<[f64; 3]>> {
    let mut mean: Vec<[f64; 3]> = try_vec(w * h)?;
    mean.resize(w * h, [0.0; 3]);
    for c in 0..3 {
        let plane: Vec<f64> = normals.iter().map(|n| f64::from(n[c])).collect();
        for (m, v) in mean.iter_mut().zip(box_reduce(&plane, size, (w, h))?) {
            m[c] = v;
        }
    }
    Ok(mean)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_weights_cover_each_span_once() {
        for (n, m) in [(8, 4), (7, 3), (300, 150), (75, 37), (5, 1), (3, 3)] {
            let weights = box_weights(n, m);
            let mut per_source = vec![0.0; n];
            for (first, w) in &weights {
                assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{n} → {m}");
                for (j, k) in w.iter().enumerate() {
                    per_source[first + j] += k;
                }
            }
            // Every source texel is counted m / n in all.
            for total in per_source {
                assert!((total - m as f64 / n as f64).abs() < 1e-12, "{n} → {m}");
            }
        }
    }

    #[test]
    fn every_level_in_one_pass_is_the_box_filter_of_the_finest() {
        for (w, h) in [(300, 7), (13, 11), (16, 8), (1, 9), (5, 1)] {
            let mut values: Vec<f64> = (0..w * h).map(|i| ((i * 37 % 101) as f64 * 0.173).sin()).collect();
            // Missing values: a few texels, and a whole run of them.
            for i in (0..w * h).step_by(7).chain(0..3.min(w * h)) {
                values[i] = f64::NAN;
            }
            let levels = box_levels(&values, (w, h), usize::MAX).unwrap();
            assert_eq!(levels.len(), level_sizes(w, h).len());
            for level in &levels[1..] {
                let want = box_reduce(&values, (w, h), (level.width, level.height)).unwrap();
                for (t, (got, want)) in level.texels.iter().zip(&want).enumerate() {
                    let same = (got.is_nan() && want.is_nan()) || (got - want).abs() < 1e-12;
                    assert!(same, "{w} × {h} → {} × {}, texel {t}: {got}, want {want}", level.width, level.height);
                }
            }
            assert!(levels[0].texels.iter().zip(&values).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
        assert_eq!(box_levels(&[1.0; 12], (4, 3), 2).unwrap().len(), 2);
        assert!(box_levels(&[1.0; 11], (4, 3), 2).is_err());
        assert!(box_levels(&[], (0, 3), 2).is_err());
    }
}
