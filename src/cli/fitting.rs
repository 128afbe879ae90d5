//! The fit options `convert` and `shade` share: the library's [`Options`]
//! from `FitArgs`, and the border modes of one image when `--border auto`
//! or a wrap needs the tiling check.

use normalfit::tiling::TilingReport;
use normalfit::{Border, Borders, Convention, Fit, Options, Strength};

use super::args::{AxisBorder, BorderArg, ConventionArg, FitArg, FitArgs};
use super::input::Input;
use super::report::{Failure, warn};

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
    /// Whether these borders need the tiling check: a wrap (to warn when it
    /// draws a seam) or `auto`.
    pub fn needs_check(&self) -> bool {
        let check = |a: AxisBorder| matches!(a, AxisBorder::Auto | AxisBorder::Fixed(Border::Wrap));
        check(self.x) || check(self.y)
    }

    /// The border modes for one image: `auto` becomes wrap where the image
    /// tiles and mirror where it does not (`report`: the tiling check, made
    /// when [`Self::needs_check`]; without it, `auto` is mirror).
    pub fn resolve(&self, report: Option<&TilingReport>) -> Borders {
        let suggested = report.map_or(Borders::both(Border::Mirror), |r| r.suggested_borders());
        let resolve = |asked: AxisBorder, auto: Border| match asked {
            AxisBorder::Fixed(b) => b,
            AxisBorder::Auto => auto,
        };
        Borders { x: resolve(self.x, suggested.x), y: resolve(self.y, suggested.y) }
    }

    /// A wrap asked for on an axis that does not tile draws a seam: one
    /// warning line names the axes.
    pub fn warn_seams(&self, report: &TilingReport, input: &Input) {
        let wrap = AxisBorder::Fixed(Border::Wrap);
        let seams: Vec<String> = [("x", self.x, report.x), ("y", self.y, report.y)]
            .iter()
            .filter(|(_, asked, axis)| *asked == wrap && !axis.seamless)
            .map(|(name, _, axis)| format!("{name} (seam score {:.2})", axis.score))
            .collect();
        if !seams.is_empty() {
            warn(
                input.name().display(),
                format!(
                    "does not tile along {}: wrap borders will show a seam there; use --border clamp or mirror, or --border auto",
                    seams.join(" and ")
                ),
            );
        }
    }
}
