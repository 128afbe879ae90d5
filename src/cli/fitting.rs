//! The fit options `convert` and `shade` share: the library's [`Options`]
//! and border choices from `FitArgs`, and the warnings of a conversion.

use normalfit::convert::{BorderChoice, BorderChoices, Warning};
use normalfit::{Convention, Fit, Options, Strength};

use super::args::{AxisBorder, BorderArg, ConventionArg, FitArg, FitArgs};
use super::input::Input;
use super::report::{self, Failure};

/// The fit's options; the borders stay the default until an image settles
/// them ([`BorderArg::resolve`]).
pub fn options(args: &FitArgs) -> Result<Options, Failure> {
    let strength = match args.relief {
        Some(f) => Strength::Relief(f),
        None => Strength::Scale(args.scale),
    };
    let fit = Options::new()
        .with_patch(args.patch)
        .with_fit(match args.fit {
            FitArg::Orthogonal => Fit::Orthogonal,
            FitArg::Vertical => Fit::Vertical,
        })
        .with_convention(convention(args.convention))
        .with_strength(strength)
        .with_invert(args.invert);
    fit.validate().map_err(|e| Failure::usage(e.to_string()))?;
    Ok(fit)
}

pub fn convention(c: ConventionArg) -> Convention {
    match c {
        ConventionArg::Opengl => Convention::OpenGl,
        ConventionArg::Directx => Convention::DirectX,
    }
}

impl BorderArg {
    /// The library's border choices.
    pub fn choices(&self) -> BorderChoices {
        let choice = |a: AxisBorder| match a {
            AxisBorder::Fixed(b) => BorderChoice::Fixed(b),
            AxisBorder::Auto => BorderChoice::Auto,
        };
        BorderChoices { x: choice(self.x), y: choice(self.y) }
    }
}

/// Prints a conversion's warning about `input`; a seam drawn by a wrap
/// says which `--border` avoids it.
pub fn warn(warning: &Warning, input: &Input) {
    let hint = match warning {
        Warning::Seams { .. } => "; use --border clamp or mirror, or --border auto",
        _ => "",
    };
    report::warn(input.name().display(), format!("{warning}{hint}"));
}
