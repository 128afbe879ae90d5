//! Bytes in a file → `PngRows` → `convert_png_seekable`, the streaming path
//! of `normalfit convert` for PNG, against the whole-image path on the same
//! bytes (`decode` → heights → `normals_into`).
//!
//! Must hold for any bytes: no panic, abort or hang; failures are `Err`
//! with a one-line message; and when both paths succeed, the streamed
//! heights and the streamed PNG's texels are those of the whole-image path,
//! bit for bit (the documented promise of the streaming module).
#![no_main]

use std::io::Cursor;

use libfuzzer_sys::fuzz_target;
use normalfit::FitRequest;
use normalfit::io::decode;
use normalfit::pipeline::{PngDepth, PngRows, RowSource, convert_png_seekable};
use normalfit_fuzz::{Case, assert_clean_error, case_file, read_options, streamed_heights_match};

fuzz_target!(|data: &[u8]| {
    let case = Case::of(data);
    let path = case_file("png-stream", "png", data);
    let rows = match PngRows::open(path, &read_options(), case.channel.clone()) {
        Ok(Some(rows)) => rows,
        // Not a PNG that streams: the caller reads it whole, another target's path.
        Ok(None) => return,
        Err(e) => return assert_clean_error(&e),
    };
    let (w, h) = (rows.width(), rows.height());
    let depth = if case.sixteen { PngDepth::Sixteen } else { PngDepth::Eight };
    let mut streamed_heights = Vec::new();
    let mut png = Cursor::new(Vec::new());
    let streamed =
        convert_png_seekable(rows, &case.fit, depth, |row| streamed_heights.extend_from_slice(row), &mut png);
    let Some(heights) = streamed_heights_match(data, case.channel.clone(), &streamed, &streamed_heights, (w, h)) else {
        return;
    };

    // The streamed PNG's texels against the whole-image fit.
    let out = decode(png.get_ref(), &read_options()).expect("the streamed PNG decodes");
    assert_eq!((out.width, out.height, out.planes.len()), (w, h, 3));
    let top = if case.sixteen { 65535.0 } else { 255.0 };
    let texel = |k: usize| {
        out.planes
            .iter()
            .map(|p| (p.data.height(k).expect("k < width × height") * top).round() as u16)
            .collect::<Vec<_>>()
    };
    if case.sixteen {
        let mut rgb = vec![[0u16; 3]; w * h];
        FitRequest::new(&case.fit)
            .normals_into(&heights, w, h, &mut rgb)
            .expect("finite heights and valid options must fit");
        for (k, c) in rgb.iter().enumerate() {
            assert_eq!(texel(k), c, "texel {k} of the streamed 16-bit PNG");
        }
    } else {
        let mut rgb = vec![[0u8; 3]; w * h];
        FitRequest::new(&case.fit)
            .normals_into(&heights, w, h, &mut rgb)
            .expect("finite heights and valid options must fit");
        for (k, c) in rgb.iter().enumerate() {
            assert_eq!(texel(k), c.map(u16::from), "texel {k} of the streamed 8-bit PNG");
        }
    }
});
