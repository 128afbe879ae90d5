//! The largest error of a `normalfit` binary's normals against the
//! contract's formula computed in f64, at high gains, on integer ramps:
//! the figures behind "integer samples reach the fit as integers" in the
//! README.
//!
//! ```sh
//! cargo build --release
//! cargo run --release --example precision -- target/release/normalfit
//! ```
//!
//! For a 16-bit ramp around 30000 (3 steps a texel plus grain) and an
//! 8-bit one, each gain, fit and patch size, it runs
//! `BINARY convert ramp.png -s S --signed --fit F -n N --border clamp -o o.exr`
//! and compares every texel of the float EXR with the formula (SPEC §2)
//! evaluated here, plainly, in f64 over the clamped patch.

use std::path::Path;
use std::process::Command;

fn write_png(path: &Path, (w, h): (u32, u32), bits: u8, value: impl Fn(u32, u32) -> u16) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut encoder = png::Encoder::new(file, w, h);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(if bits == 8 { png::BitDepth::Eight } else { png::BitDepth::Sixteen });
    let mut writer = encoder.write_header().unwrap();
    let mut data = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let v = value(x, y);
            if bits == 8 { data.push(v as u8) } else { data.extend(v.to_be_bytes()) }
        }
    }
    writer.write_image_data(&data).unwrap();
}

/// SPEC §2's normal of the patch around (x, y), OpenGL convention, in f64.
fn formula(h: &dyn Fn(i64, i64) -> f64, (x, y): (i64, i64), n: i64, s: f64, orthogonal: bool) -> [f64; 3] {
    let r = n / 2;
    let a = (n * r * (r + 1) * (2 * r + 1)) as f64 / 3.0;
    let (mut sz, mut cx, mut cy, mut szz) = (0.0, 0.0, 0.0, 0.0);
    for j in -r..=r {
        for i in -r..=r {
            let z = s * h(x + i, y + j);
            sz += z;
            cx += i as f64 * z;
            cy += -(j as f64) * z;
            szz += z * z;
        }
    }
    let czz = szz - sz * sz / (n * n) as f64;
    let nz = if orthogonal {
        let d = (a - czz) / 2.0;
        let q = (d * d + cx * cx + cy * cy).sqrt();
        if d >= 0.0 { d + q } else { (cx * cx + cy * cy) / (q - d) }
    } else {
        a
    };
    let len = (cx * cx + cy * cy + nz * nz).sqrt();
    [-cx / len, -cy / len, nz / len]
}

fn main() {
    let binary = std::env::args().nth(1).expect("usage: precision PATH-TO-NORMALFIT");
    let dir = std::env::temp_dir().join(format!("normalfit-precision-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (w, h) = (256u32, 16u32);
    for (bits, base, per_texel) in [(16u8, 30000u32, 3u32), (8, 40, 1)] {
        let top = f64::from((1u32 << bits) - 1);
        // 8-bit: half a step a texel, so the ramp stays below 255.
        let value = move |x: u32, y: u32| {
            let along = if bits == 8 { x / 2 } else { per_texel * x };
            (base + along + (x * 7 + y * 3) % 5) as u16
        };
        let input = dir.join(format!("ramp{bits}.png"));
        write_png(&input, (w, h), bits, value);
        let height = |x: i64, y: i64| {
            let (x, y) = (x.clamp(0, i64::from(w) - 1) as u32, y.clamp(0, i64::from(h) - 1) as u32);
            f64::from(value(x, y)) / top
        };
        for s in [1000.0, 5000.0, 1e5] {
            for (fit, orthogonal) in [("orthogonal", true), ("vertical", false)] {
                for n in [3i64, 63] {
                    let out = dir.join("o.exr");
                    let status = Command::new(&binary)
                        .args(["convert", input.to_str().unwrap(), "-s", &s.to_string(), "--signed"])
                        .args(["--fit", fit, "-n", &n.to_string(), "--border", "clamp", "-o", out.to_str().unwrap()])
                        .status()
                        .unwrap();
                    assert!(status.success(), "{binary} failed");
                    let raster = normalfit::io::read_path(&out, &Default::default()).unwrap();
                    let planes = ["R", "G", "B"].map(|c| raster.plane(c).unwrap().data.to_f32().unwrap());
                    let mut worst = 0.0f64;
                    for y in 0..i64::from(h) {
                        for x in 0..i64::from(w) {
                            let want = formula(&height, (x, y), n, s, orthogonal);
                            let k = (y * i64::from(w) + x) as usize;
                            for c in 0..3 {
                                worst = worst.max((f64::from(planes[c][k]) - want[c]).abs());
                            }
                        }
                    }
                    println!("{bits:>2}-bit  S = {s:<6}  {fit:<10}  N = {n:<2}  largest error {worst:.2e}");
                }
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
