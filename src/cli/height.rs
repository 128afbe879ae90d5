//! `normalfit height`: a normal map back to heights. The work is the
//! library's ([`normalfit::height::file::HeightConversion`]); here are the
//! output's default name and the messages.

use std::path::PathBuf;

use normalfit::Border;
use normalfit::convert::Place;
use normalfit::height::HeightOptions;
use normalfit::height::file::HeightConversion;

use super::args::HeightArgs;
use super::input::check_extension;
use super::report::{Failure, print_line, warn};

/// The stem ending of height maps: `<stem>_height.exr`.
const SUFFIX: &str = "_height";

/// Converts the one input; prints the notes and warnings.
pub fn run(args: &HeightArgs) -> Result<(), Failure> {
    let options = HeightOptions::new()
        .with_patch(args.patch)
        .with_fit(args.fit)
        .with_borders(args.border)
        .with_convention(args.convention)
        .with_strength(super::fitting::strength(args.scale, args.relief))
        .with_invert(args.invert)
        .with_model(args.model);
    options.validate().map_err(|e| Failure::usage(e.to_string()))?;
    let input = &args.input;
    if input.as_os_str() == "-" {
        return Err(Failure::usage("height reads a file: name the normal map (standard input is not read)"));
    }
    if input.is_dir() {
        return Err(Failure::file(input, "is a folder, not an image"));
    }
    check_extension(input)?;
    let output = args.output.clone().unwrap_or_else(|| {
        let stem = input.file_stem().map_or_else(|| "image".into(), |s| s.to_string_lossy().into_owned());
        let ext = args.format.map_or("exr", |f| f.extension());
        input.with_file_name(format!("{stem}{SUFFIX}.{ext}"))
    });
    let conversion = HeightConversion::new()
        .with_options(options)
        .with_read(args.read.options())
        .with_signed(args.signed)
        .with_format(args.format);
    let summary = conversion.convert_file(input, &output).map_err(|e| {
        let at: &PathBuf = if e.place == Place::Input { input } else { &output };
        Failure::file(at, e.error)
    })?;
    if args.quiet {
        return Ok(());
    }
    let name = input.display();
    let report = &summary.report;
    if let Some([gl, dx]) = report.curl {
        print_line(&format!(
            "normalfit: {name}: convention {} (auto: relative curl {gl:.4} as opengl, {dx:.4} as directx)",
            report.convention
        ));
    }
    for w in &summary.warnings {
        warn(&name, w);
    }
    if let (Some((lo, hi)), Some(gain)) = (summary.png_range, summary.png_scale) {
        let borders = args.border;
        let border = |b: Border| b.name();
        print_line(&format!(
            "normalfit: {}: heights {lo:.6} to {hi:.6} stored as 0 to 1; `normalfit convert -s {gain:.6} -n {} --fit {} --border {},{}` re-creates the normals",
            output.display(),
            args.patch,
            args.fit,
            border(borders.x),
            border(borders.y),
        ));
    }
    Ok(())
}
