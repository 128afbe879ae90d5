//! `normalfit tiling`: a verdict per image and axis, as text or JSON Lines.
//! The reports and previews are the library's ([`normalfit::inspect`]);
//! here are the lines printed and the exit code.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use normalfit::inspect::{seam_preview, seam_preview_lit, tiling_report};
use normalfit::io::{self, Channel, Encoding, Raster, ReadOptions};
use normalfit::normal_map::ImageKind;
use normalfit::tiling::{self, TilingOptions, TilingReport};

use super::args::{TilingArgs, library_message};
use super::batch::{Batch, Job, Outcome, Turn, Words};
use super::exit;
use super::input::{Input, read_input};
use super::output::STDOUT;
use super::report::Failure;

/// Checks every image (files, and the images of folders). Exit 2 if any
/// could not be checked, else 1 if one has a seam, else 0: an error
/// outranks a seam, since the images not checked may have seams too.
pub fn run(args: TilingArgs) -> Result<u8, Failure> {
    let mut opts = TilingOptions::default().with_kind(args.kind).with_nodata(args.holes.value());
    if let Some(t) = args.threshold {
        opts = opts.with_threshold(t);
    }
    opts.validate().map_err(|e| Failure::usage(format!("--{}", library_message(&e))))?;
    let words = Words { done: "checked", purpose: "to check" };
    // No stem marks a file as ours: previews go where --preview says.
    let batch = Batch::gather(&args.inputs, &args.batch, "", words);
    let many = batch.many();
    let plan = Plan {
        opts,
        read: args.holes.apply(args.terrain.apply(args.read.options())),
        channel: args.channel.clone(),
        json: args.json,
        plain: args.preview.as_deref().map(|p| PreviewTarget::new(p, many)).transpose()?,
        lit: args.preview_lit.as_deref().map(|p| PreviewTarget::new(p, many)).transpose()?,
        seams: AtomicUsize::new(0),
    };
    let errors = batch.run(|job, turn| plan.check_one(job, turn));
    Ok(exit::of_batch(errors, plan.seams.load(Ordering::Relaxed)))
}

/// What `tiling` does with every input, decided once from the arguments.
struct Plan {
    opts: TilingOptions,
    read: ReadOptions,
    channel: Option<Channel>,
    json: bool,
    plain: Option<PreviewTarget>,
    lit: Option<PreviewTarget>,
    /// Images found with a seam so far.
    seams: AtomicUsize,
}

impl Plan {
    /// Reads one image, checks it, writes its previews, and prints its line
    /// once the lines of the images before it are printed.
    fn check_one(&self, job: &Job, turn: &Turn) -> Result<Outcome, Failure> {
        let input = &job.input;
        let channel = self.channel.as_ref();
        let raster = read_input(input, &self.read)?;
        let report = tiling_report(&raster, &self.opts, channel).map_err(|e| Failure::file(input.name(), e))?;
        self.write_previews(job, turn, &raster, &report)?;
        let size = (raster.width, raster.height);
        let line = if self.json { json_line(input, size, &report)? } else { text_line(input, &report) };
        if !report.seamless() {
            self.seams.fetch_add(1, Ordering::Relaxed);
        }
        // A reader that stops early (`| head -3`) closes the pipe: the
        // reports it does not want are not computed, and that is no error
        // (`println!` would panic on it).
        turn.in_order(|| {
            let mut stdout = std::io::stdout().lock();
            match writeln!(stdout, "{line}").and_then(|()| stdout.flush()) {
                Ok(()) => Ok(Outcome::Done),
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(Outcome::PipeClosed),
                Err(e) => Err(Failure::file(STDOUT, e)),
            }
        })
    }

    /// Writes the asked-for previews of one image, each shifted by half its
    /// size so that both wrap seams cross the middle.
    fn write_previews(&self, job: &Job, turn: &Turn, raster: &Raster, report: &TilingReport) -> Result<(), Failure> {
        let input = &job.input;
        let channel = self.channel.as_ref();
        let (w, h) = (raster.width, raster.height);
        let fail = |e: normalfit::Error| Failure::file(input.name(), e);
        let plain = self.plain.as_ref().map(|t| t.path_for(job, "preview"));
        let lit = self.lit.as_ref().map(|t| t.path_for(job, "preview_lit"));
        let outputs: Vec<&Path> = plain.iter().chain(&lit).map(PathBuf::as_path).collect();
        if outputs.is_empty() {
            return Ok(());
        }
        turn.claim(input, &outputs)?;
        if let Some(path) = plain.filter(|p| turn.wanted(Some(p), input)) {
            let rgb = seam_preview(raster, report, channel).map_err(fail)?;
            save(&path, !job.subfolder.as_os_str().is_empty(), &rgb, w, h)?;
        }
        if let Some(path) = lit.filter(|p| turn.wanted(Some(p), input)) {
            let rgb = seam_preview_lit(raster, report, channel).map_err(fail)?;
            save(&path, !job.subfolder.as_os_str().is_empty(), &rgb, w, h)?;
        }
        Ok(())
    }
}

/// Where `--preview` pictures go: one file, or a folder for many images.
enum PreviewTarget {
    File(PathBuf),
    Folder(PathBuf),
}

impl PreviewTarget {
    fn new(path: &Path, many: bool) -> Result<PreviewTarget, Failure> {
        if !many {
            return Ok(PreviewTarget::File(path.to_path_buf()));
        }
        std::fs::create_dir_all(path)
            .map_err(|e| Failure::file(path, format!("cannot create the preview folder: {e}")))?;
        Ok(PreviewTarget::Folder(path.to_path_buf()))
    }

    /// The preview of `job`: in a folder, `<stem>_<suffix>.png` under the
    /// input's subfolder.
    fn path_for(&self, job: &Job, suffix: &str) -> PathBuf {
        match self {
            PreviewTarget::File(p) => p.clone(),
            PreviewTarget::Folder(dir) => dir.join(&job.subfolder).join(format!("{}_{suffix}.png", job.input.stem())),
        }
    }
}

/// Writes one preview; `in_subfolder`: its folder, under the preview
/// folder, is made if missing.
fn save(path: &Path, in_subfolder: bool, rgb: &[[u8; 3]], w: usize, h: usize) -> Result<(), Failure> {
    if in_subfolder && let Some(folder) = path.parent() {
        std::fs::create_dir_all(folder)
            .map_err(|e| Failure::file(folder, format!("cannot create the preview folder: {e}")))?;
    }
    io::write_file_atomically(path, |out| io::encode_normals(rgb, None, w, h, &Encoding::png8(), out))
        .map_err(|e| Failure::file(path, e))
}

fn kind_name(kind: ImageKind) -> &'static str {
    match kind {
        ImageKind::Height => "height",
        ImageKind::Normal => "normal",
    }
}

fn text_line(input: &Input, r: &TilingReport) -> String {
    let axis = |a: &tiling::AxisReport| format!("{:.2} {}", a.score, if a.seamless { "seamless" } else { "SEAM" });
    format!(
        "{}: {} ({} map; x {}, y {})",
        input.name().display(),
        if r.seamless() { "tiles" } else { "does not tile" },
        kind_name(r.kind),
        axis(&r.x),
        axis(&r.y)
    )
}

/// One `--json` line: the library's report (`kind`, `x`, `y`) with the file
/// it is about, its size and the verdict on both axes.
#[derive(serde::Serialize)]
struct JsonLine<'a> {
    path: String,
    width: usize,
    height: usize,
    #[serde(flatten)]
    report: &'a TilingReport,
    seamless: bool,
}

/// serde_json's compact form with a space after every `:` and `,`, and
/// numbers with four decimals: the lines `--json` has always printed (a
/// score's further digits are noise). serde_json writes infinities and NaN
/// as null, which JSON has in their place.
pub(super) struct JsonStyle;

impl serde_json::ser::Formatter for JsonStyle {
    fn begin_object_key<W: ?Sized + Write>(&mut self, writer: &mut W, first: bool) -> std::io::Result<()> {
        if first { Ok(()) } else { writer.write_all(b", ") }
    }

    fn begin_object_value<W: ?Sized + Write>(&mut self, writer: &mut W) -> std::io::Result<()> {
        writer.write_all(b": ")
    }

    fn write_f64<W: ?Sized + Write>(&mut self, writer: &mut W, value: f64) -> std::io::Result<()> {
        write!(writer, "{value:.4}")
    }
}

fn json_line(input: &Input, (width, height): (usize, usize), report: &TilingReport) -> Result<String, Failure> {
    let name = input.name().display().to_string();
    let line = JsonLine { path: name, width, height, report, seamless: report.seamless() };
    let mut out = Vec::new();
    serde::Serialize::serialize(&line, &mut serde_json::Serializer::with_formatter(&mut out, JsonStyle))
        .map_err(|e| Failure::file(input.name(), format!("cannot write its JSON line: {e}")))?;
    String::from_utf8(out).map_err(|e| Failure::file(input.name(), format!("cannot write its JSON line: {e}")))
}
