//! The fit options `convert` and `shade` share: the library's [`Options`]
//! and border choices from `FitArgs`, and the warnings of a conversion.

use normalfit::convert::Warning;
use normalfit::{Options, Strength};

use super::args::FitArgs;
use super::input::Input;
use super::report::{self, Failure};

/// The fit's options; the borders stay the default until an image settles
/// them (the library's `BorderChoices::resolve`).
pub fn options(args: &FitArgs) -> Result<Options, Failure> {
    let fit = Options::new()
        .with_patch(args.patch)
        .with_detail(args.detail.clone())
        .with_fit(args.fit)
        .with_weights(args.weights)
        .with_convention(args.convention)
        .with_strength(strength(args.scale, args.relief))
        .with_invert(args.invert);
    fit.validate().map_err(|e| Failure::usage(e.to_string()))?;
    Ok(fit)
}

/// The gain from `--scale` (which has a default) and `--relief` (which
/// clap lets through only without `--scale`).
pub fn strength(scale: f64, relief: Option<f64>) -> Strength {
    relief.map_or(Strength::Scale(scale), Strength::Relief)
}

/// Prints the count of missing texels of an input with holes: the
/// summary of its conversion (`what`: how the map marks them).
pub fn report_missing(input: &Input, missing: usize, texels: usize, nodata: Option<f64>, what: &str) {
    let nodata = nodata.map(|v| format!(" (nodata {})", normalfit::error::Number(v))).unwrap_or_default();
    report::print_line(&format!(
        "normalfit: {}: {missing} of {texels} texels missing{nodata}: {what}",
        input.name().display()
    ));
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
