//! `normalfit convert`: where each output goes, in which format, and the
//! promise that outputs appear whole or not at all and never replace an input.

use std::collections::HashSet;
use std::io::{Cursor, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use normalfit::io::stream::{self, ExrFormat, ExrRows, PngDepth, PngOutput, PngRows, RowSource};
use normalfit::io::{self, Channel, ExrDepth, InputFormat, Layout, PngCompression, ReadOptions, SampleType};
use normalfit::tiling::{self, HeightSeams, KindChoice, TilingOptions};
use normalfit::{Border, Borders, FromNormal, Options, Samples};

use super::args::{AlphaArg, AxisBorder, BorderArg, ChannelsArg, CompressionArg, ConvertArgs, FormatArg, OverwriteArg};
use super::batch::{self, ClaimOrder, Job, RESIDUAL_SUFFIX};
use super::fitting;
use super::input::{Input, InputIds, check_extension, read_input, stdin_at_most_once};
use super::output::{self, Destination};
use super::progress::Progress;
use super::report::{Failure, print_line, warn};

/// What `convert` does with every input, decided once from the arguments.
struct Plan {
    /// The fit's options; the borders are settled per image (`--border auto`).
    fit: Options,
    border: BorderArg,
    channel: Option<Channel>,
    bits: Option<u8>,
    format: Option<FormatArg>,
    signed: bool,
    compression: PngCompression,
    destination: Destination,
    /// The size limit and the EXR layer, for every read.
    read: ReadOptions,
    layout: Layout,
    residual: Option<ResidualPlace>,
    /// Appended to an input's stem to name its normal map.
    suffix: String,
    overwrite: OverwriteArg,
    quiet: bool,
}

/// Where residual maps go (`--residual`).
enum ResidualPlace {
    /// This file (one input).
    File(PathBuf),
    /// `<stem>_residual.<ext>` in this folder, under the input's subfolder.
    Folder(PathBuf),
}

/// What became of one input.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Outcome {
    Converted,
    /// Every output exists already and `--overwrite` keeps it.
    Skipped,
}

/// What the files of one run share while they are converted at once.
struct Shared {
    /// The inputs' identities, so that no output replaces one.
    ids: InputIds,
    /// The outputs claimed so far.
    claimed: Mutex<HashSet<PathBuf>>,
    order: ClaimOrder,
    progress: Progress,
}

/// Converts every input (files, and the images of folders); returns the
/// failures (already reported).
pub fn run(args: ConvertArgs) -> Result<usize, Failure> {
    let batch_args = &args.batch;
    let listing = batch::gather(&args.inputs, batch_args.recursive, &batch_args.suffix);
    let many = listing.jobs.len() + listing.failures.len() > 1 || listing.any_folder;
    let plan = Plan::from_args(&args, many)?;
    listing.failures.iter().for_each(Failure::report);
    if !plan.quiet {
        let hint = if batch_args.recursive { "" } else { " (--recursive searches its subfolders)" };
        for dir in &listing.empty_folders {
            warn(dir.display(), format!("holds no image files to convert{hint}"));
        }
    }
    let jobs = &listing.jobs;
    let files: Vec<PathBuf> = jobs
        .iter()
        .filter_map(|j| match &j.input {
            Input::File(p) => Some(p.clone()),
            Input::Stdin => None,
        })
        .collect();
    let shared = Shared {
        ids: InputIds::of(&files),
        claimed: Mutex::new(HashSet::new()),
        order: ClaimOrder::new(jobs.len()),
        progress: Progress::new(jobs.len(), !plan.quiet),
    };
    let workers = batch_args.jobs.map_or_else(default_jobs, usize::from);
    let outcomes = batch::run_jobs(jobs.len(), workers, |k| {
        shared.progress.begin(k, &jobs[k].input.name().display().to_string());
        let outcome = plan.convert_one(&jobs[k], k, &shared);
        // A job that failed before claiming its outputs lets the next claim.
        shared.order.pass(k);
        shared.progress.finish(k);
        if let Err(f) = &outcome {
            f.report();
        }
        outcome
    });
    shared.progress.close();
    let count = |wanted: Outcome| outcomes.iter().filter(|o| o.as_ref().is_ok_and(|&o| o == wanted)).count();
    let failures = listing.failures.len() + outcomes.iter().filter(|o| o.is_err()).count();
    if many && !plan.quiet {
        print_line(&format!(
            "normalfit: {} converted, {} skipped, {} failed in {:.2} s",
            count(Outcome::Converted),
            count(Outcome::Skipped),
            failures,
            shared.progress.elapsed().as_secs_f64()
        ));
    }
    Ok(failures)
}

/// Files converted at once unless `--jobs` says: twice the cores, at most
/// 8. Each file's fit already uses every core, but its decoding, deflate
/// and sync to disk run on one thread or wait: on 2 cores, 200 files of
/// 256² took 1.4 s one at a time, 0.73 s two at a time, 0.55 s four at a
/// time and no less with eight; four 2048² files took the same time
/// either way. The cap bounds memory when files are large.
fn default_jobs() -> usize {
    std::thread::available_parallelism().map_or(2, |n| (2 * n.get()).min(8))
}

impl Plan {
    fn from_args(args: &ConvertArgs, many: bool) -> Result<Plan, Failure> {
        let fit = fitting::options(&args.fit)?;
        stdin_at_most_once(&args.inputs)?;
        let destination = Destination::for_batch(args.output.as_deref(), many)?;
        let layout = match (args.channels.alpha, args.channels.channels) {
            (AlphaArg::None, ChannelsArg::Rgb) => Layout::Rgb,
            (AlphaArg::Height, ChannelsArg::Rgb) => Layout::RgbHeight,
            (AlphaArg::One, ChannelsArg::Rgb) => Layout::RgbOpaque,
            (AlphaArg::None, ChannelsArg::Rg) => Layout::Rg,
            (_, ChannelsArg::Rg) => {
                return Err(Failure::usage("--channels rg has no alpha: it is for two-channel (BC5) textures"));
            }
        };
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
        Ok(Plan {
            fit,
            border: args.fit.border,
            channel: args.channel.clone(),
            bits: args.bits,
            format: args.format,
            signed: args.signed,
            compression: match args.compression {
                CompressionArg::Fast => PngCompression::Fast,
                CompressionArg::Small => PngCompression::Default,
            },
            destination,
            read: args.read.options(),
            layout,
            residual,
            suffix: args.batch.suffix.clone(),
            overwrite: args.batch.overwrite,
            quiet: args.batch.quiet,
        })
    }

    /// Converts one input. PNG and scan-line EXR files stream, unless a
    /// residual map is asked for (it is made from the whole image).
    fn convert_one(&self, job: &Job, k: usize, shared: &Shared) -> Result<Outcome, Failure> {
        let input = &job.input;
        if let Input::File(path) = input {
            check_extension(path)?;
        }
        if let (Input::File(path), None) = (input, &self.residual) {
            let in_failure = |e: normalfit::Error| Failure::file(path, e);
            if let Some(rows) = PngRows::reopen(path, &self.read, self.channel.clone()).map_err(in_failure)? {
                let sample = SampleType::Int { bits: if rows.more_than_8_bits() { 16 } else { 8 } };
                let target = self.target(job, InputFormat::Png, sample)?;
                return self.convert_streaming(job, k, shared, rows, &target);
            }
            if let Some(rows) = ExrRows::reopen(path, &self.read, self.channel.clone()).map_err(in_failure)? {
                let target = self.target(job, InputFormat::Exr, SampleType::Float)?;
                return self.convert_streaming(job, k, shared, rows, &target);
            }
        }
        let raster = read_input(input, &self.read)?;
        let target = self.target(job, raster.format.clone(), raster.sample)?;
        self.claim(job, &target, k, shared)?;
        let write_normals = self.wanted(target.path.as_deref(), input);
        let residual = target.residual.as_ref().filter(|r| self.wanted(Some(&r.path), input));
        if !write_normals && residual.is_none() {
            return Ok(Outcome::Skipped);
        }
        let (width, height) = (raster.width, raster.height);
        let heights = raster.into_heights(self.channel.clone()).map_err(|e| Failure::file(input.name(), e))?;
        let report = match self.needs_check() {
            true => match self.seam_check(width, height, input)? {
                Some(mut seams) => {
                    seams.push_samples(&heights).map_err(|e| Failure::file(input.name(), e))?;
                    Some(seams.finish(&TilingOptions::new().with_kind(KindChoice::Height)))
                }
                None => None,
            },
            false => None,
        };
        if let Some(report) = &report {
            self.warn_seams(report, input);
        }
        let fit = self.fit.clone().with_borders(self.borders_for(report.as_ref()));
        // Named by the first output to be written.
        let first_output = match (write_normals, residual) {
            (false, Some(r)) => r.path.as_path(),
            _ => target.path.as_deref().unwrap_or(Path::new("<standard output>")),
        };
        check_encode_memory(&target, write_normals, residual.is_some(), width, height)
            .map_err(|e| Failure::file(first_output, e))?;
        let mut distances = residual
            .map(|_| texel_buffer::<f32>(heights.len()))
            .transpose()
            .map_err(|e| Failure::file(input.name(), e))?;
        let texels = Texels::fit(&heights, width, height, &fit, &target, distances.as_deref_mut())
            .map_err(|e| Failure::file(input.name(), e))?;
        // An alpha of heights takes them in contract units, as f32.
        let heights = if target.layout.needs_heights() {
            heights.into_f32().map_err(|e| Failure::file(input.name(), e))?
        } else {
            Vec::new()
        };
        if write_normals {
            match &target.path {
                Some(path) => {
                    make_subfolder(job, path)?;
                    // Into the file itself, which seeks as EXR needs: no
                    // copy of the encoded image in memory.
                    io::write_file_atomically(path, |file| {
                        texels.encode(&heights, width, height, &target, self.compression, file)
                    })
                    .map_err(|e| Failure::file(path, e))?;
                }
                None => {
                    // EXR needs to seek while writing, so the bytes are assembled first.
                    let mut bytes = InMemory::default();
                    texels
                        .encode(&heights, width, height, &target, self.compression, &mut bytes)
                        .and_then(|()| write_stdout(bytes.0.get_ref()))
                        .map_err(|e| Failure::file("<standard output>", e))?;
                }
            }
        }
        if let (Some(residual), Some(distances)) = (residual, &distances) {
            make_subfolder(job, &residual.path)?;
            let scale = fit.scale_for_width(width);
            io::write_file_atomically(&residual.path, |out| {
                encode_residual(distances, width, height, scale, residual.format, out)
            })
            .map_err(|e| Failure::file(&residual.path, e))?;
        }
        Ok(Outcome::Converted)
    }

    /// A PNG or scan-line EXR input, converted without holding the image:
    /// rows stream from the decoder through the fit to the encoder. One
    /// pass over the input, but for a wrap in y into an output written in
    /// order (EXR, or PNG into a pipe), which needs the image's last rows
    /// first: an EXR gives them from its last blocks, a PNG by a first
    /// pass; and for `--border auto`, whose borders depend on the tiling
    /// check, which then comes from a first pass too.
    fn convert_streaming<S: Reopen>(
        &self,
        job: &Job,
        k: usize,
        shared: &Shared,
        rows: S,
        target: &Target,
    ) -> Result<Outcome, Failure> {
        let input = &job.input;
        let path = input.name();
        self.claim(job, target, k, shared)?;
        if !self.wanted(target.path.as_deref(), input) {
            return Ok(Outcome::Skipped);
        }
        if let Some(out) = &target.path {
            make_subfolder(job, out)?;
        }
        let in_failure = |e: normalfit::Error| Failure::file(path, e);
        let (width, height, r) = (rows.width(), rows.height(), self.fit.patch / 2);
        let auto = self.border.x == AxisBorder::Auto || self.border.y == AxisBorder::Auto;
        let may_wrap_y = matches!(self.border.y, AxisBorder::Auto | AxisBorder::Fixed(Border::Wrap));
        // A PNG file takes its top rows last, in room kept after the header.
        let png_file = target.path.is_some() && target.png_depth().is_some();
        let needs_tail = may_wrap_y && !png_file;
        let check_opts = TilingOptions::new().with_kind(KindChoice::Height);
        let cheap_tail =
            if needs_tail && !auto { S::last_rows(path, &self.read, self.channel.clone(), r) } else { None };
        let (report, tail) = match cheap_tail {
            Some(tail) => (None, Some(tail.map_err(in_failure)?)),
            None if auto || needs_tail => {
                let first = S::reopen(path, &self.read, self.channel.clone()).map_err(in_failure)?;
                let first = first.ok_or_else(|| Failure::file(path, "changed while being read"))?;
                let mut seams = self.seam_check(width, height, input)?;
                let tail = first
                    .read_tail(r, |row| {
                        // Whole rows from the decoder, at most `height` of
                        // them: the check takes every one.
                        if let Some(s) = seams.as_mut() {
                            let _ = s.push_row(row);
                        }
                    })
                    .map_err(in_failure)?;
                (seams.map(|s| s.finish(&check_opts)), Some(tail))
            }
            None => (None, None),
        };
        // Without a first pass, the check runs on the rows as they stream
        // and the warning comes after the output.
        if let Some(report) = &report {
            self.warn_seams(report, input);
        }
        let fit = self.fit.clone().with_borders(self.borders_for(report.as_ref()));
        let tail = if fit.borders.y == Border::Wrap { tail.as_deref() } else { None };
        let mut seams = match report.is_none() && self.needs_check() {
            true => self.seam_check(width, height, input)?,
            false => None,
        };
        let progress = &shared.progress;
        progress.size(k, width, height);
        let visit = |row: &[f32]| {
            progress.row(k);
            // Whole rows from the decoder, at most `height` of them: the
            // check takes every one.
            if let Some(s) = seams.as_mut() {
                let _ = s.push_row(row);
            }
        };
        // Decoding and fitting fail on the input; writing, on the output.
        let mut failed_input = None;
        let mut on_input = |e: &normalfit::Error| {
            if !matches!(e, normalfit::Error::Io(_) | normalfit::Error::Encode(_)) {
                failed_input = Some(e.to_string());
            }
        };
        let stdout_name = "<standard output>";
        let result = match (&target.path, target.encoding) {
            (Some(out), Encoding::Exr(depth)) => io::write_file_atomically(out, |file| {
                let format = ExrFormat { depth, signed: target.signed, layout: self.layout };
                stream::convert_exr(rows, tail, &fit, format, visit, file).inspect_err(&mut on_input)
            })
            .map_err(|e| Failure::file(out, e)),
            (None, Encoding::Exr(depth)) => {
                // EXR seeks back to its offset table: the file is assembled
                // first, and must leave the stream room to work.
                let mut bytes = InMemory::default();
                let format = ExrFormat { depth, signed: target.signed, layout: self.layout };
                check_assembly_memory(target, width, height)
                    .and_then(|()| stream::convert_exr(rows, tail, &fit, format, visit, &mut bytes))
                    .inspect_err(&mut on_input)
                    .and_then(|()| write_stdout(bytes.0.get_ref()))
                    .map_err(|e| Failure::file(stdout_name, e))
            }
            (Some(out), Encoding::Png8 | Encoding::Png16) => io::write_file_atomically(out, |file| {
                let png = self.png_output(target).expect("a png encoding");
                stream::convert_png_seekable(rows, &fit, png, visit, file).inspect_err(&mut on_input)
            })
            .map_err(|e| Failure::file(out, e)),
            (None, Encoding::Png8 | Encoding::Png16) => {
                let png = self.png_output(target).expect("a png encoding");
                let mut stdout = std::io::stdout().lock();
                stream::convert_png(rows, tail, &fit, png, visit, &mut stdout)
                    .inspect_err(&mut on_input)
                    .and_then(|()| Ok(stdout.flush()?))
                    .map_err(|e| Failure::file(stdout_name, e))
            }
        };
        if let Some(problem) = failed_input {
            return Err(Failure::file(path, problem));
        }
        // A failed write stopped the rows part way: no seams to judge.
        if let (Some(seams), Ok(())) = (seams, &result) {
            self.warn_seams(&seams.finish(&check_opts), input);
        }
        result.map(|()| Outcome::Converted)
    }

    /// Refuses an output that is an input, or that an earlier input of this
    /// run (in the order of the command line, whichever finishes first)
    /// writes too.
    fn claim(&self, job: &Job, target: &Target, k: usize, shared: &Shared) -> Result<(), Failure> {
        let outputs: Vec<&PathBuf> = target.path.iter().chain(target.residual.as_ref().map(|r| &r.path)).collect();
        if let [normals, residual] = outputs[..] {
            if normals == residual {
                return Err(Failure::file(normals, "is named for both the normal map and the residual"));
            }
        }
        shared.order.wait_turn(k);
        let mut claimed = shared.claimed.lock().unwrap_or_else(|e| e.into_inner());
        for path in outputs {
            output::claim(path, &job.input, &shared.ids, &mut claimed)?;
        }
        drop(claimed);
        shared.order.pass(k);
        Ok(())
    }

    /// Whether `--overwrite` lets the output at `path` (None: standard
    /// output, always written) be written for `input`.
    fn wanted(&self, path: Option<&Path>, input: &Input) -> bool {
        let Some(path) = path else { return true };
        match self.overwrite {
            OverwriteArg::Always => true,
            OverwriteArg::Never => std::fs::metadata(path).is_err(),
            OverwriteArg::Older => {
                let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified());
                match (input, modified(path)) {
                    (Input::File(source), Ok(written)) => modified(source).is_ok_and(|changed| written < changed),
                    _ => true,
                }
            }
        }
    }

    /// The streamed PNG's settings, for a PNG target.
    fn png_output(&self, target: &Target) -> Option<PngOutput> {
        target.png_depth().map(|depth| PngOutput { depth, compression: self.compression, layout: self.layout })
    }

    /// The streamed tiling check of a `width` × `height` image, or `None`
    /// with a warning when its memory is not there (a conversion of an
    /// image 2^24 texels wide can fit where its check does not): the check
    /// only warns about a wrap that draws a seam. `--border auto` needs its
    /// verdict, so there the lack of memory is an error.
    fn seam_check(&self, width: usize, height: usize, input: &Input) -> Result<Option<HeightSeams>, Failure> {
        match HeightSeams::new(width, height) {
            Ok(seams) => Ok(Some(seams)),
            Err(e) if self.border.x == AxisBorder::Auto || self.border.y == AxisBorder::Auto => {
                Err(Failure::file(input.name(), e))
            }
            Err(e) => {
                if !self.quiet {
                    warn(input.name().display(), format!("seam check skipped: {e}"));
                }
                Ok(None)
            }
        }
    }

    /// Whether the borders asked for need the tiling check.
    fn needs_check(&self) -> bool {
        self.border.needs_check()
    }

    /// The border modes for one image, `auto` settled by `report`.
    fn borders_for(&self, report: Option<&tiling::TilingReport>) -> Borders {
        self.border.resolve(report)
    }

    /// Warns about a wrap on an axis that does not tile (not with `--quiet`).
    fn warn_seams(&self, report: &tiling::TilingReport, input: &Input) {
        if !self.quiet {
            self.border.warn_seams(report, input);
        }
    }

    /// The output's path (None: standard output), format and depth, and
    /// the residual map's.
    fn target(&self, job: &Job, format: InputFormat, sample: SampleType) -> Result<Target, Failure> {
        let input = &job.input;
        let float_input = sample == io::SampleType::Float;
        let from_input = match format {
            InputFormat::Exr => FormatArg::Exr,
            InputFormat::Png => FormatArg::Png,
            _ if float_input => FormatArg::Exr,
            _ => FormatArg::Png,
        };
        let explicit_file = match &self.destination {
            Destination::File(p) => Some(p),
            _ => None,
        };
        let from_extension = match explicit_file {
            Some(p) => format_of_extension(p)?,
            None => None,
        };
        let format = self.format.or(from_extension).unwrap_or(from_input);
        if let (Some(f), Some(e), Some(p)) = (self.format, from_extension, explicit_file) {
            if f != e {
                return Err(Failure::file(p, format!("extension says {e:?} but --format says {f:?}").to_lowercase()));
            }
        }
        let ext = match format {
            FormatArg::Png => "png",
            FormatArg::Exr => "exr",
        };
        let path = self.destination.path_in(input, &job.subfolder, &format!("{}{}.{ext}", input.stem(), self.suffix));
        let residual = match &self.residual {
            None => None,
            Some(ResidualPlace::Folder(dir)) => {
                let name = format!("{}{RESIDUAL_SUFFIX}.{ext}", input.stem());
                Some(ResidualTarget::of(dir.join(&job.subfolder).join(name), format)?)
            }
            Some(ResidualPlace::File(p)) => Some(ResidualTarget::of(p.clone(), format)?),
        };
        let name = path.as_deref().unwrap_or(Path::new("<standard output>"));
        let encoding = match (format, self.bits) {
            (FormatArg::Png, None) => {
                if sample.more_than_8_bits() {
                    Encoding::Png16
                } else {
                    Encoding::Png8
                }
            }
            (FormatArg::Png, Some(8)) => Encoding::Png8,
            (FormatArg::Png, Some(16)) => Encoding::Png16,
            (FormatArg::Png, Some(_)) => {
                return Err(Failure::file(name, "PNG holds 8 or 16 bits: --bits 32 needs EXR output"));
            }
            (FormatArg::Exr, None | Some(32)) => Encoding::Exr(ExrDepth::Float),
            (FormatArg::Exr, Some(16)) => Encoding::Exr(ExrDepth::Half),
            (FormatArg::Exr, Some(_)) => {
                return Err(Failure::file(name, "EXR holds 16- or 32-bit floats: --bits 8 needs PNG output"));
            }
        };
        if self.signed && !matches!(encoding, Encoding::Exr(_)) {
            return Err(Failure::file(name, "--signed needs a float output (EXR): PNG stores only [0, 1]"));
        }
        Ok(Target { path, encoding, signed: self.signed, layout: self.layout, residual })
    }
}

/// Creates the subfolder of an output under `-o DIR` (or `--residual
/// DIR`) for an input found in a subfolder.
fn make_subfolder(job: &Job, output: &Path) -> Result<(), Failure> {
    match output.parent() {
        Some(parent) if !job.subfolder.as_os_str().is_empty() => std::fs::create_dir_all(parent)
            .map_err(|e| Failure::file(parent, format!("cannot create the output folder: {e}"))),
        _ => Ok(()),
    }
}

/// Where one output goes and how it is encoded.
struct Target {
    path: Option<PathBuf>,
    encoding: Encoding,
    signed: bool,
    layout: Layout,
    residual: Option<ResidualTarget>,
}

/// Where the residual map goes, and in which format.
struct ResidualTarget {
    path: PathBuf,
    format: FormatArg,
}

impl ResidualTarget {
    /// The residual map at `path`, in the format of its extension, else
    /// the normal map's `format`.
    fn of(path: PathBuf, format: FormatArg) -> Result<ResidualTarget, Failure> {
        let format = format_of_extension(&path)?.unwrap_or(format);
        Ok(ResidualTarget { path, format })
    }
}

impl Target {
    /// The depth of a PNG output, which can be written as rows stream.
    fn png_depth(&self) -> Option<PngDepth> {
        match self.encoding {
            Encoding::Png8 => Some(PngDepth::Eight),
            Encoding::Png16 => Some(PngDepth::Sixteen),
            Encoding::Exr(_) => None,
        }
    }
}

#[derive(Clone, Copy)]
enum Encoding {
    Png8,
    Png16,
    Exr(ExrDepth),
}

/// A normal map fitted straight into the output's texel type.
enum Texels {
    Eight(Vec<[u8; 3]>),
    Sixteen(Vec<[u16; 3]>),
    /// (n + 1)/2, or n with `--signed`.
    Float(Vec<[f32; 3]>),
}

impl Texels {
    /// Fits the normals for `target`'s encoding; with `residual`, the fit's
    /// RMS distances too (in surface units).
    fn fit(
        heights: &Samples,
        w: usize,
        h: usize,
        opts: &Options,
        target: &Target,
        residual: Option<&mut [f32]>,
    ) -> normalfit::Result<Texels> {
        fn fitted<T: FromNormal + Default>(
            heights: &Samples,
            w: usize,
            h: usize,
            opts: &Options,
            residual: Option<&mut [f32]>,
        ) -> normalfit::Result<Vec<T>> {
            let mut texels = texel_buffer::<T>(heights.len())?;
            match residual {
                Some(r) => heights.normals_and_residual_into(w, h, opts, &mut texels, r)?,
                None => heights.normals_into(w, h, opts, &mut texels)?,
            }
            Ok(texels)
        }
        Ok(match target.encoding {
            Encoding::Png8 => Texels::Eight(fitted(heights, w, h, opts, residual)?),
            Encoding::Png16 => Texels::Sixteen(fitted(heights, w, h, opts, residual)?),
            Encoding::Exr(_) => {
                let mut texels: Vec<[f32; 3]> = fitted(heights, w, h, opts, residual)?;
                if !target.signed {
                    texels.iter_mut().for_each(|t| *t = t.map(|c| (c + 1.0) * 0.5));
                }
                Texels::Float(texels)
            }
        })
    }

    /// Encodes the map with `target`'s channels (`heights` for an alpha of
    /// heights).
    fn encode<W: Write + Seek>(
        &self,
        heights: &[f32],
        w: usize,
        h: usize,
        target: &Target,
        compression: PngCompression,
        out: &mut W,
    ) -> normalfit::Result<()> {
        let layout = target.layout;
        match (self, target.encoding) {
            (Texels::Eight(t), _) => io::encode_png_normals(t, Some(heights), w, h, layout, compression, out),
            (Texels::Sixteen(t), _) => io::encode_png_normals(t, Some(heights), w, h, layout, compression, out),
            (Texels::Float(t), encoding) => {
                let depth = match encoding {
                    Encoding::Exr(depth) => depth,
                    Encoding::Png8 | Encoding::Png16 => ExrDepth::Float,
                };
                io::encode_exr_normals(t, Some(heights), w, h, layout, depth, out)
            }
        }
    }
}

/// Writes the residual map: the RMS distances (surface units) divided by
/// the gain |S|, so in height units; 0 where S = 0 (a flat surface). PNG:
/// 16-bit gray, 65535 · value clamped to [0, 1]; EXR: 32-bit float,
/// channel Y, the value as it is.
fn encode_residual<W: Write + Seek>(
    distances: &[f32],
    w: usize,
    h: usize,
    scale: f64,
    format: FormatArg,
    out: &mut W,
) -> normalfit::Result<()> {
    let per_height = if scale == 0.0 { 0.0 } else { 1.0 / scale.abs() };
    let values = distances.iter().map(|&d| f64::from(d) * per_height);
    match format {
        FormatArg::Png => {
            let mut stored = texel_buffer::<u16>(distances.len())?;
            stored.iter_mut().zip(values).for_each(|(s, v)| *s = (v.clamp(0.0, 1.0) * 65535.0).round() as u16);
            io::encode_png_gray16(&stored, w, h, PngCompression::default(), out)
        }
        FormatArg::Exr => {
            let mut stored = texel_buffer::<f32>(distances.len())?;
            stored.iter_mut().zip(values).for_each(|(s, v)| *s = v as f32);
            io::encode_exr_gray(&stored, w, h, ExrDepth::Float, out)
        }
    }
}

/// Refuses an encode that the memory limits leave no room for, before it
/// starts: past our own buffers the encoders allocate as they go, and a
/// failure there would abort the process. Bytes held per texel, from what
/// the encoders do:
/// * the normal map: 3, 6 or 12 (8-bit, 16-bit, float);
/// * PNG (c samples of s bytes a texel): the samples laid out, unless RGB
///   (c·s); for 16 bits, the native-endian and `image`'s big-endian
///   copies (2·c·s); the whole zlib stream, which `png` assembles in
///   memory, and its stored fallback when deflate does not pay (2·c·s);
/// * EXR: only a few blocks at a time;
/// * the residual: its distances (4), and for its one-channel encode no
///   more than 10;
/// * for standard output, the encoded file: at most about its raw size.
fn check_encode_memory(target: &Target, normals: bool, residual: bool, w: usize, h: usize) -> normalfit::Result<()> {
    let c: u64 = match target.layout {
        Layout::Rgb | Layout::Rg => 3,
        _ => 4,
    };
    let (map, encode, raw) = match target.encoding {
        Encoding::Png8 => (3, if target.layout == Layout::Rgb { 0 } else { c } + 2 * c, c),
        Encoding::Png16 => (6, if target.layout == Layout::Rgb { 0 } else { 2 * c } + 4 * c + 4 * c, 2 * c),
        Encoding::Exr(_) => (12, 0, 4 * c),
    };
    let assembled = if target.path.is_none() { raw } else { 0 };
    let per_texel = map + if normals { encode + assembled } else { 0 } + if residual { 4 + 10 } else { 0 };
    let texels = (w as u64).saturating_mul(h as u64);
    io::check_memory("encoding the normal map", texels.saturating_mul(per_texel))
}

/// Refuses to assemble an EXR for standard output in memory when the
/// memory limits leave no room for it (its raw size, which ZIP does not
/// exceed) beside the stream's own buffers.
fn check_assembly_memory(target: &Target, w: usize, h: usize) -> normalfit::Result<()> {
    let channels: u64 = match target.layout {
        Layout::Rg => 2,
        Layout::Rgb => 3,
        _ => 4,
    };
    let sample = match target.encoding {
        Encoding::Exr(ExrDepth::Half) => 2,
        _ => 4,
    };
    let texels = (w as u64).saturating_mul(h as u64);
    io::check_memory("assembling the output in memory", texels.saturating_mul(channels * sample))
}

/// A buffer of `len` values, or an error when the memory is not there:
/// `vec!` would abort the process instead (under `ulimit -v`).
fn texel_buffer<T: Clone + Default>(len: usize) -> normalfit::Result<Vec<T>> {
    let mut texels = Vec::new();
    texels.try_reserve_exact(len).map_err(|_| {
        let mib = len.saturating_mul(size_of::<T>()) >> 20;
        normalfit::Error::Limits(format!("not enough memory for the output ({mib} MiB more)"))
    })?;
    texels.resize(len, T::default());
    Ok(texels)
}

/// An encoded file assembled in memory, like `Cursor<Vec<u8>>`, but whose
/// growth is reserved fallibly: running out of memory is an error, where a
/// growing `Vec` would abort the process (under `ulimit -v`).
#[derive(Default)]
struct InMemory(Cursor<Vec<u8>>);

impl Write for InMemory {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let end = usize::try_from(self.0.position()).unwrap_or(usize::MAX).saturating_add(buf.len());
        let bytes = self.0.get_mut();
        if end > bytes.capacity() {
            // Amortised growth, as `Vec` itself would.
            bytes.try_reserve(end - bytes.len()).map_err(|_| {
                let mib = end >> 20;
                std::io::Error::new(
                    std::io::ErrorKind::OutOfMemory,
                    format!("not enough memory to assemble the output ({mib} MiB)"),
                )
            })?;
        }
        self.0.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for InMemory {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        self.0.seek(to)
    }
}

/// PNG or EXR from a file name's extension; other extensions are refused,
/// none at all leaves the choice to the input.
fn format_of_extension(path: &Path) -> Result<Option<FormatArg>, Failure> {
    let Some(ext) = path.extension() else { return Ok(None) };
    match ext.to_string_lossy().to_ascii_lowercase().as_str() {
        "png" => Ok(Some(FormatArg::Png)),
        "exr" => Ok(Some(FormatArg::Exr)),
        other => Err(Failure::file(path, format!("cannot write .{other} files: name the output .png or .exr"))),
    }
}

/// Writes `bytes` to standard output and flushes it.
fn write_stdout(bytes: &[u8]) -> normalfit::Result<()> {
    let mut stdout = std::io::stdout().lock();
    stdout.write_all(bytes)?;
    stdout.flush()?;
    Ok(())
}

/// An input format whose rows stream, opened by path.
trait Reopen: RowSource + Sized {
    /// Opens `path` if it is this format and can stream (`Ok(None)`: read
    /// it whole).
    fn reopen(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> normalfit::Result<Option<Self>>;

    /// The image's last `rows` rows, if the format can give them without
    /// reading the whole file (`None`: it cannot).
    fn last_rows(
        path: &Path,
        opts: &ReadOptions,
        channel: Option<Channel>,
        rows: usize,
    ) -> Option<normalfit::Result<Vec<f64>>>;
}

impl Reopen for PngRows {
    fn reopen(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> normalfit::Result<Option<Self>> {
        PngRows::open(path, opts, channel)
    }

    fn last_rows(_: &Path, _: &ReadOptions, _: Option<Channel>, _: usize) -> Option<normalfit::Result<Vec<f64>>> {
        // PNG cannot seek: its last rows come from a pass over the file.
        None
    }
}

impl Reopen for ExrRows {
    fn reopen(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> normalfit::Result<Option<Self>> {
        ExrRows::open(path, opts, channel)
    }

    fn last_rows(
        path: &Path,
        opts: &ReadOptions,
        channel: Option<Channel>,
        rows: usize,
    ) -> Option<normalfit::Result<Vec<f64>>> {
        Some(ExrRows::last_rows(path, opts, channel, rows))
    }
}
