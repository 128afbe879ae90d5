//! `normalfit blend`: a detail normal map onto a base. The work is the
//! library's ([`normalfit::blend::BlendFiles`]: reading, the conventions,
//! the tiling of the detail, writing whole or not at all, never over an
//! input); here are the arguments and the messages.

use normalfit::blend::{BlendFiles, BlendOptions};
use normalfit::convert::Place;

use super::args::{BlendArgs, library_message};
use super::input::{Input, source};
use super::output::{self, STDOUT};
use super::report::{Failure, print_line};

/// Blends the detail onto the base into the output.
pub fn run(args: &BlendArgs) -> Result<(), Failure> {
    let options = BlendOptions::new()
        .with_method(args.method)
        .with_strength(args.strength)
        .with_convention(args.convention)
        .with_detail_convention(args.detail_convention.unwrap_or(args.convention));
    options.validate().map_err(|e| Failure::usage(format!("--{}", library_message(&e))))?;
    if args.base.as_os_str() == "-" && args.detail.as_os_str() == "-" {
        return Err(Failure::usage("standard input ('-') can be read only once"));
    }
    let mut files = BlendFiles::new()
        .with_options(options)
        .with_read(args.read.options())
        .with_bits(args.bits)
        .with_signed(args.signed);
    files.format = args.format;
    let (base, detail) = (Input::from_arg(&args.base), Input::from_arg(&args.detail));
    let (mut base_bytes, mut detail_bytes) = (Vec::new(), Vec::new());
    let base_source = source(&base, &mut base_bytes)?;
    let detail_source = source(&detail, &mut detail_bytes)?;
    let to_stdout = args.output.as_os_str() == "-";
    let target = (!to_stdout).then_some(args.output.as_path());
    let mut stdout = None;
    let out = output::file_or_stdout(target, std::path::Path::new(""), &mut stdout);
    let summary = match files.blend(base_source, detail_source, out) {
        Ok(summary) => summary,
        Err(e) if output::stdout_closed(&e, to_stdout) => return Ok(()),
        Err(e) => {
            let at = match e.place {
                Place::Input => base.name(),
                Place::Detail => detail.name(),
                _ => target.unwrap_or(std::path::Path::new(STDOUT)),
            };
            return Err(Failure::file(at, e.error));
        }
    };
    let report = summary.report;
    if report.base != report.detail {
        print_line(&format!(
            "normalfit: {}: {} map, flipped to the base's {}",
            detail.name().display(),
            report.detail,
            report.base
        ));
    }
    Ok(())
}
