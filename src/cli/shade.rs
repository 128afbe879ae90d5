//! `normalfit shade`: a normal map, or a height map through the fit, lit by
//! a directional light and written as a gray PNG, optionally tiled 2×2.
//! The picture is the library's ([`normalfit::shade::lit_view`]); here are
//! the output names, the rule that no output replaces an input, and the
//! messages.

use normalfit::convert::Place;
use normalfit::io::ReadOptions;
use normalfit::shade::{LitOptions, lit_file, lit_format};
use normalfit::units::MapSpacing;

use super::args::ShadeArgs;
use super::batch::{Batch, Job, Outcome, Turn, Words};
use super::fitting;
use super::input::{source, stdin_at_most_once};
use super::output::{self, Destination};
use super::report::Failure;

/// The stem ending of lit views: `<stem>_lit.png`.
const SUFFIX: &str = "_lit";

/// What `shade` does with every input, decided once from the arguments.
struct Plan {
    lit: LitOptions,
    read: ReadOptions,
    destination: Destination,
    quiet: bool,
}

/// Shades every input (files, and the images of folders); returns the
/// failures (already reported).
pub fn run(args: ShadeArgs) -> Result<usize, Failure> {
    let fit = fitting::options(&args.fit)?.with_nodata(args.holes.value());
    stdin_at_most_once(&args.inputs)?;
    let words = Words { done: "shaded", purpose: "to shade" };
    let batch = Batch::gather(&args.inputs, &args.batch, SUFFIX, words);
    let destination = Destination::for_batch(args.output.as_deref(), batch.many())?;
    if let Destination::File(path) = &destination {
        lit_format(path).map_err(|e| Failure::file(path, e))?;
    }
    let lit = LitOptions::new()
        .with_fit(fit)
        .with_borders(args.fit.border)
        .with_lighting(args.light.map(|l| l.0), args.azimuth, args.altitude)
        .map_err(|e| Failure::usage(e.to_string()))?
        .with_tile(args.tile)
        .with_kind(args.kind)
        .with_channel(args.channel.clone())
        .with_signed(args.signed)
        .with_map_units(MapSpacing::choose(args.units.units, args.units.pixel_size));
    let plan = Plan {
        lit,
        read: args.holes.apply(args.terrain.apply(ReadOptions::default())),
        destination,
        quiet: args.batch.quiet,
    };
    Ok(batch.run(|job, turn| plan.shade_one(job, turn)))
}

impl Plan {
    fn shade_one(&self, job: &Job, turn: &Turn) -> Result<Outcome, Failure> {
        let input = &job.input;
        let name = format!("{}{SUFFIX}.png", input.stem());
        let target = self.destination.path_in(input, &job.subfolder, &name);
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
        let lit = self.lit.clone().with_replace(turn.replace(input));
        let done = match lit_file(source, &self.read, &lit, output) {
            Ok(done) => done,
            Err(e) if output::stdout_closed(&e, target.is_none()) => return Ok(Outcome::PipeClosed),
            Err(e) => {
                let at = if e.place == Place::Input { input.name() } else { output::name(target.as_deref()) };
                return Err(Failure::file(at, e.error));
            }
        };
        if !self.quiet {
            done.warnings.iter().for_each(|w| fitting::warn(w, input));
            if done.missing > 0 || self.lit.fit.nodata.is_some() {
                let scale = if self.lit.tile { 4 } else { 1 };
                let texels = done.width * done.height / scale;
                fitting::report_missing(input, done.missing, texels, self.lit.fit.nodata, "grey 0");
            }
        }
        Ok(Outcome::Done)
    }
}
