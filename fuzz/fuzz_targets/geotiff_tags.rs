//! Bytes → `decode` with a GeoTIFF's tags read (ModelPixelScale,
//! ModelTiepoint, ModelTransformation, the GeoKey directory, GDAL_NODATA)
//! → the spacing of `--units map` (`MapSpacing::FromFile`) → a conversion
//! in map units through the engine into memory (PNG, TIFF with the tags
//! copied, EXR), read whole from the bytes and streamed from a file; and
//! the lit view of the same raster in map units, lit by the sun.
//!
//! Must hold for any bytes: no panic, abort, hang or huge allocation;
//! failures are `Err` with a one-line message; a georeferencing that is
//! accepted has finite values and finite, non-zero scales, and the map
//! units made from it finite, positive spacings; the whole and streamed
//! conversions write the same texels; a TIFF written carries the source's
//! georeferencing back.
#![no_main]

use libfuzzer_sys::fuzz_target;
use normalfit::Strength;
use normalfit::convert::{Conversion, Input, Output};
use normalfit::io::{OutputFormat, decode};
use normalfit::shade::{LitOptions, lit_view};
use normalfit::units::MapSpacing;
use normalfit_fuzz::{
    Pick, assert_clean_convert_error, assert_clean_error, assert_georef, assert_map_units, assert_raster, case_file,
    fit_options, read_options,
};

fuzz_target!(|data: &[u8]| {
    let mut pick = Pick::last(data, 4);
    let nodata_tag = pick.flag();
    let band = pick.one(&[None, None, Some(1), Some(2)]);
    let format = pick.one(&[OutputFormat::Png, OutputFormat::Tiff, OutputFormat::Exr]);
    let sun = pick.one(&[(None, None), (Some(315.0), Some(45.0)), (Some(90.0), Some(10.0))]);
    let fit = fit_options(&mut pick, &[Strength::Scale(1.0), Strength::Scale(8.0), Strength::Relief(0.5)]);
    let mut read = read_options().with_nodata_tag(nodata_tag);
    if let Some(b) = band {
        read = read.with_band(b);
    }

    let raster = match decode(data, &read) {
        Ok(r) => r,
        Err(e) => return assert_clean_error(&e),
    };
    assert_raster(&raster);
    let (w, h) = (raster.width, raster.height);
    if let Some(g) = &raster.georef {
        assert_georef(g, h);
    }
    let georeferenced = match MapSpacing::FromFile.units(raster.georef.as_ref(), h) {
        Ok(units) => {
            assert_map_units(&units, h);
            true
        }
        Err(e) => {
            assert_clean_error(&e);
            false
        }
    };

    // The conversion in map units: whole from the bytes, streamed (a band
    // of a TIFF) from a file.
    let conversion = Conversion::new()
        .with_read(read.clone())
        .with_fit(fit.clone())
        .with_map_units(Some(MapSpacing::FromFile))
        .with_format(Some(format));
    let mut whole = Vec::new();
    let from_bytes = conversion.convert(Input::Bytes(data), Output::Writer(&mut whole));
    let path = case_file("geotiff-tags", "tif", data);
    let mut streamed = Vec::new();
    let from_file = conversion.convert(Input::Path(path), Output::Writer(&mut streamed));
    for r in [&from_bytes, &from_file] {
        if let Err(e) = r {
            assert_clean_convert_error(e);
        }
    }
    if let Ok(summary) = &from_bytes {
        assert!(georeferenced, "a conversion in map units of a raster without its spacing succeeded");
        assert_eq!((summary.width, summary.height), (w, h));
        let out = decode(&whole, &read_options()).expect("the written image decodes");
        assert_eq!((out.width, out.height), (w, h));
        if format == OutputFormat::Tiff {
            let (a, b) = (raster.georef.as_ref().expect("map units had a georef"), out.georef.as_ref());
            let b = b.expect("the written TIFF carries the georeferencing");
            assert_eq!(
                (&a.pixel_scale, &a.tiepoints, &a.transformation),
                (&b.pixel_scale, &b.tiepoints, &b.transformation)
            );
            assert_eq!(
                (a.model, a.epsg, a.linear_unit, a.vertical_unit),
                (b.model, b.epsg, b.linear_unit, b.vertical_unit)
            );
        }
    }
    if let (Ok(_), Ok(_)) = (&from_bytes, &from_file) {
        // The same texels (the encoders may lay the bytes out otherwise).
        let (a, b) = (decode(&whole, &read_options()), decode(&streamed, &read_options()));
        let (a, b) = (a.expect("the written image decodes"), b.expect("the streamed image decodes"));
        assert!(a.planes == b.planes, "the conversion from the file wrote other texels than from memory");
    }

    // The lit view in map units, the sun placed by the georeferencing.
    let lit = match LitOptions::new()
        .with_fit(fit)
        .with_map_units(Some(MapSpacing::FromFile))
        .with_lighting(None, sun.0, sun.1)
    {
        Ok(lit) => lit,
        Err(e) => return assert_clean_error(&e),
    };
    match lit_view(&raster, &lit) {
        Ok(view) => {
            assert_eq!(view.pixels.len(), view.width * view.height);
            assert_eq!((view.width, view.height), (w, h));
        }
        Err(e) => assert_clean_error(&e),
    }
});
