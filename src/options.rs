//! What a conversion is asked to do: the plane fit's parameters, each with
//! its default from the contract (`SPEC.md`, sections 1 and 2).

use std::sync::Arc;

use crate::error::{Error, Number};

mod detail;
pub use detail::{Detail, MAX_SCALES, MAX_WEIGHT};

/// Which plane the fit finds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Fit {
    /// The plane minimising the summed squared *perpendicular* distances to
    /// the patch's points (total least squares). Steep slopes keep their
    /// true angle. The default.
    #[default]
    Orthogonal,
    /// Ordinary least squares of height over the patch (vertical distances).
    /// For N = 3 it is the Prewitt filter divided by 6, DirectXTex's kernel.
    Vertical,
}

/// What a texel index outside the image maps to, per axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Border {
    /// `k mod n`: the texture tiles. The default.
    #[default]
    Wrap,
    /// The nearest edge texel.
    Clamp,
    /// Reflection about the edge texel, the edge not repeated (−1 → 1);
    /// period 2(n − 1). An axis of one texel acts as clamp.
    Mirror,
}

impl Border {
    /// Maps any index `k` (possibly far outside) onto `[0, n)`. `n` must be ≥ 1.
    #[must_use]
    pub fn map(self, k: isize, n: usize) -> usize {
        debug_assert!(n >= 1);
        let n = n as isize;
        let m = match self {
            Border::Wrap => k.rem_euclid(n),
            Border::Clamp => k.clamp(0, n - 1),
            Border::Mirror if n == 1 => 0,
            Border::Mirror => {
                let period = 2 * (n - 1);
                let m = k.rem_euclid(period);
                if m < n { m } else { period - m }
            }
        };
        m as usize
    }
}

/// Border modes for the two axes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Borders {
    /// Along x (columns). Default: wrap.
    pub x: Border,
    /// Along y (rows). Default: wrap.
    pub y: Border,
}

impl Borders {
    /// The same mode on both axes.
    #[must_use]
    pub fn both(mode: Border) -> Self {
        Borders { x: mode, y: mode }
    }
}

impl std::fmt::Display for Borders {
    /// As front ends spell it (`--border`): one mode when both axes have
    /// it ("wrap"), else x then y ("wrap,clamp").
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.x == self.y { write!(f, "{}", self.x) } else { write!(f, "{},{}", self.x, self.y) }
    }
}

/// Which way the normal's green (+Y) component points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Convention {
    /// +Y points to smaller row indices ("green up"): OpenGL, glTF, Blender,
    /// Unity. The default.
    #[default]
    OpenGl,
    /// +Y points to larger row indices ("green down"): DirectX, Unreal.
    DirectX,
}

impl Convention {
    /// σ of the contract: the sign that turns a row offset into the patch's
    /// v coordinate.
    #[must_use]
    pub(crate) fn sigma(self) -> f64 {
        match self {
            Convention::OpenGl => -1.0,
            Convention::DirectX => 1.0,
        }
    }
}

/// The names of an option's values, one spelling each (plus aliases that
/// parse), shared by every front end: the command line, the Python
/// package, configuration files. `Display` prints the name, `FromStr`
/// parses it (ASCII case ignored) with an error that lists the names.
macro_rules! named_values {
    ($ty:ident, $what:literal, { $($variant:ident => $name:literal $(| $alias:literal)*),+ $(,)? }) => {
        impl $ty {
            /// Every value, in the order the docs list them.
            pub const ALL: &'static [$ty] = &[$($ty::$variant),+];

            /// The value's name, as the command line spells it.
            #[must_use]
            pub fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }

            /// Other spellings that parse as this value.
            #[must_use]
            pub fn aliases(self) -> &'static [&'static str] {
                match self {
                    $($ty::$variant => &[$($alias),*]),+
                }
            }
        }

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl std::str::FromStr for $ty {
            type Err = Error;

            fn from_str(s: &str) -> Result<Self, Error> {
                let s = s.trim();
                $(
                    if s.eq_ignore_ascii_case($name) $(|| s.eq_ignore_ascii_case($alias))* {
                        return Ok($ty::$variant);
                    }
                )+
                let names: Vec<&str> = $ty::ALL.iter().map(|v| v.name()).collect();
                Err(Error::InvalidOption(format!(
                    "unknown {} '{s}': use {}",
                    $what,
                    crate::options::one_of(&names)
                )))
            }
        }
    };
}

pub(crate) use named_values;

named_values!(Fit, "fit", { Orthogonal => "orthogonal", Vertical => "vertical" });
named_values!(Border, "border mode", { Wrap => "wrap", Clamp => "clamp", Mirror => "mirror" });
named_values!(Convention, "convention", { OpenGl => "opengl" | "gl", DirectX => "directx" | "dx" });
named_values!(Weights, "weights", { Uniform => "uniform", Binomial => "binomial" });

/// How the fit weighs a patch's points (`--weights`, `weights=`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Weights {
    /// Every point alike: the contract's fit. The default.
    #[default]
    Uniform,
    /// Point (i, j) weighs w(i)·w(j), w the row of Pascal's triangle for N
    /// (1 2 1 at N = 3, 1 4 6 4 1 at N = 5), normalised to sum 1: at
    /// N = 3 the vertical fit is Horn's gradient, gdaldem's (docs/spec.md
    /// §2, "Weights").
    Binomial,
}

impl Weights {
    /// The weights w(k), k = 0 … n − 1, of one axis of an n-point patch,
    /// summing to 1: all 1/n, or C(n − 1, k) / 2^(n − 1), each formed in
    /// f64 by the recurrence of Pascal's triangle halved at every step,
    /// so that nothing overflows up to N = [`MAX_PATCH`] (C(1022, 511) is
    /// about 10^306; its share of 2^1022 is about 0.025).
    #[must_use]
    pub fn axis(self, n: usize) -> Vec<f64> {
        match self {
            Weights::Uniform => vec![1.0 / n as f64; n],
            Weights::Binomial => {
                let mut w = vec![0.0; n.max(1)];
                w[0] = 1.0;
                for row in 1..n {
                    for k in (1..=row).rev() {
                        w[k] = 0.5 * (w[k] + w[k - 1]);
                    }
                    w[0] *= 0.5;
                }
                w
            }
        }
    }
}

/// "a, b or c".
pub(crate) fn one_of(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [one] => (*one).to_string(),
        [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
    }
}

/// How heights become surface z in texel units.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum Strength {
    /// z = S · h: the full [0, 1] height range spans S texel widths.
    Scale(f64),
    /// z = F · W · h (W the image width), so the look does not change when
    /// the texture is resampled.
    Relief(f64),
}

impl Strength {
    /// The gain from a caller's two optional settings, as every front end
    /// takes them (`-s`/`--scale` or `--relief`, `scale=` or `relief=`):
    /// either one, or neither for the default.
    ///
    /// Errors: [`Error::InvalidOption`] when both are given.
    pub fn from_scale_or_relief(scale: Option<f64>, relief: Option<f64>) -> Result<Strength, Error> {
        match (scale, relief) {
            (Some(_), Some(_)) => Err(Error::InvalidOption("give scale or relief, not both".into())),
            (Some(s), None) => Ok(Strength::Scale(s)),
            (None, Some(f)) => Ok(Strength::Relief(f)),
            (None, None) => Ok(Strength::default()),
        }
    }
}

impl Default for Strength {
    /// `Scale(1.0)` ([`Options::DEFAULT_SCALE`]): the gain of DirectXTex,
    /// GIMP's 3×3 filter and Godot.
    fn default() -> Self {
        Strength::Scale(Options::DEFAULT_SCALE)
    }
}

/// What units the heights and the texel grid are in.
#[derive(Clone, Debug, Default, PartialEq)]
#[non_exhaustive]
pub enum Units {
    /// The contract's units (SPEC §1): integers are value / (2^bits − 1),
    /// texel centres one texel width apart, z = S · h in texel widths.
    /// The default.
    #[default]
    Texels,
    /// Real-world units (docs/terrain.md): heights as given (the stored
    /// values, a DEM's metres: an integer sample counts its own value, not
    /// value / (2^bits − 1)), texel centres [`Spacing`] apart in the same
    /// unit, z = S · h. With S = 1 a texel's slope is the terrain's true
    /// slope (rise over run); S is then a vertical exaggeration.
    Map(Spacing),
}

/// The distance between neighbouring texel centres, in the heights' unit,
/// for [`Units::Map`]: `x` along a row (column to column), `y` down a
/// column (row to row). A pixel need not be square.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Spacing {
    /// The same spacing for every row: a projected map.
    Uniform {
        /// Column to column.
        x: f64,
        /// Row to row.
        y: f64,
    },
    /// One `[x, y]` per image row: a geographic raster, whose metres per
    /// degree of longitude shrink towards the poles. A texel's patch is
    /// fitted with the spacing of its centre row (the rows above and below
    /// it are taken at that spacing too, as GIS tools' 3×3 kernels do).
    Rows(Arc<[[f64; 2]]>),
}

impl Spacing {
    /// The same spacing on both axes.
    #[must_use]
    pub fn square(size: f64) -> Spacing {
        Spacing::Uniform { x: size, y: size }
    }

    /// The spacing `[x, y]` of image row `row` (which must be a row of a
    /// [`Spacing::Rows`]).
    #[must_use]
    pub fn at(&self, row: usize) -> [f64; 2] {
        match self {
            Spacing::Uniform { x, y } => [*x, *y],
            Spacing::Rows(rows) => rows[row],
        }
    }

    /// Checks every spacing: finite, positive, within [`MAX_SPACING_RATIO`]
    /// of each other across an axis pair (a ratio beyond it is a unit mix-up,
    /// and leaves nothing of one axis in the fit), and, per row, as many
    /// rows as the image's `height` when it is known.
    pub fn validate(&self, height: Option<usize>) -> Result<(), Error> {
        let rows: &[[f64; 2]] = match self {
            Spacing::Uniform { x, y } => &[[*x, *y]],
            Spacing::Rows(rows) => rows,
        };
        if let (Spacing::Rows(rows), Some(h)) = (self, height)
            && rows.len() != h
        {
            return Err(Error::InvalidOption(format!("spacing given for {} rows, the image has {h}", rows.len())));
        }
        if rows.is_empty() {
            return Err(Error::InvalidOption("spacing given for no rows".into()));
        }
        for (row, &[x, y]) in rows.iter().enumerate() {
            let at = if rows.len() > 1 { format!(" (row {row})") } else { String::new() };
            let (sx, sy) = (Number(x), Number(y));
            if !(x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0) {
                return Err(Error::InvalidOption(format!(
                    "texel spacing must be finite and positive, got {sx} × {sy}{at}"
                )));
            }
            let ratio = x.max(y) / x.min(y);
            if !(ratio <= MAX_SPACING_RATIO && x.min(y) >= 1e-30 && x.max(y) <= 1e30) {
                return Err(Error::InvalidOption(format!(
                    "texel spacing {sx} × {sy}{at} is out of range: each side within 1e-30 to 1e30, \
                     one at most {MAX_SPACING_RATIO:e} times the other"
                )));
            }
        }
        Ok(())
    }
}

/// The largest ratio of a texel's two spacings accepted.
pub const MAX_SPACING_RATIO: f64 = 1e6;

named_values!(Product, "product", {
    Normals => "normals",
    Curvature => "curvature",
    Slope => "slope",
    Aspect => "aspect",
    Hillshade => "hillshade",
});

/// What a conversion makes of the heights (`--product`, `product=`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Product {
    /// The normal map of the plane fitted over each patch. The default.
    #[default]
    Normals,
    /// The mean curvature of the quadratic fitted over each patch, convex
    /// positive (docs/curvature.md, [`crate::fit::curvature`]): one
    /// channel, float as it is, 8 or 16 bits mapped round mid-grey.
    Curvature,
    /// The slope of the plane fitted over each patch, in degrees or
    /// percent ([`SlopeUnits`]), as `gdaldem slope` (docs/products.md):
    /// one float channel.
    Slope,
    /// The compass direction the plane faces, degrees clockwise from north,
    /// as `gdaldem aspect` (docs/products.md): one float channel.
    Aspect,
    /// The plane lit by the GIS sun, 8-bit grey 1 to 255 with 0 for
    /// nodata, as `gdaldem hillshade` (docs/products.md).
    Hillshade,
}

impl Product {
    /// How the product marks a missing texel (a hole, or a patch without a
    /// plane), as a summary names it.
    #[must_use]
    pub fn missing_mark(self) -> &'static str {
        match self {
            Product::Normals => "alpha 0",
            Product::Curvature => "NaN",
            Product::Slope | Product::Aspect => "-9999",
            Product::Hillshade => "grey 0",
        }
    }
}

named_values!(SlopeUnits, "slope units", { Degrees => "degrees", Percent => "percent" });

/// How a slope is given (`--slope-units`, `slope_units=`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SlopeUnits {
    /// The angle from the horizontal, 0 to 90. The default, as gdaldem's.
    #[default]
    Degrees,
    /// Rise over run times 100, as `gdaldem slope -p`.
    Percent,
}

named_values!(UnitsName, "units", { Texels => "texels", Map => "map" });

/// The names of [`Units`] as front ends spell them (`--units texels|map`):
/// the spacing of `map` comes from the file or from the caller.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum UnitsName {
    /// [`Units::Texels`]. The default.
    #[default]
    Texels,
    /// [`Units::Map`].
    Map,
}

/// Everything the plane fit needs besides the heights.
///
/// ```
/// use normalfit::{Border, Borders, Fit, Options};
/// let opts = Options::default()
///     .with_patch(9)
///     .with_fit(Fit::Vertical)
///     .with_borders(Borders { x: Border::Wrap, y: Border::Clamp });
/// assert_eq!(opts.patch, 9);
/// ```
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct Options {
    /// Patch size N: the fit uses the N×N texels around each texel. Odd, ≥ 3.
    /// Default: 3.
    pub patch: usize,
    /// Orthogonal or vertical least squares. Default: orthogonal.
    pub fit: Fit,
    /// Border mode per axis. Default: wrap on both.
    pub borders: Borders,
    /// Green up (OpenGL) or down (DirectX). Default: OpenGL.
    pub convention: Convention,
    /// Height gain. Default: `Scale(1.0)`.
    pub strength: Strength,
    /// Negate the gain: heights are depths. Default: false.
    pub invert: bool,
    /// Heights and texel spacing in the contract's units, or in a map's.
    /// Default: [`Units::Texels`].
    pub units: Units,
    /// Holes: texels whose value as given (the stored sample: a 16-bit
    /// PNG's integer, a DEM's metres) equals it, and texels that are NaN
    /// or infinite, are missing; each patch is fitted to its valid points
    /// alone (docs/terrain.md, "Holes"). `Some(f64::NAN)` marks only the
    /// non-finite texels. Default: `None`, the contract's rule (SPEC §1):
    /// a NaN or infinite height is an error, and no value is special.
    pub nodata: Option<f64>,
    /// Several patch sizes at once, in place of `patch` (which is then left
    /// at its default: [`Options::validate`] refuses both): the normal of
    /// the weighted sum of their slopes (docs/detail.md). Default: `None`.
    pub detail: Option<Detail>,
    /// How the fit weighs the patch's points. Default:
    /// [`Weights::Uniform`], the contract's.
    pub weights: Weights,
}

impl Default for Options {
    fn default() -> Self {
        Options::new()
    }
}

impl Options {
    /// The contract's patch size N.
    pub const DEFAULT_PATCH: usize = 3;

    /// The contract's gain S ([`Strength::Scale`]).
    pub const DEFAULT_SCALE: f64 = 1.0;

    /// The contract's defaults: N = 3, orthogonal fit, wrap on both axes,
    /// OpenGL, scale 1, not inverted.
    #[must_use]
    pub fn new() -> Self {
        Options {
            patch: Options::DEFAULT_PATCH,
            fit: Fit::Orthogonal,
            borders: Borders::default(),
            convention: Convention::OpenGl,
            strength: Strength::default(),
            invert: false,
            units: Units::Texels,
            nodata: None,
            detail: None,
            weights: Weights::Uniform,
        }
    }

    /// Sets the patch size N (odd, ≥ 3).
    #[must_use]
    pub fn with_patch(mut self, n: usize) -> Self {
        self.patch = n;
        self
    }
    /// Sets the fit.
    #[must_use]
    pub fn with_fit(mut self, fit: Fit) -> Self {
        self.fit = fit;
        self
    }
    /// Sets the border modes.
    #[must_use]
    pub fn with_borders(mut self, borders: Borders) -> Self {
        self.borders = borders;
        self
    }
    /// Sets the green convention.
    #[must_use]
    pub fn with_convention(mut self, convention: Convention) -> Self {
        self.convention = convention;
        self
    }
    /// Sets the height gain.
    #[must_use]
    pub fn with_strength(mut self, strength: Strength) -> Self {
        self.strength = strength;
        self
    }
    /// Heights are depths when `invert` is true.
    #[must_use]
    pub fn with_invert(mut self, invert: bool) -> Self {
        self.invert = invert;
        self
    }

    /// Sets the units (real-world units: [`Units::Map`]).
    #[must_use]
    pub fn with_units(mut self, units: Units) -> Self {
        self.units = units;
        self
    }

    /// Sets the nodata value (see [`Options::nodata`]).
    #[must_use]
    pub fn with_nodata(mut self, nodata: Option<f64>) -> Self {
        self.nodata = nodata;
        self
    }

    /// Sets detail at several scales (see [`Options::detail`]), in place
    /// of `patch`, which must then be left at its default.
    #[must_use]
    pub fn with_detail(mut self, detail: Option<Detail>) -> Self {
        self.detail = detail;
        self
    }

    /// Sets how the fit weighs the patch's points (see [`Weights`]).
    #[must_use]
    pub fn with_weights(mut self, weights: Weights) -> Self {
        self.weights = weights;
        self
    }

    /// The largest patch the fit reads: N, or with [`Options::detail`] its
    /// largest size. A window's or a band's halo is half of it.
    #[must_use]
    pub fn largest_patch(&self) -> usize {
        self.detail.as_ref().map_or(self.patch, Detail::largest_patch)
    }

    /// The gain S for an image `width` texels wide, sign included.
    #[must_use]
    pub fn scale_for_width(&self, width: usize) -> f64 {
        let s = match self.strength {
            Strength::Scale(s) => s,
            Strength::Relief(f) => f * width as f64,
        };
        if self.invert { -s } else { s }
    }

    /// Checks the options on their own (the image is checked elsewhere).
    pub fn validate(&self) -> Result<(), Error> {
        if self.patch < 3 || self.patch.is_multiple_of(2) {
            return Err(Error::InvalidOption(format!("patch size must be odd and at least 3, got {}", self.patch)));
        }
        if self.patch > MAX_PATCH {
            return Err(Error::InvalidOption(format!("patch size must be at most {MAX_PATCH}, got {}", self.patch)));
        }
        let (name, value) = match self.strength {
            Strength::Scale(s) => ("scale", s),
            Strength::Relief(f) => ("relief", f),
        };
        if !value.is_finite() || value.abs() > MAX_GAIN {
            return Err(Error::InvalidOption(format!(
                "{name} must be a finite number of magnitude at most {MAX_GAIN:e}, got {}",
                Number(value)
            )));
        }
        if let Units::Map(spacing) = &self.units {
            spacing.validate(None)?;
            // Relief scales the gain with the image's width in texels; in
            // map units the gain is the vertical exaggeration, which the
            // texel count must not change.
            if let Strength::Relief(f) = self.strength {
                return Err(Error::InvalidOption(format!(
                    "relief {} (a gain per image width) has no meaning in map units, where the gain is the \
                     vertical exaggeration: give -s (scale=), 1 for the terrain's own slopes",
                    Number(f)
                )));
            }
        }
        if self.detail.is_some() && self.patch != Options::DEFAULT_PATCH {
            return Err(Error::InvalidOption(format!(
                "give a patch size ({}) or detail at several scales, not both",
                self.patch
            )));
        }
        if self.weights != Weights::Uniform && self.detail.is_some() {
            return Err(Error::InvalidOption(format!(
                "{} weights fit one patch size: give -n (patch=), not detail at several scales (a weighted \
                 sum of several sizes' slopes is not defined yet)",
                self.weights
            )));
        }
        Ok(())
    }
}

/// The largest patch accepted. Sums stay exact far beyond it; the limit only
/// keeps a typo (`-n 30001`) from asking for gigabytes of ring buffers.
pub const MAX_PATCH: usize = 1023;

/// A patch size N as a caller types it (`-n 9`): a whole number that
/// [`Options::validate`] accepts (odd, at least 3, at most [`MAX_PATCH`]).
///
/// Errors: [`Error::InvalidOption`] for text that is not a whole number,
/// and for a size the fit does not take, naming the rule.
///
/// ```
/// assert_eq!(normalfit::options::parse_patch("9").unwrap(), 9);
/// assert!(normalfit::options::parse_patch("4").is_err());
/// ```
pub fn parse_patch(s: &str) -> Result<usize, Error> {
    let n: usize =
        s.parse().map_err(|_| Error::InvalidOption(format!("patch size must be a whole number, got '{s}'")))?;
    Options::new().with_patch(n).validate().map_err(|_| {
        Error::InvalidOption(format!("patch size must be odd, at least 3 and at most {MAX_PATCH}, got {n}"))
    })?;
    Ok(n)
}

/// The largest gain accepted: with heights up to ±3.4e38 (f32's range) the
/// squared sums stay far inside f64's range, so no normal becomes NaN.
pub const MAX_GAIN: f64 = 1e30;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_value_parses_by_its_name_and_aliases_in_any_case() {
        fn round_trip<T: Copy + PartialEq + std::fmt::Debug + std::fmt::Display + std::str::FromStr>(
            all: &[T],
            aliases: impl Fn(T) -> &'static [&'static str],
        ) where
            T::Err: std::fmt::Debug,
        {
            for &v in all {
                let name = v.to_string();
                assert_eq!(name.parse::<T>().unwrap(), v);
                assert_eq!(format!(" {} ", name.to_uppercase()).parse::<T>().unwrap(), v);
                for alias in aliases(v) {
                    assert_eq!(alias.parse::<T>().unwrap(), v, "{alias}");
                }
            }
        }
        round_trip(Fit::ALL, Fit::aliases);
        round_trip(Border::ALL, Border::aliases);
        round_trip(Convention::ALL, Convention::aliases);
        assert_eq!(Border::ALL.len(), 3);
        assert_eq!("dx".parse::<Convention>().unwrap(), Convention::DirectX);
        assert_eq!(Convention::OpenGl.to_string(), "opengl");
    }

    #[test]
    fn an_unknown_name_is_refused_with_the_names() {
        let e = "tile".parse::<Border>().unwrap_err();
        assert_eq!(e.to_string(), "invalid option: unknown border mode 'tile': use wrap, clamp or mirror");
        let e = "ols".parse::<Fit>().unwrap_err();
        assert_eq!(e.to_string(), "invalid option: unknown fit 'ols': use orthogonal or vertical");
        assert!("".parse::<Convention>().is_err());
    }

    #[test]
    fn default_is_the_contracts() {
        let o = Options::default();
        assert_eq!(
            (o.patch, o.fit, o.borders, o.convention),
            (3, Fit::Orthogonal, Borders::both(Border::Wrap), Convention::OpenGl)
        );
        assert_eq!((o.strength, o.invert), (Strength::Scale(1.0), false));
        assert_eq!((Options::DEFAULT_PATCH, Options::DEFAULT_SCALE), (3, 1.0));
        assert_eq!(Strength::default(), Strength::Scale(Options::DEFAULT_SCALE));
    }

    #[test]
    fn borders_print_as_front_ends_spell_them() {
        assert_eq!(Options::default().borders.to_string(), "wrap");
        assert_eq!(Borders { x: Border::Wrap, y: Border::Clamp }.to_string(), "wrap,clamp");
        let round_trip: crate::convert::BorderChoices = "mirror,wrap".parse().unwrap();
        assert_eq!(round_trip.fixed().unwrap().to_string(), "mirror,wrap");
    }

    #[test]
    fn border_maps_follow_the_contract() {
        let n = 4;
        let wrap: Vec<usize> = (-5..9).map(|k| Border::Wrap.map(k, n)).collect();
        assert_eq!(wrap, [3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0]);
        let clamp: Vec<usize> = (-2..6).map(|k| Border::Clamp.map(k, n)).collect();
        assert_eq!(clamp, [0, 0, 0, 1, 2, 3, 3, 3]);
        // Period 2(n - 1) = 6: ... 2 1 | 0 1 2 3 | 2 1 0 1 2 3 ...
        let mirror: Vec<usize> = (-4..10).map(|k| Border::Mirror.map(k, n)).collect();
        assert_eq!(mirror, [2, 3, 2, 1, 0, 1, 2, 3, 2, 1, 0, 1, 2, 3]);
        assert_eq!(Border::Mirror.map(-7, 1), 0);
        assert_eq!(Border::Mirror.map(5, 2), 1);
    }

    #[test]
    fn validation_refuses_even_small_and_non_finite() {
        assert!(Options::new().with_patch(4).validate().is_err());
        assert!(Options::new().with_patch(1).validate().is_err());
        assert!(Options::new().with_patch(63).validate().is_ok());
        let nan = Options::new().with_strength(Strength::Scale(f64::NAN));
        assert!(nan.validate().is_err());
    }

    #[test]
    fn a_patch_size_parses_as_the_fit_takes_it() {
        for n in [3, 5, 63, MAX_PATCH] {
            assert_eq!(parse_patch(&n.to_string()).unwrap(), n);
        }
        let refused = |s: &str| parse_patch(s).unwrap_err().to_string();
        let rule = format!("invalid option: patch size must be odd, at least 3 and at most {MAX_PATCH}, got");
        for n in [0, 1, 2, 4, MAX_PATCH - 1, MAX_PATCH + 2] {
            assert_eq!(refused(&n.to_string()), format!("{rule} {n}"));
            assert!(Options::new().with_patch(n).validate().is_err(), "the same rule as validate: {n}");
        }
        for s in ["", "3.0", "-3", " 3", "three", "99999999999999999999999"] {
            assert_eq!(refused(s), format!("invalid option: patch size must be a whole number, got '{s}'"));
        }
    }

    /// Pascal's rows, exactly (the halvings are exact in binary), summing
    /// to 1 and symmetric up to the largest patch, with nothing overflowed.
    #[test]
    fn binomial_weights_are_pascals_rows() {
        assert_eq!(Weights::Binomial.axis(3), [0.25, 0.5, 0.25]);
        assert_eq!(Weights::Binomial.axis(5), [1.0, 4.0, 6.0, 4.0, 1.0].map(|c| c / 16.0));
        let choose = |n: u64, k: u64| (0..k).fold(1u128, |c, i| c * u128::from(n - i) / u128::from(i + 1));
        let w = Weights::Binomial.axis(33);
        for (k, &wk) in w.iter().enumerate() {
            assert_eq!(wk, choose(32, k as u64) as f64 / 2f64.powi(32), "k {k}");
        }
        for n in [3, 9, 255, MAX_PATCH] {
            let w = Weights::Binomial.axis(n);
            assert!(w.iter().all(|x| x.is_finite() && *x >= 0.0), "N {n}");
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12, "N {n}");
            assert!(w.iter().zip(w.iter().rev()).all(|(a, b)| a == b), "N {n}");
        }
        assert_eq!(Weights::Uniform.axis(4), [0.25; 4]);
        assert_eq!("Binomial".parse::<Weights>().unwrap(), Weights::Binomial);
        assert_eq!(Options::new().weights, Weights::Uniform, "the contract's fit stays the default");
        let both = Options::new().with_weights(Weights::Binomial).with_detail(Some("3,9".parse().unwrap()));
        assert!(both.validate().unwrap_err().to_string().contains("binomial weights fit one patch size"));
    }

    #[test]
    fn relief_scales_with_width_and_invert_negates() {
        let o = Options::new().with_strength(Strength::Relief(0.5)).with_invert(true);
        assert_eq!(o.scale_for_width(64), -32.0);
    }
}
