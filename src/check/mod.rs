//! A normal map checked: lengths, negative z, a two-channel layout, the
//! green convention, 8-bit banding and the tiling seams; and the map
//! repaired (renormalised, z rebuilt, green flipped). docs/check.md is the
//! reference; the rules are here.
//!
//! # Measures
//!
//! The normals are the map's stored colours read back by the one decoding
//! ([`crate::normal_map::decode_planes`]: n = 2c − 1, or c for a signed
//! float map).
//!
//! - **Length.** A stored component is off its true value by at most half
//!   the storage's step s ([`Storage::step`]: 2/255, 2/65535; floats
//!   2⁻¹⁰, half's, the coarser float a file may hold), so a unit normal
//!   decodes to a length within √3·s/2 of 1. A texel further off was not a
//!   unit normal when it was stored.
//! - **Negative z**: nz < −s/2, a normal pointing into the surface.
//! - **Two channels (RG)**: the map has no B plane, or B is the same in
//!   every texel while most lengths are off (a BC5 map decoded with B = 0).
//!   Its z is rebuilt as √(1 − x² − y²) for every other measure; a length
//!   is then off when x² + y² exceeds 1 by more than the rounding allows.
//! - **Convention**: [`convention`], from the map's curl.
//! - **Banding** (integer maps of 8 bits or fewer): along rows and
//!   columns of R and of G, windows of 8 texels starting every 4; a window
//!   *varies* unless its 8 codes are equal, and is a *staircase* when every
//!   step between neighbours is at most one code and at most 3 of its 7
//!   steps are not 0 (plateaus two texels wide or more: the relief changes
//!   slower than the storage can follow). The score is the share of
//!   staircases among varying windows; the map is banded when the score is
//!   at least [`BANDED_SHARE`] over at least [`BANDING_MIN_WINDOWS`]
//!   varying windows.
//! - **Tiling**: [`crate::tiling::check`] of the R, G, B planes (a normal
//!   map's seams of value; for RG maps, B from the rebuilt z).

pub mod convention;

use std::fmt;
use std::path::Path;

use crate::Convention;
use crate::engine::{self, ConvertError, Input, Output, Place};
use crate::error::{Error, Result};
use crate::height::ConventionChoice;
use crate::io::{self, Encoding, OutputFormat, PngCompression, Raster, ReadOptions, SampleType};
use crate::normal_map::{KindChoice, Storage, decode_planes};
use crate::par::prelude::*;
use crate::tiling::{self, TilingOptions, TilingReport};
use crate::{FromNormal, samples::try_vec};

pub use convention::ConventionGuess;

/// The least share of staircases among varying windows for a banded map.
pub const BANDED_SHARE: f64 = 0.5;

/// The fewest varying windows for a verdict of banding.
pub const BANDING_MIN_WINDOWS: usize = 256;

/// Length of the banding windows, in texels.
const WINDOW: usize = 8;

/// How a map stores its normals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize), serde(rename_all = "lowercase"))]
#[non_exhaustive]
pub enum MapLayout {
    /// x, y, z in R, G, B.
    Rgb,
    /// x and y in R and G, z to be rebuilt.
    Rg,
}

/// The choices of a check.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct CheckOptions {
    /// The convention the map should be in; a confident guess of the other
    /// is a finding. Default: auto (no expectation).
    pub convention: ConventionChoice,
    /// The tiling check's options (its kind is always normal).
    pub tiling: TilingOptions,
    /// Float maps hold n itself, not (n + 1)/2. Default: false.
    pub signed: bool,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            convention: ConventionChoice::Auto,
            tiling: TilingOptions::default().with_kind(KindChoice::Normal),
            signed: false,
        }
    }
}

impl CheckOptions {
    /// The defaults.
    #[must_use]
    pub fn new() -> Self {
        CheckOptions::default()
    }
    /// With the convention the map should be in (auto: none).
    #[must_use]
    pub fn with_convention(mut self, c: ConventionChoice) -> Self {
        self.convention = c;
        self
    }
    /// With these tiling options.
    #[must_use]
    pub fn with_tiling(mut self, t: TilingOptions) -> Self {
        self.tiling = t.with_kind(KindChoice::Normal);
        self
    }
    /// Float maps hold n itself.
    #[must_use]
    pub fn with_signed(mut self, signed: bool) -> Self {
        self.signed = signed;
        self
    }
}

/// The banding measure of an integer map of 8 bits or fewer.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct Banding {
    /// Staircases over varying windows (0 where none varies).
    pub score: f64,
    /// Varying windows counted.
    pub windows: usize,
    /// The verdict.
    pub banded: bool,
}

/// What a check found in one map.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct CheckReport {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// How the samples were stored.
    pub sample: SampleType,
    /// RGB, or two channels.
    pub layout: MapLayout,
    /// The largest distance from length 1 that rounding explains.
    pub length_tolerance: f64,
    /// Texels whose length is off by more.
    pub off_length: usize,
    /// Texels with nz below −s/2.
    pub negative_z: usize,
    /// The convention's guess.
    pub guess: ConventionGuess,
    /// The convention the map should be in, if stated.
    pub expected: Option<Convention>,
    /// Banding, for integer maps of 8 bits or fewer.
    pub banding: Option<Banding>,
    /// The seams.
    pub tiling: TilingReport,
}

/// One thing found wrong with a map.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Finding {
    /// Texels whose length is off by more than rounding allows.
    OffLength {
        /// How many.
        count: usize,
        /// Their share of the texels.
        share: f64,
    },
    /// Texels pointing into the surface.
    NegativeZ {
        /// How many.
        count: usize,
        /// Their share.
        share: f64,
    },
    /// Two channels: z must be rebuilt.
    TwoChannel,
    /// Confidently the other convention than the one stated.
    Convention {
        /// The one stated.
        expected: Convention,
        /// The one found.
        found: Convention,
    },
    /// 8-bit banding.
    Banded {
        /// The score.
        score: f64,
    },
    /// A seam on an axis.
    Seam {
        /// "x" or "y".
        axis: &'static str,
        /// Its score.
        score: f64,
    },
}

impl Finding {
    /// A short name: `length`, `negative_z`, `rg`, `convention`, `banding`,
    /// `seam`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Finding::OffLength { .. } => "length",
            Finding::NegativeZ { .. } => "negative_z",
            Finding::TwoChannel => "rg",
            Finding::Convention { .. } => "convention",
            Finding::Banded { .. } => "banding",
            Finding::Seam { .. } => "seam",
        }
    }
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Finding::OffLength { count, share } => {
                write!(f, "{count} texels ({:.2} %) are not unit length within the storage's rounding", share * 100.0)
            }
            Finding::NegativeZ { count, share } => {
                write!(f, "{count} texels ({:.2} %) have negative z", share * 100.0)
            }
            Finding::TwoChannel => write!(f, "two-channel (RG) map: z must be rebuilt"),
            Finding::Convention { expected, found } => write!(f, "expected {expected}, but its curl says {found}"),
            Finding::Banded { score } => write!(f, "8-bit banding (score {score:.2})"),
            Finding::Seam { axis, score } => write!(f, "seam on {axis} (score {score:.2})"),
        }
    }
}

impl CheckReport {
    /// Texels in the map.
    #[must_use]
    pub fn texels(&self) -> usize {
        self.width * self.height
    }

    /// `count` over the texels.
    #[must_use]
    pub fn share(&self, count: usize) -> f64 {
        count as f64 / self.texels().max(1) as f64
    }

    /// Everything found wrong, in a fixed order; empty for a clean map.
    #[must_use]
    pub fn findings(&self) -> Vec<Finding> {
        let mut found = Vec::new();
        if self.layout == MapLayout::Rg {
            found.push(Finding::TwoChannel);
        }
        if self.off_length > 0 {
            found.push(Finding::OffLength { count: self.off_length, share: self.share(self.off_length) });
        }
        if self.negative_z > 0 {
            found.push(Finding::NegativeZ { count: self.negative_z, share: self.share(self.negative_z) });
        }
        if let Some(expected) = self.expected
            && self.guess.confident
            && self.guess.convention != expected
        {
            found.push(Finding::Convention { expected, found: self.guess.convention });
        }
        if let Some(b) = self.banding
            && b.banded
        {
            found.push(Finding::Banded { score: b.score });
        }
        for (axis, a) in [("x", self.tiling.x), ("y", self.tiling.y)] {
            if !a.seamless {
                found.push(Finding::Seam { axis, score: a.score });
            }
        }
        found
    }

    /// Whether nothing was found.
    #[must_use]
    pub fn clean(&self) -> bool {
        self.findings().is_empty()
    }

    /// The map's convention: as stated, else the guess when confident.
    #[must_use]
    pub fn known_convention(&self) -> Option<Convention> {
        self.expected.or(self.guess.confident.then_some(self.guess.convention))
    }
}

/// A map's normals as decoded, with what the check needs of its storage.
struct Decoded {
    /// n per texel (z rebuilt for RG).
    normals: Vec<[f32; 3]>,
    /// The stored values of R, G (B when present), in [0, 1] or as floats.
    planes: [Vec<f32>; 3],
    layout: MapLayout,
    storage: Storage,
}

/// The step and the length tolerance of a storage.
fn tolerances(storage: Storage) -> (f64, f64) {
    let step = match storage {
        Storage::Int { .. } => storage.step(),
        // A float file may hold half floats: their step near 1.
        _ => 2f64.powi(-10),
    };
    (step, 3f64.sqrt() * step / 2.0 + 1e-7)
}

fn decoded(raster: &Raster, signed: bool) -> Result<Decoded> {
    let storage = Storage::of_file(raster.sample, signed)?;
    let (r, g) = match (raster.plane("R"), raster.plane("G")) {
        (Some(r), Some(g)) => (r.data.to_f32()?, g.data.to_f32()?),
        _ => return Err(Error::Unsupported("a normal map needs R and G channels (and B, or z is rebuilt)".into())),
    };
    let b = raster.plane("B").map(|b| b.data.to_f32()).transpose()?;
    let len = r.len();
    let (_, tolerance) = tolerances(storage);
    let (b, layout) = match b {
        None => (vec![if signed { 0.0 } else { 0.5 }; len], MapLayout::Rg),
        Some(b) => {
            let constant = b.first().is_some_and(|&v0| b.par_iter().all(|&v| v == v0));
            let mut layout = MapLayout::Rgb;
            if constant {
                let normals = decode_planes([&r, &g, &b], signed)?;
                let off = normals.par_iter().filter(|n| (length(n) - 1.0).abs() > tolerance).count();
                if off * 2 > len {
                    layout = MapLayout::Rg;
                }
            }
            (b, layout)
        }
    };
    let mut normals = decode_planes([&r, &g, &b], signed)?;
    if layout == MapLayout::Rg {
        normals.par_chunks_mut(raster.width.max(1)).for_each(|row| {
            for n in row {
                let (x, y) = (f64::from(n[0]), f64::from(n[1]));
                n[2] = (1.0 - x * x - y * y).max(0.0).sqrt() as f32;
            }
        });
    }
    Ok(Decoded { normals, planes: [r, g, b], layout, storage })
}

fn length(n: &[f32; 3]) -> f64 {
    let [x, y, z] = n.map(f64::from);
    (x * x + y * y + z * z).sqrt()
}

/// Checks a decoded normal map (the measures of the [module docs](self)).
///
/// Errors: [`Error::Unsupported`] for an image without R and G;
/// [`Error::InvalidOption`] for `signed` with integer samples and a zero
/// size; [`Error::NonFiniteNormal`] naming the first texel with a NaN or
/// infinite component; [`Error::Limits`] when the memory is not there.
pub fn check(raster: &Raster, opts: &CheckOptions) -> Result<CheckReport> {
    opts.tiling.validate()?;
    let (w, h) = (raster.width, raster.height);
    crate::fit::checked_len(w, h)?;
    // The planes, the normals and the slopes' field: about 40 bytes a texel.
    crate::memory::check_memory("the check", (w as u64 * h as u64).saturating_mul(48))?;
    let d = decoded(raster, opts.signed)?;
    if let Some(k) = d.normals.iter().position(|n| !n.iter().all(|c| c.is_finite())) {
        return Err(Error::NonFiniteNormal { x: k % w, y: k / w });
    }
    let (step, tolerance) = tolerances(d.storage);
    let off_length = match d.layout {
        MapLayout::Rgb => d.normals.par_iter().filter(|n| (length(n) - 1.0).abs() > tolerance).count(),
        MapLayout::Rg => d
            .normals
            .par_iter()
            .filter(|n| {
                let (x, y) = (f64::from(n[0]), f64::from(n[1]));
                (x * x + y * y).sqrt() > 1.0 + tolerance
            })
            .count(),
    };
    let negative_z = d.normals.par_iter().filter(|n| f64::from(n[2]) < -step / 2.0).count();
    let guess = convention::guess(&d.normals, w, h)?;
    let banding = match d.storage {
        Storage::Int { bits } if bits <= 8 => Some(banding(&d.planes[0], &d.planes[1], w, h, bits)),
        _ => None,
    };
    let b_plane: Vec<f32>;
    let b = match d.layout {
        MapLayout::Rgb => &d.planes[2],
        MapLayout::Rg => {
            b_plane = d.normals.iter().map(|n| if opts.signed { n[2] } else { (n[2] + 1.0) / 2.0 }).collect();
            &b_plane
        }
    };
    let tiling = tiling::check(&[&d.planes[0], &d.planes[1], b], w, h, &opts.tiling)?;
    let expected = match opts.convention {
        ConventionChoice::OpenGl => Some(Convention::OpenGl),
        ConventionChoice::DirectX => Some(Convention::DirectX),
        _ => None,
    };
    Ok(CheckReport {
        width: w,
        height: h,
        sample: raster.sample,
        layout: d.layout,
        length_tolerance: tolerance,
        off_length,
        negative_z,
        guess,
        expected,
        banding,
        tiling,
    })
}

/// The banding measure of the R and G planes (stored values in [0, 1]) of
/// an integer map of `bits` bits.
fn banding(r: &[f32], g: &[f32], w: usize, h: usize, bits: u8) -> Banding {
    let top = f64::from((1u32 << bits) - 1);
    let code = |v: f32| (f64::from(v) * top).round() as i32;
    // (staircases, varying) of one window of codes.
    let judge = |codes: &[i32; WINDOW]| -> (usize, usize) {
        if codes.iter().all(|&c| c == codes[0]) {
            return (0, 0);
        }
        let steps = codes.windows(2).map(|p| p[1] - p[0]);
        let smooth = steps.clone().all(|s| s.abs() <= 1);
        let changes = steps.filter(|&s| s != 0).count();
        (usize::from(smooth && changes <= 3), 1)
    };
    let add = |a: (usize, usize), b: (usize, usize)| (a.0 + b.0, a.1 + b.1);
    let mut total = (0, 0);
    for plane in [r, g] {
        let rows = (0..h)
            .into_par_iter()
            .map(|y| {
                let row = &plane[y * w..][..w];
                let mut sums = (0, 0);
                let mut x = 0;
                while x + WINDOW <= w {
                    let codes: [i32; WINDOW] = std::array::from_fn(|i| code(row[x + i]));
                    sums = add(sums, judge(&codes));
                    x += WINDOW / 2;
                }
                sums
            })
            .collect::<Vec<_>>()
            .into_iter()
            .fold((0, 0), add);
        let starts: Vec<usize> = (0..h.saturating_sub(WINDOW - 1)).step_by(WINDOW / 2).collect();
        let columns = starts
            .into_par_iter()
            .map(|y| {
                let mut sums = (0, 0);
                for x in 0..w {
                    let codes: [i32; WINDOW] = std::array::from_fn(|i| code(plane[(y + i) * w + x]));
                    sums = add(sums, judge(&codes));
                }
                sums
            })
            .collect::<Vec<_>>()
            .into_iter()
            .fold((0, 0), add);
        total = add(total, add(rows, columns));
    }
    let (stairs, varying) = total;
    let score = if varying > 0 { stairs as f64 / varying as f64 } else { 0.0 };
    Banding { score, windows: varying, banded: varying >= BANDING_MIN_WINDOWS && score >= BANDED_SHARE }
}

/// [`check`] of the image file at `path`.
///
/// Errors: those of [`io::read_path`] and [`check`].
pub fn check_file(path: &Path, read: &ReadOptions, opts: &CheckOptions) -> Result<CheckReport> {
    check(&io::read_path(path, read)?, opts)
}

/// How a map is repaired.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct FixOptions {
    /// The convention to write; `None` keeps the map's.
    pub to: Option<Convention>,
    /// The output format when the output's name does not say (default: as
    /// the input's).
    pub format: Option<OutputFormat>,
}

impl FixOptions {
    /// Keeps the convention, the format as named.
    #[must_use]
    pub fn new() -> Self {
        FixOptions::default()
    }
    /// Writes in this convention.
    #[must_use]
    pub fn with_to(mut self, to: Option<Convention>) -> Self {
        self.to = to;
        self
    }
}

/// The repaired normals of a checked map: each n renormalised (z rebuilt
/// first for an RG map; a texel of zero length becomes (0, 0, 1)), green
/// negated when `to` is not the map's convention.
///
/// Errors: [`Error::InvalidOption`] when `to` is given and the map's
/// convention is neither stated nor confidently guessed; those of
/// [`check`]'s decoding.
pub fn fixed_normals<O: FromNormal + Send>(
    raster: &Raster,
    report: &CheckReport,
    signed: bool,
    to: Option<Convention>,
) -> Result<Vec<O>> {
    let flip = match to {
        None => false,
        Some(to) => match report.known_convention() {
            Some(from) => from != to,
            None => {
                let [gl, dx] = report.guess.curl;
                return Err(Error::InvalidOption(format!(
                    "cannot tell its convention (relative curl {gl:.3} as opengl, {dx:.3} as directx): state it with --convention to flip it"
                )));
            }
        },
    };
    let d = decoded(raster, signed)?;
    let mut out = try_vec(d.normals.len())?;
    out.par_extend(d.normals.par_iter().map(|n| {
        let v = n.map(f64::from);
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let u = if len > 0.0 && len.is_finite() { v.map(|c| c / len) } else { [0.0, 0.0, 1.0] };
        O::from_normal([u[0], if flip { -u[1] } else { u[1] }, u[2]])
    }));
    Ok(out)
}

/// Writes the repaired map ([`fixed_normals`]) of `raster` into `output`,
/// in the input's depth (8, 16 bits or float) and the format the output's
/// name says (else [`FixOptions::format`], else the input's), RGB.
///
/// Errors: [`Place::Input`] for the repair; [`Place::Output`] for the
/// name, encoding and writing, and an output that is the input (`input`).
pub fn write_fixed(
    raster: &Raster,
    report: &CheckReport,
    signed: bool,
    fix: &FixOptions,
    output: Output<'_>,
    input: Option<&Path>,
) -> Result<OutputFormat, ConvertError> {
    let fail = ConvertError::at;
    if let (Some(i), Some(o)) = (input, output.path())
        && io::same_file(i, o)
    {
        return Err(fail(Place::Output)(Error::InvalidOption(
            "the output is the input (or a link to it): normalfit never writes over an input".into(),
        )));
    }
    let named = output.path().map(OutputFormat::from_path).transpose().map_err(fail(Place::Output))?.flatten();
    let format = named.or(fix.format).unwrap_or_else(|| OutputFormat::for_input(&raster.format, raster.sample));
    let float_signed = signed && !matches!(format, OutputFormat::Png);
    let encoding =
        Encoding::choose(format, None, float_signed, io::Layout::Rgb, PngCompression::default(), raster.sample)
            .map_err(fail(Place::Output))?;
    let (texels, ()) = engine::Texels::of(&encoding, |depth| {
        Ok((
            match depth {
                engine::Depth::Eight => engine::Texels::Eight(fixed_normals(raster, report, signed, fix.to)?),
                engine::Depth::Sixteen => engine::Texels::Sixteen(fixed_normals(raster, report, signed, fix.to)?),
                engine::Depth::Float => engine::Texels::Float(fixed_normals(raster, report, signed, fix.to)?),
            },
            (),
        ))
    })
    .map_err(|e| match e {
        Error::Encode(_) | Error::Io(_) => fail(Place::Output)(e),
        other => fail(Place::Input)(other),
    })?;
    engine::write_normals(output, &texels, (raster.width, raster.height), &encoding).map_err(fail(Place::Output))?;
    Ok(format)
}

/// [`check`] then [`write_fixed`] of one input, read once.
///
/// Errors: as [`check`] (at [`Place::Input`]) and [`write_fixed`].
pub fn check_and_fix(
    input: Input<'_>,
    read: &ReadOptions,
    opts: &CheckOptions,
    fix: Option<(&FixOptions, Output<'_>)>,
) -> Result<CheckReport, ConvertError> {
    let path = match &input {
        Input::Path(p) => Some(*p),
        _ => None,
    };
    let raster = engine::decode_whole(input, read).map_err(ConvertError::at(Place::Input))?;
    let report = check(&raster, opts).map_err(ConvertError::at(Place::Input))?;
    if let Some((fix, output)) = fix {
        write_fixed(&raster, &report, opts.signed, fix, output, path)?;
    }
    Ok(report)
}
