//! The fit request (`FitRequest`), the fit's one way in: its parts alone
//! and together — the whole image or windows of it with the halo the
//! library plans (`HaloPlan`), holes, the residual, the value of missing
//! texels, sample and texel types, thread pools — against the shared slow
//! reference (`common/reference.rs`) and against each other, bit for bit.

use crate::common;

use std::ops::Range;

use common::reference;
use normalfit::fit::{Halo, HaloPlan, Window};
use normalfit::{Border, Borders, Error, Fit, FitRequest, Options, Sample, Samples, Strength};

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

/// Heights in [0, 1] with structure and noise.
fn field(w: usize, h: usize, rng: &mut Rng) -> Vec<f64> {
    let (fx, fy) = (0.2 + rng.unit(), 0.3 + rng.unit());
    (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            0.5 + 0.25 * (fx * x + 0.1 * y).sin() * (fy * y).cos() + 0.2 * rng.unit()
        })
        .collect()
}

/// Cuts of 0..len into runs at random places, runs of one texel common.
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

/// What a request gave, as bits.
#[derive(Debug, PartialEq)]
struct Fitted {
    normals: Vec<[u32; 3]>,
    residual: Vec<u32>,
    valid: Vec<bool>,
    missing: usize,
}

/// How the request is asked.
#[derive(Clone, Copy, Debug)]
struct Asked {
    /// Holes reported (`holes`), and non-finite heights holes.
    holes: bool,
    /// The value of missing texels (`missing`), or the default.
    fill: Option<[f64; 3]>,
}

/// The whole image's request.
fn whole<H: Sample>(heights: &[H], (w, h): (usize, usize), opts: &Options, asked: Asked) -> Fitted {
    let mut normals = vec![[0.0f32; 3]; w * h];
    let mut residual = vec![0.0f32; w * h];
    let mut valid = vec![true; w * h];
    let mut request = FitRequest::new(opts).residual(&mut residual);
    if asked.holes {
        request = request.holes(&mut valid);
    }
    if let Some(fill) = asked.fill {
        request = request.missing(fill);
    }
    let missing = request.normals_into(heights, w, h, &mut normals).unwrap();
    bits(normals, residual, valid, missing)
}

fn bits(normals: Vec<[f32; 3]>, residual: Vec<f32>, valid: Vec<bool>, missing: usize) -> Fitted {
    Fitted {
        normals: normals.iter().map(|n| n.map(f32::to_bits)).collect(),
        residual: residual.iter().map(|r| r.to_bits()).collect(),
        valid,
        missing,
    }
}

/// The heights a window holds: image columns `xs` and rows `ys`, beyond
/// the edges through the borders (as Dask's `periodic` gives them).
fn held<H: Copy>(heights: &[H], (w, h): (usize, usize), borders: Borders, window: &Window) -> Vec<H> {
    let x0 = window.origin.0 as isize - window.halo.left as isize;
    let y0 = window.origin.1 as isize - window.halo.top as isize;
    let (hw, hh) = window.held_size();
    (y0..y0 + hh as isize)
        .flat_map(|y| {
            let y = borders.y.map(y, h);
            (x0..x0 + hw as isize).map(move |x| heights[y * w + borders.x.map(x, w)])
        })
        .collect()
}

/// Every window of the partition `xs` × `ys` fitted alone, from the halo
/// the library plans, and the texels put together.
fn by_windows<H: Sample>(
    heights: &[H],
    image: (usize, usize),
    opts: &Options,
    (xs, ys): (&[Range<usize>], &[Range<usize>]),
    asked: Asked,
) -> Fitted {
    let (w, h) = image;
    let plan = HaloPlan::new(opts).unwrap();
    let mut normals = vec![[f32::NAN; 3]; w * h];
    let mut residual = vec![f32::NAN; w * h];
    let mut valid = vec![true; w * h];
    let mut missing = 0;
    for ys in ys {
        for xs in xs {
            let window = plan.window(image, (xs.start, ys.start), (xs.len(), ys.len()));
            let values = held(heights, image, opts.borders, &window);
            let (hw, hh) = window.held_size();
            let len = xs.len() * ys.len();
            let (mut n, mut r, mut v) = (vec![[0.0f32; 3]; len], vec![0.0f32; len], vec![true; len]);
            let mut request = FitRequest::new(opts).window(window).residual(&mut r);
            if asked.holes {
                request = request.holes(&mut v);
            }
            if let Some(fill) = asked.fill {
                request = request.missing(fill);
            }
            missing +=
                request.normals_into(&values, hw, hh, &mut n).unwrap_or_else(|e| panic!("window {xs:?} × {ys:?}: {e}"));
            for (k, y) in ys.clone().enumerate() {
                let (row, at) = (y * w + xs.start..y * w + xs.end, k * xs.len()..(k + 1) * xs.len());
                normals[row.clone()].copy_from_slice(&n[at.clone()]);
                residual[row.clone()].copy_from_slice(&r[at.clone()]);
                valid[row].copy_from_slice(&v[at]);
            }
        }
    }
    bits(normals, residual, valid, missing)
}

/// Holes: about one texel in twelve is `nodata` (the stored value), one
/// in forty NaN where the type has it.
fn with_holes<H: Sample>(values: &mut [H], nodata: H, nan: Option<H>, rng: &mut Rng) {
    for v in values {
        match rng.below(120) {
            0..10 => *v = nodata,
            10..13 => *v = nan.unwrap_or(nodata),
            _ => {}
        }
    }
}

/// The whole image's request against the reference, for every border
/// pair, both fits and several patches: normals and residual, and the
/// normals with the residual the same bits as without it.
#[test]
fn the_request_matches_the_reference_for_every_border_pair() {
    let mut rng = Rng(11);
    for &bx in &BORDERS {
        for &by in &BORDERS {
            for fit in [Fit::Orthogonal, Fit::Vertical] {
                for n in [3, 5, 9] {
                    let (w, h) = (4 + rng.below(20), 3 + rng.below(16));
                    let heights: Vec<f32> = field(w, h, &mut rng).into_iter().map(|v| v as f32).collect();
                    let opts = Options::new()
                        .with_patch(n)
                        .with_fit(fit)
                        .with_borders(Borders { x: bx, y: by })
                        .with_strength(Strength::Scale(2.0 + 5.0 * rng.unit()));
                    let got = whole(&heights, (w, h), &opts, Asked { holes: false, fill: None });
                    let plain = normalfit::normals(&heights, w, h, &opts).unwrap();
                    assert!(plain.iter().zip(&got.normals).all(|(a, b)| a.map(f32::to_bits) == *b));
                    let slow = reference::normal_map(&heights, w, h, &opts);
                    let tolerance = 1e-5 * (1.0 + reference::gain(&opts, w).abs());
                    for (k, (fast, slow)) in plain.iter().zip(&slow).enumerate() {
                        let what = format!("{w}×{h} {opts:?} texel {k}");
                        assert!((0..3).all(|c| (f64::from(fast[c]) - slow[c]).abs() < 1e-5), "{what}");
                        let residual = f64::from(f32::from_bits(got.residual[k]));
                        let want = reference::residual_at(&heights, w, h, &opts, k % w, k / w);
                        assert!((residual - want).abs() <= tolerance, "{what}: residual {residual}, {want}");
                    }
                    assert_eq!((got.missing, got.valid.iter().all(|&v| v)), (0, true));
                }
            }
        }
    }
}

/// Windows of the image, each from the halo the library plans, give the
/// whole image's normals, residual and valid texels bit for bit: every
/// border pair, both fits, N = 3, 5, 9, stored integers and floats, with
/// holes (a nodata value and NaN) and without.
#[test]
fn planned_windows_give_the_whole_image_for_every_border_pair() {
    let mut rng = Rng(12);
    let mut checked = 0;
    for &bx in &BORDERS {
        for &by in &BORDERS {
            for fit in [Fit::Orthogonal, Fit::Vertical] {
                for n in [3, 5, 9] {
                    let (w, h) = (5 + rng.below(30), 3 + rng.below(25));
                    let base = field(w, h, &mut rng);
                    let opts = Options::new()
                        .with_patch(n)
                        .with_fit(fit)
                        .with_borders(Borders { x: bx, y: by })
                        .with_strength(if n == 5 { Strength::Relief(0.02) } else { Strength::Scale(3.3) });
                    let partition = (cuts(w, &mut rng), cuts(h, &mut rng));
                    let partition = (&partition.0[..], &partition.1[..]);
                    let what = format!("{w}×{h}, {opts:?}, {partition:?}");
                    let mut floats: Vec<f32> = base.iter().map(|&v| v as f32).collect();
                    let mut stored: Vec<u16> = base.iter().map(|&v| (v * 65535.0) as u16).collect();
                    for asked in [Asked { holes: false, fill: None }, Asked { holes: true, fill: Some([f64::NAN; 3]) }]
                    {
                        if asked.holes {
                            with_holes(&mut floats, -1.0, Some(f32::NAN), &mut rng);
                            with_holes(&mut stored, 0, None, &mut rng);
                        }
                        let f_opts = opts.clone().with_nodata(asked.holes.then_some(-1.0));
                        let u_opts = opts.clone().with_nodata(asked.holes.then_some(0.0));
                        let want = whole(&floats, (w, h), &f_opts, asked);
                        assert_eq!(
                            by_windows(&floats, (w, h), &f_opts, partition, asked),
                            want,
                            "f32 {asked:?} {what}"
                        );
                        let want = whole(&stored, (w, h), &u_opts, asked);
                        assert_eq!(
                            by_windows(&stored, (w, h), &u_opts, partition, asked),
                            want,
                            "u16 {asked:?} {what}"
                        );
                        checked += 1;
                    }
                }
            }
        }
    }
    assert_eq!(checked, 9 * 2 * 3 * 2);
}

/// Any pool gives the same bits, with every part of the request at once:
/// windows of an image wider than one parallel strip, holes, residual.
#[test]
fn parallel_equals_serial_with_every_part_of_the_request() {
    let mut rng = Rng(13);
    let (w, h) = (1100, 70);
    let mut heights: Vec<f32> = field(w, h, &mut rng).into_iter().map(|v| 200.0 + v as f32).collect();
    with_holes(&mut heights, -9999.0, Some(f32::NAN), &mut rng);
    for n in [3, 9] {
        let opts = Options::new()
            .with_patch(n)
            .with_borders(Borders { x: Border::Mirror, y: Border::Wrap })
            .with_strength(Strength::Scale(25.0))
            .with_nodata(Some(-9999.0));
        let asked = Asked { holes: true, fill: Some([f64::NAN; 3]) };
        let (xs, ys) = ([0..3, 3..700, 700..w], [0..40, 40..h]);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                (whole(&heights, (w, h), &opts, asked), by_windows(&heights, (w, h), &opts, (&xs, &ys), asked))
            })
        };
        let serial = run(1);
        assert_eq!(serial.0, serial.1, "N {n}: windows");
        assert!(serial.0.missing > 0);
        for threads in [2, 3] {
            assert!(run(threads) == serial, "N {n}, {threads} threads");
        }
    }
}

/// A missing texel's normal is the value asked for (flat by default, in
/// every texel type), its residual NaN; the count is returned whether or
/// not `valid` is asked for; `Samples` and slices give the same bits.
#[test]
fn missing_texels_take_the_value_asked_for() {
    let mut rng = Rng(14);
    let (w, h) = (23, 17);
    let mut heights: Vec<f32> = field(w, h, &mut rng).into_iter().map(|v| v as f32).collect();
    with_holes(&mut heights, 7.0, Some(f32::INFINITY), &mut rng);
    let opts = Options::new().with_patch(5).with_nodata(Some(7.0));
    let nan = whole(&heights, (w, h), &opts, Asked { holes: true, fill: Some([f64::NAN; 3]) });
    let flat = whole(&heights, (w, h), &opts, Asked { holes: true, fill: None });
    assert!(nan.missing > 0 && nan.missing == nan.valid.iter().filter(|&&v| !v).count());
    assert_eq!((flat.missing, &flat.valid, &flat.residual), (nan.missing, &nan.valid, &nan.residual));
    for k in 0..w * h {
        let (n, f) = (nan.normals[k].map(f32::from_bits), flat.normals[k].map(f32::from_bits));
        if nan.valid[k] {
            assert_eq!(nan.normals[k], flat.normals[k], "texel {k}");
        } else {
            assert!(n.iter().all(|c| c.is_nan()) && f == [0.0, 0.0, 1.0], "texel {k}: {n:?} {f:?}");
            assert!(f32::from_bits(nan.residual[k]).is_nan(), "texel {k}");
        }
    }
    // Without `holes`, the nodata value still makes holes, and the count
    // comes back.
    let mut rgb = vec![[0u8; 3]; w * h];
    assert_eq!(FitRequest::new(&opts).normals_into(&heights, w, h, &mut rgb).unwrap(), nan.missing);
    assert!((0..w * h).all(|k| nan.valid[k] || rgb[k] == [128, 128, 255]));
    // `Samples` holding the heights: the same texels.
    let mut from_samples = vec![[0u8; 3]; w * h];
    let samples = Samples::F32(heights.clone());
    assert_eq!(FitRequest::new(&opts).normals_into(&samples, w, h, &mut from_samples).unwrap(), nan.missing);
    assert_eq!(from_samples, rgb);
}

/// Errors name what does not fit: the heights' layout against the
/// window's, buffers of the wrong length, a NaN height without holes (at
/// its image texel), and holes asked for make it a hole instead.
#[test]
fn a_request_refuses_what_does_not_fit() {
    let opts = Options::new().with_borders(Borders::both(Border::Clamp));
    let window = HaloPlan::new(&opts).unwrap().window((10, 8), (4, 3), (2, 2));
    assert_eq!(window.halo, Halo::uniform(1));
    let mut heights = vec![0.5f32; 16];
    let mut out = vec![[0.0f32; 3]; 4];
    let err = FitRequest::new(&opts).window(window).normals_into(&heights, 8, 2, &mut out).unwrap_err();
    assert!(matches!(&err, Error::InvalidOption(m) if m.contains("4×4 held")), "{err}");
    let err = FitRequest::new(&opts).window(window).normals_into(&heights, 4, 4, &mut out[..3]).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 4, actual: 3 }), "{err}");
    let mut residual = vec![0.0f32; 5];
    let err = FitRequest::new(&opts)
        .window(window)
        .residual(&mut residual)
        .normals_into(&heights, 4, 4, &mut out)
        .unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 4, actual: 5 }), "{err}");
    let (mut whole_out, mut valid) = (vec![[0.0f32; 3]; 16], vec![false; 5]);
    let err = FitRequest::new(&opts).holes(&mut valid).normals_into(&heights, 4, 4, &mut whole_out).unwrap_err();
    assert!(matches!(err, Error::BufferSize { expected: 16, actual: 5 }), "{err}");
    heights[2 * 4 + 1] = f32::NAN;
    let err = FitRequest::new(&opts).window(window).normals_into(&heights, 4, 4, &mut out).unwrap_err();
    assert!(matches!(err, Error::NonFiniteHeight { x: 4, y: 4 }), "{err}");
    let mut valid = vec![true; 4];
    let missing =
        FitRequest::new(&opts).window(window).holes(&mut valid).normals_into(&heights, 4, 4, &mut out).unwrap();
    assert_eq!((missing, valid), (1, vec![true, true, false, true]));
}

/// The halo plan checks the options without a fit, and plans the least
/// halo that holds every read: one texel less on any side it plans is a
/// read the fit names as missing.
#[test]
fn the_halo_plan_is_the_least_halo_that_holds_every_read() {
    for bad in [Options::new().with_patch(4), Options::new().with_strength(Strength::Scale(f64::NAN))] {
        assert!(matches!(HaloPlan::new(&bad), Err(Error::InvalidOption(_))));
    }
    let mut rng = Rng(15);
    let mut shrunk = 0;
    for &bx in &BORDERS {
        for &by in &BORDERS {
            let opts = Options::new().with_patch(7).with_borders(Borders { x: bx, y: by });
            let plan = HaloPlan::new(&opts).unwrap();
            assert_eq!((plan.radius(), plan.beyond_edges()), (3, (bx == Border::Wrap, by == Border::Wrap)));
            let (w, h) = (30, 20);
            let heights: Vec<f32> = field(w, h, &mut rng).into_iter().map(|v| v as f32).collect();
            for _ in 0..20 {
                let (x0, y0) = (rng.below(w), rng.below(h));
                let size = (1 + rng.below(w - x0), 1 + rng.below(h - y0));
                let window = plan.window((w, h), (x0, y0), size);
                let fit = |window: Window| {
                    let values = held(&heights, (w, h), opts.borders, &window);
                    let mut out = vec![[0.0f32; 3]; size.0 * size.1];
                    let (hw, hh) = window.held_size();
                    FitRequest::new(&opts).window(window).normals_into(&values, hw, hh, &mut out)
                };
                fit(window).unwrap();
                let Halo { left, right, top, bottom } = window.halo;
                let less = [
                    (left > 0).then(|| Halo { left: left - 1, ..window.halo }),
                    (right > 0).then(|| Halo { right: right - 1, ..window.halo }),
                    (top > 0).then(|| Halo { top: top - 1, ..window.halo }),
                    (bottom > 0).then(|| Halo { bottom: bottom - 1, ..window.halo }),
                ];
                for (side, halo) in less.into_iter().enumerate() {
                    let Some(halo) = halo else { continue };
                    // A wrap's halo beyond the edge may be read again on the
                    // far side when the window reaches it: not the least then.
                    let (n, start, len) = if side < 2 { (w, x0, size.0) } else { (h, y0, size.1) };
                    let wraps = if side < 2 { bx } else { by } == Border::Wrap;
                    if wraps && (start < 3 || start + len + 3 > n) {
                        continue;
                    }
                    let err = fit(Window { halo, ..window }).unwrap_err();
                    assert!(err.to_string().contains("lack"), "{opts:?} {window:?} side {side}: {err}");
                    shrunk += 1;
                }
            }
        }
    }
    assert!(shrunk > 100, "{shrunk}");
}
