//! Bytes → `decode` with `--decode terrain-rgb` or `terrarium`: heights
//! packed into an 8-bit RGB tile's bytes, unpacked to metres; then a
//! conversion in map units with a pixel size given (a tile has no
//! georeferencing), through the engine into memory.
//!
//! Must hold for any bytes: no panic, abort, hang or huge allocation;
//! failures are `Err` with a one-line message; an unpacked tile is one
//! plane of finite float heights within the packing's range, the packing's
//! formula applied to the R, G and B bytes the same bytes decode to
//! without it, texel for texel; and the conversion writes an image of the
//! tile's size.
#![no_main]

use libfuzzer_sys::fuzz_target;
use normalfit::convert::{Conversion, Input, Output};
use normalfit::io::{InputFormat, OutputFormat, PackedElevation, SampleType, decode};
use normalfit::units::MapSpacing;
use normalfit::{Samples, Strength};
use normalfit_fuzz::{Pick, assert_clean_convert_error, assert_clean_error, assert_raster, fit_options, read_options};

fuzz_target!(|data: &[u8]| {
    let mut pick = Pick::last(data, 3);
    let packing = pick.one(&[PackedElevation::TerrainRgb, PackedElevation::Terrarium]);
    let pixel = pick.one(&[[30.0, 30.0], [1.0, 1.0], [0.5, 2.0], [1e-3, 1e-3]]);
    let format = pick.one(&[OutputFormat::Png, OutputFormat::Exr, OutputFormat::Tiff]);
    let fit = fit_options(&mut pick, &[Strength::Scale(1.0), Strength::Scale(4.0), Strength::Relief(0.5)]);
    let read = read_options().with_decode(packing);

    let raster = match decode(data, &read) {
        Ok(r) => r,
        Err(e) => return assert_clean_error(&e),
    };
    assert_raster(&raster);
    assert!(matches!(raster.format, InputFormat::Png | InputFormat::WebP), "unpacked from {:?}", raster.format);
    assert_eq!(raster.sample, SampleType::Float);
    let [plane] = &raster.planes[..] else { panic!("{} planes unpacked", raster.planes.len()) };
    let Samples::F64(heights) = &plane.data else { panic!("unpacked to {:?}", plane.data) };
    let (lo, hi) = match packing {
        PackedElevation::TerrainRgb => (-10000.0, -10000.0 + 16_777_215.0 * 0.1),
        _ => (-32768.0, 32768.0),
    };
    assert!(heights.iter().all(|v| v.is_finite() && (lo..=hi).contains(v)), "a height outside {lo} … {hi}");

    // The same bytes read as a picture: the packing of their R, G, B.
    let picture = decode(data, &read_options()).expect("a tile decodes without its packing");
    let bytes = |name: &str| match picture.plane(name).map(|p| &p.data) {
        Some(Samples::U8(v)) => v.clone(),
        other => panic!("plane {name} of an unpacked tile is {other:?}"),
    };
    let (r, g, b) = (bytes("R"), bytes("G"), bytes("B"));
    for (k, h) in heights.iter().enumerate() {
        assert_eq!(h.to_bits(), packing.metres(r[k], g[k], b[k]).to_bits(), "texel {k}");
    }

    // In map units, the pixel size given.
    let (w, h) = (raster.width, raster.height);
    let conversion = Conversion::new()
        .with_read(read)
        .with_fit(fit)
        .with_map_units(Some(MapSpacing::Given { x: pixel[0], y: pixel[1] }))
        .with_format(Some(format));
    let mut out = Vec::new();
    match conversion.convert(Input::Bytes(data), Output::Writer(&mut out)) {
        Ok(summary) => {
            assert_eq!((summary.width, summary.height), (w, h));
            let written = decode(&out, &read_options()).expect("the written image decodes");
            assert_eq!((written.width, written.height), (w, h));
        }
        Err(e) => assert_clean_convert_error(&e),
    }
});
