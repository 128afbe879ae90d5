//! Criterion benchmark of the compute core: `normals_into` on a 4096²
//! height map of realistic detail, throughput in texels (Melem/s).
//!
//! ```text
//! cargo bench --bench fit                       # everything, ~1–2 minutes
//! cargo bench --bench fit -- --quick            # a few iterations a case
//! cargo bench --bench fit -- '/(3|63)$'         # only N = 3 and N = 63
//! cargo bench --bench fit -- threads            # only the thread scaling
//! NORMALFIT_BENCH_SIZE=1024 cargo bench --bench fit   # a smaller map
//! ```
//!
//! Groups:
//! * `f32` and `u8`: N ∈ {3, 9, 33, 63} × {orthogonal, vertical}, written
//!   to `[f32; 3]` normals or `[u8; 3]` RGB, on rayon's global pool (all
//!   threads, or `RAYON_NUM_THREADS`). Ids read `u8/orthogonal/3`.
//! * `threads`: N = 3, orthogonal, to `[u8; 3]`, on a pool of 1 thread and
//!   on a pool of all threads. Ids read `threads/N3-orthogonal-u8/1`.
//! * `seams`: the tiling check of the same map as a height map, streamed
//!   row by row on one thread (`seams/streamed`, what `convert` runs beside
//!   the fit) and whole on all threads (`seams/whole`, `normalfit tiling`).
//!
//! Each output buffer is allocated and touched once, before timing, and
//! reused by every iteration.

use std::hint::black_box;
use std::sync::OnceLock;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use normalfit::normal_map::KindChoice;
use normalfit::tiling::{HeightSeams, TilingOptions, check};
use normalfit::{Fit, FitRequest, FromNormal, Options, Strength};

/// Side of the square height map; `NORMALFIT_BENCH_SIZE` overrides it.
const SIZE: usize = 4096;
/// The patch sizes measured.
const PATCHES: [usize; 4] = [3, 9, 33, 63];
/// z = 40 · h: steep enough that the normals lean well away from +z.
const STRENGTH: f64 = 40.0;

/// The map's side and its heights, made once and shared by every group.
fn input() -> (usize, &'static [f32]) {
    static INPUT: OnceLock<(usize, Vec<f32>)> = OnceLock::new();
    let (n, h) = INPUT.get_or_init(|| {
        let n = std::env::var("NORMALFIT_BENCH_SIZE").ok().and_then(|s| s.parse().ok()).filter(|&n| n >= 64);
        let n = n.unwrap_or(SIZE);
        (n, heights(n))
    });
    (*n, h)
}

/// A deterministic `n` × `n` height map in [0, 1]: five octaves of plane
/// waves in various directions (wavelengths 1024 down to 8 texels, each
/// half the amplitude of the last) plus a little hashed white noise.
///
/// A wave sin(kx·x + ky·y + φ) is sin(u)·cos(v) + cos(u)·sin(v), so each
/// octave needs only per-column and per-row tables.
fn heights(n: usize) -> Vec<f32> {
    use std::f64::consts::TAU;
    // (wavelength in texels, direction in radians, amplitude)
    let waves: [(f64, f64, f64); 5] =
        [(1024.0, 0.3, 1.0), (256.0, 1.9, 0.5), (64.0, 4.0, 0.25), (24.0, 2.7, 0.125), (8.0, 5.5, 0.0625)];
    let tables: Vec<_> = waves
        .iter()
        .enumerate()
        .map(|(k, &(wavelength, angle, amplitude))| {
            let (kx, ky) = (TAU / wavelength * angle.cos(), TAU / wavelength * angle.sin());
            let phase = k as f64;
            let col: Vec<(f64, f64)> = (0..n).map(|x| (kx * x as f64 + phase).sin_cos()).collect();
            let row: Vec<(f64, f64)> = (0..n).map(|y| (ky * y as f64).sin_cos()).collect();
            (amplitude, col, row)
        })
        .collect();
    let mut h = vec![0.0f32; n * n];
    for (y, line) in h.chunks_exact_mut(n).enumerate() {
        for (x, v) in line.iter_mut().enumerate() {
            let mut z = 0.0;
            for (amplitude, col, row) in &tables {
                let ((su, cu), (sv, cv)) = (col[x], row[y]);
                z += amplitude * (su * cv + cu * sv);
            }
            z += 0.02 * (hash(x as u64, y as u64) - 0.5);
            *v = z as f32;
        }
    }
    let (lo, hi) = h.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    for v in &mut h {
        *v = ((*v - lo) / (hi - lo)).clamp(0.0, 1.0);
    }
    h
}

/// A uniform value in [0, 1) from a texel's coordinates (splitmix64).
fn hash(x: u64, y: u64) -> f64 {
    let mut z = x.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ y.wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

fn options(n: usize, fit: Fit) -> Options {
    Options::default().with_patch(n).with_fit(fit).with_strength(Strength::Scale(STRENGTH))
}

/// One group: every patch size and fit, into `out` (reused throughout).
fn bench_output<T: FromNormal>(c: &mut Criterion, group: &str, heights: &[f32], n: usize, out: &mut [T]) {
    let mut g = c.benchmark_group(group);
    g.sampling_mode(SamplingMode::Flat);
    g.throughput(Throughput::Elements((n * n) as u64));
    for fit in [Fit::Orthogonal, Fit::Vertical] {
        for patch in PATCHES {
            let opts = options(patch, fit);
            g.bench_with_input(BenchmarkId::new(Fit::name(fit), patch), &opts, |b, opts| {
                b.iter(|| {
                    FitRequest::new(opts).normals_into(black_box(heights), n, n, &mut *out).expect("normals_into");
                    black_box(&mut *out);
                })
            });
        }
    }
    g.finish();
}

fn bench_fit(c: &mut Criterion) {
    let (n, heights) = input();
    // Filled with a non-zero value so the pages are touched before timing.
    let mut f32_out = vec![[1.0f32; 3]; n * n];
    bench_output(c, "f32", heights, n, &mut f32_out);
    drop(f32_out);
    let mut u8_out = vec![[1u8; 3]; n * n];
    bench_output(c, "u8", heights, n, &mut u8_out);
}

/// N = 3, orthogonal, to u8, on 1 thread and on all threads.
fn bench_threads(c: &mut Criterion) {
    let (n, heights) = input();
    let mut out = vec![[1u8; 3]; n * n];
    let opts = options(3, Fit::Orthogonal);
    let all = rayon::ThreadPoolBuilder::new().build().expect("thread pool").current_num_threads();
    let mut counts = vec![1];
    if all > 1 {
        counts.push(all);
    }
    let mut g = c.benchmark_group("threads");
    g.sampling_mode(SamplingMode::Flat);
    g.throughput(Throughput::Elements((n * n) as u64));
    for threads in counts {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
        g.bench_with_input(BenchmarkId::new("N3-orthogonal-u8", threads), &opts, |b, opts| {
            b.iter(|| {
                pool.install(|| FitRequest::new(opts).normals_into(black_box(heights), n, n, &mut out))
                    .expect("normals_into");
                black_box(&mut out);
            })
        });
    }
    g.finish();
}

/// The tiling check of the map, streamed and whole.
fn bench_seams(c: &mut Criterion) {
    let (n, heights) = input();
    let opts = TilingOptions::new().with_kind(KindChoice::Height);
    let mut g = c.benchmark_group("seams");
    g.sampling_mode(SamplingMode::Flat);
    g.throughput(Throughput::Elements((n * n) as u64));
    g.bench_function("streamed", |b| {
        b.iter(|| {
            let mut seams = HeightSeams::new(n, n).unwrap();
            heights.chunks_exact(n).for_each(|row| seams.push_row(black_box(row)).unwrap());
            black_box(seams.finish(&opts).unwrap())
        })
    });
    g.bench_function("whole", |b| b.iter(|| black_box(check(&[black_box(heights)], n, n, &opts).unwrap())));
    g.finish();
}

/// Few samples and short times: one 4096² pass takes a sizeable fraction of
/// a second, so the groups also sample flat (the same iteration count in
/// every sample, one or two a sample here) rather than 1, 2, …, 10 of them. Command-line flags (`--sample-size`, `--measurement-time`,
/// `--warm-up-time`, `--quick`) override these.
fn config() -> Criterion {
    Criterion::default().sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3))
}

criterion_group! {
    name = benches;
    config = config();
    targets = bench_fit, bench_threads, bench_seams
}
criterion_main!(benches);
