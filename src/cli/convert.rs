//! `normalfit convert`: where each output goes, in which format, and the
//! promise that outputs appear whole or not at all and never replace an input.

use std::collections::HashSet;
use std::io::{Cursor, Write};
use std::path::{Path, PathBuf};

use normalfit::io::stream::{self, ExrFormat, ExrRows, PngDepth, PngRows, RowSource};
use normalfit::io::{self, Channel, ExrDepth, InputFormat, Layout, PngCompression, ReadOptions, SampleType};
use normalfit::tiling::{self, HeightSeams, KindChoice, TilingOptions};
use normalfit::{Border, Borders, Convention, Fit, Options, Strength, normals_into};

use super::args::{AxisBorder, BorderArg, ConventionArg, ConvertArgs, FitArg, FormatArg};
use super::input::{Input, InputIds, read_input};
use super::report::{Failure, warn};
use super::tiling::channel_of;

/// What `convert` does with every input, decided once from the arguments.
struct Plan {
    /// The fit's options; the borders are settled per image (`--border auto`).
    fit: Options,
    border: BorderArg,
    channel: Option<Channel>,
    bits: Option<u8>,
    format: Option<FormatArg>,
    signed: bool,
    destination: Destination,
}

/// Where outputs go.
enum Destination {
    /// `<stem>_normal.<ext>` beside each input (standard output for `-`).
    BesideInputs,
    /// This exact file (one input only).
    File(PathBuf),
    /// `<dir>/<stem>_normal.<ext>`.
    Folder(PathBuf),
    /// Standard output (one input only).
    Stdout,
}

/// Converts every input; returns the failures (already reported).
pub fn run(args: ConvertArgs) -> Result<usize, Failure> {
    let plan = Plan::from_args(&args)?;
    let ids = InputIds::of(&args.inputs);
    let mut written: HashSet<PathBuf> = HashSet::new();
    let mut failures = 0;
    for path in &args.inputs {
        let input = Input::from_arg(path);
        if let Err(f) = plan.convert_one(&input, &ids, &mut written) {
            f.report();
            failures += 1;
        }
    }
    Ok(failures)
}

impl Plan {
    fn from_args(args: &ConvertArgs) -> Result<Plan, Failure> {
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
            .with_convention(match args.convention {
                ConventionArg::Opengl => Convention::OpenGl,
                ConventionArg::Directx => Convention::DirectX,
            })
            .with_strength(strength)
            .with_invert(args.invert);
        fit.validate().map_err(|e| Failure::usage(e.to_string()))?;

        let many = args.inputs.len() > 1;
        let stdin_count = args.inputs.iter().filter(|p| p.as_os_str() == "-").count();
        if stdin_count > 1 {
            return Err(Failure::usage("standard input ('-') can be read only once"));
        }
        let destination = match &args.output {
            None => Destination::BesideInputs,
            Some(o) if o.as_os_str() == "-" => {
                if many {
                    return Err(Failure::usage("'-o -' takes one input: many images cannot share standard output"));
                }
                Destination::Stdout
            }
            Some(o) if many || o.is_dir() => Destination::Folder(o.clone()),
            Some(o) => Destination::File(o.clone()),
        };
        if let Destination::Folder(dir) = &destination {
            if dir.exists() && !dir.is_dir() {
                return Err(Failure::file(dir, "is not a folder: with many inputs, -o names the output folder"));
            }
            std::fs::create_dir_all(dir)
                .map_err(|e| Failure::file(dir, format!("cannot create the output folder: {}", e)))?;
        }
        Ok(Plan {
            fit,
            border: args.border,
            channel: args.channel.map(channel_of),
            bits: args.bits,
            format: args.format,
            signed: args.signed,
            destination,
        })
    }

    fn convert_one(&self, input: &Input, ids: &InputIds, written: &mut HashSet<PathBuf>) -> Result<(), Failure> {
        if let Input::File(path) = input {
            let in_failure = |e: normalfit::Error| Failure::file(path, e);
            if let Some(rows) = PngRows::reopen(path, self.channel).map_err(in_failure)? {
                let sample = SampleType::Int { bits: if rows.more_than_8_bits() { 16 } else { 8 } };
                let target = self.target(input, InputFormat::Png, sample)?;
                self.claim(&target, ids, written)?;
                return self.convert_streaming(path, rows, &target);
            }
            if let Some(rows) = ExrRows::reopen(path, self.channel).map_err(in_failure)? {
                let target = self.target(input, InputFormat::Exr, SampleType::Float)?;
                self.claim(&target, ids, written)?;
                return self.convert_streaming(path, rows, &target);
            }
        }
        let raster = read_input(input, &ReadOptions::default())?;
        let target = self.target(input, raster.format.clone(), raster.sample)?;
        self.claim(&target, ids, written)?;
        let (width, height) = (raster.width, raster.height);
        let heights = raster.into_heights(self.channel).map_err(|e| Failure::file(input.name(), e))?;
        let report = self
            .needs_check()
            .then(|| tiling::check(&[&heights], width, height, &TilingOptions::new().with_kind(KindChoice::Height)));
        if let Some(report) = &report {
            self.warn_seams(report, input);
        }
        let fit = self.fit.clone().with_borders(self.borders_for(report.as_ref()));
        let encoded =
            |out: &mut dyn Write| -> normalfit::Result<()> { encode(&heights, width, height, &fit, &target, out) };
        match &target.path {
            Some(path) => io::write_atomically(path, encoded).map_err(|e| Failure::file(path, e)),
            None => {
                // EXR needs to seek while writing, so the bytes are assembled first.
                let mut bytes = Cursor::new(Vec::new());
                encoded(&mut bytes).map_err(|e| Failure::file("<standard output>", e))?;
                let mut stdout = std::io::stdout().lock();
                stdout
                    .write_all(bytes.get_ref())
                    .and_then(|()| stdout.flush())
                    .map_err(|e| Failure::file("<standard output>", e))
            }
        }
    }

    /// A PNG or scan-line EXR input, converted without holding the image:
    /// rows stream from the decoder through the fit to the encoder. One
    /// pass over the input, but for a wrap in y into an output written in
    /// order (EXR, or PNG into a pipe), which needs the image's last rows
    /// first: an EXR gives them from its last blocks, a PNG by a first
    /// pass; and for `--border auto`, whose borders depend on the tiling
    /// check, which then comes from a first pass too.
    fn convert_streaming<S: Reopen>(&self, path: &Path, rows: S, target: &Target) -> Result<(), Failure> {
        let input = Input::File(path.to_path_buf());
        let in_failure = |e: normalfit::Error| Failure::file(path, e);
        let (width, height, r) = (rows.width(), rows.height(), self.fit.patch / 2);
        let auto = self.border.x == AxisBorder::Auto || self.border.y == AxisBorder::Auto;
        let may_wrap_y = matches!(self.border.y, AxisBorder::Auto | AxisBorder::Fixed(Border::Wrap));
        // A PNG file takes its top rows last, in room kept after the header.
        let png_file = target.path.is_some() && target.png_depth().is_some();
        let needs_tail = may_wrap_y && !png_file;
        let check_opts = TilingOptions::new().with_kind(KindChoice::Height);
        let cheap_tail = if needs_tail && !auto { S::last_rows(path, self.channel, r) } else { None };
        let (report, tail) = match cheap_tail {
            Some(tail) => (None, Some(tail.map_err(in_failure)?)),
            None if auto || needs_tail => {
                let first = S::reopen(path, self.channel).map_err(in_failure)?;
                let first = first.ok_or_else(|| Failure::file(path, "changed while being read"))?;
                let mut seams = HeightSeams::new(width, height);
                let tail = first.read_tail(r, |row| seams.push_row(row)).map_err(in_failure)?;
                (Some(seams.finish(&check_opts)), Some(tail))
            }
            None => (None, None),
        };
        // Without a first pass, the check runs on the rows as they stream
        // and the warning comes after the output.
        if let Some(report) = &report {
            self.warn_seams(report, &input);
        }
        let fit = self.fit.clone().with_borders(self.borders_for(report.as_ref()));
        let tail = if fit.borders.y == Border::Wrap { tail.as_deref() } else { None };
        let mut seams = (report.is_none() && self.needs_check()).then(|| HeightSeams::new(width, height));
        let visit = |row: &[f32]| {
            if let Some(s) = seams.as_mut() {
                s.push_row(row);
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
                let format = ExrFormat { depth, signed: target.signed, layout: Layout::Rgb };
                stream::convert_exr(rows, tail, &fit, format, visit, file).inspect_err(&mut on_input)
            })
            .map_err(|e| Failure::file(out, e)),
            (None, Encoding::Exr(depth)) => {
                // EXR seeks back to its offset table: the file is assembled first.
                let mut bytes = Cursor::new(Vec::new());
                let format = ExrFormat { depth, signed: target.signed, layout: Layout::Rgb };
                stream::convert_exr(rows, tail, &fit, format, visit, &mut bytes)
                    .inspect_err(&mut on_input)
                    .and_then(|()| write_stdout(bytes.get_ref()))
                    .map_err(|e| Failure::file(stdout_name, e))
            }
            (Some(out), Encoding::Png8 | Encoding::Png16) => io::write_file_atomically(out, |file| {
                let depth = target.png_depth().expect("a png encoding");
                stream::convert_png_seekable(rows, &fit, depth, Layout::Rgb, visit, file).inspect_err(&mut on_input)
            })
            .map_err(|e| Failure::file(out, e)),
            (None, Encoding::Png8 | Encoding::Png16) => {
                let depth = target.png_depth().expect("a png encoding");
                let mut stdout = std::io::stdout().lock();
                stream::convert_png(rows, tail, &fit, depth, Layout::Rgb, visit, &mut stdout)
                    .inspect_err(&mut on_input)
                    .and_then(|()| Ok(stdout.flush()?))
                    .map_err(|e| Failure::file(stdout_name, e))
            }
        };
        if let Some(problem) = failed_input {
            return Err(Failure::file(path, problem));
        }
        if let Some(seams) = seams {
            self.warn_seams(&seams.finish(&check_opts), &input);
        }
        result
    }

    /// Refuses an output that is an input, or that an earlier input of this
    /// run already wrote.
    fn claim(&self, target: &Target, ids: &InputIds, written: &mut HashSet<PathBuf>) -> Result<(), Failure> {
        if let Some(path) = &target.path {
            ids.refuse_overwrite(path)?;
            let key = std::path::absolute(path).unwrap_or_else(|_| path.clone());
            if !written.insert(key) {
                return Err(Failure::file(
                    path,
                    "is the output of an earlier input of this run; give the inputs distinct names or separate -o folders",
                ));
            }
        }
        Ok(())
    }

    /// Whether the borders asked for need the tiling check: a wrap (to warn
    /// when it draws a seam) or `auto`.
    fn needs_check(&self) -> bool {
        let check = |a: AxisBorder| matches!(a, AxisBorder::Auto | AxisBorder::Fixed(Border::Wrap));
        check(self.border.x) || check(self.border.y)
    }

    /// The border modes for one image: `auto` becomes wrap where the image
    /// tiles and mirror where it does not (`report`: the tiling check, made
    /// when [`Self::needs_check`]; without it, `auto` is mirror).
    fn borders_for(&self, report: Option<&tiling::TilingReport>) -> Borders {
        let suggested = report.map_or(Borders::both(Border::Mirror), |r| r.suggested_borders());
        let resolve = |asked: AxisBorder, auto: Border| match asked {
            AxisBorder::Fixed(b) => b,
            AxisBorder::Auto => auto,
        };
        Borders { x: resolve(self.border.x, suggested.x), y: resolve(self.border.y, suggested.y) }
    }

    /// A wrap asked for on an axis that does not tile draws a seam: one
    /// warning line names the axes.
    fn warn_seams(&self, report: &tiling::TilingReport, input: &Input) {
        let wrap = AxisBorder::Fixed(Border::Wrap);
        let seams: Vec<String> = [("x", self.border.x, report.x), ("y", self.border.y, report.y)]
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

    /// The output's path (None: standard output), format and depth.
    fn target(&self, input: &Input, format: InputFormat, sample: SampleType) -> Result<Target, Failure> {
        let float_input = match sample {
            io::SampleType::Float => true,
            io::SampleType::Int { .. } | io::SampleType::SignedInt { .. } => false,
        };
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
        let beside = |dir: &Path| dir.join(format!("{}_normal.{ext}", input.stem()));
        let path = match &self.destination {
            Destination::Stdout => None,
            Destination::BesideInputs => match input {
                Input::Stdin => None,
                Input::File(p) => Some(beside(p.parent().unwrap_or(Path::new("")))),
            },
            Destination::File(p) => Some(p.clone()),
            Destination::Folder(dir) => Some(beside(dir)),
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
        Ok(Target { path, encoding, signed: self.signed })
    }
}

/// Where one output goes and how it is encoded.
struct Target {
    path: Option<PathBuf>,
    encoding: Encoding,
    signed: bool,
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

/// Fits the normals straight into the output's texel type and encodes them.
fn encode(
    heights: &[f32],
    w: usize,
    h: usize,
    opts: &Options,
    target: &Target,
    out: &mut dyn Write,
) -> normalfit::Result<()> {
    let compression = PngCompression::default();
    match target.encoding {
        Encoding::Png8 => {
            let mut texels = vec![[0u8; 3]; heights.len()];
            normals_into(heights, w, h, opts, &mut texels)?;
            io::encode_png_rgb8(&texels, w, h, compression, out)
        }
        Encoding::Png16 => {
            let mut texels = vec![[0u16; 3]; heights.len()];
            normals_into(heights, w, h, opts, &mut texels)?;
            io::encode_png_rgb16(&texels, w, h, compression, out)
        }
        Encoding::Exr(depth) => {
            let mut texels = vec![[0f32; 3]; heights.len()];
            normals_into(heights, w, h, opts, &mut texels)?;
            if !target.signed {
                texels.iter_mut().for_each(|t| *t = t.map(|c| (c + 1.0) * 0.5));
            }
            let mut bytes = Cursor::new(Vec::new());
            io::encode_exr(&texels, w, h, depth, &mut bytes)?;
            out.write_all(bytes.get_ref())?;
            Ok(())
        }
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
    fn reopen(path: &Path, channel: Option<Channel>) -> normalfit::Result<Option<Self>>;

    /// The image's last `rows` rows, if the format can give them without
    /// reading the whole file (`None`: it cannot).
    fn last_rows(path: &Path, channel: Option<Channel>, rows: usize) -> Option<normalfit::Result<Vec<f32>>>;
}

impl Reopen for PngRows {
    fn reopen(path: &Path, channel: Option<Channel>) -> normalfit::Result<Option<Self>> {
        PngRows::open(path, &ReadOptions::default(), channel)
    }

    fn last_rows(_: &Path, _: Option<Channel>, _: usize) -> Option<normalfit::Result<Vec<f32>>> {
        // PNG cannot seek: its last rows come from a pass over the file.
        None
    }
}

impl Reopen for ExrRows {
    fn reopen(path: &Path, channel: Option<Channel>) -> normalfit::Result<Option<Self>> {
        ExrRows::open(path, &ReadOptions::default(), channel)
    }

    fn last_rows(path: &Path, channel: Option<Channel>, rows: usize) -> Option<normalfit::Result<Vec<f32>>> {
        Some(ExrRows::last_rows(path, &ReadOptions::default(), channel, rows))
    }
}
