//! The Rust core's time on the input `bench/bench.py` gives it, timed the
//! way the Python call is, for the Python/Rust ratio of the benchmark.
//!
//! `core_timing HEIGHTS.u16 WIDTH HEIGHT REPS` reads WIDTH × HEIGHT native-endian
//! u16 heights, then per repetition: `normals` (a new, zeroed output, as
//! the Python call allocates one) and a `FitRequest` into a kept buffer (as with
//! `out=`), and prints on one line the median seconds of each, then the
//! least of each (`bench/bench.py` reads the medians, `bench/python_call.py`
//! the least kept time). The kept buffer is written once before the first
//! repetition, so its page faults fall on no repetition, as a Python
//! caller's `out=` written before is.

use std::time::Instant;

use normalfit::{FitRequest, Options, normals};

fn main() {
    if let Err(e) = run() {
        eprintln!("core_timing: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [path, width, height, reps] = args.as_slice() else {
        return Err("usage: core_timing HEIGHTS.u16 WIDTH HEIGHT REPS".into());
    };
    let (width, height, reps): (usize, usize, usize) = (width.parse()?, height.parse()?, reps.parse()?);
    let bytes = std::fs::read(path)?;
    let heights: Vec<u16> = bytes.chunks_exact(2).map(|b| u16::from_ne_bytes([b[0], b[1]])).collect();
    if heights.len() != width * height {
        return Err(format!("{path} holds {} heights, not {width} × {height}", heights.len()).into());
    }
    let opts = Options::new();
    let mut fresh = Vec::new();
    let mut kept = Vec::new();
    let mut buffer = vec![[0.0f32; 3]; width * height];
    FitRequest::new(&opts).normals_into(&heights, width, height, &mut buffer)?;
    for _ in 0..reps {
        let start = Instant::now();
        let n = normals(&heights, width, height, &opts)?;
        fresh.push(start.elapsed().as_secs_f64());
        drop(n);
        let start = Instant::now();
        FitRequest::new(&opts).normals_into(&heights, width, height, &mut buffer)?;
        kept.push(start.elapsed().as_secs_f64());
    }
    let least = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let (least_fresh, least_kept) = (least(&fresh), least(&kept));
    println!("{} {} {least_fresh} {least_kept}", median(&mut fresh), median(&mut kept));
    Ok(())
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
