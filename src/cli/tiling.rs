//! `normalfit tiling`: a verdict per image and axis, as text or JSON Lines.

use std::io::Write;
use std::path::{Path, PathBuf};

use normalfit::io::{self, Channel, Encoding, Raster, ReadOptions};
use normalfit::shade::{self, Light};
use normalfit::tiling::{self, ImageKind, KindChoice, TilingOptions, TilingReport};
use normalfit::{Convention, Options, Strength};

use super::args::{KindArg, TilingArgs};
use super::exit;
use super::input::{Input, InputIds, read_input};
use super::report::Failure;

/// Checks every image; exit 0 if all tile, 1 if one has a seam, 2 on any error.
pub fn run(args: TilingArgs) -> Result<u8, Failure> {
    let mut opts = TilingOptions::default();
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
        let checked = check_one(&input, &read, args.kind, channel, &opts).and_then(|(raster, report)| {
            previews.write(&input, &raster, &report, channel)?;
            Ok((raster, report))
        });
        match checked {
            Ok((raster, report)) => {
                if !report.seamless() {
                    seams += 1;
                }
                let size = (raster.width, raster.height);
                let line = if args.json { json_line(&input, size, &report) } else { text_line(&input, &report) };
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
    kind: KindArg,
    channel: Option<&Channel>,
    opts: &TilingOptions,
) -> Result<(Raster, TilingReport), Failure> {
    let raster = read_input(input, read)?;
    let report = report_of(&raster, kind, channel, opts).map_err(|e| Failure::file(input.name(), e))?;
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
            let rgb = match (report.kind, rgb_planes(raster).map_err(fail)?) {
                (ImageKind::Normal, Some(planes)) => (0..w * h)
                    .map(|k| planes.each_ref().map(|p| (p[k].clamp(0.0, 1.0) * 255.0).round() as u8))
                    .collect(),
                _ => stretched_gray(&raster.heights(channel.cloned()).map_err(fail)?),
            };
            self.save(&target.path_for(input, "preview"), &tiling::shift_half(&rgb, w, h), w, h)?;
        }
        if let Some(target) = &self.lit {
            let normals: Vec<[f32; 3]> = match (report.kind, rgb_planes(raster).map_err(fail)?) {
                (ImageKind::Normal, Some(planes)) => {
                    (0..w * h).map(|k| planes.each_ref().map(|p| 2.0 * p[k] - 1.0)).collect()
                }
                _ => {
                    let heights = raster.heights(channel.cloned()).map_err(fail)?;
                    let opts = Options::new().with_strength(Strength::Scale(exposure(&heights, w)));
                    normalfit::normals(&heights, w, h, &opts).map_err(fail)?
                }
            };
            let gray = shade::shade(&normals, w, h, Light::default(), Convention::OpenGl).map_err(fail)?;
            let rgb: Vec<[u8; 3]> = gray.iter().map(|&g| [g; 3]).collect();
            self.save(&target.path_for(input, "preview_lit"), &tiling::shift_half(&rgb, w, h), w, h)?;
        }
        Ok(())
    }

    fn save(&self, path: &Path, rgb: &[[u8; 3]], w: usize, h: usize) -> Result<(), Failure> {
        self.ids.refuse_overwrite(path)?;
        io::write_file_atomically(path, |out| io::encode_normals(rgb, None, w, h, &Encoding::png8(), out))
            .map_err(|e| Failure::file(path, e))
    }
}

/// The R, G and B planes as stored values in [0, 1] (integers divided by
/// their top value), when the image has all three.
pub fn rgb_planes(raster: &Raster) -> normalfit::Result<Option<[Vec<f32>; 3]>> {
    match (raster.plane("R"), raster.plane("G"), raster.plane("B")) {
        (Some(r), Some(g), Some(b)) => Ok(Some([r.data.to_f32()?, g.data.to_f32()?, b.data.to_f32()?])),
        _ => Ok(None),
    }
}

/// Heights stretched to the full gray range, so that any map is visible.
fn stretched_gray(heights: &[f32]) -> Vec<[u8; 3]> {
    let (lo, hi) = heights.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let span = if hi > lo { hi - lo } else { 1.0 };
    heights.iter().map(|&v| [((v - lo) / span * 255.0).round() as u8; 3]).collect()
}

/// A gain that makes the typical step between neighbours a slope of 0.3
/// (about 17°): enough relief to see creases whatever the map's units.
fn exposure(heights: &[f32], width: usize) -> f64 {
    let steps = heights.windows(2).enumerate().filter(|(k, _)| (k + 1) % width != 0);
    let (sum, count) = steps.fold((0.0f64, 0usize), |(s, c), (_, p)| (s + f64::from((p[1] - p[0]).abs()), c + 1));
    let mean = if count > 0 { sum / count as f64 } else { 0.0 };
    if mean > 0.0 { 0.3 / mean } else { 1.0 }
}

/// The tiling report of a decoded image: a normal map is judged on its
/// R, G, B planes, a height map on its height.
pub fn report_of(
    raster: &Raster,
    kind: KindArg,
    channel: Option<&Channel>,
    opts: &TilingOptions,
) -> normalfit::Result<TilingReport> {
    let (w, h) = (raster.width, raster.height);
    let rgb = rgb_planes(raster)?;
    let kind = kind_of(raster, kind, channel)?;
    let fixed = TilingOptions { kind: kind_choice(kind), ..*opts };
    Ok(match (kind, rgb) {
        (ImageKind::Normal, Some(planes)) => tiling::check(&planes.each_ref().map(Vec::as_slice), w, h, &fixed),
        _ => {
            let heights = raster.heights(channel.cloned())?;
            tiling::check(&[&heights], w, h, &fixed)
        }
    })
}

/// What a decoded image holds: as asked, or detected from its R, G, B
/// planes. Naming a height channel (`channel`) says it is a height map.
pub fn kind_of(raster: &Raster, kind: KindArg, channel: Option<&Channel>) -> normalfit::Result<ImageKind> {
    Ok(match (kind, rgb_planes(raster)?) {
        (KindArg::Height, _) => ImageKind::Height,
        (KindArg::Normal, Some(_)) => ImageKind::Normal,
        (KindArg::Normal, None) => {
            return Err(normalfit::Error::Unsupported("a normal map needs R, G and B channels".into()));
        }
        (KindArg::Auto, Some(planes)) if channel.is_none() => {
            ImageKind::detect(&planes.each_ref().map(Vec::as_slice), raster.width, raster.height)
        }
        (KindArg::Auto, _) => ImageKind::Height,
    })
}

fn kind_choice(kind: ImageKind) -> KindChoice {
    match kind {
        ImageKind::Height => KindChoice::Height,
        ImageKind::Normal => KindChoice::Normal,
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

fn json_line(input: &Input, (w, h): (usize, usize), r: &TilingReport) -> String {
    let axis =
        |a: &tiling::AxisReport| format!("{{\"score\": {}, \"seamless\": {}}}", json_number(a.score), a.seamless);
    format!(
        "{{\"path\": {}, \"width\": {w}, \"height\": {h}, \"kind\": \"{}\", \"x\": {}, \"y\": {}, \"seamless\": {}}}",
        json_string(&input.name().display().to_string()),
        kind_name(r.kind),
        axis(&r.x),
        axis(&r.y),
        r.seamless()
    )
}

/// JSON has no infinities or NaN: they print as null.
fn json_number(v: f64) -> String {
    if v.is_finite() { format!("{v:.4}") } else { "null".into() }
}

fn json_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}
