//! Inputs the fuzzers (`fuzz/`) found, each fed through the path it broke,
//! asserting the clean result. The files in `tests/data/fuzz/` are the
//! minimised cases (`cargo fuzz tmin`), as the fuzzers wrote them.

use normalfit::io::{Raster, ReadOptions, decode};
use normalfit::normal_map::KindChoice;
use normalfit::pipeline::PngRows;
use normalfit::tiling::{HeightSeams, TilingOptions, TilingReport, check};
use normalfit::{Border, Borders, Error, FitRequest, Options};
#[cfg(feature = "hdr")]
use normalfit::{Fit, Strength};

/// The fuzzers' limit: small, so a case never costs much.
fn read() -> ReadOptions {
    ReadOptions::default().with_max_texels(1 << 20)
}

fn case(name: &str) -> Vec<u8> {
    let path = format!("{}/tests/data/fuzz/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// `decode_fit`'s path: bytes → raster → heights → normals, f32 and 8-bit.
/// Returns the first error; on success checks every normal.
fn decode_fit(bytes: &[u8], opts: &Options) -> normalfit::Result<()> {
    let raster = decode(bytes, &read())?;
    let (w, h) = (raster.width, raster.height);
    let heights = raster.into_heights(None)?;
    let mut n = vec![[0.0f32; 3]; w * h];
    FitRequest::new(opts).normals_into(&heights, w, h, &mut n)?;
    for v in &n {
        let len = v.iter().map(|c| c * c).sum::<f32>().sqrt();
        assert!(v.iter().all(|c| c.is_finite()) && (len - 1.0).abs() <= 1e-4 && v[2] >= 0.0, "bad normal {v:?}");
    }
    let mut rgb = vec![[0u8; 3]; w * h];
    FitRequest::new(opts).normals_into(&heights, w, h, &mut rgb).map(|_| ())
}

fn assert_finite(r: &TilingReport) {
    for axis in [r.x, r.y] {
        assert!(axis.score.is_finite() && axis.score > 0.0, "score {} in {r:?}", axis.score);
    }
}

/// `tiling`'s path: every plane, the kind detected; then the heights whole
/// and streamed row by row.
fn tiling_reports(raster: &Raster) -> [TilingReport; 3] {
    let (w, h) = (raster.width, raster.height);
    let planes: Vec<Vec<f32>> = raster.planes.iter().map(|p| p.data.to_f32().unwrap()).collect();
    let planes: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
    let all = check(&planes, w, h, &TilingOptions::new()).unwrap();
    let heights = raster.heights(None).expect("finite heights");
    let opts = TilingOptions::new().with_kind(KindChoice::Height);
    let whole = check(&[&heights], w, h, &opts).unwrap();
    let mut seams = HeightSeams::new(w, h).unwrap();
    heights.chunks_exact(w).for_each(|row| seams.push_row(row).unwrap());
    [all, whole, seams.finish(&opts).unwrap()]
}

/// exr's B44 decoder computes in u16 arithmetic that wraps (as OpenEXR's
/// C code does). With overflow checks, as in test and dev builds, that
/// wrap panicked in exr's decoder thread and rayon aborted the whole
/// process; the root Cargo.toml now builds exr without them. The wrapped
/// values are ordinary halves: the file converts and is checked.
/// A tiled EXR whose offset table lists a full-resolution tile but whose
/// chunk says it is of level (1, 0): `exr` only checks that in a debug
/// assertion, so debug builds (tests, fuzzing) panicked; it is an error.
#[test]
fn exr_block_of_a_resolution_level_not_asked_for_is_an_error() {
    let err = decode(&case("exr-block-of-another-level.exr"), &read()).expect_err("a corrupt block");
    assert!(matches!(err, Error::Decode(_)), "{err:?}");
}

#[test]
fn exr_b44_block_whose_arithmetic_wraps_decodes() {
    let bytes = case("exr-b44-wrap.exr");
    let raster = decode(&bytes, &read()).expect("the B44 blocks decode");
    assert_eq!((raster.width, raster.height), (8, 6));
    for r in tiling_reports(&raster) {
        assert_finite(&r);
    }
    for opts in [Options::new(), Options::new().with_patch(5).with_borders(Borders::both(Border::Mirror))] {
        decode_fit(&bytes, &opts).expect("the decoded heights fit");
    }
}

/// A Radiance HDR whose texels reach 1.7·10³⁸: their differences overflowed
/// f32 in the tiling kernels, and both scores were NaN ("x NaN SEAM").
#[cfg(feature = "hdr")]
#[test]
fn hdr_with_texels_near_f32_range_scores_finite() {
    let raster = decode(&case("hdr-huge-values.hdr"), &read()).expect("a valid HDR");
    let top = raster.planes.iter().flat_map(|p| p.data.to_f32().unwrap()).fold(0.0f32, |m, v| m.max(v.abs()));
    assert!(top > 1e38, "the case is about huge texels, its largest is {top}");
    let [all, whole, streamed] = tiling_reports(&raster);
    for r in [&all, &whole, &streamed] {
        assert_finite(r);
    }
    assert_eq!((whole.x.score, whole.y.score), (streamed.x.score, streamed.y.score));
    // The fit of the same heights was never the problem: its sums are f64.
    let opts = Options::new().with_fit(Fit::Vertical).with_strength(Strength::Scale(1e30));
    decode_fit(&case("hdr-huge-values.hdr"), &opts).expect("finite heights fit");
}

/// The tiling score is a ratio of sums, so a map and the same map times a
/// power of two score the same. Up to f32's range too: the kernels scale
/// the heights down before they sum, and back up exactly.
#[test]
fn heights_near_f32_range_score_as_the_same_map_near_one() {
    let (w, h) = (48, 40);
    // A ridge with noise: both the value and the crease sums are non-zero.
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let unit: Vec<f32> = (0..w * h)
        .map(|k| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let noise = (state >> 40) as f32 / (1u64 << 24) as f32;
            ((k % w) as f32 / w as f32 - 0.5).abs() + 0.1 * noise - 0.3
        })
        .collect();
    let huge: Vec<f32> = unit.iter().map(|v| v * 2f32.powi(127)).collect();
    assert!(huge.iter().all(|v| v.is_finite()));
    let opts = TilingOptions::new().with_kind(KindChoice::Height);
    let small = check(&[&unit], w, h, &opts).unwrap();
    let large = check(&[&huge], w, h, &opts).unwrap();
    assert_finite(&large);
    assert_eq!((small.x.score, small.y.score), (large.x.score, large.y.score));
    let mut seams = HeightSeams::new(w, h).unwrap();
    huge.chunks_exact(w).for_each(|row| seams.push_row(row).unwrap());
    let streamed = seams.finish(&opts).unwrap();
    assert_eq!((streamed.x.score, streamed.y.score), (large.x.score, large.y.score));
    // Colour: luma of three such planes, the largest weight's plane at −f32::MAX.
    let low = vec![-f32::MAX; w * h];
    let report = check(&[&huge, &low, &huge], w, h, &opts).unwrap();
    assert_finite(&report);
}

/// A PNG whose PLTE chunk holds 56 bytes, not a whole number of RGB
/// entries: png 0.18.1 panicked (slice index out of range) expanding the
/// palette into the first row, when `decode` read it through `image` and
/// when the streaming reader did (`normalfit convert` and `tiling` exited
/// with 101). Now a decode error from the header, before any row.
#[test]
fn png_palette_of_partial_entries_is_a_decode_error() {
    let bytes = case("png-palette-not-rgb.png");
    match decode(&bytes, &read()) {
        Err(Error::Decode(m)) => assert!(m.contains("palette of 56 bytes"), "{m}"),
        other => panic!("expected a decode error, got {other:?}"),
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("case.png");
    std::fs::write(&path, &bytes).unwrap();
    for channel in [None, Some(normalfit::io::Channel::A)] {
        let Err(Error::Decode(m)) = PngRows::open(&path, &read(), channel) else {
            panic!("the streaming reader must refuse the palette");
        };
        assert!(m.contains("palette"), "{m}");
    }
}

/// `geotiff_tags`' promise about a georeferencing that is read: finite
/// values, scales that are not 0, texels placed within f64's range. A
/// ModelPixelScale of NaN or 0, an infinite tiepoint, or a huge scale
/// times a huge raster point were read as they were, so `--units map`
/// refused them only through the spacing's check (with the 309 digits of
/// 1e308), and a conversion in texel units wrote the NaN or infinity into
/// its output's georeferencing (issue 32). Each is now a decode error
/// naming the tag. The files are the target's UTM seed with one value
/// changed.
#[cfg(feature = "tiff")]
#[test]
fn geotiff_tags_that_place_no_texel_are_decode_errors() {
    for (name, says) in [
        ("geotiff-scale-nan.tif", &["ModelPixelScale tag: value 1 of 3 is NaN: georeferencing must be finite"][..]),
        ("geotiff-scale-zero.tif", &["ModelPixelScale tag: a texel of 0 × 30 has no size"]),
        ("geotiff-tiepoint-inf.tif", &["ModelTiepoint tag: value", "is inf: georeferencing must be finite"]),
        ("geotiff-place-overflows.tif", &["place the raster beyond the range of 64-bit floats"]),
    ] {
        for nodata_tag in [true, false] {
            match decode(&case(name), &read().with_nodata_tag(nodata_tag)) {
                Err(Error::Decode(m)) => {
                    assert!(says.iter().all(|s| m.contains(s)) && !m.contains('\n'), "{name}: {m}");
                }
                other => panic!("{name}: expected a decode error, got {:?}", other.map(|r| r.georef)),
            }
        }
    }
}

/// `raw_sizes`: `parse_size` (`--size`, Python's `size="WxH"`) echoed the
/// text it refused as it was, so a size holding a line break (this case
/// is one byte, "\n") gave an error of two lines. The text is now shown
/// on one line, as every message is.
#[test]
fn a_size_text_with_a_line_break_is_refused_on_one_line() {
    let bytes = case("raw-size-newline.bin");
    for text in [String::from_utf8_lossy(&bytes).into_owned(), "1\n6x16\r\n".into()] {
        match normalfit::io::parse_size(&text) {
            Err(Error::InvalidOption(m)) => assert!(!m.contains(['\n', '\r']), "{m:?}"),
            other => panic!("{text:?}: expected an invalid option, got {other:?}"),
        }
    }
}

/// `python_entry` found that `tiling::check`, which Python's
/// `check_tiling` calls on arrays, scored heights holding NaN (as 0) and
/// could call them seamless, where the command line refuses them
/// (`tests/data/fuzz/python-entry-tiling-nan.bin` is the minimised
/// case, read by the target's options). The check now refuses them, as
/// the fit and the reader do (issue 32, point 5).
#[test]
fn tiling_check_of_heights_holding_nan_is_refused() {
    let mut v: Vec<f32> = (0..64).map(|k| (k % 8) as f32 / 7.0).collect();
    v[9] = f32::NAN;
    assert!(check(&[&v], 8, 8, &TilingOptions::new().with_kind(KindChoice::Height)).is_err());
}

/// `python_entry`: `tiling::check` of a normal map (3 planes, the kind
/// asked for) holding NaN counted its non-finite components as 0 and
/// called it seamless (`python-entry-tiling-normal-nonfinite.bin` is the
/// case). A normal with a NaN or infinite component is no normal: the
/// check now refuses it naming the texel, as it refuses such heights; with
/// the kind left to detection, the same texel is refused.
#[test]
fn tiling_check_of_a_normal_map_holding_nan_is_refused() {
    let (w, h) = (8, 8);
    let mut planes: Vec<Vec<f32>> = vec![vec![0.5; w * h], vec![0.5; w * h], vec![1.0; w * h]];
    planes[1][2 * w + 5] = f32::NAN;
    planes[2][3 * w + 1] = f32::INFINITY;
    let refs: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
    for kind in [KindChoice::Normal, KindChoice::Auto] {
        match check(&refs, w, h, &TilingOptions::new().with_kind(kind)) {
            Err(e @ Error::NonFiniteNormal { x: 5, y: 2 }) => {
                assert_eq!(e.to_string(), "normal at texel (x 5, y 2) has a NaN or infinite component");
            }
            // Detection judges the NaN texel's length too: the kind it
            // settles on names the error, the texel is the same.
            Err(Error::NonFiniteHeight { x: 5, y: 2 }) if kind == KindChoice::Auto => {}
            other => panic!("{kind:?}: expected the texel refused, got {other:?}"),
        }
    }
}

/// `raw_sizes`: a RAW size whose bytes overflow u64 (here
/// 18446744073709551614 × 1 at 16 bits) was refused with the saturated
/// 18446744073709551615 as the bytes it "takes" (issue 32); now "2^64 bytes
/// or more".
#[test]
fn a_raw_size_past_u64_bytes_says_so() {
    let bytes = case("raw-size-product-past-u64.raw");
    let raw = normalfit::io::RawOptions::default().with_size(usize::MAX - 1, 1);
    let e = decode(&bytes, &ReadOptions::default().with_max_texels(u64::MAX).with_raw(raw)).unwrap_err();
    let m = e.to_string();
    assert!(m.contains("2^64 bytes or more at 16 bits") && !m.contains(&u64::MAX.to_string()), "{m}");
}

/// `inverse`: a 5 × 24 map of 16-bit normals, patch 9 (wider than the
/// map), clamp in x and wrap in y, orthogonal fit, DirectX, inverted,
/// scale −3 (`tests/data/fuzz/inverse-timeout-5x24-patch9-clamp-wrap.bin`,
/// read as the target reads it: the last six bytes pick the options,
/// 2-byte texels the normals) ran past libFuzzer's 10 s: the conjugate
/// gradients of clamp with N ≥ 5 took up to 2000 iterations per solve, and
/// the orthogonal fit up to 100 solves, each pass O(N) a texel (issue 32,
/// point 4). Clamp's axes now take the exact solve in dense bases (a
/// solve is a few products a texel whatever N): the orthogonal fit's fixed
/// point and Gauss–Newton need few solves, and it returns in milliseconds
/// (timed as a benchmark by bench/height_n.sh, not here), with finite
/// heights.
#[test]
fn inverse_of_a_wide_clamped_patch_takes_few_solves() {
    use normalfit::height::{ConventionChoice, HeightOptions, heights_of_rows};
    use normalfit::normal_map::Storage;
    let data = case("inverse-timeout-5x24-patch9-clamp-wrap.bin");
    // The target's choices, in its order, from the last six bytes.
    let mut tail = [0u8; 8];
    tail[..6].copy_from_slice(&data[data.len() - 6..]);
    let mut pick = u64::from_le_bytes(tail);
    let mut index = |n: u64| {
        let v = pick % n;
        pick /= n;
        v as usize
    };
    let (kind, w) = (index(4), 1 + index(24));
    let (model, convention, step) = (index(3), index(3), index(4));
    let (patch, bx, by, fit, green, invert, gain) =
        (index(3), index(3), index(3), index(2), index(2), index(2), index(6));
    assert_eq!((kind, w, model, convention, step), (3, 5, 0, 1, 0), "16-bit texels, exact model, DirectX");
    assert_eq!((patch, bx, by, fit, green, invert, gain), (2, 1, 0, 0, 0, 1, 2), "N 9, clamp × wrap, orthogonal");
    let h = data.len() / (3 * 2) / w;
    assert_eq!(h, 24);
    let fit = Options::new()
        .with_patch(9)
        .with_borders(Borders { x: Border::Clamp, y: Border::Wrap })
        .with_fit(normalfit::Fit::Orthogonal)
        .with_invert(true)
        .with_strength(normalfit::Strength::Scale(-3.0));
    let stored = Storage::Int { bits: 16 };
    let opts = HeightOptions::from_fit(&fit).with_convention(ConventionChoice::DirectX).with_step(stored.step());
    let row = |y: usize, out: &mut [[f64; 3]]| {
        for (x, o) in out.iter_mut().enumerate() {
            *o = [0, 1, 2].map(|c| {
                let k = 2 * (3 * (y * w + x) + c);
                stored.normal(u16::from_le_bytes([data[k], data[k + 1]]))
            });
        }
    };
    let found = heights_of_rows(&row, w, h, &opts).expect("heights");
    assert!(found.values.iter().all(|v| v.is_finite()));
    assert_eq!(found.values.len(), w * h);
    println!("{} solves", found.report.iterations);
    // 126 solves (the fixed point's and Gauss–Newton's), 0.07 s in a release build.
    assert!(found.report.iterations < 200, "{} solves", found.report.iterations);
}

/// `geotiff_tags`: a 710-byte TIFF whose header describes 6 × 16389
/// texels of 17231 32-bit bands, uncompressed in one strip of 120 bytes,
/// had its 6.8 GB of samples allocated and zeroed before `tiff` found the
/// strip short (libFuzzer's out-of-memory). The stored strips now bound
/// what a header may describe, by each compression's largest ratio, before
/// anything is allocated.
#[cfg(feature = "tiff")]
#[test]
fn a_tiff_header_describing_more_than_its_strips_hold_is_refused_before_allocating() {
    for band in [None, Some(2)] {
        let read = read().with_nodata_tag(true);
        let read = if let Some(b) = band { read.with_band(b) } else { read };
        match decode(&case("geotiff-tags-17231-bands-in-120-bytes.tif"), &read) {
            Err(Error::Decode(m)) => {
                assert!(m.contains("strips or tiles of 120 bytes in all cannot hold the 6777572616 bytes"), "{m}")
            }
            other => panic!("expected a decode error, got {:?}", other.map(|r| (r.width, r.height))),
        }
    }
}

/// `decode_fit`: a 6 × 5 float64 TIFF (deflated, with a checksum only
/// fuzz builds skip, so it is rebuilt here uncompressed with the same
/// kinds of values) of heights from 16 to 33318 and of ±1e300 and
/// −3.9e80. Finite as doubles, they passed the fit's check, and their
/// squares overflowed its sums: the normal at texel 0 was (−0, −0, NaN),
/// with Ok. A height beyond `f32`'s range is now refused as infinite, as
/// `Raster::heights` rounds it, naming the first in row order.
#[cfg(feature = "tiff")]
#[test]
fn f64_heights_beyond_f32_range_are_refused_as_infinite() {
    let v: Vec<f64> = vec![
        25.0, 29.2, 33.3, 37.5, 41.7, 45.8, 16.4, 20.5, 24.7, 28.9, 0.0, -3.9e80, 0.0, 0.0, -1e300, -1e300, 1e300,
        -1e300, 1e300, 0.0, 388.3, -1e300, 1e300, -1e300, 1e300, 33318.7, 1260.5, 45.7, 0.0, -1e300,
    ];
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    let tiff = crate::corpus::tiff_gray_tagged(6, 5, 64, 3, &bytes, &[]);
    let opts = Options::new();
    match decode_fit(&tiff, &opts) {
        Err(Error::NonFiniteHeight { x: 5, y: 1 }) => {}
        other => panic!("expected texel (5, 1) refused, got {other:?}"),
    }
    // The fit holds samples from any source to the same rule. The bound is
    // f32's: its largest value fits, a double past it does not.
    let mut n = vec![[0.0f32; 3]; 9];
    let edge = normalfit::Samples::F64(vec![f64::from(f32::MAX), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert!(FitRequest::new(&opts).normals_into(&edge, 3, 3, &mut n).is_ok());
    let past = normalfit::Samples::F64(vec![f64::from(f32::MAX) * 1.000_001, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert!(matches!(
        FitRequest::new(&opts).normals_into(&past, 3, 3, &mut n),
        Err(Error::NonFiniteHeight { x: 0, y: 0 })
    ));
}
