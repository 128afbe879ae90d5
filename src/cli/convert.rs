//! `normalfit convert`: the arguments as a library [`Conversion`], where
//! each output goes, batches, progress and messages. The conversion itself
//! (format, depth, streaming or whole, memory, borders, atomic writes) is
//! the library's ([`normalfit::convert`]); what stays here is about many
//! files and a terminal: output names and folders, the rule that no output
//! replaces an input of the run or an earlier output, `--overwrite`.

use std::path::{Path, PathBuf};

use normalfit::convert::{Conversion, ConvertError, Observer, Opened, Place, Warning};
use normalfit::io::{Layout, OutputFormat};

use super::args::{ConvertArgs, library_message};
use super::batch::{Batch, Job, Outcome, RESIDUAL_SUFFIX, Turn, Words};
use super::fitting;
use super::input::{Input, source, stdin_at_most_once};
use super::output::{self, Destination};
use super::report::Failure;

/// What `convert` does with every input, decided once from the arguments.
struct Plan {
    /// Everything the library decides from.
    conversion: Conversion,
    destination: Destination,
    residual: Option<ResidualPlace>,
    /// Appended to an input's stem to name its normal map.
    suffix: String,
    quiet: bool,
}

/// Where residual maps go (`--residual`).
enum ResidualPlace {
    /// This file (one input).
    File(PathBuf),
    /// `<stem>_residual.<ext>` in this folder, under the input's subfolder.
    Folder(PathBuf),
}

/// Converts every input (files, and the images of folders); returns the
/// failures (already reported).
pub fn run(args: ConvertArgs) -> Result<usize, Failure> {
    let words = Words { done: "converted", purpose: "to convert" };
    let batch = Batch::gather(&args.inputs, &args.batch, &args.suffix, words);
    let mut plan = Plan::from_args(&args, batch.many())?;
    plan.conversion = plan.conversion.with_inputs(batch.inputs());
    Ok(batch.run(|job, turn| plan.convert_one(job, turn)))
}

impl Plan {
    fn from_args(args: &ConvertArgs, many: bool) -> Result<Plan, Failure> {
        let fit = fitting::options(&args.fit)?.with_nodata(args.holes.value());
        stdin_at_most_once(&args.inputs)?;
        let destination = Destination::for_batch(args.output.as_deref(), many)?;
        let layout = Layout::from_parts(args.channels.channels, args.channels.alpha)
            .map_err(|e| Failure::usage(format!("--{}", library_message(&e))))?;
        let residual = match &args.channels.residual {
            None => None,
            Some(r) if r.as_os_str() == "-" => {
                return Err(Failure::usage("--residual needs a file: standard output is for the normal map"));
            }
            Some(r) if many || r.is_dir() => {
                if r.exists() && !r.is_dir() {
                    return Err(Failure::file(r, "is not a folder: with many inputs, --residual names a folder"));
                }
                std::fs::create_dir_all(r)
                    .map_err(|e| Failure::file(r, format!("cannot create the residual folder: {e}")))?;
                Some(ResidualPlace::Folder(r.clone()))
            }
            Some(r) => Some(ResidualPlace::File(r.clone())),
        };
        let mut conversion = Conversion::new()
            .with_fit(fit)
            .with_borders(args.fit.border)
            .with_read(args.holes.apply(args.terrain.apply(args.read.options())))
            .with_channel(args.channel.clone())
            .with_format(args.format)
            .with_signed(args.signed)
            .with_compression(args.compression)
            .with_layout(layout)
            .with_residual(residual.is_some())
            .with_mips(args.mips.mips)
            .with_compress(args.mips.compress)
            .with_roughness(args.mips.roughness, args.mips.roughness_base.clone())
            .with_map_units(normalfit::units::MapSpacing::choose(args.units.units, args.units.pixel_size))
            .with_product(args.product)
            .with_slope_units(args.products.slope_units)
            .with_zero_for_flat(args.products.zero_for_flat)
            .with_sun(
                normalfit::convert::Sun::new(args.products.azimuth, args.products.altitude)
                    .map_err(|e| Failure::usage(library_message(&e)))?,
            );
        if let Some(range) = args.curvature_range {
            conversion = conversion.with_curvature_range(range);
        }
        conversion.bits = args.bits;
        Ok(Plan { conversion, destination, residual, suffix: args.suffix.clone(), quiet: args.batch.quiet })
    }

    /// Converts one input: opens it (the header of a file that streams,
    /// else the whole image), names its outputs by the format the library
    /// chooses, claims them, and has the library write them.
    fn convert_one(&self, job: &Job, turn: &Turn) -> Result<Outcome, Failure> {
        let input = &job.input;
        let opened = {
            // Standard input is decoded whole: its encoded bytes go once decoded.
            let mut bytes = Vec::new();
            let conversion = self.conversion.clone().with_replace(turn.replace(input));
            conversion.open(source(input, &mut bytes)?).map_err(|e| Failure::file(input.name(), e))?
        };
        let target = self.target(job, &opened)?;
        // Every file the normal map makes (a mip chain's levels and
        // roughness too), as the library names them.
        let files = target.path.as_deref().map(|p| opened.outputs(&target.encoding, p)).unwrap_or_default();
        self.claim(job, &target, &files, turn)?;
        // Skipped when `--overwrite` keeps every one; a set it keeps part
        // of is refused by the library, in one line, before any work.
        let write_normals = files.is_empty() || files.iter().any(|f| turn.wanted(Some(f), input));
        let residual = target.residual.as_ref().filter(|r| turn.wanted(Some(&r.path), input));
        if !write_normals && residual.is_none() {
            return Ok(Outcome::Skipped);
        }
        let mut stdout = None;
        let normals = match write_normals {
            true => Some(output::file_or_stdout(target.path.as_deref(), &job.subfolder, &mut stdout)),
            false => None,
        };
        let residual = residual.map(|r| (output::file(&r.path, &job.subfolder), r.format));
        let observer = JobObserver { turn, input, quiet: self.quiet };
        let written = opened.write(&target.encoding, normals, residual, &observer);
        match written {
            Ok(summary) => {
                if let Some(nodata) = summary.nodata
                    && !self.quiet
                {
                    fitting::report_missing(
                        input,
                        summary.missing,
                        summary.width * summary.height,
                        Some(nodata),
                        self.conversion.product.missing_mark(),
                    );
                }
                Ok(Outcome::Done)
            }
            Err(e) if output::stdout_closed(&e, target.path.is_none()) => Ok(Outcome::PipeClosed),
            Err(ConvertError { place, error }) => Err(Failure::file(
                match place {
                    Place::Input => input.name(),
                    Place::Residual => target.residual.as_ref().map_or(input.name(), |r| &r.path),
                    Place::RoughnessBase => self.conversion.roughness_base.as_deref().unwrap_or(input.name()),
                    _ => output::name(target.path.as_deref()),
                },
                error,
            )),
        }
    }

    /// The output's path (None: standard output) and encoding, and the
    /// residual map's path and format.
    fn target(&self, job: &Job, opened: &Opened) -> Result<Target, Failure> {
        let input = &job.input;
        let explicit_file = match &self.destination {
            Destination::File(p) => Some(p.as_path()),
            _ => None,
        };
        let named = output::name(explicit_file);
        let encoding = opened.encoding(explicit_file).map_err(|e| Failure::file(named, e.error))?;
        let ext = encoding.format().extension();
        let path = self.destination.path_in(input, &job.subfolder, &format!("{}{}.{ext}", input.stem(), self.suffix));
        let residual_at = |path: PathBuf| -> Result<ResidualTarget, Failure> {
            let format = OutputFormat::from_path(&path).map_err(|e| Failure::file(&path, e))?;
            Ok(ResidualTarget { format: format.unwrap_or(encoding.format()), path })
        };
        let residual = match &self.residual {
            None => None,
            Some(ResidualPlace::Folder(dir)) => {
                let name = format!("{}{RESIDUAL_SUFFIX}.{ext}", input.stem());
                Some(residual_at(dir.join(&job.subfolder).join(name))?)
            }
            Some(ResidualPlace::File(p)) => Some(residual_at(p.clone())?),
        };
        Ok(Target { path, encoding, residual })
    }

    /// Refuses an output that is an input, or that an earlier input of this
    /// run (in the order of the command line, whichever finishes first)
    /// writes too.
    fn claim(&self, job: &Job, target: &Target, files: &[PathBuf], turn: &Turn) -> Result<(), Failure> {
        let outputs: Vec<&Path> =
            files.iter().chain(target.residual.as_ref().map(|r| &r.path)).map(PathBuf::as_path).collect();
        if let Some(residual) = &target.residual
            && files.contains(&residual.path)
        {
            return Err(Failure::file(&residual.path, "is named for both the normal map and the residual"));
        }
        turn.claim(&job.input, &outputs)
    }
}

/// Where one input's outputs go and how the normal map is encoded.
struct Target {
    path: Option<PathBuf>,
    encoding: normalfit::io::Encoding,
    residual: Option<ResidualTarget>,
}

/// Where the residual map goes, and in which format: its extension's,
/// else the normal map's.
struct ResidualTarget {
    path: PathBuf,
    format: OutputFormat,
}

/// One job's progress on the progress line, and its warnings printed
/// (not with `--quiet`).
struct JobObserver<'a> {
    turn: &'a Turn<'a>,
    input: &'a Input,
    quiet: bool,
}

impl Observer for JobObserver<'_> {
    fn size(&self, width: usize, height: usize) {
        self.turn.size(width, height);
    }

    fn row(&self) {
        self.turn.row();
    }

    fn warning(&self, warning: &Warning) {
        if !self.quiet {
            fitting::warn(warning, self.input);
        }
    }
}
