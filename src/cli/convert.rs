//! `normalfit convert`: where each output goes, in which format, and the
//! promise that outputs appear whole or not at all and never replace an input.

use std::collections::HashSet;
use std::io::{Cursor, Seek, Write};
use std::path::{Path, PathBuf};

use normalfit::io::stream::{self, ExrRows, PngDepth, PngOutput, PngRows, RowSource};
use normalfit::io::{self, Channel, ExrDepth, InputFormat, PngCompression, ReadOptions, SampleType};
use normalfit::tiling::{self, HeightSeams, KindChoice, TilingOptions};
use normalfit::{Border, Borders, Options, normals_into};

use super::args::{AxisBorder, BorderArg, CompressionArg, ConvertArgs, FormatArg};
use super::fitting;
use super::input::{Input, InputIds, read_input, stdin_at_most_once};
use super::output::{self, Destination};
use super::report::Failure;
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
    compression: PngCompression,
    destination: Destination,
    /// The size limit and the EXR layer, for every read.
    read: ReadOptions,
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
        let fit = fitting::options(&args.fit)?;
        stdin_at_most_once(&args.inputs)?;
        let destination = Destination::new(args.output.as_deref(), &args.inputs)?;
        Ok(Plan {
            fit,
            border: args.fit.border,
            channel: args.channel.map(channel_of),
            bits: args.bits,
            format: args.format,
            signed: args.signed,
            compression: match args.compression {
                CompressionArg::Fast => PngCompression::Fast,
                CompressionArg::Small => PngCompression::Default,
            },
            destination,
            read: args.read.options(),
        })
    }

    fn convert_one(&self, input: &Input, ids: &InputIds, written: &mut HashSet<PathBuf>) -> Result<(), Failure> {
        if let Input::File(path) = input {
            let in_failure = |e: normalfit::Error| Failure::file(path, e);
            if let Some(rows) = PngRows::reopen(path, &self.read, self.channel).map_err(in_failure)? {
                let sample = SampleType::Int { bits: if rows.more_than_8_bits() { 16 } else { 8 } };
                let target = self.target(input, InputFormat::Png, sample)?;
                self.claim(&target, ids, written)?;
                return self.convert_streaming(path, rows, &target);
            }
            if let Some(rows) = ExrRows::reopen(path, &self.read, self.channel).map_err(in_failure)? {
                let target = self.target(input, InputFormat::Exr, SampleType::Float)?;
                self.claim(&target, ids, written)?;
                return self.convert_streaming(path, rows, &target);
            }
        }
        let raster = read_input(input, &self.read)?;
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
        let output = target.path.as_deref().unwrap_or(Path::new("<standard output>"));
        check_encode_memory(&target, width, height).map_err(|e| Failure::file(output, e))?;
        let compression = self.compression;
        match &target.path {
            // Into the file itself, which seeks as EXR needs: no copy of the
            // encoded image in memory.
            Some(path) => io::write_file_atomically(path, |file| {
                encode(&heights, width, height, &fit, &target, compression, file)
            })
            .map_err(|e| Failure::file(path, e)),
            None => {
                // EXR needs to seek while writing, so the bytes are assembled first.
                let mut bytes = InMemory::default();
                encode(&heights, width, height, &fit, &target, compression, &mut bytes)
                    .map_err(|e| Failure::file("<standard output>", e))?;
                let bytes = bytes.0;
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
        let cheap_tail = if needs_tail && !auto { S::last_rows(path, &self.read, self.channel, r) } else { None };
        let (report, tail) = match cheap_tail {
            Some(tail) => (None, Some(tail.map_err(in_failure)?)),
            None if auto || needs_tail => {
                let first = S::reopen(path, &self.read, self.channel).map_err(in_failure)?;
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
                stream::convert_exr(rows, tail, &fit, depth, target.signed, visit, file).inspect_err(&mut on_input)
            })
            .map_err(|e| Failure::file(out, e)),
            (None, Encoding::Exr(depth)) => {
                // EXR seeks back to its offset table: the file is assembled first.
                let mut bytes = InMemory::default();
                stream::convert_exr(rows, tail, &fit, depth, target.signed, visit, &mut bytes)
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
            self.warn_seams(&seams.finish(&check_opts), &input);
        }
        result
    }

    /// The streamed PNG's settings, for a PNG target.
    fn png_output(&self, target: &Target) -> Option<PngOutput> {
        target.png_depth().map(|depth| PngOutput { depth, compression: self.compression })
    }

    /// Refuses an output that is an input, or that an earlier input of this
    /// run already wrote.
    fn claim(&self, target: &Target, ids: &InputIds, written: &mut HashSet<PathBuf>) -> Result<(), Failure> {
        match &target.path {
            Some(path) => output::claim(path, ids, written),
            None => Ok(()),
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

    /// Warns about a wrap on an axis that does not tile.
    fn warn_seams(&self, report: &tiling::TilingReport, input: &Input) {
        self.border.warn_seams(report, input);
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
        let path = self.destination.path_for(input, &format!("{}_normal.{ext}", input.stem()));
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
fn encode<W: Write + Seek>(
    heights: &[f32],
    w: usize,
    h: usize,
    opts: &Options,
    target: &Target,
    compression: PngCompression,
    out: &mut W,
) -> normalfit::Result<()> {
    match target.encoding {
        Encoding::Png8 => {
            let mut texels = texel_buffer::<[u8; 3]>(heights.len())?;
            normals_into(heights, w, h, opts, &mut texels)?;
            io::encode_png_rgb8(&texels, w, h, compression, out)
        }
        Encoding::Png16 => {
            let mut texels = texel_buffer::<[u16; 3]>(heights.len())?;
            normals_into(heights, w, h, opts, &mut texels)?;
            io::encode_png_rgb16(&texels, w, h, compression, out)
        }
        Encoding::Exr(depth) => {
            let mut texels = texel_buffer::<[f32; 3]>(heights.len())?;
            normals_into(heights, w, h, opts, &mut texels)?;
            if !target.signed {
                texels.iter_mut().for_each(|t| *t = t.map(|c| (c + 1.0) * 0.5));
            }
            io::encode_exr(&texels, w, h, depth, out)
        }
    }
}

/// Refuses an encode that the memory limits leave no room for, before it
/// starts: past our own buffers the encoders allocate as they go, and a
/// failure there would abort the process. Bytes held per texel, measured
/// from what the encoders do: the normal map (3, 6 or 12); for PNG, the
/// whole zlib stream, which `png` assembles in memory, and its stored
/// fallback when deflate does not pay (twice the raw size); for 16-bit
/// PNG, our byte copy and `image`'s big-endian copy besides; for standard
/// output, the encoded file (at most about the raw size).
fn check_encode_memory(target: &Target, w: usize, h: usize) -> normalfit::Result<()> {
    let (raw, per_texel): (u64, u64) = match target.encoding {
        Encoding::Png8 => (3, 3 + 2 * 3),
        Encoding::Png16 => (6, 6 + 2 * 6 + 2 * 6),
        Encoding::Exr(_) => (12, 12),
    };
    let assembled = if target.path.is_none() { raw } else { 0 };
    let texels = (w as u64).saturating_mul(h as u64);
    io::check_memory("encoding the normal map", texels.saturating_mul(per_texel + assembled))
}

/// Room for the normal map of `len` texels, or an error when the memory is
/// not there: `vec!` would abort the process instead (under `ulimit -v`).
fn texel_buffer<T: Clone + Default>(len: usize) -> normalfit::Result<Vec<T>> {
    let mut texels = Vec::new();
    texels.try_reserve_exact(len).map_err(|_| {
        let mib = len.saturating_mul(size_of::<T>()) >> 20;
        normalfit::Error::Limits(format!("not enough memory for the normal map ({mib} MiB)"))
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
    ) -> Option<normalfit::Result<Vec<f32>>>;
}

impl Reopen for PngRows {
    fn reopen(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> normalfit::Result<Option<Self>> {
        PngRows::open(path, opts, channel)
    }

    fn last_rows(_: &Path, _: &ReadOptions, _: Option<Channel>, _: usize) -> Option<normalfit::Result<Vec<f32>>> {
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
    ) -> Option<normalfit::Result<Vec<f32>>> {
        Some(ExrRows::last_rows(path, opts, channel, rows))
    }
}
