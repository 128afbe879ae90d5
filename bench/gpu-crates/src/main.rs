//! BC5 and BC7 encoders compared on normal maps fitted by normalfit: the
//! angular error of the decoded normals against the float normals (mean and
//! 99th percentile, degrees) and the speed on one thread (Mtexel/s).
//!
//! ```sh
//! cargo run --release --manifest-path bench/gpu-crates/Cargo.toml -- samples/rock.png ...
//! ```

#[path = "../../../src/io/gpu/bc4.rs"]
#[allow(dead_code)]
mod bc4;

use std::time::Instant;

use block_compression::{BC7Settings, CompressionVariant};
use normalfit::io::{ReadOptions, read_path};
use normalfit::{Options, normals};

/// Normals padded to a multiple of 4 by repeating the edge.
struct Map {
    w: usize,
    h: usize,
    n: Vec<[f32; 3]>,
}

fn pad(n: &[[f32; 3]], w: usize, h: usize) -> Map {
    let (pw, ph) = (w.div_ceil(4) * 4, h.div_ceil(4) * 4);
    let mut out = Vec::with_capacity(pw * ph);
    for y in 0..ph {
        for x in 0..pw {
            out.push(n[y.min(h - 1) * w + x.min(w - 1)]);
        }
    }
    Map { w: pw, h: ph, n: out }
}

fn code(c: f32) -> f32 {
    (c + 1.0) * 127.5
}

fn u8_of(c: f32) -> u8 {
    code(c).round().clamp(0.0, 255.0) as u8
}

/// Angle in degrees between a unit normal and the one rebuilt from x, y
/// codes (z = √(1 − x² − y²)).
fn angle_xy(n: [f32; 3], x: f32, y: f32) -> f64 {
    let (x, y) = (f64::from(x) / 127.5 - 1.0, f64::from(y) / 127.5 - 1.0);
    let z = (1.0 - x * x - y * y).max(0.0).sqrt();
    angle(n, [x, y, z])
}

fn angle(n: [f32; 3], m: [f64; 3]) -> f64 {
    let len = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
    let dot = (f64::from(n[0]) * m[0] + f64::from(n[1]) * m[1] + f64::from(n[2]) * m[2]) / len;
    dot.clamp(-1.0, 1.0).acos().to_degrees()
}

fn stats(mut e: Vec<f64>) -> (f64, f64) {
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    e.sort_by(f64::total_cmp);
    (mean, e[((e.len() - 1) as f64 * 0.99).round() as usize])
}

/// Row-major BC blocks → per-texel decoded (x, y) codes for BC5.
fn bc5_errors(map: &Map, blocks: &[u8]) -> Vec<f64> {
    let bw = map.w / 4;
    let mut e = Vec::with_capacity(map.n.len());
    for (b, block) in blocks.chunks_exact(16).enumerate() {
        let (bx, by) = (b % bw, b / bw);
        let xs = bc4::decode_block(block[..8].try_into().unwrap());
        let ys = bc4::decode_block(block[8..].try_into().unwrap());
        for i in 0..16 {
            let (x, y) = (bx * 4 + i % 4, by * 4 + i / 4);
            e.push(angle_xy(map.n[y * map.w + x], xs[i], ys[i]));
        }
    }
    e
}

fn bc7_errors(map: &Map, blocks: &[u8]) -> Vec<f64> {
    let bw = map.w / 4;
    let mut e = Vec::with_capacity(map.n.len());
    for (b, block) in blocks.chunks_exact(16).enumerate() {
        let (bx, by) = (b % bw, b / bw);
        let mut rgba = [0u8; 64];
        block_compression::decode::decode_block_bc7(block, &mut rgba, 16);
        for i in 0..16 {
            let (x, y) = (bx * 4 + i % 4, by * 4 + i / 4);
            let p = &rgba[((i / 4) * 16 + (i % 4) * 4)..][..3];
            let m: [f64; 3] = std::array::from_fn(|c| f64::from(p[c]) / 127.5 - 1.0);
            e.push(angle(map.n[y * map.w + x], m));
        }
    }
    e
}

fn timed<T>(texels: usize, f: impl Fn() -> T) -> (T, f64) {
    // The best of three runs.
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..3 {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (out.unwrap(), texels as f64 / best / 1e6)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let pool = normalfit_one_thread();
    println!("| input | encoder | BC | mean ° | p99 ° | Mtexel/s |");
    println!("|---|---|---|---|---|---|");
    for path in std::env::args().skip(1) {
        let raster = read_path(path.as_ref(), &ReadOptions::default())?;
        let heights = raster.heights(None)?;
        let n = normals(&heights, raster.width, raster.height, &Options::default())?;
        let map = pad(&n, raster.width, raster.height);
        let name = std::path::Path::new(&path).file_name().unwrap().to_string_lossy().into_owned();
        let texels = map.n.len();
        let rg8: Vec<u8> = map.n.iter().flat_map(|t| [u8_of(t[0]), u8_of(t[1])]).collect();
        let rgba8: Vec<u8> = map.n.iter().flat_map(|t| [u8_of(t[0]), u8_of(t[1]), u8_of(t[2]), 255]).collect();
        let rgba8_xy: Vec<u8> = map.n.iter().flat_map(|t| [u8_of(t[0]), u8_of(t[1]), 0, 255]).collect();
        let row = |enc: &str, bc: &str, blocks: &[u8], speed: f64, bc7: bool| {
            let (mean, p99) = stats(if bc7 { bc7_errors(&map, blocks) } else { bc5_errors(&map, blocks) });
            println!("| {name} | {enc} | {bc} | {mean:.3} | {p99:.3} | {speed:.1} |");
        };
        pool.install(|| {
            // 8-bit alone (no block compression), the floor.
            let e: Vec<f64> =
                map.n.iter().map(|t| angle_xy(*t, f32::from(u8_of(t[0])), f32::from(u8_of(t[1])))).collect();
            let (mean, p99) = stats(e);
            println!("| {name} | RG8, no blocks | — | {mean:.3} | {p99:.3} | — |");

            let ours = |from_u8: bool| {
                let mut out = vec![0u8; texels];
                for (b, block) in out.chunks_exact_mut(16).enumerate() {
                    let (bx, by) = (b % (map.w / 4), b / (map.w / 4));
                    for c in 0..2 {
                        let v: [f32; 16] = std::array::from_fn(|i| {
                            let t = map.n[(by * 4 + i / 4) * map.w + bx * 4 + i % 4][c];
                            if from_u8 { f32::from(u8_of(t)) } else { code(t) }
                        });
                        block[c * 8..][..8].copy_from_slice(&bc4::encode_block(&v));
                    }
                }
                out
            };
            let (b, s) = timed(texels, || ours(false));
            row("normalfit bc4.rs, from f32", "BC5", &b, s, false);
            let (b, s) = timed(texels, || ours(true));
            row("normalfit bc4.rs, from 8-bit", "BC5", &b, s, false);

            let (b, s) = timed(texels, || {
                let surface = intel_tex_2::RgSurface {
                    width: map.w as u32,
                    height: map.h as u32,
                    stride: map.w as u32 * 2,
                    data: &rg8,
                };
                intel_tex_2::bc5::compress_blocks(&surface)
            });
            row("intel_tex_2 0.5", "BC5", &b, s, false);

            let (b, s) = timed(texels, || {
                let mut out = vec![0u8; texels];
                block_compression::encode::compress_rgba8(
                    CompressionVariant::BC5,
                    &rgba8_xy,
                    &mut out,
                    map.w as u32,
                    map.h as u32,
                    map.w as u32 * 4,
                );
                out
            });
            row("block_compression 0.11 (CPU)", "BC5", &b, s, false);

            let (b, s) = timed(texels, || {
                let mut out = vec![0u8; texels];
                texpresso::Format::Bc5.compress(&rgba8_xy, map.w, map.h, texpresso::Params::default(), &mut out);
                out
            });
            row("texpresso 2.0", "BC5", &b, s, false);

            for (label, settings, isettings) in [
                ("basic", BC7Settings::opaque_basic(), intel_tex_2::bc7::opaque_basic_settings()),
                ("fast", BC7Settings::opaque_fast(), intel_tex_2::bc7::opaque_fast_settings()),
            ] {
                let (b, s) = timed(texels, || {
                    let surface = intel_tex_2::RgbaSurface {
                        width: map.w as u32,
                        height: map.h as u32,
                        stride: map.w as u32 * 4,
                        data: &rgba8,
                    };
                    intel_tex_2::bc7::compress_blocks(&isettings, &surface)
                });
                row(&format!("intel_tex_2 0.5, {label}"), "BC7", &b, s, true);
                let (b, s) = timed(texels, || {
                    let mut out = vec![0u8; texels];
                    block_compression::encode::compress_rgba8(
                        CompressionVariant::BC7(settings),
                        &rgba8,
                        &mut out,
                        map.w as u32,
                        map.h as u32,
                        map.w as u32 * 4,
                    );
                    out
                });
                row(&format!("block_compression 0.11 (CPU), {label}"), "BC7", &b, s, true);
            }
            // RGB8 alone, the floor of BC7.
            let e: Vec<f64> =
                map.n.iter().map(|t| angle(*t, [0, 1, 2].map(|c| f64::from(u8_of(t[c])) / 127.5 - 1.0))).collect();
            let (mean, p99) = stats(e);
            println!("| {name} | RGB8, no blocks | — | {mean:.3} | {p99:.3} | — |");
        });
    }
    Ok(())
}

/// One thread for every encoder (texpresso's and normalfit's rayon).
fn normalfit_one_thread() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap()
}
