//! Normals → heights (`normalfit height`, the inverse of the fit) on small
//! arbitrary normal maps: components from the case's bytes as float32 or
//! float64 (any bits: NaN, infinities, zeros, normals facing down) or as
//! 8- or 16-bit encoded texels read by the library's rule
//! (`Storage::normal`, as the Python package reads its arrays), with the
//! options from the case's last bytes: patch 3, 5 or 9, every border pair,
//! both fits, the exact or generic model, a convention or auto, the
//! input's step, gains from tiny to huge, relief, invert.
//!
//! Must hold: no panic, abort or hang; heights are finite, as many as the
//! texels, with the range reported theirs and the report's numbers finite;
//! or an `Err` with a one-line message.
#![no_main]

use libfuzzer_sys::fuzz_target;
use normalfit::Strength;
use normalfit::height::{ConventionChoice, HeightOptions, Model, heights, heights_of_rows};
use normalfit::normal_map::Storage;
use normalfit_fuzz::{Pick, assert_clean_error, fit_options};

/// Widths up to this; the height is what the bytes hold.
const MAX_WIDTH: usize = 24;

fuzz_target!(|data: &[u8]| {
    let mut pick = Pick::last(data, 6);
    let kind = pick.index(4);
    let w = 1 + pick.index(MAX_WIDTH);
    let model = pick.one(&[Model::Exact, Model::Exact, Model::Generic]);
    let convention = pick.one(&[ConventionChoice::OpenGl, ConventionChoice::DirectX, ConventionChoice::Auto]);
    let step = pick.one(&[None, Some(0.0), Some(2.0 / 255.0), Some(2.0)]);
    let gains = [
        Strength::Scale(1.0),
        Strength::Scale(8.0),
        Strength::Scale(-3.0),
        Strength::Relief(0.5),
        Strength::Scale(1e-40),
        Strength::Scale(1e30),
    ];
    let fit = fit_options(&mut pick, &gains);

    let size = [4, 8, 1, 2][kind];
    let texels = data.len() / (3 * size);
    let h = texels / w;
    if h == 0 {
        return;
    }
    let len = w * h;
    let component = |k: usize| -> f64 {
        let b = &data[k * size..][..size];
        match kind {
            0 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            1 => f64::from_le_bytes(std::array::from_fn(|i| b[i])),
            2 => Storage::Int { bits: 8 }.normal(b[0]),
            _ => Storage::Int { bits: 16 }.normal(u16::from_le_bytes([b[0], b[1]])),
        }
    };
    let storage = [
        Storage::Float32 { signed: true },
        Storage::Float64 { signed: true },
        Storage::Int { bits: 8 },
        Storage::Int { bits: 16 },
    ][kind];
    let opts = HeightOptions::from_fit(&fit)
        .with_convention(convention)
        .with_model(model)
        .with_step(step.unwrap_or(storage.step()));

    let found = match kind {
        // Arrays of n: `heights`.
        0 => {
            let n: Vec<[f32; 3]> = (0..len).map(|t| [0, 1, 2].map(|c| component(3 * t + c) as f32)).collect();
            heights(&n, w, h, &opts)
        }
        1 => {
            let n: Vec<[f64; 3]> = (0..len).map(|t| [0, 1, 2].map(|c| component(3 * t + c))).collect();
            heights(&n, w, h, &opts)
        }
        // Encoded texels, row by row: `heights_of_rows`, as Python reads them.
        _ => {
            let row = |y: usize, out: &mut [[f64; 3]]| {
                for (x, o) in out.iter_mut().enumerate() {
                    *o = [0, 1, 2].map(|c| component(3 * (y * w + x) + c));
                }
            };
            heights_of_rows(&row, w, h, &opts)
        }
    };
    match found {
        Ok(found) => {
            assert_eq!((found.width, found.height, found.values.len()), (w, h, len));
            let mut range = (f64::INFINITY, f64::NEG_INFINITY);
            for (k, &v) in found.values.iter().enumerate() {
                assert!(v.is_finite(), "height {v} at texel {k}");
                range = (range.0.min(v), range.1.max(v));
            }
            let r = &found.report;
            assert_eq!(r.range, range, "the range reported is not the heights'");
            assert!(r.bad_texels <= len);
            assert!(r.regularisation.is_finite() && r.regularisation >= 0.0);
            if let Some(curl) = r.curl {
                assert!(curl.iter().all(|c| c.is_finite() && *c >= 0.0), "curl {curl:?}");
            }
            if let Some(q) = r.quantisation_error {
                assert!(q.is_finite() && q >= 0.0, "quantisation error {q}");
            }
        }
        Err(e) => assert_clean_error(&e),
    }
});
