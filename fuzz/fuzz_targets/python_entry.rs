//! The library calls the Python package makes (normalfit-py/src/lib.rs),
//! on arrays and options as a Python caller may give them: heights of
//! uint8, uint16, float32 or float64 of any shape from 0 × 0 up (NaN
//! holes, infinities), patch sizes Python ints may be, `scale` and
//! `relief` of any float (both, or none), `auto` borders, nodata, map
//! units with a pixel size of any float, a residual; then:
//!
//! * `normals`: `Options::validate`, `BorderChoices::settle`, `FitRequest`
//!   (missing texels NaN) into float32, uint8 or uint16 texels;
//! * `window_normals` (`normalfit.dask`): the halo `HaloPlan` plans, the
//!   window fitted from its held texels, against the whole image's fit;
//! * `check_tiling` of (H, W, C) arrays, C = 1 … 4, any threshold and kind;
//! * `lit_view` of the same samples as a RAW file with `size=`.
//!
//! Must hold: no panic, abort, hang or huge allocation; errors one line;
//! float normals unit and facing up except the missing ones (NaN, as many
//! as reported); a window's normals the whole fit's, bit for bit; tiling
//! scores finite and positive, the verdict the score against the
//! threshold, and a height array holding NaN or infinities refused (as
//! the command line refuses it); a lit view of the size asked.
#![no_main]

use libfuzzer_sys::fuzz_target;
use normalfit::convert::{BorderChoice, BorderChoices};
use normalfit::fit::HaloPlan;
use normalfit::io::{ByteOrder, RawOptions, ReadOptions};
use normalfit::normal_map::KindChoice;
use normalfit::options::UnitsName;
use normalfit::shade::{Light, LitOptions, lit_view_of_file};
use normalfit::tiling::{TilingOptions, check};
use normalfit::units::MapSpacing;
use normalfit::{Border, Convention, Fit, FitRequest, FromNormal, Options, Sample, Samples, Strength};
use normalfit_fuzz::{Pick, assert_clean_error, assert_report, assert_unit_normal, case_file_as};

/// What one case asks for besides the array.
struct Call {
    opts: Options,
    borders: BorderChoices,
    output: usize,
    residual: bool,
    window: [usize; 4],
}

fuzz_target!(|data: &[u8]| {
    let mut pick = Pick::last(data, 8);
    let dtype = pick.index(4);
    let w = pick.index(33);
    let channels = 1 + pick.index(4);
    let patch = pick.one(&[3usize, 5, 9, 3, 1, 4, 0, 1023]);
    let fit = pick.one(&[Fit::Orthogonal, Fit::Vertical]);
    let convention = pick.one(&[Convention::OpenGl, Convention::DirectX]);
    let choice = [
        BorderChoice::Auto,
        BorderChoice::Fixed(Border::Wrap),
        BorderChoice::Fixed(Border::Clamp),
        BorderChoice::Fixed(Border::Mirror),
    ];
    let borders = BorderChoices { x: pick.one(&choice), y: pick.one(&choice) };
    let scale =
        pick.one(&[None, Some(1.0), Some(-2.0), Some(0.0), Some(f64::NAN), Some(1e30), Some(1e31), Some(1e-300)]);
    let relief = pick.one(&[None, None, Some(0.5), Some(f64::INFINITY)]);
    let nodata = pick.one(&[None, None, Some(f64::NAN), Some(0.0)]);
    let pixel = pick.one(&[
        None,
        None,
        Some((1.0, 1.0)),
        Some((30.0, 10.0)),
        Some((0.0, 1.0)),
        Some((f64::NAN, 1.0)),
        Some((1e-40, 1e-40)),
        Some((1e300, 1.0)),
    ]);
    let output = pick.index(3);
    let residual = pick.flag();
    let holes = pick.flag();
    let window = [pick.index(8), pick.index(8), 1 + pick.index(8), 1 + pick.index(8)];
    let threshold = pick.one(&[TilingOptions::new().threshold, 0.0, -1.0, f64::NAN, 1e9]);
    let kind = pick.one(&[KindChoice::Auto, KindChoice::Height, KindChoice::Normal]);
    let light = pick.one(&[
        (None, None, None),
        (Some((135.0, 45.0)), None, None),
        (None, Some(315.0), Some(45.0)),
        (None, Some(f64::NAN), Some(90.5)),
    ]);
    let tile = pick.flag();

    // The array: (h, w) samples, then a hole every seventh when asked.
    let size = [1, 2, 4, 8][dtype];
    let h = if w == 0 { data.len().min(3) } else { (data.len() / size / w).min(256) };
    let texels = w * h;
    let bytes = |k: usize| &data[(k * size) % data.len().max(size)..][..size.min(data.len())];
    let mut samples = match dtype {
        0 => Samples::U8((0..texels).map(|k| bytes(k)[0]).collect()),
        1 => Samples::U16((0..texels).map(|k| u16::from_le_bytes(std::array::from_fn(|i| bytes(k)[i]))).collect()),
        2 => Samples::F32((0..texels).map(|k| f32::from_le_bytes(std::array::from_fn(|i| bytes(k)[i]))).collect()),
        _ => Samples::F64((0..texels).map(|k| f64::from_le_bytes(std::array::from_fn(|i| bytes(k)[i]))).collect()),
    };
    if holes {
        match &mut samples {
            Samples::F32(v) => v.iter_mut().step_by(7).for_each(|x| *x = f32::NAN),
            Samples::F64(v) => v.iter_mut().step_by(7).for_each(|x| *x = f64::NAN),
            _ => {}
        }
    }

    // The options as `fit_options` makes them, then the map units and nodata.
    let opts = match Strength::from_scale_or_relief(scale, relief).and_then(|strength| {
        let opts = Options::new().with_patch(patch).with_fit(fit).with_convention(convention).with_strength(strength);
        opts.validate().map(|()| opts)
    }) {
        Ok(opts) => Some(opts),
        Err(e) => {
            assert_clean_error(&e);
            None
        }
    };
    let opts = opts.and_then(|opts| match MapSpacing::choose(UnitsName::Texels, pixel.map(|(x, y)| [x, y])) {
        None => Some(opts.with_nodata(nodata)),
        Some(map) => match map.units(None, h) {
            Ok(units) => Some(opts.with_units(units).with_nodata(nodata)),
            Err(e) => {
                assert_clean_error(&e);
                None
            }
        },
    });
    if let Some(opts) = opts {
        let call = Call { opts, borders, output, residual, window };
        match &samples {
            Samples::U8(v) => fit_all(v, w, h, &call),
            Samples::U16(v) => fit_all(v, w, h, &call),
            Samples::F32(v) => fit_all(v, w, h, &call),
            Samples::F64(v) => fit_all(v, w, h, &call),
            _ => unreachable!("the four dtypes"),
        }
    }

    // check_tiling of the (h, w / channels, channels) array.
    if let Ok(tiling) = TilingOptions::new()
        .with_threshold(threshold)
        .with_kind(kind)
        .validate()
        .map(|()| TilingOptions::new().with_threshold(threshold).with_kind(kind))
    {
        let cw = w / channels;
        let planes: Vec<Vec<f32>> = (0..channels)
            .map(|c| {
                let plane = (0..cw * h).map(|k| (k / cw * w) + (k % cw) * channels + c);
                match &samples {
                    Samples::U8(v) => Samples::U8(plane.map(|k| v[k]).collect()),
                    Samples::U16(v) => Samples::U16(plane.map(|k| v[k]).collect()),
                    Samples::F32(v) => Samples::F32(plane.map(|k| v[k]).collect()),
                    Samples::F64(v) => Samples::F64(plane.map(|k| v[k]).collect()),
                    _ => unreachable!(),
                }
                .into_f32()
                .expect("memory for a small plane")
            })
            .collect();
        let refs: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
        // The planes the check judges: the first three, or the first
        // (an alpha plane, or a second of two, is not judged).
        let judged = if planes.len() >= 3 { &planes[..3] } else { &planes[..1] };
        let finite = judged.iter().all(|p| p.iter().all(|v| v.is_finite()));
        match check(&refs, cw, h, &tiling) {
            Ok(report) => {
                assert_report(&report, &tiling);
                assert!(finite, "the tiling check of an array holding NaN or infinities reported {report:?}");
            }
            Err(e) => assert_clean_error(&e),
        }
    } else {
        let e = TilingOptions::new().with_threshold(threshold).with_kind(kind).validate().unwrap_err();
        assert_clean_error(&e);
    }

    // lit_view of the samples as a 16-bit RAW file of `size=`.
    if texels > 0 {
        let raw: Vec<u8> =
            (0..texels).flat_map(|k| u16::from_le_bytes([bytes(k)[0], bytes(k)[size - 1]]).to_le_bytes()).collect();
        let path = case_file_as("python-entry", "bin", &raw);
        let read = ReadOptions::default()
            .with_max_texels(1 << 20)
            .with_raw(RawOptions::default().with_size(w, h).with_byte_order(ByteOrder::Little));
        let lit = Light::new(light.0.map_or(0.0, |l: (f64, f64)| l.0), light.0.map_or(45.0, |l| l.1)).and_then(|l| {
            LitOptions::new()
                .with_fit(Options::new().with_patch(3).with_nodata(nodata))
                .with_borders(borders)
                .with_lighting(light.0.map(|_| l), light.1, light.2)
        });
        let lit = lit.map(|lit| {
            lit.with_tile(tile)
                .with_kind(kind)
                .with_map_units(MapSpacing::choose(UnitsName::Texels, pixel.map(|(x, y)| [x, y])))
        });
        match lit.and_then(|lit| lit_view_of_file(&path, &read, &lit)) {
            Ok(view) => {
                let k = if tile { 2 } else { 1 };
                assert_eq!((view.width, view.height), (k * w, k * h));
                assert_eq!(view.pixels.len(), view.width * view.height);
            }
            Err(e) => assert_clean_error(&e),
        }
    }
});

/// `normals` and `window_normals` of heights `v` (h rows of w).
fn fit_all<H: Sample>(v: &[H], w: usize, h: usize, call: &Call) {
    match call.output {
        0 => fit_into::<H, f32>(v, w, h, call),
        1 => fit_into::<H, u8>(v, w, h, call),
        _ => fit_into::<H, u16>(v, w, h, call),
    }
}

fn fit_into<H: Sample, E: Copy + Default + PartialEq + std::fmt::Debug + 'static>(
    v: &[H],
    w: usize,
    h: usize,
    call: &Call,
) where
    [E; 3]: FromNormal,
{
    let borders = match call.borders.settle(v, w, h) {
        Ok(b) => b,
        Err(e) => return assert_clean_error(&e),
    };
    let mut out = vec![[E::default(); 3]; w * h];
    let mut residual = vec![0.0f32; if call.residual { w * h } else { 0 }];
    let mut request = FitRequest::new(&call.opts).borders(borders).missing([f64::NAN; 3]);
    if call.residual {
        request = request.residual(&mut residual);
    }
    let missing = match request.normals_into(v, w, h, &mut out) {
        Ok(missing) => missing,
        Err(e) => return assert_clean_error(&e),
    };
    if let Some(out) = (&out as &dyn std::any::Any).downcast_ref::<Vec<[f32; 3]>>() {
        let nan = out.iter().filter(|n| n.iter().any(|c| c.is_nan())).count();
        assert_eq!(nan, missing, "missing texels reported and NaN texels differ");
        for (k, &n) in out.iter().enumerate().filter(|(_, n)| !n[0].is_nan()) {
            assert_unit_normal(n, k);
        }
    }

    // The window `normalfit.dask` would fit, from the texels it holds.
    let [ox, oy, ww, wh] = call.window;
    if ox + ww > w || oy + wh > h {
        return;
    }
    let plan = HaloPlan::new(&call.opts.clone().with_borders(borders)).expect("options that fitted");
    let window = plan.window((w, h), (ox, oy), (ww, wh));
    let (hw, hh) = window.held_size();
    let x0 = ox as isize - window.halo.left as isize;
    let y0 = oy as isize - window.halo.top as isize;
    let held: Vec<H> = (0..hh)
        .flat_map(|j| (0..hw).map(move |i| (x0 + i as isize, y0 + j as isize)))
        .map(|(x, y)| v[y.rem_euclid(h as isize) as usize * w + x.rem_euclid(w as isize) as usize])
        .collect();
    let mut part = vec![[E::default(); 3]; ww * wh];
    let mut request = FitRequest::new(&call.opts).borders(borders).missing([f64::NAN; 3]).window(window);
    let mut part_residual = vec![0.0f32; if call.residual { ww * wh } else { 0 }];
    if call.residual {
        request = request.residual(&mut part_residual);
    }
    request.normals_into(&held, hw, hh, &mut part).expect("a window of an image that fitted");
    for j in 0..wh {
        for i in 0..ww {
            let (a, b) = (part[j * ww + i], out[(oy + j) * w + ox + i]);
            let same = a.iter().zip(&b).all(|(a, b)| a == b || (a != a && b != b));
            assert!(same, "window texel ({i}, {j}) at ({ox}, {oy}): {a:?}, the whole fit {b:?}");
        }
    }
}
