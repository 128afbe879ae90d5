//! The compute core's time by patch size, fit and output, for the ratios
//! of docs/speed.md: `FitRequest::normals_into` on SIZE² float heights
//! (or 16-bit ones with `--u16`) into a kept buffer, each case REPS times;
//! prints one line a case: the least wall time, the least processor time
//! of all the process's threads (from /proc/self/task/*/schedstat, in
//! nanoseconds: under load it moves less than the wall time), Mtexel/s by
//! the wall time, both times over the same output and fit at N = 3, and a
//! digest of the output (two builds that give the same bits print the
//! same digests).
//!
//! ```text
//! cargo run --release --example core_speed -- [SIZE] [REPS] [N,N,...] [--u16] [--geographic]
//! ```
//!
//! `--geographic`: map units as a geographic DEM's (the heights 0 to
//! 250 m, slopes of hills, rows 1/9000° apart from 45.2° N: 11.1 m north to south, about
//! 7.8 m east to west, one spacing a row), the unequal spacing's fit.
//!
//! `bench/core_speed.py` runs two builds of it turn about.

use std::time::Instant;

use std::sync::Arc;

use normalfit::{Fit, FitRequest, FromNormal, Heights, Options, Spacing, Units};

fn main() {
    if let Err(e) = run() {
        eprintln!("core_speed: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let u16_heights = args.iter().any(|a| a == "--u16");
    let geographic = args.iter().any(|a| a == "--geographic");
    let positional: Vec<&String> = args.iter().filter(|a| !a.starts_with("--")).collect();
    let size: usize = positional.first().map_or(Ok(4096), |s| s.parse())?;
    let reps: usize = positional.get(1).map_or(Ok(5), |s| s.parse())?;
    let patches: Vec<usize> = match positional.get(2) {
        Some(list) => list.split(',').map(str::parse).collect::<Result<_, _>>()?,
        None => vec![3, 5, 7, 9, 15, 33, 63],
    };
    let mut floats = heights(size);
    let units = if geographic {
        floats.iter_mut().for_each(|h| *h *= 250.0);
        let metres_per_degree = 111_120.0;
        let rows: Vec<[f64; 2]> = (0..size)
            .map(|y| {
                let latitude = 45.2 - (y as f64 + 0.5) / 9000.0;
                let dy = metres_per_degree / 9000.0;
                [dy * latitude.to_radians().cos(), dy]
            })
            .collect();
        Units::Map(Spacing::Rows(Arc::from(rows)))
    } else {
        Units::Texels
    };
    let integers: Vec<u16> = floats.iter().map(|&h| (h * 65535.0).round() as u16).collect();
    let input = if u16_heights { "u16" } else { "f32" };
    println!("input output fit N wall_ms cpu_ms mtexel_s wall_vs_3 cpu_vs_3 digest");
    for fit in [Fit::Orthogonal, Fit::Vertical] {
        for output in ["u8", "f32"] {
            let mut at_3 = None;
            for &n in &patches {
                let opts = Options::new().with_patch(n).with_fit(fit).with_units(units.clone());
                let (wall, cpu, digest) = match (u16_heights, output) {
                    (false, "u8") => time::<_, [u8; 3]>(&floats[..], size, &opts, reps)?,
                    (false, _) => time::<_, [f32; 3]>(&floats[..], size, &opts, reps)?,
                    (true, "u8") => time::<_, [u8; 3]>(&integers[..], size, &opts, reps)?,
                    (true, _) => time::<_, [f32; 3]>(&integers[..], size, &opts, reps)?,
                };
                if n == 3 {
                    at_3 = Some((wall, cpu));
                }
                let (w3, c3) = at_3.unwrap_or((f64::NAN, f64::NAN));
                let name = if fit == Fit::Orthogonal { "orthogonal" } else { "vertical" };
                let mtexels = (size * size) as f64 / wall / 1e6;
                println!(
                    "{input} {output} {name} {n} {:.1} {:.1} {mtexels:.0} {:.3} {:.3} {digest:016x}",
                    wall * 1e3,
                    cpu * 1e3,
                    wall / w3,
                    cpu / c3
                );
            }
        }
    }
    Ok(())
}

/// The least wall and least processor seconds of `reps` fits of `heights`
/// into one kept buffer (written once before, so no repetition pays its
/// page faults).
fn time<S: Heights + ?Sized, T: FromNormal + Default + Clone + Digest>(
    heights: &S,
    size: usize,
    opts: &Options,
    reps: usize,
) -> Result<(f64, f64, u64), Box<dyn std::error::Error>> {
    let mut out = vec![T::default(); size * size];
    FitRequest::new(opts).normals_into(heights, size, size, &mut out)?;
    let (mut wall, mut cpu) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..reps {
        let (start, start_cpu) = (Instant::now(), process_cpu()?);
        FitRequest::new(opts).normals_into(heights, size, size, &mut out)?;
        wall = wall.min(start.elapsed().as_secs_f64());
        cpu = cpu.min(process_cpu()? - start_cpu);
    }
    let digest = out.iter().fold(0xCBF2_9CE4_8422_2325u64, |h, t| t.digest(h));
    Ok((wall, cpu, digest))
}

/// A texel's bits folded into an FNV-1a digest.
trait Digest {
    fn digest(&self, h: u64) -> u64;
}

fn fold(h: u64, bits: u32) -> u64 {
    (h ^ u64::from(bits)).wrapping_mul(0x0100_0000_01B3)
}

impl Digest for [u8; 3] {
    fn digest(&self, h: u64) -> u64 {
        self.iter().fold(h, |h, &b| fold(h, u32::from(b)))
    }
}

impl Digest for [f32; 3] {
    fn digest(&self, h: u64) -> u64 {
        self.iter().fold(h, |h, &v| fold(h, v.to_bits()))
    }
}

/// Seconds on a processor of every thread of the process so far (the
/// first field of each thread's schedstat, in nanoseconds).
fn process_cpu() -> Result<f64, Box<dyn std::error::Error>> {
    let mut ns = 0u64;
    for task in std::fs::read_dir("/proc/self/task")? {
        let stat = std::fs::read_to_string(task?.path().join("schedstat"))?;
        ns += stat.split_whitespace().next().ok_or("an empty schedstat")?.parse::<u64>()?;
    }
    Ok(ns as f64 * 1e-9)
}

/// A deterministic `n` × `n` height map in [0, 1]: plane waves of
/// wavelengths 1024 down to 8 texels, each half the last's amplitude, and
/// a little hashed noise, so that every patch size sees relief.
fn heights(n: usize) -> Vec<f32> {
    use std::f64::consts::TAU;
    let waves = [(1024.0, 0.3), (256.0, 1.9), (64.0, 4.0), (24.0, 2.7), (8.0, 5.5)];
    let mut h = vec![0.0f32; n * n];
    for (y, row) in h.chunks_exact_mut(n).enumerate() {
        for (x, v) in row.iter_mut().enumerate() {
            let mut z = 0.0;
            let mut amplitude = 1.0;
            for (k, &(wavelength, angle)) in waves.iter().enumerate() {
                let (kx, ky) = (TAU / wavelength * f64::cos(angle), TAU / wavelength * f64::sin(angle));
                z += amplitude * (kx * x as f64 + ky * y as f64 + k as f64).sin();
                amplitude *= 0.5;
            }
            let hash = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
            let noise = (hash >> 40) as f64 / (1u64 << 24) as f64 - 0.5;
            *v = ((z / 2.0 + 0.5) * 0.98 + 0.02 * noise) as f32;
        }
    }
    h
}
