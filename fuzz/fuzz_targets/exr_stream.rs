//! Bytes in a file → `ExrRows` → `convert_exr`, the streaming path of
//! `normalfit convert` for scan-line OpenEXR, against the whole-image path
//! on the same bytes (`decode` → heights → `normals_into`).
//!
//! Must hold for any bytes: no panic, abort or hang; failures are `Err`
//! with a one-line message; and when both paths succeed, the streamed
//! heights are the decoded ones and the streamed EXR holds the whole-image
//! fit's values, bit for bit.
#![no_main]

use std::io::Cursor;

use libfuzzer_sys::fuzz_target;
use normalfit::FitRequest;
use normalfit::io::decode;
use normalfit::pipeline::{ExrOptions, ExrRows, RowSource, convert_exr};
use normalfit_fuzz::{Case, assert_clean_error, case_file, read_options, streamed_heights_match};

fuzz_target!(|data: &[u8]| {
    let case = Case::of(data);
    let path = case_file("exr-stream", "exr", data);
    let open = || ExrRows::open(path, &read_options(), case.channel.clone());
    let rows = match open() {
        Ok(Some(rows)) => rows,
        // Not an EXR that streams: the caller reads it whole, another target's path.
        Ok(None) => return,
        Err(e) => return assert_clean_error(&e),
    };
    let (w, h) = (rows.width(), rows.height());
    // A wrap in y takes the last rows first, from the file's last blocks.
    let tail = if case.fit.borders.y == normalfit::Border::Wrap {
        match ExrRows::last_rows(path, &read_options(), case.channel.clone(), case.fit.patch / 2) {
            Ok(tail) => Some(tail),
            Err(e) => return assert_clean_error(&e),
        }
    } else {
        None
    };
    let mut streamed_heights = Vec::new();
    let mut exr = Cursor::new(Vec::new());
    let format = ExrOptions::default();
    let streamed =
        convert_exr(rows, tail.as_deref(), &case.fit, format, |row| streamed_heights.extend_from_slice(row), &mut exr);
    let Some(heights) = streamed_heights_match(data, case.channel.clone(), &streamed, &streamed_heights, (w, h)) else {
        return;
    };

    // The streamed EXR's values against the whole-image fit, (n + 1)/2 in f32.
    let out = decode(exr.get_ref(), &read_options()).expect("the streamed EXR decodes");
    assert_eq!((out.width, out.height), (w, h));
    let mut normals = vec![[0f32; 3]; w * h];
    FitRequest::new(&case.fit)
        .normals_into(&heights, w, h, &mut normals)
        .expect("finite heights and valid options must fit");
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        let plane = out.plane(name).expect("the streamed EXR has R, G and B").data.to_f32().expect("memory");
        for (k, n) in normals.iter().enumerate() {
            let expected = (n[c] + 1.0) * 0.5;
            assert_eq!(plane[k].to_bits(), expected.to_bits(), "texel {k} channel {name} of the streamed EXR");
        }
    }
});
