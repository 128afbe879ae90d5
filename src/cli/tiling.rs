//! `normalfit tiling`: a verdict per image and axis, as text or JSON Lines.

use normalfit::io::{Channel, Raster, ReadOptions};
use normalfit::tiling::{self, ImageKind, KindChoice, TilingOptions, TilingReport};

use super::args::{ChannelArg, KindArg, TilingArgs};
use super::exit;
use super::input::{Input, read_input};
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
    let channel = args.channel.map(channel_of);
    let (mut errors, mut seams) = (0, 0);
    for path in &args.inputs {
        let input = Input::from_arg(path);
        match check_one(&input, args.kind, channel, &opts) {
            Ok((raster_size, report)) => {
                if !report.seamless() {
                    seams += 1;
                }
                let line = if args.json { json_line(&input, raster_size, &report) } else { text_line(&input, &report) };
                println!("{line}");
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

pub fn channel_of(c: ChannelArg) -> Channel {
    match c {
        ChannelArg::Luma => Channel::Luma,
        ChannelArg::R => Channel::R,
        ChannelArg::G => Channel::G,
        ChannelArg::B => Channel::B,
        ChannelArg::A => Channel::A,
    }
}

/// Reads one image and checks it.
fn check_one(
    input: &Input,
    kind: KindArg,
    channel: Option<Channel>,
    opts: &TilingOptions,
) -> Result<((usize, usize), TilingReport), Failure> {
    let raster = read_input(input, &ReadOptions::default())?;
    let report = report_of(&raster, kind, channel, opts).map_err(|e| Failure::file(input.name(), e))?;
    Ok(((raster.width, raster.height), report))
}

/// The tiling report of a decoded image: a normal map is judged on its
/// R, G, B planes, a height map on its height.
pub fn report_of(
    raster: &Raster,
    kind: KindArg,
    channel: Option<Channel>,
    opts: &TilingOptions,
) -> normalfit::Result<TilingReport> {
    let (w, h) = (raster.width, raster.height);
    let rgb: Option<[&[f32]; 3]> = match (raster.plane("R"), raster.plane("G"), raster.plane("B")) {
        (Some(r), Some(g), Some(b)) => Some([&r.data, &g.data, &b.data]),
        _ => None,
    };
    let kind = match (kind, rgb) {
        (KindArg::Height, _) => ImageKind::Height,
        (KindArg::Normal, Some(_)) => ImageKind::Normal,
        (KindArg::Normal, None) => {
            return Err(normalfit::Error::Unsupported("a normal map needs R, G and B channels".into()));
        }
        (KindArg::Auto, Some(planes)) if channel.is_none() => ImageKind::detect(&planes, w, h),
        (KindArg::Auto, _) => ImageKind::Height,
    };
    let fixed = TilingOptions { kind: kind_choice(kind), ..opts.clone() };
    Ok(match (kind, rgb) {
        (ImageKind::Normal, Some(planes)) => tiling::check(&planes, w, h, &fixed),
        _ => {
            let heights = raster.heights(channel)?;
            tiling::check(&[&heights], w, h, &fixed)
        }
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
