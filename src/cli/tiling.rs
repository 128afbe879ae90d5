//! `normalfit tiling`: a verdict per image and axis, as text or JSON Lines.
//! The reports and previews are the library's ([`normalfit::inspect`]);
//! here are the lines printed and the exit code.

use std::io::Write;
use std::path::{Path, PathBuf};

use normalfit::inspect::{seam_preview, seam_preview_lit, tiling_report};
use normalfit::io::{self, Channel, Encoding, Raster, ReadOptions};
use normalfit::tiling::{self, ImageKind, TilingOptions, TilingReport};

use super::args::TilingArgs;
use super::exit;
use super::input::{Input, InputIds, read_input};
use super::report::Failure;

/// Checks every image; exit 0 if all tile, 1 if one has a seam, 2 on any error.
pub fn run(args: TilingArgs) -> Result<u8, Failure> {
    let mut opts = TilingOptions::default().with_kind(super::shade::kind_choice(args.kind));
    if let Some(t) = args.threshold {
        if t <= 0.0 {
            return Err(Failure::usage(format!("--threshold must be positive, got {t}")));
        }
        opts.threshold = t;
    }
    let channel = args.channel.as_ref();
    let read = args.read.options();
    let many = args.inputs.len() > 1;
    let previews = Previews {
        plain: args.preview.as_deref().map(|p| PreviewTarget::new(p, many)).transpose()?,
        lit: args.preview_lit.as_deref().map(|p| PreviewTarget::new(p, many)).transpose()?,
        ids: InputIds::of(&args.inputs),
    };
    let (mut errors, mut seams) = (0, 0);
    for path in &args.inputs {
        let input = Input::from_arg(path);
        let checked = check_one(&input, &read, channel, &opts).and_then(|(raster, report)| {
            previews.write(&input, &raster, &report, channel)?;
            Ok((raster, report))
        });
        match checked {
            Ok((raster, report)) => {
                if !report.seamless() {
                    seams += 1;
                }
                let size = (raster.width, raster.height);
                let line = if args.json { json_line(&input, size, &report) } else { Ok(text_line(&input, &report)) };
                let line = match line {
                    Ok(line) => line,
                    Err(f) => {
                        f.report();
                        errors += 1;
                        continue;
                    }
                };
                // A reader that stops early (`| head -3`) closes the pipe:
                // the reports it does not want are not computed, and that
                // is no error (`println!` would panic on it).
                let mut stdout = std::io::stdout().lock();
                if let Err(e) = writeln!(stdout, "{line}").and_then(|()| stdout.flush()) {
                    if e.kind() == std::io::ErrorKind::BrokenPipe {
                        break;
                    }
                    super::report::print_line(&format!("normalfit: <standard output>: {e}"));
                    errors += 1;
                    break;
                }
            }
            Err(f) => {
                f.report();
                errors += 1;
            }
        }
    }
    Ok(if errors > 0 {
        exit::ERROR
    } else if seams > 0 {
        exit::SEAM
    } else {
        exit::OK
    })
}

/// Reads one image and checks it.
fn check_one(
    input: &Input,
    read: &ReadOptions,
    channel: Option<&Channel>,
    opts: &TilingOptions,
) -> Result<(Raster, TilingReport), Failure> {
    let raster = read_input(input, read)?;
    let report = tiling_report(&raster, opts, channel).map_err(|e| Failure::file(input.name(), e))?;
    Ok((raster, report))
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

    fn path_for(&self, input: &Input, suffix: &str) -> PathBuf {
        match self {
            PreviewTarget::File(p) => p.clone(),
            PreviewTarget::Folder(dir) => dir.join(format!("{}_{suffix}.png", input.stem())),
        }
    }
}

struct Previews {
    plain: Option<PreviewTarget>,
    lit: Option<PreviewTarget>,
    ids: InputIds,
}

impl Previews {
    /// Writes the asked-for previews of one image, each shifted by half its
    /// size so that both wrap seams cross the middle.
    fn write(
        &self,
        input: &Input,
        raster: &Raster,
        report: &TilingReport,
        channel: Option<&Channel>,
    ) -> Result<(), Failure> {
        let (w, h) = (raster.width, raster.height);
        let fail = |e: normalfit::Error| Failure::file(input.name(), e);
        if let Some(target) = &self.plain {
            let rgb = seam_preview(raster, report, channel).map_err(fail)?;
            self.save(&target.path_for(input, "preview"), &rgb, w, h)?;
        }
        if let Some(target) = &self.lit {
            let rgb = seam_preview_lit(raster, report, channel).map_err(fail)?;
            self.save(&target.path_for(input, "preview_lit"), &rgb, w, h)?;
        }
        Ok(())
    }

    fn save(&self, path: &Path, rgb: &[[u8; 3]], w: usize, h: usize) -> Result<(), Failure> {
        self.ids.refuse_overwrite(path)?;
        io::write_file_atomically(path, |out| io::encode_normals(rgb, None, w, h, &Encoding::png8(), out))
            .map_err(|e| Failure::file(path, e))
    }
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
struct JsonStyle;

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
