//! `normalfit check`: a verdict per normal map, as text or JSON Lines, and
//! the repaired maps. The measures and the repair are the library's
//! ([`normalfit::check`]); here are the lines printed, the outputs' names
//! and the exit code.

use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering};

use normalfit::check::{CheckOptions, CheckReport, FixOptions, MapLayout, check_and_fix};
use normalfit::convert::Place;
use normalfit::io::{OutputFormat, SampleType};
use normalfit::tiling::TilingOptions;

use super::args::{CheckArgs, library_message};
use super::batch::{Batch, Job, Outcome, Turn, Words};
use super::exit;
use super::input::{Input, source, stdin_at_most_once};
use super::output::{self, Destination, STDOUT};
use super::report::Failure;
use super::tiling::JsonStyle;

/// The stem ending of repaired maps: `<stem>_fixed.<ext>`.
const SUFFIX: &str = "_fixed";

/// Checks every map. Exit 2 if any could not be checked (or repaired), else
/// 1 if one has a finding, else 0.
pub fn run(args: &CheckArgs) -> Result<u8, Failure> {
    let mut tiling = TilingOptions::default();
    if let Some(t) = args.threshold {
        tiling = tiling.with_threshold(t);
    }
    tiling.validate().map_err(|e| Failure::usage(format!("--{}", library_message(&e))))?;
    let opts = CheckOptions::new().with_convention(args.convention).with_tiling(tiling).with_signed(args.signed);
    stdin_at_most_once(&args.inputs)?;
    let words = Words { done: "checked", purpose: "to check" };
    let batch = Batch::gather(&args.inputs, &args.batch, SUFFIX, words);
    let destination = args.fix.as_deref().map(|p| Destination::for_batch(Some(p), batch.many())).transpose()?;
    let plan = Plan { opts, fix: FixOptions::new().with_to(args.to), destination, args, findings: AtomicUsize::new(0) };
    let errors = batch.run(|job, turn| plan.check_one(job, turn));
    Ok(exit::of_batch(errors, plan.findings.load(Ordering::Relaxed)))
}

struct Plan<'a> {
    opts: CheckOptions,
    fix: FixOptions,
    destination: Option<Destination>,
    args: &'a CheckArgs,
    /// Maps found with a finding so far.
    findings: AtomicUsize,
}

impl Plan<'_> {
    fn check_one(&self, job: &Job, turn: &Turn) -> Result<Outcome, Failure> {
        let input = &job.input;
        let target = self.destination.as_ref().map(|d| {
            let ext = match input {
                Input::File(p) => OutputFormat::from_path(p).ok().flatten().unwrap_or(OutputFormat::Png),
                Input::Stdin => OutputFormat::Png,
            }
            .extension();
            d.path_in(input, &job.subfolder, &format!("{}{SUFFIX}.{ext}", input.stem()))
        });
        if let Some(Some(path)) = &target {
            turn.claim(input, &[path.as_path()])?;
        }
        let mut bytes = Vec::new();
        let src = source(input, &mut bytes)?;
        let mut stdout = None;
        let fix_output = target.as_ref().map(|t| output::file_or_stdout(t.as_deref(), &job.subfolder, &mut stdout));
        let fix = fix_output.map(|o| (&self.fix, o));
        let report = match check_and_fix(src, &self.args.read.options(), &self.opts, fix) {
            Ok(report) => report,
            Err(e) => {
                let at = match (e.place, &target) {
                    (Place::Output, Some(t)) => output::name(t.as_deref()).to_path_buf(),
                    (Place::Output, None) => STDOUT.into(),
                    _ => input.name().to_path_buf(),
                };
                return Err(Failure::file(at, e.error));
            }
        };
        if !report.clean() {
            self.findings.fetch_add(1, Ordering::Relaxed);
        }
        let line = if self.args.json { json_line(input, &report)? } else { text_line(input, &report) };
        // Repaired maps written to standard output take it: no lines then.
        if matches!(target, Some(None)) {
            return Ok(Outcome::Done);
        }
        turn.in_order(|| {
            let mut stdout = std::io::stdout().lock();
            match writeln!(stdout, "{line}").and_then(|()| stdout.flush()) {
                Ok(()) => Ok(Outcome::Done),
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(Outcome::PipeClosed),
                Err(e) => Err(Failure::file(STDOUT, e)),
            }
        })
    }
}

fn storage(sample: SampleType) -> String {
    match sample {
        SampleType::Int { bits } | SampleType::SignedInt { bits } => format!("{bits}-bit"),
        _ => "float".into(),
    }
}

fn text_line(input: &Input, r: &CheckReport) -> String {
    let g = &r.guess;
    let convention = format!("{}{} (confidence {:.2})", g.convention, if g.confident { "" } else { "?" }, g.confidence);
    let findings = r.findings();
    let verdict = if findings.is_empty() {
        "clean".to_string()
    } else {
        findings.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")
    };
    format!(
        "{}: {verdict} ({} {}, {convention}; seams x {:.2}, y {:.2})",
        input.name().display(),
        storage(r.sample),
        if r.layout == MapLayout::Rg { "rg" } else { "rgb" },
        r.tiling.x.score,
        r.tiling.y.score
    )
}

fn json_line(input: &Input, r: &CheckReport) -> Result<String, Failure> {
    let g = &r.guess;
    let value = serde_json::json!({
        "path": input.name().display().to_string(),
        "width": r.width,
        "height": r.height,
        "storage": storage(r.sample),
        "layout": r.layout,
        "length": {"tolerance": r.length_tolerance, "off": r.off_length, "share": r.share(r.off_length)},
        "negative_z": {"count": r.negative_z, "share": r.share(r.negative_z)},
        "convention": g.convention.name(),
        "confident": g.confident,
        "confidence": g.confidence,
        "curl": {"opengl": g.curl[0], "directx": g.curl[1], "scale": g.scale},
        "banding": r.banding,
        "tiling": {"x": r.tiling.x, "y": r.tiling.y, "seamless": r.tiling.seamless()},
        "findings": r.findings().iter().map(|f| f.name()).collect::<Vec<_>>(),
        "clean": r.clean(),
    });
    let mut out = Vec::new();
    serde::Serialize::serialize(&value, &mut serde_json::Serializer::with_formatter(&mut out, JsonStyle))
        .map_err(|e| Failure::file(input.name(), format!("cannot write its JSON line: {e}")))?;
    String::from_utf8(out).map_err(|e| Failure::file(input.name(), format!("cannot write its JSON line: {e}")))
}
