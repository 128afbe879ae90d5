//! The fast fit against the slow reference, and the properties the
//! contract promises (parallel equals serial, wrap commutes with shifts,
//! flat in → flat out, known answers).

use crate::common;

use common::reference;
use normalfit::{Border, Borders, Convention, Fit, FitRequest, Options, Strength, normals};
use proptest::prelude::*;

const BORDERS: [Border; 3] = [Border::Wrap, Border::Clamp, Border::Mirror];

fn max_error(fast: &[[f32; 3]], slow: &[[f64; 3]]) -> (f64, usize) {
    let mut worst = (0.0, 0);
    for (k, (f, s)) in fast.iter().zip(slow).enumerate() {
        for c in 0..3 {
            let e = (f[c] as f64 - s[c]).abs();
            if e > worst.0 {
                worst = (e, k);
            }
        }
    }
    worst
}

fn options_strategy() -> impl Strategy<Value = Options> {
    (
        (1usize..=31).prop_map(|r| 2 * r + 1),
        prop_oneof![Just(Fit::Orthogonal), Just(Fit::Vertical)],
        (0usize..3, 0usize..3),
        prop_oneof![Just(Convention::OpenGl), Just(Convention::DirectX)],
        prop_oneof![(0.05f64..50.0).prop_map(Strength::Scale), (0.001f64..0.3).prop_map(Strength::Relief)],
        any::<bool>(),
    )
        .prop_map(|(n, fit, (bx, by), conv, strength, invert)| {
            Options::new()
                .with_patch(n)
                .with_fit(fit)
                .with_borders(Borders { x: BORDERS[bx], y: BORDERS[by] })
                .with_convention(conv)
                .with_strength(strength)
                .with_invert(invert)
        })
}

fn image_strategy() -> impl Strategy<Value = (usize, usize, Vec<f32>)> {
    prop_oneof![
        Just((1usize, 1usize)),
        (1usize..=40).prop_map(|w| (w, 1)),
        (1usize..=40).prop_map(|h| (1, h)),
        (2usize..=40, 2usize..=40),
    ]
    .prop_flat_map(|(w, h)| (Just(w), Just(h), prop::collection::vec(0.0f32..1.0, w * h)))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn fast_fit_matches_the_reference((w, h, heights) in image_strategy(), opts in options_strategy()) {
        let fast = normals(&heights, w, h, &opts).unwrap();
        let slow = reference::normal_map(&heights, w, h, &opts);
        let (err, at) = max_error(&fast, &slow);
        prop_assert!(err < 1e-5, "error {err:e} at texel {at} of {w}x{h}: fast {:?} slow {:?}", fast[at], slow[at]);
    }

    #[test]
    fn heights_far_from_zero_keep_their_detail(
        (w, h, detail) in image_strategy(),
        offset in -1000.0f32..1000.0,
        opts in options_strategy(),
    ) {
        // Detail of a few hundredths on top of an offset up to ±1000.
        let heights: Vec<f32> = detail.iter().map(|d| offset + 0.05 * d).collect();
        let fast = normals(&heights, w, h, &opts).unwrap();
        let slow = reference::normal_map(&heights, w, h, &opts);
        let (err, at) = max_error(&fast, &slow);
        prop_assert!(err < 1e-5, "error {err:e} at texel {at}");
    }
}

/// A tilted plane z = a·x + b·y has one exact normal everywhere the patch
/// lies inside the image (clamp only distorts the texels near its edges).
/// The fast residual and the normals that come with it.
/// An integer ramp as a terrain or a 16-bit bake stores it: values from
/// `base`, `steps` tenths of a value per texel along an angle, and a
/// little grain; the heights are value / (2^bits − 1), computed plainly in
/// f64 for the reference.
fn integer_ramp(w: usize, h: usize, top: u32, base: u32, steps: u32, angle: usize) -> (Vec<u32>, Vec<f64>) {
    let values: Vec<u32> = (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as u32, (k / w) as u32);
            let along = (x * steps + y * steps * angle as u32 / 4) / 10;
            (base + along + (x * 7 + y * 3) % 3).min(top)
        })
        .collect();
    let heights = values.iter().map(|&v| f64::from(v) / f64::from(top)).collect();
    (values, heights)
}

/// Options for the high-gain ramps: either fit, N = 3 or 63, any borders.
fn high_gain_options(n: usize, fit: Fit, borders: (usize, usize), gain: f64) -> Options {
    Options::new()
        .with_patch(n)
        .with_fit(fit)
        .with_borders(Borders { x: BORDERS[borders.0], y: BORDERS[borders.1] })
        .with_strength(Strength::Scale(gain))
}

/// The fast fit of an integer ramp's samples (`u8` or `u16`, as `to`
/// makes them) against the slow reference of its heights.
fn integer_ramp_matches_the_reference<H: normalfit::Sample>(
    (w, h): (usize, usize),
    top: u32,
    (base, steps, angle): (u32, u32, usize),
    opts: &Options,
    to: impl Fn(u32) -> H,
) -> Result<(), TestCaseError> {
    let (values, heights) = integer_ramp(w, h, top, base, steps, angle);
    let samples: Vec<H> = values.into_iter().map(to).collect();
    let fast = normals(&samples, w, h, opts).unwrap();
    let slow = reference::normal_map(&heights, w, h, opts);
    let (err, at) = max_error(&fast, &slow);
    prop_assert!(err < 1e-5, "error {err:e} at texel {at} of {w}x{h}: fast {:?} slow {:?}", fast[at], slow[at]);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    // SPEC's 1e-5 at any gain up to 10⁵ for integer heights: the samples
    // reach the fit as integers and 1/(2^bits − 1) goes into the gain in
    // f64. (Heights rounded to f32 as value / 65535 first were off by
    // 1.4e-5 at S = 1000 and 2e-4 at S = 10⁵ on such ramps.)
    #[test]
    fn sixteen_bit_ramps_at_high_gain_match_the_reference(
        size in (1usize..=72, 1usize..=12),
        ramp in (0u32..60000, 1u32..40, 0usize..4),
        n in prop_oneof![Just(3usize), Just(63)],
        fit in prop_oneof![Just(Fit::Orthogonal), Just(Fit::Vertical)],
        borders in (0usize..3, 0usize..3),
        gain in prop_oneof![Just(1e5), 100.0f64..1e5],
    ) {
        let opts = high_gain_options(n, fit, borders, gain);
        integer_ramp_matches_the_reference(size, 65535, ramp, &opts, |v| v as u16)?;
    }

    #[test]
    fn eight_bit_ramps_at_high_gain_match_the_reference(
        size in (1usize..=72, 1usize..=12),
        ramp in (0u32..200, 1u32..20, 0usize..4),
        n in prop_oneof![Just(3usize), Just(63)],
        fit in prop_oneof![Just(Fit::Orthogonal), Just(Fit::Vertical)],
        borders in (0usize..3, 0usize..3),
        gain in prop_oneof![Just(1e5), 100.0f64..1e5],
    ) {
        let opts = high_gain_options(n, fit, borders, gain);
        integer_ramp_matches_the_reference(size, 255, ramp, &opts, |v| v as u8)?;
    }
}

/// The same ramp as u16 samples, as f64 heights and as f32 heights: the
/// integers and f64 give the formula's normals at a gain of 10⁵, f32
/// heights (value / 65535 rounded) do not: the test can tell them apart.
#[test]
fn integers_keep_what_f32_heights_lose_at_high_gain() {
    let (w, h) = (64, 4);
    let (values, heights) = integer_ramp(w, h, 65535, 30000, 30, 0);
    let samples: Vec<u16> = values.iter().map(|&v| v as u16).collect();
    let rounded: Vec<f32> = heights.iter().map(|&v| v as f32).collect();
    let opts = high_gain_options(3, Fit::Orthogonal, (1, 1), 1e5);
    let slow = reference::normal_map(&heights, w, h, &opts);
    let (from_integers, _) = max_error(&normals(&samples, w, h, &opts).unwrap(), &slow);
    let (from_f64, _) = max_error(&normals(&heights, w, h, &opts).unwrap(), &slow);
    let (from_f32, _) = max_error(&normals(&rounded, w, h, &opts).unwrap(), &slow);
    assert!(from_integers < 1e-6 && from_f64 < 1e-6, "{from_integers:e} {from_f64:e}");
    assert!(from_f32 > 1e-5, "f32 heights should lose precision here: {from_f32:e}");
}

fn residual(heights: &[f32], w: usize, h: usize, opts: &Options) -> (Vec<[f32; 3]>, Vec<f32>) {
    let mut normals = vec![[0.0f32; 3]; w * h];
    let mut residual = vec![0.0f32; w * h];
    FitRequest::new(opts).residual(&mut residual).normals_into(heights, w, h, &mut normals).unwrap();
    (normals, residual)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 150, ..ProptestConfig::default() })]

    /// The residual from the sums against distances measured point by
    /// point from the reference's plane; the normals that come with it are
    /// those of `normals`, bit for bit.
    #[test]
    fn fast_residual_matches_the_reference((w, h, heights) in image_strategy(), opts in options_strategy()) {
        let (with_residual, fast) = residual(&heights, w, h, &opts);
        prop_assert!(with_residual == normals(&heights, w, h, &opts).unwrap());
        let tolerance = 1e-5 * (1.0 + reference::gain(&opts, w).abs());
        for y in 0..h {
            for x in 0..w {
                let slow = reference::residual_at(&heights, w, h, &opts, x, y);
                let got = f64::from(fast[y * w + x]);
                prop_assert!((got - slow).abs() <= tolerance, "({x}, {y}) of {w}x{h}: fast {got} slow {slow}");
            }
        }
    }
}

/// A tilted plane leaves no residual; adding a checkerboard of amplitude a
/// leaves a known one. On an odd patch the checkerboard (±a) is
/// uncorrelated with u and v, so the least-squares plane is the plane
/// itself and the residual is the checkerboard less its mean, ±a/N²:
/// RMS = a·√(1 − 1/N⁴), in surface units S·a. The orthogonal fit gives the
/// same on an untilted plane and less on a tilted one (perpendicular
/// distances are shorter than vertical ones, by about cos θ).
#[test]
fn a_plane_has_no_residual_and_a_checkerboard_its_known_one() {
    let (w, h) = (40, 30);
    let scale = 4.0;
    for n in [3usize, 5, 9, 15] {
        let r = n / 2;
        let n4 = (n * n * n * n) as f64;
        for slope in [0.0f32, 0.02, 0.07] {
            for amplitude in [0.0f32, 0.01, 0.03] {
                let heights: Vec<f32> = (0..w * h)
                    .map(|k| {
                        let (x, y) = (k % w, k / w);
                        let checker = if (x + y) % 2 == 0 { amplitude } else { -amplitude };
                        0.3 + slope * x as f32 - 0.5 * slope * y as f32 + checker
                    })
                    .collect();
                let base = Options::new()
                    .with_patch(n)
                    .with_borders(Borders::both(Border::Clamp))
                    .with_strength(Strength::Scale(scale));
                let vertical = residual(&heights, w, h, &base.clone().with_fit(Fit::Vertical)).1;
                let orthogonal = residual(&heights, w, h, &base.clone().with_fit(Fit::Orthogonal)).1;
                // Interior texels: their patches are the plane and checkerboard unbroken.
                for y in r..h - r {
                    for x in r..w - r {
                        let k = y * w + x;
                        let what = format!("N {n} slope {slope} amplitude {amplitude} at ({x}, {y})");
                        let known = scale * f64::from(amplitude) * (1.0 - 1.0 / n4).sqrt();
                        assert!((f64::from(vertical[k]) - known).abs() < 2e-6, "{what}: vertical {}", vertical[k]);
                        if slope == 0.0 {
                            assert!((f64::from(orthogonal[k]) - known).abs() < 2e-6, "{what}: {}", orthogonal[k]);
                        } else {
                            let slow = reference::residual_at(&heights, w, h, &base, x, y);
                            assert!(
                                (f64::from(orthogonal[k]) - slow).abs() < 2e-6,
                                "{what}: {} vs {slow}",
                                orthogonal[k]
                            );
                            if amplitude > 0.0 {
                                assert!(orthogonal[k] < vertical[k], "{what}");
                                // tan θ = S·slope·√(1 + 1/4) on this plane.
                                let tan = scale * f64::from(slope) * 1.25f64.sqrt();
                                let cos = 1.0 / (1.0 + tan * tan).sqrt();
                                let ratio = f64::from(orthogonal[k]) / known;
                                assert!((ratio - cos).abs() < 0.02, "{what}: ratio {ratio} vs cos θ {cos}");
                            }
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn residual_buffers_of_the_wrong_size_are_errors() {
    let heights = vec![0.5f32; 12];
    let mut normals = vec![[0.0f32; 3]; 12];
    let mut short = vec![0.0f32; 11];
    let e =
        FitRequest::new(&Options::new()).residual(&mut short).normals_into(&heights, 4, 3, &mut normals).unwrap_err();
    assert!(matches!(e, normalfit::Error::BufferSize { expected: 12, actual: 11 }), "{e:?}");
}

#[test]
fn tilted_plane_gives_its_exact_normal() {
    let (w, h) = (40, 30);
    let (a, b) = (0.3, -0.2); // heights per texel
    let heights: Vec<f32> = (0..w * h).map(|k| (a * (k % w) as f64 + b * (k / w) as f64) as f32 + 2.0).collect();
    for n in [3, 5, 9, 15] {
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            for conv in [Convention::OpenGl, Convention::DirectX] {
                let opts = Options::new()
                    .with_patch(n)
                    .with_fit(fit)
                    .with_convention(conv)
                    .with_borders(Borders::both(Border::Clamp));
                let out = normals(&heights, w, h, &opts).unwrap();
                // Surface z = a·u + b·row; with v = σ·row, ∂z/∂v = σ·b.
                let sigma = if conv == Convention::OpenGl { -1.0 } else { 1.0 };
                let raw = [-a, -sigma * b, 1.0];
                let len = (raw[0] * raw[0] + raw[1] * raw[1] + 1.0f64).sqrt();
                let want = raw.map(|c| c / len);
                let r = n / 2;
                for y in r..h - r {
                    for x in r..w - r {
                        let got = out[y * w + x];
                        for c in 0..3 {
                            assert!(
                                (got[c] as f64 - want[c]).abs() < 1e-6,
                                "n={n} {fit:?} {conv:?} at ({x},{y}): {got:?} vs {want:?}"
                            );
                        }
                    }
                }
            }
        }
    }
}

/// A bump: right of it the surface falls to the right, so red > 0.5;
/// above it (smaller rows) the surface falls upward, so OpenGL green > 0.5
/// there and DirectX green < 0.5.
#[test]
fn bump_lights_red_on_its_right_and_green_above_it() {
    let (w, h) = (33, 33);
    let heights: Vec<f32> = (0..w * h)
        .map(|k| {
            let (dx, dy) = ((k % w) as f32 - 16.0, (k / w) as f32 - 16.0);
            (-(dx * dx + dy * dy) / 30.0).exp()
        })
        .collect();
    for fit in [Fit::Orthogonal, Fit::Vertical] {
        let gl: Vec<[u8; 3]> = encoded(&heights, w, h, &Options::new().with_fit(fit));
        let dx: Vec<[u8; 3]> =
            encoded(&heights, w, h, &Options::new().with_fit(fit).with_convention(Convention::DirectX));
        let right = 16 * w + 20;
        let above = 12 * w + 16;
        assert!(gl[right][0] > 128 && gl[right][1] == 128, "right of bump: {:?}", gl[right]);
        assert!(gl[above][1] > 128 && gl[above][0] == 128, "above bump, OpenGL: {:?}", gl[above]);
        assert!(dx[above][1] < 128, "above bump, DirectX: {:?}", dx[above]);
        assert_eq!(gl[16 * w + 16], [128, 128, 255], "the top of the bump is flat");
    }
}

fn encoded(heights: &[f32], w: usize, h: usize, opts: &Options) -> Vec<[u8; 3]> {
    let mut out = vec![[0u8; 3]; w * h];
    FitRequest::new(opts).normals_into(heights, w, h, &mut out).unwrap();
    out
}

/// Flat in, flat out: any constant height, any options.
#[test]
fn constant_heights_give_flat_normals() {
    for (w, h) in [(1, 1), (7, 1), (1, 9), (70, 50)] {
        for value in [0.0f32, 0.5, -812.25, 3.0e38] {
            for n in [3, 7, 63] {
                let heights = vec![value; w * h];
                let opts = Options::new().with_patch(n).with_strength(Strength::Scale(40.0));
                let out = encoded(&heights, w, h, &opts);
                assert!(out.iter().all(|&t| t == [128, 128, 255]), "{w}x{h} value {value} n {n}");
            }
        }
    }
}

fn random_heights(w: usize, h: usize, seed: u64) -> Vec<f32> {
    let mut s = seed;
    (0..w * h)
        .map(|_| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        })
        .collect()
}

/// Wrapping makes the fit commute with circular shifts of the image.
#[test]
fn wrap_commutes_with_circular_shifts() {
    let (w, h) = (150, 90); // larger than one tile, so tile seams are crossed
    let heights = random_heights(w, h, 7);
    for n in [3, 9, 31] {
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            let opts = Options::new().with_patch(n).with_fit(fit).with_strength(Strength::Scale(8.0));
            let base = normals(&heights, w, h, &opts).unwrap();
            let (sx, sy) = (37, 71);
            let shifted: Vec<f32> = (0..w * h).map(|k| heights[((k / w + sy) % h) * w + (k % w + sx) % w]).collect();
            let out = normals(&shifted, w, h, &opts).unwrap();
            for (k, got) in out.iter().enumerate() {
                let from = ((k / w + sy) % h) * w + (k % w + sx) % w;
                for c in 0..3 {
                    assert!((got[c] - base[from][c]).abs() < 1e-6, "n {n} {fit:?} texel {k}");
                }
            }
        }
    }
}

/// The output is the same bit for bit whatever the number of threads.
#[test]
fn parallel_equals_serial_bit_for_bit() {
    let (w, h) = (301, 517); // several tiles each way, odd sizes
    let heights: Vec<f32> = random_heights(w, h, 3).iter().map(|v| 500.0 + v).collect();
    for n in [3, 15, 63] {
        let opts = Options::new()
            .with_patch(n)
            .with_strength(Strength::Scale(40.0))
            .with_borders(Borders { x: Border::Mirror, y: Border::Wrap });
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| normals(&heights, w, h, &opts).unwrap())
        };
        let serial = run(1);
        for threads in [2, 3, 8] {
            let par = run(threads);
            assert!(
                serial.iter().zip(&par).all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)),
                "n {n}, {threads} threads"
            );
        }
    }
}

/// Images wider than one parallel strip of the fit (about 512 columns, in
/// whole segments of max(8N, 64)), with a last strip cut short, against
/// the reference: normals and residuals at every texel of every strip edge
/// and of a sample in between, all borders.
#[test]
fn wide_images_cut_into_strips_match_the_reference() {
    for (w, h, n) in [(1100, 7, 3), (1300, 5, 9), (1111, 4, 63)] {
        let heights = random_heights(w, h, 11);
        for border in BORDERS {
            let opts = Options::new()
                .with_patch(n)
                .with_strength(Strength::Scale(7.0))
                .with_borders(Borders { x: border, y: Border::Wrap });
            let (fast, fast_residual) = residual(&heights, w, h, &opts);
            let edges = [0, 1, 503, 504, 505, 511, 512, 513, 1007, 1008, 1023, 1024, 1025];
            let columns = edges.into_iter().chain((0..w).step_by(37)).chain([w - 2, w - 1]).filter(|&x| x < w);
            for x in columns {
                for y in 0..h {
                    let slow = reference::normal_at(&heights, w, h, &opts, x, y);
                    let got = fast[y * w + x];
                    let err = (0..3).map(|c| (f64::from(got[c]) - slow[c]).abs()).fold(0.0, f64::max);
                    assert!(err < 1e-5, "{w}x{h} N {n} {border:?} ({x}, {y}): fast {got:?} slow {slow:?}");
                    let slow = reference::residual_at(&heights, w, h, &opts, x, y);
                    let got = f64::from(fast_residual[y * w + x]);
                    assert!((got - slow).abs() <= 1e-5 * 8.0, "{w}x{h} N {n} residual ({x}, {y}): {got} vs {slow}");
                }
            }
        }
    }
}

/// Bad calls are errors, never panics.
#[test]
fn bad_calls_are_errors() {
    let opts = Options::new();
    assert!(normals::<f32>(&[], 0, 0, &opts).is_err());
    assert!(normals(&[0.0; 5], 2, 3, &opts).is_err());
    let err = normals(&[0.0, 1.0, f32::NAN, 0.0], 2, 2, &opts).unwrap_err();
    assert!(matches!(err, normalfit::Error::NonFiniteHeight { x: 0, y: 1 }), "{err}");
    assert!(normals(&[0.0; 4], 2, 2, &opts.clone().with_patch(4)).is_err());
    let mut short = vec![[0u8; 3]; 3];
    assert!(FitRequest::new(&opts).normals_into(&[0.0; 4], 2, 2, &mut short).is_err());
}

/// Finite heights of extreme size never turn into NaN normals.
#[test]
fn extreme_heights_stay_finite() {
    let (w, h) = (20, 20);
    let heights: Vec<f32> = random_heights(w, h, 11).iter().map(|v| if *v > 0.5 { 3.0e38 } else { -3.0e38 }).collect();
    for fit in [Fit::Orthogonal, Fit::Vertical] {
        let opts = Options::new().with_fit(fit).with_strength(Strength::Scale(1e30));
        let out = normals(&heights, w, h, &opts).unwrap();
        assert!(out.iter().all(|n| n.iter().all(|c| c.is_finite()) && n[2] >= 0.0));
    }
}

/// Rows and columns where the fit's work is cut, for an image `w` wide and
/// patch `n`, from the rules in `src/fit.rs`'s module docs: the top r rows
/// are a tile of their own, then blocks of max(8N, 64) rows (more, up to
/// 2^14 texels a block, for a narrow image); columns in segments of
/// max(8N, 64). Returned with their neighbours, clipped to the image.
fn cut_lines(w: usize, h: usize, n: usize) -> (Vec<usize>, Vec<usize>) {
    let r = n / 2;
    let tile = (8 * n).max(64);
    let block_rows = tile.max((1usize << 14).div_ceil(w));
    let near = |edges: Vec<usize>, len: usize| -> Vec<usize> {
        let mut lines: Vec<usize> =
            edges.iter().flat_map(|&e| [e.wrapping_sub(1), e, e + 1]).filter(|&k| k < len).collect();
        lines.extend([0, len - 1]);
        lines.sort_unstable();
        lines.dedup();
        lines
    };
    let rows = std::iter::once(r).chain((r..h).step_by(block_rows)).chain([h - r]).collect();
    let cols = (0..w).step_by(tile).chain([w - r]).collect();
    (near(rows, h), near(cols, w))
}

/// Images of a few hundred rows and columns, so that the fit's row blocks
/// and column segments are crossed several times: every odd N from 3 to
/// 33 (`every_n`) or a few, every border pair, both fits, normals and
/// residuals against the slow reference at every texel of the rows next to
/// a block edge (a sample of their columns, the segment edges among them)
/// and at random texels.
fn large_image_matches_the_reference(w: usize, h: usize, every_n: bool, seed: u64) {
    // Noise on a slope, offset from zero: the reference value c each tile
    // subtracts then matters, and the normals lean every way.
    let heights: Vec<f32> = random_heights(w, h, seed)
        .iter()
        .enumerate()
        .map(|(k, v)| 40.0 + 0.002 * (k % w) as f32 - 0.003 * (k / w) as f32 + 0.3 * v)
        .collect();
    let patches: Vec<usize> = if every_n { (3..=33).step_by(2).collect() } else { vec![3, 11, 33] };
    let mut rng = seed;
    let mut next = |below: usize| {
        rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((rng >> 33) as usize) % below
    };
    let mut checked = 0;
    for n in patches {
        let (rows, cols) = cut_lines(w, h, n);
        for fit in [Fit::Orthogonal, Fit::Vertical] {
            for (bx, by) in (0..3).flat_map(|bx| (0..3).map(move |by| (bx, by))) {
                let opts = Options::new()
                    .with_patch(n)
                    .with_fit(fit)
                    .with_borders(Borders { x: BORDERS[bx], y: BORDERS[by] })
                    .with_strength(Strength::Scale(6.0));
                let (fast, fast_residual) = residual(&heights, w, h, &opts);
                let mut texels: Vec<(usize, usize)> = Vec::new();
                for &y in &rows {
                    texels.extend(cols.iter().map(|&x| (x, y)));
                    texels.extend((0..4).map(|_| (next(w), y)));
                }
                for &x in &cols {
                    texels.extend((0..4).map(|_| (x, next(h))));
                }
                texels.extend((0..64).map(|_| (next(w), next(h))));
                let tolerance = 1e-5 * (1.0 + reference::gain(&opts, w).abs());
                for (x, y) in texels {
                    let what = format!("{w}x{h} N {n} {fit:?} {:?} ({x}, {y})", opts.borders);
                    let slow = reference::normal_at(&heights, w, h, &opts, x, y);
                    let got = fast[y * w + x];
                    let err = (0..3).map(|c| (f64::from(got[c]) - slow[c]).abs()).fold(0.0, f64::max);
                    assert!(err < 1e-5, "{what}: fast {got:?} slow {slow:?}");
                    let slow = reference::residual_at(&heights, w, h, &opts, x, y);
                    let got = f64::from(fast_residual[y * w + x]);
                    assert!((got - slow).abs() <= tolerance, "{what} residual: fast {got} slow {slow}");
                    checked += 1;
                }
            }
        }
    }
    // Enough texels that each block edge was seen many times.
    assert!(checked > 1000, "{checked} texels checked");
}

#[test]
fn large_images_crossing_row_blocks_match_the_reference_for_every_n() {
    // N = 3: blocks of 64 rows (eight edges); N = 33: 264 rows (two).
    large_image_matches_the_reference(301, 517, true, 5);
}

#[test]
fn narrow_tall_images_with_taller_blocks_match_the_reference() {
    // 37 columns: blocks of 443 rows (2^14 texels), so edges at r, r + 443, r + 886.
    large_image_matches_the_reference(37, 1003, false, 6);
}

#[test]
fn wide_images_crossing_strips_and_blocks_match_the_reference() {
    // More than one parallel strip (about 512 columns) and several blocks.
    large_image_matches_the_reference(613, 211, false, 7);
}
