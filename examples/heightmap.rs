//! Writes a 16-bit gray PNG height map of realistic detail, of any size,
//! for benchmarks and tests; or, named `.exr`, the same heights as a float
//! OpenEXR (channel Y, ZIP compression, scan lines):
//!
//! ```sh
//! cargo run --release --example heightmap -- 4096 /tmp/h4096.png
//! cargo run --release --example heightmap -- 32768 /tmp/h32768.png
//! cargo run --release --example heightmap -- 8192 /tmp/h8192.exr
//! cargo run --release --example heightmap -- 2048x256 /tmp/h2048x256.png
//! ```
//!
//! The field is ridged fractal value noise (8 octaves, periodic, so the map
//! tiles) over broad hills: large forms, sharp creases and texel-scale
//! grain, like an eroded terrain or a rock scan. Its texel steps use the
//! full 16-bit range, so no encoder sees long runs of equal values that
//! would flatter its compression. Rows are computed in parallel and
//! streamed to the PNG encoder in blocks, so memory stays a few rows wide
//! at any size.

use std::fs::File;
use std::io::BufWriter;
use std::io::Write;

use rayon::prelude::*;

/// Rows computed per parallel block.
const BLOCK_ROWS: usize = 64;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [size, path] = args.as_slice() else {
        return Err("usage: heightmap SIZE|WIDTHxHEIGHT OUT.png".into());
    };
    // WIDTHxHEIGHT: the top rows of the WIDTH² map (a strip for the
    // non-square cases of the benchmarks).
    let (size, rows): (usize, usize) = match size.split_once('x') {
        Some((w, h)) => (w.parse()?, h.parse()?),
        None => (size.parse()?, size.parse()?),
    };
    if size == 0 || size > 1 << 16 || rows == 0 || rows > 1 << 16 {
        return Err("SIZE must be 1 … 65536".into());
    }
    let noise = Noise::new(size);
    if path.ends_with(".exr") {
        write_exr(&noise, size, rows, path)?;
        println!("wrote {path}: {size}×{rows} float Y");
        return Ok(());
    }
    let file = BufWriter::with_capacity(1 << 20, File::create(path)?);
    let mut encoder = png::Encoder::new(file, size as u32, rows as u32);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header()?.into_stream_writer()?;
    let mut block = vec![0u8; BLOCK_ROWS * size * 2];
    let height = rows;
    for y0 in (0..height).step_by(BLOCK_ROWS) {
        let rows = BLOCK_ROWS.min(height - y0);
        block[..rows * size * 2].par_chunks_mut(size * 2).enumerate().for_each(|(i, row)| {
            for (x, out) in row.chunks_exact_mut(2).enumerate() {
                let v = noise.height(x, y0 + i);
                out.copy_from_slice(&((v * 65535.0).round() as u16).to_be_bytes());
            }
        });
        writer.write_all(&block[..rows * size * 2])?;
    }
    writer.finish()?;
    println!("wrote {path}: {size}×{height} 16-bit gray");
    Ok(())
}

/// The heights as a float EXR; `exr` asks for the pixels block by block,
/// so the image is never held whole.
fn write_exr(noise: &Noise, size: usize, rows: usize, path: &str) -> Result<(), Box<dyn std::error::Error>> {
    use exr::prelude::*;
    let channels = SpecificChannels::build()
        .with_channel("Y")
        .with_pixel_fn(|p: Vec2<usize>| (noise.height(p.x(), p.y()) as f32,));
    let layer = Layer::new((size, rows), LayerAttributes::default(), Encoding::SMALL_LOSSLESS, channels);
    Image::from_layer(layer).write().to_file(path)?;
    Ok(())
}

/// Periodic fractal noise on a `size`-texel square.
struct Noise {
    size: usize,
    /// Lattice cells across the image at the first octave.
    base_cells: usize,
}

impl Noise {
    fn new(size: usize) -> Self {
        Noise { size, base_cells: 4 }
    }

    /// The height at texel (x, y), in [0, 1].
    fn height(&self, x: usize, y: usize) -> f64 {
        let (u, v) = ((x as f64 + 0.5) / self.size as f64, (y as f64 + 0.5) / self.size as f64);
        let hills = value_noise(u, v, self.base_cells, 1);
        let mut ridges = 0.0;
        let (mut amp, mut total) = (1.0, 0.0);
        let mut cells = self.base_cells * 2;
        for octave in 0..8 {
            // Ridged: 1 − |2n − 1| turns the noise's mid-level into creases.
            let n = value_noise(u, v, cells, 7 + octave);
            ridges += amp * (1.0 - (2.0 * n - 1.0).abs());
            total += amp;
            amp *= 0.5;
            cells *= 2;
        }
        (0.45 * hills + 0.55 * ridges / total).clamp(0.0, 1.0)
    }
}

/// Smooth value noise with `cells` lattice cells per unit, periodic on
/// [0, 1)², seeded by `seed`. In [0, 1].
fn value_noise(u: f64, v: f64, cells: usize, seed: u64) -> f64 {
    let (fx, fy) = (u * cells as f64, v * cells as f64);
    let (ix, iy) = (fx.floor() as usize, fy.floor() as usize);
    let (tx, ty) = (smooth(fx - ix as f64), smooth(fy - iy as f64));
    let at = |i: usize, j: usize| lattice((i % cells) as u64, (j % cells) as u64, seed);
    let top = at(ix, iy) + tx * (at(ix + 1, iy) - at(ix, iy));
    let bottom = at(ix, iy + 1) + tx * (at(ix + 1, iy + 1) - at(ix, iy + 1));
    top + ty * (bottom - top)
}

/// Quintic fade: continuous slope and curvature across lattice cells.
fn smooth(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// A hash of a lattice point, uniform in [0, 1).
fn lattice(i: u64, j: u64, seed: u64) -> f64 {
    let mut h = i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ j.wrapping_mul(0xC2B2_AE3D_27D4_EB4F) ^ seed;
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    h = h.wrapping_mul(0xC4CE_B9FE_1A85_EC53);
    h ^= h >> 33;
    (h >> 11) as f64 / (1u64 << 53) as f64
}
