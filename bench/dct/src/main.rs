//! The mirror border's transforms along a row of n texels, as the height
//! inverse (src/height/solve.rs) needs them: the even extension's spectrum
//! (a DCT-I of length n) and the odd one's (a DST-I of length n − 2). Each
//! is timed two ways, on the same rows, turn about: realfft's real FFT of
//! the period 2(n − 1) (what the solver does), and rustdct's DCT-I /
//! DST-I. Prints the time per row and checks that both give the same
//! coefficients. Asserts nothing about time.

use std::time::Instant;

use realfft::RealFftPlanner;
use rustdct::DctPlanner;

fn main() {
    for n in [1024usize, 4096, 4097] {
        let rows = (1 << 24) / n;
        let p = 2 * (n - 1);
        let data: Vec<f64> = (0..rows * n).map(|k| ((k * 7919) % 1013) as f64 / 1013.0 - 0.5).collect();
        let mut fft_planner = RealFftPlanner::<f64>::new();
        let r2c = fft_planner.plan_fft_forward(p);
        let mut dct_planner = DctPlanner::<f64>::new();
        let dct1 = dct_planner.plan_dct1(n);
        let dst1 = dct_planner.plan_dst1(n - 2);
        let (mut ext, mut spectrum, mut scratch) =
            (r2c.make_input_vec(), r2c.make_output_vec(), r2c.make_scratch_vec());
        let mut row = vec![0.0; n];
        let mut dct_scratch = vec![0.0; dct1.get_scratch_len().max(dst1.get_scratch_len())];
        let (mut fft_even, mut fft_odd, mut dct_even, mut dct_odd) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut worst = 0.0f64;
        for round in 0..3 {
            let (mut te, mut to, mut de, mut dd) = (0.0, 0.0, 0.0, 0.0);
            for src in data.chunks_exact(n) {
                // Even extension: x[0..n] then x[n−2] down to x[1].
                let t = Instant::now();
                ext[..n].copy_from_slice(src);
                for k in 1..n - 1 {
                    ext[p - k] = src[k];
                }
                r2c.process_with_scratch(&mut ext, &mut spectrum, &mut scratch).unwrap();
                te += t.elapsed().as_secs_f64();
                let even_fft: Vec<f64> = spectrum.iter().map(|c| c.re).collect();

                let t = Instant::now();
                row.copy_from_slice(src);
                dct1.process_dct1_with_scratch(&mut row, &mut dct_scratch);
                de += t.elapsed().as_secs_f64();
                // rustdct's DCT-I is the even extension's FFT over 2 (its
                // ends weighted a half): compare the bins.
                if round == 0 {
                    for (&f, &d) in even_fft.iter().zip(&row) {
                        worst = worst.max((f - 2.0 * d).abs() / (1.0 + f.abs()));
                    }
                }

                // Odd extension: 0, x[1..n−1], 0, then −x[n−2] down to −x[1].
                let t = Instant::now();
                ext[0] = 0.0;
                ext[1..n - 1].copy_from_slice(&src[1..n - 1]);
                ext[n - 1] = 0.0;
                for k in 1..n - 1 {
                    ext[p - k] = -src[k];
                }
                r2c.process_with_scratch(&mut ext, &mut spectrum, &mut scratch).unwrap();
                to += t.elapsed().as_secs_f64();

                let t = Instant::now();
                row[..n - 2].copy_from_slice(&src[1..n - 1]);
                dst1.process_dst1_with_scratch(&mut row[..n - 2], &mut dct_scratch);
                dd += t.elapsed().as_secs_f64();
            }
            if round > 0 {
                fft_even += te;
                fft_odd += to;
                dct_even += de;
                dct_odd += dd;
            }
        }
        let per = |t: f64| t / (2.0 * rows as f64) * 1e6;
        println!(
            "n = {n:5} ({rows} rows, 2 timed rounds): even: realfft {:.2} µs/row, rustdct DCT-I {:.2} ({:.2}×); \
             odd: realfft {:.2}, rustdct DST-I {:.2} ({:.2}×); DCT-I vs FFT bins, worst relative difference {worst:.1e}",
            per(fft_even),
            per(dct_even),
            dct_even / fft_even,
            per(fft_odd),
            per(dct_odd),
            dct_odd / fft_odd
        );
    }
}
