//! What the fuzz targets share: the read limit, the options a case runs
//! with, and the invariants every result must keep.
//!
//! A case is the input bytes, whole. The options are taken from its last two
//! bytes *without removing them*: every seed is then a plain image file
//! (tools and tests can open it as it is), most formats ignore bytes past
//! their data, and the fuzzer can still steer the options by mutating or
//! appending trailing bytes.

#![forbid(unsafe_code)]

use normalfit::io::{Channel, Raster, ReadOptions};
use normalfit::normal_map::KindChoice;
use normalfit::tiling::{AxisReport, TilingOptions, TilingReport};
use normalfit::{Border, Borders, Convention, Error, Fit, Options, Samples, Strength};

/// Small enough that a forged header costs the fuzzer little (a 1024² map
/// decodes and fits in milliseconds), large enough for every code path:
/// the fit's tiles are at most 8 × 9 = 72 texels for the patches used here.
pub const MAX_TEXELS: u64 = 1 << 20;

/// The read options of every target.
#[must_use]
pub fn read_options() -> ReadOptions {
    ReadOptions::default().with_max_texels(MAX_TEXELS)
}

/// Writes a case's bytes to this process's temporary file for `target`
/// (the streaming readers read a path) and returns the path.
pub fn case_file(target: &str, extension: &str, data: &[u8]) -> &'static std::path::Path {
    static PATH: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    let path = PATH.get_or_init(|| {
        std::env::temp_dir().join(format!("normalfit-fuzz-{target}-{}.{extension}", std::process::id()))
    });
    std::fs::write(path, data).expect("write the case to a temporary file");
    path
}

/// What one case asks for besides its bytes.
#[derive(Clone, Debug)]
pub struct Case {
    /// The channel the heights come from.
    pub channel: Option<Channel>,
    /// The fit's options: patch 3, 5 or 9, every border pair, both fits and
    /// conventions, gains from 1 to the largest accepted, inverted or not.
    pub fit: Options,
    /// How the tiling check is told the kind.
    pub kind: KindChoice,
    /// Rows of a truncated stream, as a fraction 1/256 … 256/256 of the height.
    pub fraction: u8,
    /// 16-bit output instead of 8-bit, where a target writes PNG.
    pub sixteen: bool,
}

impl Case {
    /// The case of these bytes (see the module docs).
    #[must_use]
    pub fn of(data: &[u8]) -> Case {
        let last = |k: usize| data.len().checked_sub(k).map_or(0, |i| data[i]);
        let mut c = u32::from(u16::from_le_bytes([last(2), last(1)]));
        let mut pick = |n: u32| {
            let v = c % n;
            c /= n;
            v as usize
        };
        let channel =
            [None, Some(Channel::Luma), Some(Channel::R), Some(Channel::G), Some(Channel::B), Some(Channel::A)]
                [pick(6)]
            .clone();
        let patch = [3, 5, 9][pick(3)];
        let modes = [Border::Wrap, Border::Clamp, Border::Mirror];
        let borders = Borders { x: modes[pick(3)], y: modes[pick(3)] };
        let fit = [Fit::Orthogonal, Fit::Vertical][pick(2)];
        let convention = [Convention::OpenGl, Convention::DirectX][pick(2)];
        let invert = pick(2) == 1;
        // 1e30 is MAX_GAIN: with heights up to f32's range, the sums must
        // still stay finite.
        let strength =
            [Strength::Scale(1.0), Strength::Scale(8.0), Strength::Relief(0.5), Strength::Scale(1e30)][pick(4)];
        let kind = [KindChoice::Auto, KindChoice::Height, KindChoice::Normal][pick(3)];
        let sixteen = pick(2) == 1;
        let fit = Options::new()
            .with_patch(patch)
            .with_borders(borders)
            .with_fit(fit)
            .with_convention(convention)
            .with_invert(invert)
            .with_strength(strength);
        Case { channel, fit, kind, fraction: last(3), sixteen }
    }
}

/// An error must be a clean one: one non-empty line (the crate's rule for
/// messages, which callers prefix with the file name).
pub fn assert_clean_error(e: &Error) {
    let msg = e.to_string();
    assert!(!msg.trim().is_empty(), "empty error message: {e:?}");
    assert!(!msg.contains('\n'), "error message of several lines: {msg:?}");
}

/// What `decode` promises of a raster: a non-zero size within the limit,
/// and every plane `width * height` long.
pub fn assert_raster(raster: &Raster) {
    let (w, h) = (raster.width, raster.height);
    assert!(w >= 1 && h >= 1, "decode gave a zero size {w} × {h}");
    assert!((w as u64) * (h as u64) <= MAX_TEXELS, "decode gave {w} × {h}, above the limit {MAX_TEXELS}");
    assert!(!raster.planes.is_empty(), "decode gave no planes");
    for p in &raster.planes {
        assert_eq!(p.data.len(), w * h, "plane {:?} of a {w} × {h} raster", p.name);
    }
}

/// `decode` of the bytes, as the whole-image path reads them: the raster,
/// checked against `decode`'s promises, or `None` after a clean error.
pub fn decoded(data: &[u8]) -> Option<Raster> {
    match normalfit::io::decode(data, &read_options()) {
        Ok(raster) => {
            assert_raster(&raster);
            Some(raster)
        }
        Err(e) => {
            assert_clean_error(&e);
            None
        }
    }
}

/// After a streamed conversion of the bytes: when it and the whole-image
/// decode both succeed, the rows the stream visited (`streamed`, of a `w` ×
/// `h` image) are the decoded heights (in contract units, as f32) bit for
/// bit, and the decoded samples are returned for the comparison of the
/// outputs; `None` when either failed (cleanly).
pub fn streamed_heights_match(
    data: &[u8],
    channel: Option<Channel>,
    conversion: &normalfit::Result<()>,
    streamed: &[f32],
    (w, h): (usize, usize),
) -> Option<Samples> {
    if let Err(e) = conversion {
        assert_clean_error(e);
    }
    let whole = normalfit::io::decode(data, &read_options()).and_then(|r| r.into_heights(channel));
    let (Ok(()), Ok(heights)) = (conversion, whole) else { return None };
    assert_eq!(streamed.len(), w * h, "the stream visited {} heights of {w} × {h}", streamed.len());
    let whole = heights.to_f32().expect("memory for a copy");
    let same = streamed.iter().zip(&whole).all(|(a, b)| a.to_bits() == b.to_bits());
    assert!(same, "streamed heights differ from the decoded ones");
    Some(heights)
}

/// Heights are `Ok` only when finite; otherwise the error is the channel's
/// absence or a non-finite height, cleanly.
pub fn check_heights<H: Heights>(result: normalfit::Result<H>, texels: usize) -> Option<H> {
    match result {
        Ok(h) => {
            assert_eq!(h.count(), texels, "heights of the wrong length");
            assert!((0..texels).all(|k| h.at(k).is_finite()), "non-finite height passed the check");
            Some(h)
        }
        Err(e) => {
            assert!(
                matches!(e, Error::Unsupported(_) | Error::NonFiniteHeight { .. }),
                "heights failed with an unexpected error: {e:?}"
            );
            assert_clean_error(&e);
            None
        }
    }
}

/// Heights as the fuzz targets check them: the f32 view or the samples.
pub trait Heights {
    /// How many.
    fn count(&self) -> usize;
    /// Height `k` in contract units.
    fn at(&self, k: usize) -> f64;
}

impl Heights for Vec<f32> {
    fn count(&self) -> usize {
        self.len()
    }
    fn at(&self, k: usize) -> f64 {
        f64::from(self[k])
    }
}

impl Heights for Samples {
    fn count(&self) -> usize {
        self.len()
    }
    fn at(&self, k: usize) -> f64 {
        self.height(k).expect("k < count()")
    }
}

/// A unit normal within 1e-4, finite, facing up (z ≥ 0).
pub fn assert_unit_normal(n: [f32; 3], at: usize) {
    let len = n.iter().map(|&c| f64::from(c) * f64::from(c)).sum::<f64>().sqrt();
    assert!(n.iter().all(|c| c.is_finite()), "normal {n:?} at texel {at} is not finite");
    assert!((len - 1.0).abs() <= 1e-4, "normal {n:?} at texel {at} has length {len}");
    assert!(n[2] >= 0.0, "normal {n:?} at texel {at} faces down");
}

/// The contract's 8-bit encoding of a normal component, round(255 (n + 1) / 2).
#[must_use]
pub fn encode8(c: f32) -> i32 {
    ((f64::from(c) + 1.0) * 127.5).round() as i32
}

/// A tiling report keeps its documented promises: scores finite and
/// positive, verdicts the score against the threshold.
pub fn assert_report(report: &TilingReport, opts: &TilingOptions) {
    for (name, axis) in [("x", &report.x), ("y", &report.y)] {
        assert_axis(name, axis, opts);
    }
}

fn assert_axis(name: &str, axis: &AxisReport, opts: &TilingOptions) {
    assert!(axis.score.is_finite() && axis.score > 0.0, "{name} score {} is not finite and positive", axis.score);
    assert_eq!(axis.seamless, axis.score <= opts.threshold, "{name} verdict does not follow its score");
}

/// Two reports of the same heights by different routes (`check` and
/// `HeightSeams`): the same kind, scores equal up to the f64 summation order
/// (documented as at worst about 1e-15 relative; 1e-9 leaves room), and the
/// same verdicts unless a score is that close to the threshold.
pub fn assert_same_report(a: &TilingReport, b: &TilingReport, opts: &TilingOptions) {
    assert_eq!(a.kind, b.kind);
    for (name, x, y) in [("x", &a.x, &b.x), ("y", &a.y, &b.y)] {
        let rel = (x.score - y.score).abs() / x.score.abs().max(y.score.abs()).max(f64::MIN_POSITIVE);
        assert!(rel <= 1e-9, "{name} scores differ: {} against {}", x.score, y.score);
        let near = (x.score - opts.threshold).abs() <= 1e-9 * opts.threshold;
        assert!(x.seamless == y.seamless || near, "{name} verdicts differ at scores {} and {}", x.score, y.score);
    }
}

/// Options read from a case's last `k` bytes (at most 8), little-endian,
/// as [`Case::of`] reads two: the bytes stay part of the case, so seeds
/// are plain files, and the fuzzer steers the options by changing them.
#[derive(Clone, Debug)]
pub struct Pick(u64);

impl Pick {
    /// The options in the last `k` bytes of `data` (missing bytes read as 0).
    #[must_use]
    pub fn last(data: &[u8], k: usize) -> Pick {
        let k = k.min(8);
        let tail = &data[data.len().saturating_sub(k)..];
        let mut bytes = [0u8; 8];
        bytes[..tail.len()].copy_from_slice(tail);
        Pick(u64::from_le_bytes(bytes))
    }

    /// A choice among `n` (n ≥ 1), taken from what is left.
    pub fn index(&mut self, n: usize) -> usize {
        let v = self.0 % n as u64;
        self.0 /= n as u64;
        v as usize
    }

    /// One of `values`.
    pub fn one<T: Clone>(&mut self, values: &[T]) -> T {
        values[self.index(values.len())].clone()
    }

    /// A coin.
    pub fn flag(&mut self) -> bool {
        self.index(2) == 1
    }
}

/// The fit's options the new targets share: patch 3, 5 or 9, every border
/// pair, both fits and conventions, inverted or not, and a gain from
/// `gains`.
pub fn fit_options(pick: &mut Pick, gains: &[Strength]) -> Options {
    let patch = pick.one(&[3, 5, 9]);
    let modes = [Border::Wrap, Border::Clamp, Border::Mirror];
    let borders = Borders { x: pick.one(&modes), y: pick.one(&modes) };
    let fit = pick.one(&[Fit::Orthogonal, Fit::Vertical]);
    let convention = pick.one(&[Convention::OpenGl, Convention::DirectX]);
    let invert = pick.flag();
    Options::new()
        .with_patch(patch)
        .with_borders(borders)
        .with_fit(fit)
        .with_convention(convention)
        .with_invert(invert)
        .with_strength(pick.one(gains))
}

/// What a read georeferencing promises (issue 32: georeferencing tags are
/// validated): a pixel scale's x and y finite and non-zero (z finite), every
/// tiepoint and transformation value finite, a transform that places
/// texels apart (finite, non-zero spacing on both axes).
pub fn assert_georef(g: &normalfit::io::Georef, height: usize) {
    if let Some([x, y, z]) = g.pixel_scale {
        assert!(x.is_finite() && y.is_finite() && x != 0.0 && y != 0.0, "pixel scale {x} × {y} accepted");
        assert!(z.is_finite(), "pixel scale z {z} accepted");
    }
    for t in &g.tiepoints {
        assert!(t.iter().all(|v| v.is_finite()), "tiepoint {t:?} accepted");
    }
    if let Some(m) = &g.transformation {
        assert!(m.iter().all(|v| v.is_finite()), "transformation {m:?} accepted");
    }
    if let Some(t) = g.affine() {
        for v in [t.a, t.b, t.c, t.d, t.e, t.f] {
            assert!(v.is_finite(), "affine {t:?} is not finite");
        }
    }
    if let Some((x, y)) = g.spacing() {
        assert!(x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0, "spacing {x} × {y} accepted");
    }
    // Spacings in metres are the map units' to check (a huge scale in
    // degrees may not be a length in f64): `assert_map_units`.
    let _ = height;
}

/// Every spacing of map units finite and positive (what a fit in map
/// units divides by).
pub fn assert_map_units(units: &normalfit::Units, height: usize) {
    let normalfit::Units::Map(spacing) = units else { panic!("map units asked for, got {units:?}") };
    for row in 0..height {
        let [x, y] = spacing.at(row);
        assert!(x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0, "spacing {x} × {y} at row {row}");
        if matches!(spacing, normalfit::Spacing::Uniform { .. }) {
            break;
        }
    }
}

/// A conversion's error: clean, wherever it happened.
pub fn assert_clean_convert_error(e: &normalfit::convert::ConvertError) {
    assert_clean_error(&e.error);
    let msg = e.to_string();
    assert!(!msg.contains('\n'), "conversion error of several lines: {msg:?}");
}

/// Writes a case's bytes to this process's temporary file named for
/// `target` and `extension` (several extensions a target; the path is made
/// each call, the file kept between cases) and returns the path.
pub fn case_file_as(target: &str, extension: &str, data: &[u8]) -> std::path::PathBuf {
    let path = std::env::temp_dir().join(format!("normalfit-fuzz-{target}-{}.{extension}", std::process::id()));
    std::fs::write(&path, data).expect("write the case to a temporary file");
    path
}
