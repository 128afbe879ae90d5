//! Benchmark peer for `bench/compare.sh`: a tangent-space normal map with
//! imageproc's Sobel kernels.
//!
//!     imageproc-normals IN.png OUT.png S
//!
//! Reads a gray height map (16-bit stays 16-bit: imageproc's
//! `gradients::horizontal_sobel` takes 8-bit images only, so this runs the
//! same `kernel::SOBEL_*_3X3` kernels through `filter::filter_clamped_parallel`
//! on the 16-bit image; clamp-to-edge borders). With h = value / max and the
//! Sobel sums divided by 8 (the slope per texel), the normal is
//! (−S·∂h/∂x, +S·∂h/∂row, 1) normalised (OpenGL, green up), written as
//! round(255 · (n + 1) / 2) in an 8-bit RGB PNG.
//!
//!     imageproc-normals --reencode IN.png OUT.png
//!
//! Reads any PNG and writes it again with `image`'s default PNG settings
//! (`DynamicImage::save`, as above): the size `compare.sh` measures
//! normalfit's output against.

use image::{ImageBuffer, Luma, RgbImage};
use imageproc::filter::filter_clamped_parallel;
use imageproc::kernel::{SOBEL_HORIZONTAL_3X3, SOBEL_VERTICAL_3X3};
use rayon::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let [flag, input, output] = args.as_slice() {
        if flag == "--reencode" {
            image::open(input)?.save(output)?;
            return Ok(());
        }
    }
    let [input, output, scale] = args.as_slice() else {
        return Err("usage: imageproc-normals IN.png OUT.png SCALE".into());
    };
    let scale: f32 = scale.parse()?;
    let heights: ImageBuffer<Luma<u16>, Vec<u16>> = image::open(input)?.into_luma16();
    let (w, h) = heights.dimensions();
    let gx: ImageBuffer<Luma<i32>, Vec<i32>> =
        filter_clamped_parallel(&heights, SOBEL_HORIZONTAL_3X3);
    let gy: ImageBuffer<Luma<i32>, Vec<i32>> =
        filter_clamped_parallel(&heights, SOBEL_VERTICAL_3X3);
    // Sobel sum / 8 = slope in value units per texel; / 65535 = in [0, 1] heights.
    let k = scale / (8.0 * 65535.0);
    let mut out = RgbImage::new(w, h);
    let (gx, gy) = (gx.as_raw(), gy.as_raw());
    out.par_chunks_mut(3 * w as usize).enumerate().for_each(|(y, row)| {
        let base = y * w as usize;
        for (x, px) in row.chunks_exact_mut(3).enumerate() {
            let nx = -k * gx[base + x] as f32;
            let ny = k * gy[base + x] as f32;
            let inv = 1.0 / (nx * nx + ny * ny + 1.0).sqrt();
            let enc = |c: f32| (127.5 * (c * inv + 1.0)).round() as u8;
            px[0] = enc(nx);
            px[1] = enc(ny);
            px[2] = enc(1.0);
        }
    });
    out.save(output)?;
    Ok(())
}
