//! The README's pictures of mip chains, from the gallery's rock
//! (`docs/gallery/rock.png`, 256², made by `make_samples`) at the gallery's
//! gain (`-s 8`):
//!
//! * `docs/gallery/rock_mips.png`: the chain `--mips fit` makes, level 0
//!   (256²) down to 1 × 1, side by side as texture viewers show a chain,
//!   the normals' colours as an 8-bit normal map stores them;
//! * `docs/gallery/rock_fit_average.png`: level 3 (32²) lit from the
//!   top-left (`normalfit shade`'s light), magnified 8 times: on the left
//!   as `--mips fit` makes it (the fit of the heights box-filtered to
//!   32²), on the right as averaging the finest normals makes it (the
//!   renormalised mean, `--mips average` of the level-0 normal map, what
//!   mip tools do). It prints the mean angle between the two and their
//!   mean slopes.
//!
//! ```text
//! cargo run --release --example mip_gallery
//! ```

use std::path::Path;

use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use normalfit::mips::{average_chain, fit_chain};
use normalfit::shade::{Light, shade};
use normalfit::{Convention, Options, Strength};

/// The level compared.
const LEVEL: usize = 3;
/// How much it is magnified.
const ZOOM: usize = 8;
/// Texels between the pictures, and their grey.
const GAP: usize = 4;
const BACKGROUND: u8 = 255;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let gallery = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs").join("gallery");
    let raster = normalfit::io::read_path(&gallery.join("rock.png"), &Default::default())?;
    let (w, h) = (raster.width, raster.height);
    let heights = raster.heights(None)?;
    let opts = Options::new().with_strength(Strength::Scale(8.0));
    let fitted = fit_chain(&heights, (w, h), &opts)?;
    let averaged = average_chain(&fitted[0].texels, (w, h))?;

    // The chain in a row, top-aligned.
    let width = fitted.iter().map(|l| l.width).sum::<usize>() + GAP * (fitted.len() - 1);
    let mut row = vec![BACKGROUND; width * h * 3];
    let mut left = 0;
    for level in &fitted {
        for (t, n) in level.texels.iter().enumerate() {
            let (x, y) = (left + t % level.width, t / level.width);
            let rgb = n.map(|c| ((f64::from(c) + 1.0) * 127.5).round() as u8);
            row[3 * (y * width + x)..][..3].copy_from_slice(&rgb);
        }
        left += level.width + GAP;
    }
    write_png(&gallery.join("rock_mips.png"), &row, (width, h), ExtendedColorType::Rgb8)?;

    // Level 3 by both ways, lit and magnified.
    let (fit, average) = (&fitted[LEVEL], &averaged[LEVEL]);
    let (lw, lh) = (fit.width, fit.height);
    let lit = |texels: &[[f32; 3]]| shade(texels, lw, lh, Light::default(), Convention::OpenGl);
    let pictures = [lit(&fit.texels)?, lit(&average.texels)?];
    let (side, tall) = (lw * ZOOM, lh * ZOOM);
    let width = 2 * side + ZOOM * GAP;
    let mut pair = vec![BACKGROUND; width * tall];
    for (p, grey) in pictures.iter().enumerate() {
        for y in 0..tall {
            for x in 0..side {
                pair[y * width + p * (side + ZOOM * GAP) + x] = grey[(y / ZOOM) * lw + x / ZOOM];
            }
        }
    }
    write_png(&gallery.join("rock_fit_average.png"), &pair, (width, tall), ExtendedColorType::L8)?;

    let angle = |a: [f32; 3], b: [f32; 3]| {
        let dot: f64 = (0..3).map(|c| f64::from(a[c]) * f64::from(b[c])).sum();
        dot.clamp(-1.0, 1.0).acos().to_degrees()
    };
    let slope = |n: &[f32; 3]| f64::from(n[2]).clamp(-1.0, 1.0).acos().to_degrees();
    let count = (lw * lh) as f64;
    let mean_angle = fit.texels.iter().zip(&average.texels).map(|(&a, &b)| angle(a, b)).sum::<f64>() / count;
    let fit_slope = fit.texels.iter().map(slope).sum::<f64>() / count;
    let average_slope = average.texels.iter().map(slope).sum::<f64>() / count;
    println!(
        "level {LEVEL} ({lw} × {lh}): fit and average {mean_angle:.2}° apart on average; \
         mean slope {fit_slope:.2}° fitted, {average_slope:.2}° averaged"
    );
    Ok(())
}

/// Writes 8-bit samples as a PNG, deflated hard (the pictures are
/// committed).
fn write_png(path: &Path, bytes: &[u8], (w, h): (usize, usize), color: ExtendedColorType) -> std::io::Result<()> {
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    PngEncoder::new_with_quality(file, CompressionType::Best, FilterType::Adaptive)
        .write_image(bytes, w as u32, h as u32, color)
        .map_err(std::io::Error::other)?;
    println!("wrote {}", path.display());
    Ok(())
}
