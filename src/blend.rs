//! A detail normal map blended onto a base: Reoriented Normal Mapping,
//! whiteout, UDN, or the normalised sum.
//!
//! Every method works on unit normals b (base) and d (detail), each
//! normalised first, and the result is normalised (docs/blend.md gives the
//! sources):
//!
//! ```text
//! linear    r = (b + d)
//! udn       r = (bx + dx, by + dy, bz)
//! whiteout  r = (bx + dx, by + dy, bz · dz)
//! rnm       t = (bx, by, bz + 1),  u = (−dx, −dy, dz),  r = t · (t·u) / tz − u
//! ```
//!
//! RNM (Barré-Brisebois & Hill, "Blending in Detail", 2012) rotates the
//! detail by the rotation that takes (0, 0, 1) to b: its result is unit
//! for unit inputs, a flat base gives the detail and a flat detail the
//! base, and two tilts in one plane add their angles. Whiteout and UDN are
//! the same article's cheaper forms; a flat detail gives the base for
//! RNM, whiteout and UDN (linear halves the base's tilt), a flat base
//! gives the detail for RNM and whiteout only.
//!
//! **Strength** F scales the detail's slopes before the blend: d is
//! replaced by (F·dx, F·dy, dz) normalised, so F = 0 makes the detail flat
//! (the base, but for linear) and F = 2 doubles the detail's relief.
//!
//! **Conventions.** Every formula commutes with flipping green on both
//! inputs, so maps of one convention blend the same way in either and the
//! result is in theirs. A detail of the other convention than the base has
//! its green flipped first; the result is in the base's convention.
//!
//! **Sizes.** A detail smaller than the base is tiled: its width and
//! height must divide the base's (a 512² detail on a 2048² base repeats
//! 4 × 4 times); other sizes are refused.

use std::path::Path;

use crate::check::convention::{self, ConventionGuess};
use crate::engine::{self, ConvertError, Input, Output, Place};
use crate::error::{Error, Number, Result};
use crate::height::{ConventionChoice, NormalComponent};
use crate::io::{self, Encoding, OutputFormat, PngCompression, Raster, ReadOptions};
use crate::options::named_values;
use crate::par::prelude::*;
use crate::{Convention, FromNormal};

/// How the detail is combined with the base.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Method {
    /// Reoriented Normal Mapping: the detail rotated onto the base. The
    /// default.
    #[default]
    Rnm,
    /// Whiteout: slopes added, z multiplied.
    Whiteout,
    /// UDN: slopes added, the base's z kept.
    Udn,
    /// The normalised sum b + d.
    Linear,
}

named_values!(Method, "blend method", {
    Rnm => "rnm" | "reoriented",
    Whiteout => "whiteout",
    Udn => "udn",
    Linear => "linear",
});

/// Every choice of a blend.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct BlendOptions {
    /// The formula. Default: [`Method::Rnm`].
    pub method: Method,
    /// F, the factor on the detail's slopes (finite, ≥ 0). Default: 1.
    pub strength: f64,
    /// The base's green convention, or [`ConventionChoice::Auto`]: guessed
    /// from its curl ([`crate::check::convention`]). Default: auto.
    pub base: ConventionChoice,
    /// The detail's green convention, or auto. Default: auto.
    pub detail: ConventionChoice,
}

impl Default for BlendOptions {
    fn default() -> Self {
        BlendOptions::new()
    }
}

impl BlendOptions {
    /// RNM, strength 1, both conventions guessed.
    #[must_use]
    pub fn new() -> Self {
        BlendOptions {
            method: Method::Rnm,
            strength: 1.0,
            base: ConventionChoice::Auto,
            detail: ConventionChoice::Auto,
        }
    }
    /// With this method.
    #[must_use]
    pub fn with_method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }
    /// With this strength.
    #[must_use]
    pub fn with_strength(mut self, strength: f64) -> Self {
        self.strength = strength;
        self
    }
    /// With both inputs' convention.
    #[must_use]
    pub fn with_convention(mut self, c: ConventionChoice) -> Self {
        (self.base, self.detail) = (c, c);
        self
    }
    /// With the detail's convention alone.
    #[must_use]
    pub fn with_detail_convention(mut self, c: ConventionChoice) -> Self {
        self.detail = c;
        self
    }

    /// Errors: [`Error::InvalidOption`] for a strength that is negative or
    /// not finite.
    pub fn validate(&self) -> Result<()> {
        if !(self.strength.is_finite() && self.strength >= 0.0) {
            return Err(Error::InvalidOption(format!(
                "strength must be finite and ≥ 0, got {}",
                Number(self.strength)
            )));
        }
        Ok(())
    }
}

/// v / |v|, or (0, 0, 1) where v has no length.
#[inline]
fn unit(v: [f64; 3]) -> [f64; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len > 0.0 && len.is_finite() { v.map(|c| c / len) } else { [0.0, 0.0, 1.0] }
}

/// One texel's blend: base `b` and detail `d` (any length, finite) by
/// `method` with the detail's slopes scaled by `strength` (the formulas of
/// the [module docs](self)). The result is unit.
#[must_use]
pub fn blend_normal(b: [f64; 3], d: [f64; 3], method: Method, strength: f64) -> [f64; 3] {
    let b = unit(b);
    let d = unit(d);
    let d = if strength == 1.0 { d } else { unit([strength * d[0], strength * d[1], d[2]]) };
    let r = match method {
        Method::Linear => [b[0] + d[0], b[1] + d[1], b[2] + d[2]],
        Method::Udn => [b[0] + d[0], b[1] + d[1], b[2]],
        Method::Whiteout => [b[0] + d[0], b[1] + d[1], b[2] * d[2]],
        Method::Rnm => {
            let t = [b[0], b[1], b[2] + 1.0];
            // A base pointing straight down has no rotation onto it.
            if t[2] <= 0.0 {
                return b;
            }
            let u = [-d[0], -d[1], d[2]];
            let k = (t[0] * u[0] + t[1] * u[1] + t[2] * u[2]) / t[2];
            [t[0] * k - u[0], t[1] * k - u[1], t[2] * k - u[2]]
        }
    };
    unit(r)
}

/// What a blend decided besides the normals.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct BlendReport {
    /// The base's convention, the result's.
    pub base: Convention,
    /// The detail's convention (its green flipped when it is not the
    /// base's).
    pub detail: Convention,
    /// The base's guess, where its convention was guessed.
    pub base_guess: Option<ConventionGuess>,
    /// The detail's guess, where its convention was guessed.
    pub detail_guess: Option<ConventionGuess>,
    /// How many times the detail repeats across and down.
    pub repeats: (usize, usize),
}

/// How many times a detail of `detail` size repeats across a base of `base`
/// size.
///
/// Errors: [`Error::InvalidOption`] when a side of the detail does not
/// divide the base's, or a side is 0.
pub fn repeats(base: (usize, usize), detail: (usize, usize)) -> Result<(usize, usize)> {
    let ((bw, bh), (dw, dh)) = (base, detail);
    if bw == 0 || bh == 0 || dw == 0 || dh == 0 {
        return Err(Error::InvalidOption(format!("image is {bw}×{bh} or {dw}×{dh}: both sides must be at least 1")));
    }
    if bw % dw != 0 || bh % dh != 0 {
        return Err(Error::InvalidOption(format!(
            "the detail is {dw}×{dh} and the base {bw}×{bh}: the detail's sides must divide the base's to tile it"
        )));
    }
    Ok((bw / dw, bh / dh))
}

/// Which way each map's green points: as told, or guessed; a guess that is
/// not confident takes the other map's convention (blending commutes with
/// flipping both, so two maps that cannot tell are taken as one).
fn settle(
    opts: &BlendOptions,
    guess_base: impl FnOnce() -> Result<ConventionGuess>,
    guess_detail: impl FnOnce() -> Result<ConventionGuess>,
) -> Result<(Convention, Convention, Option<ConventionGuess>, Option<ConventionGuess>)> {
    let told = |c: ConventionChoice| match c {
        ConventionChoice::OpenGl => Some(Convention::OpenGl),
        ConventionChoice::DirectX => Some(Convention::DirectX),
        _ => None,
    };
    let bg = if told(opts.base).is_none() { Some(guess_base()?) } else { None };
    let dg = if told(opts.detail).is_none() { Some(guess_detail()?) } else { None };
    let known = |t: Option<Convention>, g: Option<ConventionGuess>| {
        t.or_else(|| g.filter(|g| g.confident).map(|g| g.convention))
    };
    let (kb, kd) = (known(told(opts.base), bg), known(told(opts.detail), dg));
    let (base, detail) = match (kb, kd) {
        (Some(b), Some(d)) => (b, d),
        (Some(b), None) => (b, b),
        (None, Some(d)) => (d, d),
        (None, None) => {
            let c = bg.map_or(Convention::OpenGl, |g| g.convention);
            (c, c)
        }
    };
    Ok((base, detail, bg, dg))
}

/// Blends `detail` (`detail_size` = (width, height), row-major normals,
/// any length) onto `base` (`base_size`), the detail tiled when smaller,
/// each result straight into the texel type `O` ([`FromNormal`]: f32 or
/// f64 normals, or 8/16-bit encoded).
///
/// ```
/// use normalfit::blend::{BlendOptions, Method, blend};
/// use normalfit::height::ConventionChoice;
///
/// let base = vec![[0.6f64, 0.0, 0.8]; 4];
/// let flat = vec![[0.0f64, 0.0, 1.0]; 1];
/// let opts = BlendOptions::new().with_method(Method::Rnm).with_convention(ConventionChoice::OpenGl);
/// let (out, report) = blend::<f64, [f64; 3]>(&base, (2, 2), &flat, (1, 1), &opts)?;
/// assert_eq!(report.repeats, (2, 2));
/// assert!((out[3][0] - 0.6).abs() < 1e-12 && (out[3][2] - 0.8).abs() < 1e-12);
/// # Ok::<(), normalfit::Error>(())
/// ```
///
/// Errors: [`Error::InvalidOption`] for invalid options or sizes that do
/// not divide ([`repeats`]); [`Error::BufferSize`] for a buffer that does
/// not hold its size; [`Error::NonFiniteNormal`] naming the first texel
/// (of the base, then of the detail) with a NaN or infinite component;
/// [`Error::Limits`] when the memory is not there.
pub fn blend<T: NormalComponent, O: FromNormal + Default + Clone>(
    base: &[[T; 3]],
    base_size: (usize, usize),
    detail: &[[T; 3]],
    detail_size: (usize, usize),
    opts: &BlendOptions,
) -> Result<(Vec<O>, BlendReport)> {
    opts.validate()?;
    let rep = repeats(base_size, detail_size)?;
    let ((bw, bh), (dw, dh)) = (base_size, detail_size);
    for (buf, (w, h)) in [(base, base_size), (detail, detail_size)] {
        let len = crate::fit::checked_len(w, h)?;
        if buf.len() != len {
            return Err(Error::BufferSize { expected: len, actual: buf.len() });
        }
        finite(buf, w)?;
    }
    let (b, d, bg, dg) = settle(opts, || convention::guess(base, bw, bh), || convention::guess(detail, dw, dh))?;
    let flip = if b == d { 1.0 } else { -1.0 };
    let mut out: Vec<O> = crate::samples::try_filled(bw * bh, O::default())?;
    let (method, strength) = (opts.method, opts.strength);
    out.par_chunks_mut(bw).enumerate().for_each(|(y, row)| {
        let drow = &detail[(y % dh) * dw..][..dw];
        let brow = &base[y * bw..][..bw];
        for (x, (o, bn)) in row.iter_mut().zip(brow).enumerate() {
            let dn = drow[x % dw].map(T::to_f64);
            let dn = [dn[0], flip * dn[1], dn[2]];
            *o = O::from_normal(blend_normal(bn.map(T::to_f64), dn, method, strength));
        }
    });
    Ok((out, BlendReport { base: b, detail: d, base_guess: bg, detail_guess: dg, repeats: rep }))
}

/// The first texel with a NaN or infinite component.
fn finite<T: NormalComponent>(normals: &[[T; 3]], width: usize) -> Result<()> {
    match normals.iter().position(|n| !n.iter().all(|c| c.to_f64().is_finite())) {
        Some(k) => Err(Error::NonFiniteNormal { x: k % width, y: k / width }),
        None => Ok(()),
    }
}

/// A blend of two files: the options, reading and the output's encoding.
#[derive(Clone, Debug, Default)]
#[non_exhaustive]
pub struct BlendFiles {
    /// The blend's options.
    pub options: BlendOptions,
    /// Limits and the EXR layer, for both inputs.
    pub read: ReadOptions,
    /// Float inputs hold n itself, not (n + 1)/2 (both inputs).
    pub signed: bool,
    /// Bits of the output (8 or 16 for PNG and TIFF, 16 or 32 for EXR);
    /// `None`: as SPEC §3 chooses from the base's samples.
    pub bits: Option<u8>,
    /// A float output holds n itself.
    pub signed_output: bool,
    /// The output format when the output's name does not say (default: the
    /// base's).
    pub format: Option<OutputFormat>,
}

/// What a blend of files did.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct BlendSummary {
    /// The output's width and height (the base's).
    pub size: (usize, usize),
    /// The format written.
    pub format: OutputFormat,
    /// The conventions and repeats.
    pub report: BlendReport,
}

impl BlendFiles {
    /// The defaults.
    #[must_use]
    pub fn new() -> Self {
        BlendFiles::default()
    }
    /// With these options.
    #[must_use]
    pub fn with_options(mut self, options: BlendOptions) -> Self {
        self.options = options;
        self
    }
    /// With these read options.
    #[must_use]
    pub fn with_read(mut self, read: ReadOptions) -> Self {
        self.read = read;
        self
    }
    /// With the output's bits.
    #[must_use]
    pub fn with_bits(mut self, bits: Option<u8>) -> Self {
        self.bits = bits;
        self
    }
    /// Float inputs hold n itself.
    #[must_use]
    pub fn with_signed(mut self, signed: bool) -> Self {
        self.signed = signed;
        self
    }

    /// Blends the files `detail` onto `base` into `output`.
    ///
    /// Errors: as [`BlendFiles::blend`].
    pub fn blend_files(&self, base: &Path, detail: &Path, output: &Path) -> Result<BlendSummary, ConvertError> {
        self.blend(Input::Path(base), Input::Path(detail), Output::file(output))
    }

    /// Reads both maps whole, blends them ([`blend`]) and writes the result
    /// (a file, atomically and never over an input; or a writer, given the
    /// whole encoded image). Nothing is written when any step fails.
    ///
    /// Errors: [`Place::Input`] for the base (reading, decoding, a map
    /// without R, G and B, a non-finite normal), [`Place::Detail`] for the
    /// detail, and for sizes that do not divide; [`Place::Output`] for the
    /// output's name, encoding and writing, and an output that is an
    /// input.
    pub fn blend(&self, base: Input<'_>, detail: Input<'_>, output: Output<'_>) -> Result<BlendSummary, ConvertError> {
        let fail = ConvertError::at;
        self.options.validate().map_err(fail(Place::Input))?;
        let out_path = output.path();
        for input in [&base, &detail] {
            if let (Input::Path(p), Some(o)) = (input, out_path)
                && io::same_file(p, o)
            {
                return Err(fail(Place::Output)(Error::InvalidOption(
                    "the output is an input (or a link to one): normalfit never writes over an input".into(),
                )));
            }
        }
        let named = out_path.map(OutputFormat::from_path).transpose().map_err(fail(Place::Output))?.flatten();
        let b = engine::decode_whole(base, &self.read).map_err(fail(Place::Input))?;
        let base_normals = normals_of(&b, self.signed).map_err(fail(Place::Input))?;
        let format = named.or(self.format).unwrap_or_else(|| OutputFormat::for_input(&b.format, b.sample));
        let encoding = Encoding::choose(
            format,
            self.bits,
            self.signed_output,
            io::Layout::Rgb,
            PngCompression::default(),
            b.sample,
        )
        .map_err(fail(Place::Output))?;
        let (bw, bh) = (b.width, b.height);
        drop(b);
        let d = engine::decode_whole(detail, &self.read).map_err(fail(Place::Detail))?;
        let detail_normals = normals_of(&d, self.signed).map_err(fail(Place::Detail))?;
        let (dw, dh) = (d.width, d.height);
        drop(d);
        repeats((bw, bh), (dw, dh)).map_err(fail(Place::Detail))?;
        finite(&base_normals, bw).map_err(fail(Place::Input))?;
        finite(&detail_normals, dw).map_err(fail(Place::Detail))?;
        let (base, detail, opts) = (&base_normals, &detail_normals, &self.options);
        let (texels, report) = engine::Texels::of(&encoding, |depth| -> Result<_> {
            Ok(match depth {
                engine::Depth::Eight => {
                    let (t, r) = blend::<f32, [u8; 3]>(base, (bw, bh), detail, (dw, dh), opts)?;
                    (engine::Texels::Eight(t), r)
                }
                engine::Depth::Sixteen => {
                    let (t, r) = blend::<f32, [u16; 3]>(base, (bw, bh), detail, (dw, dh), opts)?;
                    (engine::Texels::Sixteen(t), r)
                }
                engine::Depth::Float => {
                    let (t, r) = blend::<f32, [f32; 3]>(base, (bw, bh), detail, (dw, dh), opts)?;
                    (engine::Texels::Float(t), r)
                }
            })
        })
        .map_err(fail(Place::Input))?;
        drop((base_normals, detail_normals));
        engine::write_normals(output, &texels, (bw, bh), &encoding).map_err(fail(Place::Output))?;
        Ok(BlendSummary { size: (bw, bh), format, report })
    }
}

/// A decoded normal map's normals (R, G, B by [`crate::normal_map::decode`]).
fn normals_of(raster: &Raster, signed: bool) -> Result<Vec<[f32; 3]>> {
    crate::normal_map::decode(raster, signed)
}
