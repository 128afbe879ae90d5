//! The cost of `normalfit::curvature` in-process, against the patch size:
//! float heights (f32) or 16-bit integers, every N given, user seconds of
//! the process and wall seconds of each call (the figures of
//! docs/curvature.md's "What it costs").
//!
//! ```sh
//! cargo run --release --example curvature_cost -- 4096 f32 3 5 9 33 63 255
//! cargo run --release --example curvature_cost -- 4096 u16 3 33
//! ```
//!
//! The heights are a smooth relief with grain (no two rows alike), made
//! here before the clock starts. Only the library's public `curvature` is
//! called, so the same file measures any version of it.

use std::time::Instant;

use normalfit::{Border, Borders, Options, Strength, curvature};

/// The process's user CPU seconds so far (Linux: /proc/self/stat, field 14,
/// in clock ticks of 1/100 s).
fn user_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // Fields after the command name, which ends with ')'.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    rest.split_whitespace().nth(11).and_then(|t| t.parse::<f64>().ok()).map_or(f64::NAN, |t| t / 100.0)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: curvature_cost SIZE f32|u16 N…";
    let size: usize = args.first().and_then(|s| s.parse().ok()).expect(usage);
    let kind = args.get(1).map(String::as_str).expect(usage);
    let patches: Vec<usize> = args[2..].iter().map(|s| s.parse().expect(usage)).collect();
    let (w, h) = (size, size);
    let field = |k: usize| {
        let (x, y) = ((k % w) as f64, (k / w) as f64);
        let grain = ((k.wrapping_mul(2_654_435_761) >> 7) % 1000) as f64 / 1000.0;
        0.5 + 0.3 * (x * 0.013).sin() * (y * 0.011).cos() + 0.1 * (x * 0.21 + y * 0.17).sin() + 0.01 * grain
    };
    let f32s: Vec<f32> = if kind == "f32" { (0..w * h).map(|k| field(k) as f32).collect() } else { Vec::new() };
    let u16s: Vec<u16> =
        if kind == "u16" { (0..w * h).map(|k| (field(k) * 65535.0) as u16).collect() } else { Vec::new() };
    println!("{w}×{h} {kind}: N, user s, wall s");
    for n in patches {
        let opts =
            Options::new().with_patch(n).with_borders(Borders::both(Border::Wrap)).with_strength(Strength::Scale(4.0));
        let (user, wall) = (user_seconds(), Instant::now());
        let k = match kind {
            "f32" => curvature(&f32s, w, h, &opts),
            _ => curvature(&u16s, w, h, &opts),
        }
        .expect("the curvature");
        let (user, wall) = (user_seconds() - user, wall.elapsed().as_secs_f64());
        // Used, so the call is not optimised away.
        let sum: f64 = k.iter().map(|&v| f64::from(v)).sum();
        println!("{n} {user:.2} {wall:.2} (Σ {sum:.3e})");
    }
}
