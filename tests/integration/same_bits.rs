//! The same bits with and without the `parallel` feature.
//!
//! The library promises results that do not depend on the number of
//! threads: fit_reference.rs compares pools of 1 to 8 threads within one
//! build. A build without `parallel` has no pool at all, so the promise
//! between builds is checked here by known answers: checksums of the bits
//! a fit, a tiling report and whole conversions give for fixed inputs,
//! recorded from the default (parallel) build. CI runs this file in both
//! builds (`.ci/run`), so either differing from the other fails.
//!
//! The inputs cross what splits work between threads: rows beyond one row
//! tile (64 rows), columns beyond one strip of the fit (about 512), PNG
//! rows filtered and deflated in parallel, EXR blocks compressed in
//! parallel.

use crate::corpus;

use corpus::png_gray16;
use normalfit::convert::{Conversion, Input, Output};
use normalfit::io::OutputFormat;
use normalfit::tiling::{TilingOptions, check};
use normalfit::{Border, Borders, FitRequest, Options, Strength};

const WIDTH: usize = 700;
const HEIGHT: usize = 150;

/// FNV-1a, 64 bits: a checksum written out here, so nothing of the code
/// under test computes it.
fn fnv(bytes: impl IntoIterator<Item = u8>) -> u64 {
    bytes.into_iter().fold(0xcbf2_9ce4_8422_2325, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// Heights in [0, 1) from a linear congruential generator, rough enough
/// that every texel's fit differs.
fn heights() -> Vec<f32> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    (0..WIDTH * HEIGHT)
        .map(|_| {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        })
        .collect()
}

fn fail_message(what: &str, got: u64) -> String {
    format!(
        "{what}: checksum {got:#018x}; the bits differ from the default build's (or the fit changed: record the new value)"
    )
}

#[test]
fn the_fit_gives_the_recorded_bits() {
    let h = heights();
    let cases: [(usize, Borders, u64); 3] = [
        (3, Borders::both(Border::Wrap), 0xa73b_a26a_a76d_615f),
        (9, Borders { x: Border::Mirror, y: Border::Clamp }, 0x22f8_1700_b03f_5242),
        (33, Borders { x: Border::Clamp, y: Border::Wrap }, 0x6de2_1f8b_730c_a2d8),
    ];
    for (n, borders, want) in cases {
        let opts = Options::new().with_patch(n).with_borders(borders).with_strength(Strength::Scale(20.0));
        let mut normals = vec![[0f32; 3]; WIDTH * HEIGHT];
        let mut residual = vec![0f32; WIDTH * HEIGHT];
        FitRequest::new(&opts).residual(&mut residual).normals_into(&h, WIDTH, HEIGHT, &mut normals).unwrap();
        let bits = normals.iter().flatten().chain(&residual).flat_map(|v| v.to_bits().to_le_bytes());
        let got = fnv(bits);
        assert_eq!(got, want, "{}", fail_message(&format!("n {n}, {borders:?}"), got));
    }
}

#[test]
fn the_tiling_check_gives_the_recorded_report() {
    let h = heights();
    let report = check(&[&h], WIDTH, HEIGHT, &TilingOptions::new()).unwrap();
    // `{:?}` writes every f64 with the digits that give its bits back.
    let got = fnv(format!("{report:?}").into_bytes());
    assert_eq!(got, 0x1aa2_5784_e260_0a4b, "{}", fail_message(&format!("{report:?}"), got));
}

#[test]
fn conversions_give_the_recorded_bytes() {
    let h = heights();
    let png = png_gray16(WIDTH as u32, HEIGHT as u32, |x, y| (h[y * WIDTH + x] * 65535.0) as u16);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("height.png");
    std::fs::write(&input, &png).unwrap();
    let cases = [
        ("PNG streamed", Input::Path(&input), OutputFormat::Png, 0x417a_5a31_90c5_eddd_u64),
        ("EXR streamed", Input::Path(&input), OutputFormat::Exr, 0xbe60_1a1e_58cd_de8a),
        ("PNG whole", Input::Bytes(&png), OutputFormat::Png, 0xe97e_59b4_9d0d_088a),
    ];
    for (what, source, format, want) in cases {
        let mut out = Vec::new();
        let conversion = Conversion::new().with_format(Some(format)).with_bits(16);
        conversion.convert(source, Output::Writer(&mut out)).unwrap();
        let got = fnv(out);
        assert_eq!(got, want, "{}", fail_message(what, got));
    }
}
