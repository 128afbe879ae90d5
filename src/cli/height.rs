//! `normalfit height`: normal maps back to heights. The work is the
//! library's ([`normalfit::height::file::HeightConversion`]: reading,
//! solving, writing whole or not at all, never over the input); here are
//! the batch (files, folders, standard input and output, as `convert`),
//! the outputs' names and the messages.

use std::path::Path;

use normalfit::convert::Place;
use normalfit::height::HeightOptions;
use normalfit::height::file::{HeightConversion, HeightSummary};
use normalfit::{Border, Options};

use super::args::HeightArgs;
use super::batch::{Batch, Job, Outcome, Turn, Words};
use super::input::{Input, source, stdin_at_most_once};
use super::output::{self, Destination};
use super::report::{Failure, print_line, warn};

/// The stem ending of height maps: `<stem>_height.exr`.
const SUFFIX: &str = "_height";

/// What `height` does with every input, decided once from the arguments.
struct Plan<'a> {
    conversion: HeightConversion,
    destination: Destination,
    args: &'a HeightArgs,
}

/// Turns every input (files, the images of folders, standard input) into
/// heights; returns the failures (already reported).
pub fn run(args: &HeightArgs) -> Result<usize, Failure> {
    let fit = Options::new()
        .with_patch(args.patch)
        .with_fit(args.fit)
        .with_borders(args.border)
        .with_strength(super::fitting::strength(args.scale, args.relief))
        .with_invert(args.invert);
    let options = HeightOptions::from_fit(&fit).with_convention(args.convention).with_model(args.model);
    options.validate().map_err(|e| Failure::usage(e.to_string()))?;
    stdin_at_most_once(&args.inputs)?;
    let words = Words { done: "converted", purpose: "to turn into heights" };
    let batch = Batch::gather(&args.inputs, &args.batch, SUFFIX, words);
    let destination = Destination::for_batch(args.output.as_deref(), batch.many())?;
    let conversion = HeightConversion::new()
        .with_options(options)
        .with_read(args.read.options())
        .with_signed(args.signed)
        .with_format(args.format)
        .with_holes(args.holes.clone());
    if let Destination::File(path) = &destination {
        // A name the library cannot write is a usage error, before any work.
        conversion.output_format(Some(path)).map_err(|e| Failure::file(path, e))?;
    }
    let plan = Plan { conversion, destination, args };
    Ok(batch.run(|job, turn| plan.one(job, turn)))
}

impl Plan<'_> {
    fn one(&self, job: &Job, turn: &Turn) -> Result<Outcome, Failure> {
        let input = &job.input;
        // The name's extension is the format's (the library's rule: -o's,
        // else --format's, else EXR; run() has refused a -o it cannot write).
        let named = match &self.destination {
            Destination::File(path) => Some(path.as_path()),
            _ => None,
        };
        let format =
            self.conversion.output_format(named).map_err(|e| Failure::file(named.unwrap_or(input.name()), e))?;
        let ext = format.extension();
        let target = self.destination.path_in(input, &job.subfolder, &format!("{}{SUFFIX}.{ext}", input.stem()));
        if let Some(path) = &target {
            turn.claim(input, &[path])?;
        }
        if !turn.wanted(target.as_deref(), input) {
            return Ok(Outcome::Skipped);
        }
        let mut bytes = Vec::new();
        let source = source(input, &mut bytes)?;
        let mut stdout = None;
        let output = output::file_or_stdout(target.as_deref(), &job.subfolder, &mut stdout);
        let out_name = output::name(target.as_deref());
        let summary = match self.conversion.convert(source, output) {
            Ok(summary) => summary,
            Err(e) if output::stdout_closed(&e, target.is_none()) => return Ok(Outcome::PipeClosed),
            Err(e) => {
                let at = if e.place == Place::Input { input.name() } else { out_name };
                return Err(Failure::file(at, e.error));
            }
        };
        if !self.args.batch.quiet {
            turn.in_order(|| self.notes(input, out_name, &summary));
        }
        Ok(Outcome::Done)
    }

    /// The convention chosen, the warnings, and a PNG's range with the
    /// command that makes the normals again.
    fn notes(&self, input: &Input, output: &Path, summary: &HeightSummary) {
        let name = input.name().display();
        let report = &summary.report;
        if let Some([gl, dx]) = report.curl {
            print_line(&format!(
                "normalfit: {name}: convention {} (auto: relative curl {gl:.4} as opengl, {dx:.4} as directx)",
                report.convention
            ));
        }
        if report.holes > 0 {
            print_line(&format!(
                "normalfit: {name}: {} of {} texels are holes: written as holes (NaN, alpha 0 in a PNG)",
                report.holes,
                summary.width * summary.height
            ));
        }
        for w in &summary.warnings {
            warn(&name, w);
        }
        if let (Some((lo, hi)), Some(gain)) = (summary.png_range, summary.png_scale) {
            let args = self.args;
            let border = |b: Border| b.name();
            print_line(&format!(
                "normalfit: {}: heights {lo:.6} to {hi:.6} stored as 0 to 1; `normalfit convert -s {gain:.6} -n {} --fit {} --border {},{}` re-creates the normals",
                output.display(),
                args.patch,
                args.fit,
                border(args.border.x),
                border(args.border.y),
            ));
        }
    }
}
