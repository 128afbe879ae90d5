//! What the N = 3 orthogonal fit's own arithmetic costs at least, for
//! docs/speed.md ("The compute core"): a 4096² image's texels made on all
//! cores without reading any heights, each one's normal from two f64
//! square roots and a division (as the orthogonal fit's closed form takes
//! them), encoded to 8-bit RGB and stored as the fit stores them; then the
//! same loop without the square roots and the division (the encoding and
//! the stores alone). Compiled, as the fit's loops are, for the widest
//! vectors the processor has. Prints the least of REPS runs of each.
//!
//! ```text
//! cargo run --release --example arithmetic_floor -- [SIZE] [REPS]
//! ```

use std::time::Instant;

use normalfit::FromNormal;
use rayon::prelude::*;

/// One row of texels, their normals made from the texel's place.
struct Row<'a> {
    y: usize,
    out: &'a mut [[u8; 3]],
    roots: bool,
}

impl pulp::WithSimd for Row<'_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let Row { y, out, roots } = self;
        let fy = y as f64 * 1e-3;
        for (x, texel) in out.iter_mut().enumerate() {
            let fx = x as f64 * 1e-3;
            let (a, b) = (fx * fx + fy + 1.0, fy * fy + fx + 2.0);
            // Two square roots and a division, or products in their place.
            let (r, q, s) = if roots { (a.sqrt(), b.sqrt(), 1.0 / (a + b)) } else { (a * 0.5, b * 0.5, a * b) };
            *texel = <[u8; 3]>::from_normal([fx * s - 0.5, r * 0.1 - 0.5, q * 0.1 - 0.5]);
        }
    }
}

fn least_ms(image: &mut [[u8; 3]], width: usize, reps: usize, roots: bool) -> f64 {
    (0..reps)
        .map(|_| {
            let start = Instant::now();
            image.par_chunks_mut(width).enumerate().for_each(|(y, out)| {
                pulp::Arch::new().dispatch(Row { y, out, roots });
            });
            std::hint::black_box(&image);
            start.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("SIZE and REPS: numbers")).collect();
    let size = args.first().copied().unwrap_or(4096);
    let reps = args.get(1).copied().unwrap_or(9);
    let mut image = vec![[0u8; 3]; size * size];
    let with = least_ms(&mut image, size, reps, true);
    let without = least_ms(&mut image, size, reps, false);
    let texels = (size * size) as f64;
    println!("{size}², {} threads, least of {reps}", rayon::current_num_threads());
    println!("two square roots and a division, encoded and stored: {with:.1} ms ({:.0} Mtexel/s)", texels / with / 1e3);
    println!(
        "the encoding and the stores alone: {without:.1} ms; the roots and the division: {:.1} ms",
        with - without
    );
}
