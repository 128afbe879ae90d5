//! The checksum of a PNG's image data (zlib's Adler-32 of the inflated
//! rows): a stream whose checksum does not match is an error, in the
//! library's whole-image decode and in its streamed rows alike, and the
//! same files with the checksum right read as the values written.
//!
//! Each file is 8- or 16-bit gray, plain or Adam7-interlaced, its
//! checksum in the last IDAT chunk or in one of its own after the bytes
//! the image's last row needs (which a decoder that stops there never
//! reads). The broken file differs from the good one in those four bytes
//! and the CRC that covers them, so the checksum is all that is wrong.

use crate::corpus;

use corpus::*;
use normalfit::Error;
use normalfit::io::{ReadOptions, decode};
use normalfit::pipeline::{PngRows, RowSource};

const MISMATCH: &str = "image data is corrupt: zlib checksum (Adler-32) does not match";
const SIDE: usize = 24;

/// The stored sample of texel (x, y), different everywhere.
fn value(x: usize, y: usize, bits: u8) -> u16 {
    let v = (x * 29 + y * 67 + x * y * 3) as u16;
    if bits == 8 { v % 256 } else { v.wrapping_mul(613) }
}

/// A SIDE² gray PNG of [`value`]s, deflated (not stored, so the checksum
/// follows Huffman-coded data).
fn gray_png(bits: u8, interlaced: bool) -> Vec<u8> {
    let pixel = |x, y| match bits {
        8 => vec![value(x, y, 8) as u8],
        _ => value(x, y, 16).to_be_bytes().to_vec(),
    };
    let (header, raw) = if interlaced {
        (ihdr_adam7(SIDE as u32, SIDE as u32, bits, 0), adam7_scanlines(SIDE, SIDE, pixel))
    } else {
        (ihdr(SIDE as u32, SIDE as u32, bits, 0), scanlines(SIDE, |y| (0..SIDE).flat_map(|x| pixel(x, y)).collect()))
    };
    png_file(&header, &[], &fdeflate::compress_to_vec(&raw))
}

/// Row y's heights as written, in contract units.
fn expected_row(y: usize, bits: u8) -> Vec<f32> {
    let top = if bits == 8 { 255.0 } else { 65535.0 };
    (0..SIDE).map(|x| f32::from(value(x, y, bits)) / top).collect()
}

/// Every file: (name, bits, interlaced, checksum in its own chunk).
fn files() -> Vec<(String, u8, bool, bool)> {
    let mut out = Vec::new();
    for bits in [8, 16] {
        for interlaced in [false, true] {
            for own_chunk in [false, true] {
                let name = format!("{bits}-bit, interlaced {interlaced}, checksum in its own chunk {own_chunk}");
                out.push((name, bits, interlaced, own_chunk));
            }
        }
    }
    out
}

#[test]
fn decode_refuses_image_data_whose_checksum_does_not_match() {
    for (name, bits, interlaced, own_chunk) in files() {
        let png = gray_png(bits, interlaced);
        let good = decode(&png_adler_case(&png, false, own_chunk), &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{name}: the good file: {e}"));
        let want: Vec<f32> = (0..SIDE).flat_map(|y| expected_row(y, bits)).collect();
        assert_eq!(good.heights(None).unwrap(), want, "{name}");

        match decode(&png_adler_case(&png, true, own_chunk), &ReadOptions::default()) {
            Err(Error::Decode(m)) => assert_eq!(m, MISMATCH, "{name}"),
            other => panic!("{name}: want the checksum error, got {other:?}"),
        }
    }
}

#[test]
fn streamed_rows_refuse_image_data_whose_checksum_does_not_match() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bits, interlaced, own_chunk) in files() {
        let png = gray_png(bits, interlaced);
        let good = dir.path().join("good.png");
        let bad = dir.path().join("bad.png");
        std::fs::write(&good, png_adler_case(&png, false, own_chunk)).unwrap();
        std::fs::write(&bad, png_adler_case(&png, true, own_chunk)).unwrap();
        let open = |path| PngRows::open(path, &ReadOptions::default(), None).unwrap();
        if interlaced {
            // Adam7 does not stream: it is decoded whole, as tested above.
            assert!(open(&good).is_none() && open(&bad).is_none(), "{name}");
            continue;
        }

        let mut rows = open(&good).expect("streams");
        let mut row = vec![0.0; SIDE];
        // Rows hold the stored values; times the unit, the heights.
        let unit = rows.unit();
        let heights = |row: &[f64]| -> Vec<f32> { row.iter().map(|&v| (v * unit) as f32).collect() };
        for y in 0..SIDE {
            rows.next_row(&mut row).unwrap_or_else(|e| panic!("{name}: good row {y}: {e}"));
            assert_eq!(heights(&row), expected_row(y, bits), "{name}: row {y}");
        }

        // The decoder reads ahead, so the checksum may be read with any
        // row, the last at the latest; the rows before it are right.
        let mut rows = open(&bad).expect("streams");
        let error = (0..SIDE).find_map(|y| match rows.next_row(&mut row) {
            Ok(()) => {
                assert_eq!(heights(&row), expected_row(y, bits), "{name}: row {y}");
                None
            }
            Err(e) => Some(e),
        });
        match error {
            Some(Error::Decode(m)) => assert_eq!(m, MISMATCH, "{name}"),
            other => panic!("{name}: want the checksum error by the last row, got {other:?}"),
        }
    }
}
