//! The round trip's error: a height map and the heights `normalfit height`
//! gave back, compared up to a constant (both made mean 0), as the largest
//! and the RMS difference over the original's range, both in the
//! original's units divided by the gain given (`-s`), which `height -s`
//! undoes:
//!
//! ```sh
//! cargo run --release --example height_error -- h.png back.exr
//! ```

use normalfit::io::{ReadOptions, read_path};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [original, back] = args.as_slice() else {
        return Err("usage: height_error ORIGINAL BACK".into());
    };
    let read = |p: &str| -> Result<Vec<f64>, Box<dyn std::error::Error>> {
        let raster = read_path(p.as_ref(), &ReadOptions::default())?;
        let h = raster.heights(None)?;
        let mean = h.iter().map(|&v| f64::from(v)).sum::<f64>() / h.len() as f64;
        Ok(h.iter().map(|&v| f64::from(v) - mean).collect())
    };
    let (a, b) = (read(original)?, read(back)?);
    if a.len() != b.len() {
        return Err(format!("{original} has {} texels, {back} {}", a.len(), b.len()).into());
    }
    let (lo, hi) = a.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    let max = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    let rms = (a.iter().zip(&b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64).sqrt();
    println!("max {:.3e} rms {:.3e} (of the range)", max / (hi - lo), rms / (hi - lo));
    Ok(())
}
