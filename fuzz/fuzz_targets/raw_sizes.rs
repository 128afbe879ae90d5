//! RAW heightmaps (headerless 8- or 16-bit samples) with the layout a
//! caller gives (`--size WxH`, `--byte-order`, the depth of `.r8`/`.r16`)
//! taken from the case's last bytes: sizes that fit the length, sizes that
//! do not, zero, and sizes whose products overflow; depths of 8, 16 and
//! others; every texel limit up to none. Read from the bytes (`decode`)
//! and from a file named `.raw`, `.r8`, `.r16` or `.bin` (`read_path`),
//! then fitted; and `parse_size` of text from the case.
//!
//! Must hold for any bytes and layout: no panic, abort or huge allocation
//! (a size is checked against the length before anything is allocated);
//! impossible layouts are `Err` with a one-line message that names no
//! saturated number; a RAW read holds exactly the bytes given, as the
//! layout says; the file and the bytes read the same.
#![no_main]

use libfuzzer_sys::fuzz_target;
use normalfit::io::{ByteOrder, InputFormat, RawOptions, ReadOptions, SampleType, decode, parse_size, read_path};
use normalfit::{Error, FitRequest, Samples, Strength};
use normalfit_fuzz::{Pick, assert_clean_error, assert_unit_normal, case_file_as, check_heights, fit_options};

/// Sizes no file of a fuzz case holds: zero, around 2^31, 2^32 and
/// 2^63, the largest.
const HUGE: [usize; 8] = [0, 1, 1 << 31, (1 << 32) + 1, 1 << 62, (1 << 63) + 3, usize::MAX - 1, usize::MAX];

fuzz_target!(|data: &[u8]| {
    let mut pick = Pick::last(data, 8);
    let bits = pick.one(&[None, Some(8), Some(16), None, Some(0), Some(12), Some(32), Some(255)]);
    let bytes_per = usize::from(bits.unwrap_or(8).max(8) / 8).min(2);
    let size = match pick.index(4) {
        0 => None,
        // A width, and the height the length gives at that depth: often
        // exact, else one row short.
        1 | 2 => {
            let w = 1 + pick.index(64);
            Some((w, (data.len() / bytes_per / w).max(pick.index(2))))
        }
        _ => Some((pick.one(&HUGE), pick.one(&HUGE))),
    };
    let order = pick.one(&[ByteOrder::Little, ByteOrder::Big]);
    let max_texels = pick.one(&[1 << 20, 1 << 20, 1 << 30, u64::MAX]);
    let extension = pick.one(&["raw", "r8", "r16", "bin"]);
    let fit = fit_options(&mut pick, &[Strength::Scale(1.0), Strength::Relief(0.5)]);

    let mut raw = RawOptions::default().with_byte_order(order);
    raw.size = size;
    raw.bits = bits;
    let read = ReadOptions::default().with_max_texels(max_texels).with_raw(raw.clone());
    let saturated = u64::MAX.to_string();
    let names_saturated = |e: &Error| {
        let given = size.is_some_and(|(w, h)| w as u64 == u64::MAX || h as u64 == u64::MAX);
        !given && e.to_string().contains(&saturated)
    };

    let from_bytes = decode(data, &read);
    match &from_bytes {
        Ok(r) => {
            assert_eq!(r.format, InputFormat::Raw);
            let (w, h) = (r.width, r.height);
            if let Some(s) = size {
                assert_eq!((w, h), s, "the size given");
            }
            assert!((w as u64) * (h as u64) <= max_texels);
            let [plane] = &r.planes[..] else { panic!("a RAW read gave {} planes", r.planes.len()) };
            match &plane.data {
                Samples::U8(v) => {
                    assert_eq!(r.sample, SampleType::Int { bits: 8 });
                    assert!(bits.is_none() || bits == Some(8));
                    assert_eq!(&v[..], data, "8-bit samples are the bytes");
                }
                Samples::U16(v) => {
                    assert_eq!(r.sample, SampleType::Int { bits: 16 });
                    assert!(bits.is_none() || bits == Some(16));
                    assert_eq!(v.len() * 2, data.len());
                    for (s, p) in v.iter().zip(data.chunks_exact(2)) {
                        let want = match order {
                            ByteOrder::Little => u16::from_le_bytes([p[0], p[1]]),
                            ByteOrder::Big => u16::from_be_bytes([p[0], p[1]]),
                        };
                        assert_eq!(*s, want);
                    }
                }
                other => panic!("a RAW read gave {other:?}"),
            }
            assert_eq!(plane.data.len(), w * h);
        }
        Err(e) => {
            assert_clean_error(e);
            assert!(!names_saturated(e), "a saturated number in {e}");
            if matches!(size, Some((0, _) | (_, 0))) || !matches!(bits, None | Some(8 | 16)) {
                assert!(matches!(e, Error::InvalidOption(_)), "a layout the options refuse: {e:?}");
            }
        }
    }

    // From a file: an extension of RAW's gives the depth when none is given.
    let path = case_file_as("raw-sizes", extension, data);
    let from_file = read_path(&path, &read);
    let mut expected = raw.clone();
    if expected.bits.is_none() {
        expected.bits = match extension {
            "r8" => Some(8),
            "r16" => Some(16),
            _ => None,
        };
    }
    let expected = decode(data, &read.clone().with_raw(expected));
    match (&from_file, &expected) {
        (Ok(a), Ok(b)) => assert!(a == b, "the file read otherwise than its bytes"),
        (Err(a), Err(_)) => {
            assert_clean_error(a);
            assert!(!names_saturated(a), "a saturated number in {a}");
        }
        (a, b) => panic!("the file gave {:?}, its bytes {:?}", a.as_ref().err(), b.as_ref().err()),
    }

    // A size as the command line and Python take it.
    let text = String::from_utf8_lossy(&data[..data.len().min(24)]);
    match parse_size(&text) {
        Ok((w, h)) => assert!(w >= 1 && h >= 1),
        Err(e) => assert_clean_error(&e),
    }
    if let Some((w, h)) = size {
        match parse_size(&format!("{w}x{h}")) {
            Ok(s) => assert_eq!(s, (w, h)),
            Err(e) => {
                assert!(w == 0 || h == 0, "{w}x{h} refused: {e}");
                assert_clean_error(&e);
            }
        }
    }

    // The heights read fit.
    let Ok(raster) = from_bytes else { return };
    let (w, h) = (raster.width, raster.height);
    if (w * h) > 1 << 16 {
        return;
    }
    let Some(heights) = check_heights(raster.into_heights(None), w * h) else { return };
    let mut normals = vec![[0.0f32; 3]; w * h];
    FitRequest::new(&fit).normals_into(&heights, w, h, &mut normals).expect("RAW heights fit");
    for (k, &n) in normals.iter().enumerate() {
        assert_unit_normal(n, k);
    }
});
