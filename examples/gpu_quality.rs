//! BC5's error and speed on real height maps: the mip chain fitted from
//! each map (`mips::fit_chain`, default options), stored as BC5 by
//! `io::gpu` from the float normals and from the same normals rounded to
//! 8 bits first (as an 8-bit normal map would give them); per level, the
//! angle between each float normal and the normal the shader rebuilds from
//! the decoded x, y (z = √(1 − x² − y²)), mean and 99th percentile, in
//! degrees; and the encoding's speed over the whole chain, in Mtexel/s,
//! on the threads rayon has (`RAYON_NUM_THREADS`). With `--bc7`, BC7's
//! speed too (its error is in `bench/gpu-crates`, which has a BC7 decoder).
//!
//! ```sh
//! cargo run --release --example gpu_quality -- samples/rock.png ../shared/data/tileable/*/*disp*.png
//! ```
//!
//! docs/mips.md ("GPU containers") has the figures it printed.

use std::time::Instant;

use normalfit::Options;
use normalfit::io::gpu::{Chain, Compression, MipLevel, encode_chain};
use normalfit::io::{ReadOptions, read_path};
use normalfit::mips::fit_chain;

/// A BC4 block's 16 values in [0, 255] (Direct3D's float decoding).
fn decode_bc4(block: &[u8]) -> [f64; 16] {
    let (r0, r1) = (f64::from(block[0]), f64::from(block[1]));
    let bits = (0..6).fold(0u64, |bits, i| bits | u64::from(block[2 + i]) << (8 * i));
    std::array::from_fn(|i| match (bits >> (3 * i)) & 7 {
        0 => r0,
        1 => r1,
        k if r0 > r1 => ((8 - k) as f64 * r0 + (k - 1) as f64 * r1) / 7.0,
        6 => 0.0,
        7 => 255.0,
        k => ((6 - k) as f64 * r0 + (k - 1) as f64 * r1) / 5.0,
    })
}

/// Degrees between a unit normal and a decoded one (normalised).
fn angle(n: [f32; 3], m: [f64; 3]) -> f64 {
    let len = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
    let dot = (0..3).map(|c| f64::from(n[c]) * m[c]).sum::<f64>() / len;
    dot.clamp(-1.0, 1.0).acos().to_degrees()
}

/// Mean and 99th percentile.
fn stats(mut e: Vec<f64>) -> (f64, f64) {
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    e.sort_by(f64::total_cmp);
    (mean, e[((e.len() - 1) as f64 * 0.99).round() as usize])
}

/// The angular errors of a BC5 level against its float normals.
fn bc5_errors(bytes: &[u8], level: &MipLevel<[f32; 3]>) -> Vec<f64> {
    let (w, h) = (level.width, level.height);
    let across = w.div_ceil(4);
    let mut errors = Vec::with_capacity(w * h);
    for (b, block) in bytes.chunks_exact(16).enumerate() {
        let (xs, ys) = (decode_bc4(&block[..8]), decode_bc4(&block[8..]));
        for i in 0..16 {
            let (x, y) = ((b % across) * 4 + i % 4, (b / across) * 4 + i / 4);
            if x < w && y < h {
                let (nx, ny) = (xs[i] / 127.5 - 1.0, ys[i] / 127.5 - 1.0);
                let nz = (1.0 - nx * nx - ny * ny).max(0.0).sqrt();
                errors.push(angle(level.texels[y * w + x], [nx, ny, nz]));
            }
        }
    }
    errors
}

/// The chain with every component rounded to 8 bits and back.
fn rounded(chain: &[MipLevel<[f32; 3]>]) -> Vec<MipLevel<[f32; 3]>> {
    chain
        .iter()
        .map(|l| MipLevel {
            width: l.width,
            height: l.height,
            texels: l.texels.iter().map(|n| n.map(|c| ((c + 1.0) * 127.5).round() / 127.5 - 1.0)).collect(),
        })
        .collect()
}

/// The encoding's speed over the whole chain (the best of three), Mtexel/s.
fn speed(chain: &[MipLevel<[f32; 3]>], compression: Compression) -> Result<f64, normalfit::Error> {
    let texels: usize = chain.iter().map(|l| l.texels.len()).sum();
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        encode_chain(Chain::Normals(chain), compression)?;
        best = best.min(t.elapsed().as_secs_f64());
    }
    Ok(texels as f64 / best / 1e6)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let bc7 = args.iter().any(|a| a == "--bc7");
    args.retain(|a| a != "--bc7");
    if args.is_empty() {
        return Err("usage: gpu_quality [--bc7] HEIGHT_MAP...".into());
    }
    println!("threads: {}", rayon_threads());
    for path in &args {
        let raster = read_path(path.as_ref(), &ReadOptions::default())?;
        let heights = raster.heights(None)?;
        let chain = fit_chain(&heights, (raster.width, raster.height), &Options::default())?;
        let eight = rounded(&chain);
        let from_floats = encode_chain(Chain::Normals(&chain), Compression::Bc5)?;
        let from_bytes = encode_chain(Chain::Normals(&eight), Compression::Bc5)?;
        let name = std::path::Path::new(path).file_name().unwrap_or_default().to_string_lossy();
        println!("\n{name}: {} × {}, {} levels", raster.width, raster.height, chain.len());
        println!(
            "| level | size | BC5 from f32: mean ° | p99 ° | BC5 from 8-bit: mean ° | p99 ° | RG8 alone: mean ° | p99 ° |"
        );
        println!("|---|---|---|---|---|---|---|---|");
        for (k, level) in chain.iter().enumerate() {
            let (fm, fp) = stats(bc5_errors(&from_floats.levels[k], level));
            let (bm, bp) = stats(bc5_errors(&from_bytes.levels[k], level));
            let rg8: Vec<f64> = level
                .texels
                .iter()
                .zip(&eight[k].texels)
                .map(|(n, r)| {
                    let (x, y) = (f64::from(r[0]), f64::from(r[1]));
                    angle(*n, [x, y, (1.0 - x * x - y * y).max(0.0).sqrt()])
                })
                .collect();
            let (rm, rp) = stats(rg8);
            println!(
                "| {k} | {} × {} | {fm:.3} | {fp:.3} | {bm:.3} | {bp:.3} | {rm:.3} | {rp:.3} |",
                level.width, level.height
            );
        }
        println!("BC5 encoding, the whole chain: {:.1} Mtexel/s", speed(&chain, Compression::Bc5)?);
        if bc7 {
            println!("BC7 encoding, the whole chain: {:.2} Mtexel/s", speed(&chain, Compression::Bc7)?);
        }
    }
    Ok(())
}

/// The threads the encoders run on.
fn rayon_threads() -> usize {
    std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1))
}
