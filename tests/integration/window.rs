//! Windows of an image (issue 15): any partition of an image into windows,
//! each computed alone from its heights and a halo, gives the whole-image
//! output bit for bit — every sample type, border pair, fit, gain, with
//! and without the residual, windows smaller than the halo included.

use std::ops::Range;

use normalfit::fit::{Halo, HaloPlan, Heights, Window};
use normalfit::{Border, Borders, Error, Fit, FitRequest, FromNormal, Options, Sample, Strength};

const BORDERS: [Border; 3] = [Border::Wrap, Border::Clamp, Border::Mirror];

/// A small deterministic generator (xorshift64*), so failures replay.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Heights in [0, 1] with structure at several scales and noise, so that
/// sums do not cancel to round numbers.
fn field(w: usize, h: usize, rng: &mut Rng) -> Vec<f64> {
    let (fx, fy) = (0.2 + rng.unit(), 0.3 + rng.unit());
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            0.5 + 0.25 * (fx * x + 0.1 * y).sin() * (fy * y).cos() + 0.2 * rng.unit()
        })
        .collect()
}

/// Cuts of 0..len into runs, at random places: runs of one texel (less
/// than any halo) are common, and one run may take the whole axis.
fn cuts(len: usize, rng: &mut Rng) -> Vec<Range<usize>> {
    let mut runs = Vec::new();
    let mut start = 0;
    while start < len {
        let run = match rng.below(4) {
            0 => 1,
            1 => 1 + rng.below(3),
            _ => 1 + rng.below(len),
        };
        let end = (start + run).min(len);
        runs.push(start..end);
        start = end;
    }
    runs
}

/// How a window's halo is held.
#[derive(Clone, Copy, Debug)]
enum Held {
    /// As the library plans it ([`HaloPlan`]): r texels beyond the edge of
    /// an axis that wraps, none beyond the edge of one that clamps or
    /// mirrors, none on an axis the window spans (what `normalfit.dask`
    /// holds).
    Planned,
    /// r texels on every side, those beyond the image's edge filled as the
    /// border gives them (Dask's `periodic` / `nearest`).
    Padded,
    /// r texels where the image goes on, none beyond its edges (Dask's
    /// `none`): the fit maps through the border.
    Clipped,
}

/// The heights a window holds: image texels of columns `xs` and rows `ys`,
/// beyond the edges through the borders.
fn held<H: Copy>(
    heights: &[H],
    (w, h): (usize, usize),
    borders: Borders,
    xs: Range<isize>,
    ys: Range<isize>,
) -> Vec<H> {
    ys.flat_map(|y| {
        let ys = borders.y.map(y, h);
        xs.clone().map(move |x| heights[ys * w + borders.x.map(x, w)])
    })
    .collect()
}

/// The window `xs` × `ys` held as `held` says.
fn window_of(image: (usize, usize), xs: &Range<usize>, ys: &Range<usize>, opts: &Options, held: Held) -> Window {
    let r = opts.patch / 2;
    let halo = match held {
        Held::Planned => {
            return HaloPlan::new(opts).unwrap().window(image, (xs.start, ys.start), (xs.len(), ys.len()));
        }
        Held::Padded => Halo::uniform(r),
        Held::Clipped => Halo {
            left: r.min(xs.start),
            right: r.min(image.0 - xs.end),
            top: r.min(ys.start),
            bottom: r.min(image.1 - ys.end),
        },
    };
    Window { image, origin: (xs.start, ys.start), size: (xs.len(), ys.len()), halo }
}

/// Computes every window of the partition alone and puts the texels
/// together, normals and residual.
fn by_windows<H: Sample>(
    heights: &[H],
    image: (usize, usize),
    opts: &Options,
    partition: (&[Range<usize>], &[Range<usize>]),
    held_as: Held,
) -> (Vec<[f32; 3]>, Vec<f32>) {
    let (w, h) = image;
    let mut normals = vec![[f32::NAN; 3]; w * h];
    let mut residual = vec![f32::NAN; w * h];
    for ys in partition.1 {
        for xs in partition.0 {
            let window = window_of(image, xs, ys, opts, held_as);
            let x0 = xs.start as isize - window.halo.left as isize;
            let y0 = ys.start as isize - window.halo.top as isize;
            let (hw, hh) = window.held_size();
            let values = held(heights, image, opts.borders, x0..x0 + hw as isize, y0..y0 + hh as isize);
            let mut out = vec![[0.0f32; 3]; xs.len() * ys.len()];
            let mut res = vec![0.0f32; xs.len() * ys.len()];
            fit_window(&values, &window, opts, &mut out, Some(&mut res))
                .unwrap_or_else(|e| panic!("window {xs:?} × {ys:?}: {e}"));
            for (k, y) in ys.clone().enumerate() {
                normals[y * w + xs.start..y * w + xs.end].copy_from_slice(&out[k * xs.len()..][..xs.len()]);
                residual[y * w + xs.start..y * w + xs.end].copy_from_slice(&res[k * xs.len()..][..xs.len()]);
            }
        }
    }
    (normals, residual)
}

/// The request's fit of `window` from its held `values`.
fn fit_window<S: Heights + ?Sized, T: FromNormal>(
    values: &S,
    window: &Window,
    opts: &Options,
    out: &mut [T],
    residual: Option<&mut [f32]>,
) -> normalfit::Result<usize> {
    let (hw, hh) = window.held_size();
    let request = FitRequest::new(opts).window(*window);
    match residual {
        Some(r) => request.residual(r).normals_into(values, hw, hh, out),
        None => request.normals_into(values, hw, hh, out),
    }
}

fn whole<H: Sample>(heights: &[H], (w, h): (usize, usize), opts: &Options) -> (Vec<[f32; 3]>, Vec<f32>) {
    let mut normals = vec![[0.0f32; 3]; w * h];
    let mut residual = vec![0.0f32; w * h];
    FitRequest::new(opts).residual(&mut residual).normals_into(heights, w, h, &mut normals).unwrap();
    (normals, residual)
}

fn bits(normals: &[[f32; 3]], residual: &[f32]) -> (Vec<[u32; 3]>, Vec<u32>) {
    (normals.iter().map(|n| n.map(f32::to_bits)).collect(), residual.iter().map(|r| r.to_bits()).collect())
}

/// Every border pair and fit, N = 3, 5 and 9, a scale that is not a power
/// of two and a relief (the whole image's width, not a window's), random
/// partitions held both ways: the same bits as the whole image.
fn partitions_match<H: Sample>(to_sample: impl Fn(f64) -> H, seed: u64) {
    let mut rng = Rng(seed);
    let mut checked = 0;
    for &bx in &BORDERS {
        for &by in &BORDERS {
            for fit in [Fit::Orthogonal, Fit::Vertical] {
                for n in [3, 5, 9] {
                    for strength in [Strength::Scale(3.7 + rng.unit()), Strength::Relief(0.013)] {
                        let (w, h) = (5 + rng.below(30), 3 + rng.below(25));
                        let heights: Vec<H> = field(w, h, &mut rng).into_iter().map(&to_sample).collect();
                        let opts = Options::new()
                            .with_patch(n)
                            .with_fit(fit)
                            .with_borders(Borders { x: bx, y: by })
                            .with_strength(strength);
                        let expected = whole(&heights, (w, h), &opts);
                        for held_as in [Held::Padded, Held::Clipped, Held::Planned] {
                            if matches!(held_as, Held::Clipped) && (bx == Border::Wrap || by == Border::Wrap) {
                                continue; // a wrap reads the far edge: see `a_wrap_needs_its_halo_beyond_the_edge`
                            }
                            let (xs, ys) = (cuts(w, &mut rng), cuts(h, &mut rng));
                            let got = by_windows(&heights, (w, h), &opts, (&xs, &ys), held_as);
                            let what = format!("{w}×{h}, {opts:?}, {held_as:?}, columns {xs:?}, rows {ys:?}");
                            assert_eq!(bits(&got.0, &got.1).0, bits(&expected.0, &expected.1).0, "normals: {what}");
                            assert_eq!(bits(&got.0, &got.1).1, bits(&expected.0, &expected.1).1, "residual: {what}");
                            checked += 1;
                        }
                    }
                }
            }
        }
    }
    assert_eq!(checked, 2 * (3 * 3 * 2 * 3 * 2) + 2 * 2 * 2 * 3 * 2);
}

#[test]
fn any_partition_of_float_heights_gives_the_whole_image_bits() {
    partitions_match(|v| v as f32, 1);
    // Far from zero, where sums of raw heights would lose the detail.
    partitions_match(|v| (300.0 + v) as f32, 2);
    // Magnitudes from 1e-9 to 1e2 side by side: sums of them round in f64.
    partitions_match(|v| (((v - 0.5) * 10.0).powi(5) * 1e-3) as f32, 7);
}

/// Float heights in rows wide enough that the blocked sums (N ≥ 9) sum
/// four whole blocks at once, one a vector lane, against windows narrower
/// than four blocks, whose every block is summed alone: the same bits of
/// f64 normals (which show a sum's last bit more often than f32 ones), for
/// widths that leave blocks cut at both ends, both fits, magnitudes far
/// apart, and a hole.
#[test]
fn blocks_summed_side_by_side_give_the_bits_of_blocks_summed_alone() {
    let mut rng = Rng(11);
    for n in [9, 11, 33] {
        let (w, h) = (9 * n + 5, n + 7);
        for (k, fit) in [Fit::Orthogonal, Fit::Vertical].into_iter().enumerate() {
            let mut heights: Vec<f32> =
                field(w, h, &mut rng).into_iter().map(|v| (((v - 0.5) * 10.0).powi(5) * 1e-3) as f32).collect();
            let nodata = (k == 1).then(|| {
                heights[3 * w + 2 * n + 1] = -1.0e4;
                -1.0e4
            });
            let opts =
                Options::new().with_patch(n).with_fit(fit).with_strength(Strength::Scale(2.3)).with_nodata(nodata);
            let mut expected = vec![[0.0f64; 3]; w * h];
            FitRequest::new(&opts).normals_into(&heights, w, h, &mut expected).unwrap();
            let mut got = vec![[f64::NAN; 3]; w * h];
            for x in (0..w).step_by(n + 3) {
                let xs = x..(x + n + 3).min(w);
                let window = window_of((w, h), &xs, &(0..h), &opts, Held::Padded);
                let (hw, hh) = window.held_size();
                let x0 = x as isize - window.halo.left as isize;
                let y0 = -(window.halo.top as isize);
                let values = held(&heights, (w, h), opts.borders, x0..x0 + hw as isize, y0..y0 + hh as isize);
                let mut out = vec![[0.0f64; 3]; xs.len() * h];
                fit_window(&values, &window, &opts, &mut out, None).unwrap();
                for y in 0..h {
                    got[y * w + xs.start..y * w + xs.end].copy_from_slice(&out[y * xs.len()..][..xs.len()]);
                }
            }
            let bits = |normals: &[[f64; 3]]| normals.iter().map(|n| n.map(f64::to_bits)).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&expected), "{w}×{h}, {opts:?}");
        }
    }
}

#[test]
fn any_partition_of_f64_heights_gives_the_whole_image_bits() {
    partitions_match(|v| v, 3);
}

#[test]
fn any_partition_of_8_bit_heights_gives_the_whole_image_bits() {
    partitions_match(|v| (v * 255.0).round() as u8, 4);
}

#[test]
fn any_partition_of_16_bit_heights_gives_the_whole_image_bits() {
    partitions_match(|v| (v * 65535.0).round() as u16, 5);
}

/// 16-bit heights with N = 63 (the largest sums) and a high gain: the
/// encoded texels of windows are the whole image's.
#[test]
fn large_patches_and_gains_of_16_bit_heights_match_in_every_texel_type() {
    let mut rng = Rng(6);
    let (w, h) = (90, 70);
    let heights: Vec<u16> = field(w, h, &mut rng).into_iter().map(|v| (v * 65535.0) as u16).collect();
    for n in [33, 63] {
        let opts = Options::new().with_patch(n).with_strength(Strength::Scale(1e5));
        let mut expected = vec![[0u8; 3]; w * h];
        FitRequest::new(&opts).normals_into(&heights, w, h, &mut expected).unwrap();
        let (xs, ys) = (cuts(w, &mut rng), cuts(h, &mut rng));
        for ys in &ys {
            for xs in &xs {
                let window = window_of((w, h), xs, ys, &opts, Held::Padded);
                let (hw, hh) = window.held_size();
                let (x0, y0) = (xs.start as isize - (n / 2) as isize, ys.start as isize - (n / 2) as isize);
                let values = held(&heights, (w, h), opts.borders, x0..x0 + hw as isize, y0..y0 + hh as isize);
                let mut out = vec![[0u8; 3]; xs.len() * ys.len()];
                fit_window(&values, &window, &opts, &mut out, None).unwrap();
                for (k, y) in ys.clone().enumerate() {
                    assert_eq!(out[k * xs.len()..][..xs.len()], expected[y * w + xs.start..y * w + xs.end], "N = {n}");
                }
            }
        }
    }
}

#[test]
fn a_wrap_needs_its_halo_beyond_the_edge() {
    let (w, h) = (12, 8);
    let heights = vec![0.5f32; w * h];
    let opts = Options::new(); // wrap, N = 3
    let window = window_of((w, h), &(0..4), &(2..5), &opts, Held::Clipped);
    let (hw, hh) = window.held_size();
    let values = held(&heights, (w, h), opts.borders, 0..hw as isize, 1..1 + hh as isize);
    let mut out = vec![[0.0f32; 3]; 4 * 3];
    let err = fit_window(&values, &window, &opts, &mut out, None).unwrap_err();
    assert!(matches!(&err, Error::InvalidOption(m) if m.contains("column -1")), "{err}");
    // With the column beyond the edge held, as the wrap gives it, it works.
    let window = Window { halo: Halo { left: 1, ..window.halo }, ..window };
    let (hw, hh) = window.held_size();
    let values = held(&heights, (w, h), opts.borders, -1..hw as isize - 1, 1..1 + hh as isize);
    fit_window(&values, &window, &opts, &mut out, None).unwrap();
    assert!(out.iter().all(|n| *n == [0.0, 0.0, 1.0]), "flat in, flat out");
}

#[test]
fn bad_windows_are_errors_naming_the_problem() {
    let opts = Options::new();
    let heights = vec![0.0f32; 9];
    let mut out = vec![[0.0f32; 3]; 1];
    let outside = Window { image: (4, 4), origin: (4, 0), size: (1, 1), halo: Halo::uniform(1) };
    let err = fit_window(&heights, &outside, &opts, &mut out, None).unwrap_err();
    assert!(err.to_string().contains("not inside"), "{err}");
    let short = Window { image: (4, 4), origin: (1, 1), size: (1, 1), halo: Halo::uniform(1) };
    let err = fit_window(&heights[..8], &short, &opts, &mut out, None).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 9, actual: 8 }), "{err}");
    let mut nan = heights.clone();
    nan[5] = f32::NAN;
    let err = fit_window(&nan, &short, &opts, &mut out, None).unwrap_err();
    assert!(matches!(err, Error::NonFiniteHeight { x: 2, y: 1 }), "{err}");
}
