//! TIFF input streams (`pipeline::TiffRows`): for every layout — each
//! sample type, one and three bands, chunky and planar, strips and tiles
//! cut by the image's edges — and every band, the normal map streamed is
//! the whole-image path's byte for byte (float EXR, so every bit of every
//! normal counts; 16-bit PNG too). The lit view streamed is the whole
//! view's, grey for grey. The georeferencing written beside a PNG output
//! (world file, .aux.xml) places it where the GeoTIFF is.

use crate::common;

use std::path::Path;

use common::geotiff::{self, GeoTag, Kind, Layout};
use normalfit::convert::{BorderChoice, BorderChoices, Conversion, Input, Output};
use normalfit::io::{ReadOptions, read_path};
use normalfit::shade::{LitOptions, Sun, SunChoice, lit_file, lit_view};
use normalfit::units::MapSpacing;
use normalfit::{Border, Borders, Options, Strength};

/// Every layout, as tests/integration/terrain_io.rs reads them: strips of 5 rows (the
/// last short) and 16 × 16 tiles cut by the edges of a 37 × 23 image.
fn layouts() -> Vec<Layout> {
    let mut all = Vec::new();
    for kind in Kind::ALL {
        for (bands, planar) in [(1, false), (3, false), (3, true)] {
            for tile in [None, Some((16, 16))] {
                all.push(Layout { kind, bands, planar, tile, rows_per_strip: 5, photometric: 1 });
            }
        }
    }
    all
}

/// Smooth heights in the type's range, so the fit sees slopes, not noise
/// only; values exact in the type.
fn values(layout: &Layout, w: usize, h: usize) -> Vec<Vec<f64>> {
    let raw = geotiff::band_values(layout, w, h);
    raw.iter()
        .map(|band| {
            band.iter()
                .enumerate()
                .map(|(i, &v)| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    let wave = (x * 0.3).sin() * (y * 0.2).cos();
                    match layout.kind {
                        Kind::U8 => (127.0 + 100.0 * wave).round(),
                        Kind::U16 => (30000.0 + 20000.0 * wave).round() + (v % 7.0),
                        Kind::I16 => (-2000.0 + 20000.0 * wave).round() + (v % 7.0),
                        Kind::F32 => f64::from((1500.0 + 300.0 * wave) as f32) + v * 1e-3,
                        _ => v + (1e9 * wave).round(),
                    }
                })
                .map(|v| if layout.kind == Kind::F32 { f64::from(v as f32) } else { v })
                .collect()
        })
        .collect()
}

/// Converts `input` to `output`: streamed, or whole (a residual map is made
/// from the whole image, so asking for one reads it whole). Returns the
/// output's bytes (an EXR's, which both paths encode alike; a PNG's
/// samples, which the two PNG encoders compress differently) and whether
/// it streamed.
fn convert(input: &Path, output: &Path, read: &ReadOptions, borders: Borders, whole: bool) -> (Vec<u8>, bool) {
    let fit = Options::new().with_patch(5);
    let conversion = Conversion::new()
        .with_fit(fit)
        .with_borders(BorderChoices::from(borders))
        .with_read(read.clone())
        .with_signed(output.extension().is_some_and(|e| e == "exr"))
        .with_residual(whole);
    let summary = conversion.convert_file(input, output).unwrap_or_else(|e| panic!("{}: {e}", input.display()));
    let bytes = if output.extension().is_some_and(|e| e == "png") {
        let raster = read_path(output, &ReadOptions::default()).unwrap();
        raster.planes.iter().flat_map(|p| p.data.to_f32().unwrap()).flat_map(f32::to_le_bytes).collect()
    } else {
        std::fs::read(output).unwrap()
    };
    (bytes, summary.streamed)
}

#[test]
fn every_tiff_layout_and_band_streams_the_whole_image_normals_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37, 23);
    let (mut streamed_layouts, mut must) = (0, 0);
    for layout in layouts() {
        let values = values(&layout, w, h);
        let input = dir.path().join("in.tif");
        std::fs::write(&input, geotiff::write(w, h, &layout, &values, &geotiff::utm_tags())).unwrap();
        let bands: Vec<Option<u32>> = std::iter::once(None).chain((1..=layout.bands as u32).map(Some)).collect();
        for band in bands {
            let read = band.map_or_else(ReadOptions::default, |b| ReadOptions::default().with_band(b));
            // 8- and 16-bit gray and RGB without a band are `image`'s, read whole.
            let must_stream = band.is_some() || !matches!(layout.kind, Kind::U8 | Kind::U16);
            must += usize::from(must_stream);
            for borders in [Borders::both(Border::Wrap), Borders { x: Border::Clamp, y: Border::Mirror }] {
                for ext in ["exr", "png"] {
                    let what = format!("{layout:?}, band {band:?}, {borders:?}, {ext}");
                    let (a, streamed) = convert(&input, &dir.path().join(format!("s.{ext}")), &read, borders, false);
                    assert!(streamed || !must_stream, "{what}: did not stream");
                    streamed_layouts += usize::from(streamed);
                    let (b, whole_streamed) =
                        convert(&input, &dir.path().join(format!("w.{ext}")), &read, borders, true);
                    assert!(!whole_streamed, "{what}: a residual reads the image whole");
                    assert!(a == b, "{what}: the streamed output differs from the whole image's");
                }
            }
        }
    }
    // 7 kinds × 6 layouts, each with no band and every band, 2 borders, 2 outputs.
    assert!(must > 100 && streamed_layouts >= 4 * must, "{streamed_layouts} conversions streamed, {must} layouts must");
}

/// [`convert`] in map units (the spacing as `map` says), with `nodata`
/// for holes and `auto` borders when asked: the output's bytes and
/// whether it streamed.
fn convert_in_map_units(
    input: &Path,
    output: &Path,
    read: &ReadOptions,
    (map, borders, nodata): (MapSpacing, BorderChoices, Option<f64>),
    whole: bool,
) -> (Vec<u8>, bool) {
    let fit = Options::new().with_patch(5).with_nodata(nodata);
    let conversion = Conversion::new()
        .with_fit(fit)
        .with_borders(borders)
        .with_read(read.clone())
        .with_signed(true)
        .with_map_units(Some(map))
        .with_residual(whole);
    let summary = conversion.convert_file(input, output).unwrap_or_else(|e| panic!("{}: {e}", input.display()));
    (std::fs::read(output).unwrap(), summary.streamed)
}

/// Map units (`--units map`, as GIS users convert a DEM) stream too: the
/// heights as stored, the spacing from the GeoTIFF, for every sample
/// type and layout, fixed and `auto` borders, with holes and without: the
/// float EXR streamed is the whole image's byte for byte.
#[test]
fn map_units_stream_the_whole_image_normals_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37, 23);
    let mut streamed = 0;
    for layout in layouts() {
        let values = values(&layout, w, h);
        let input = dir.path().join("in.tif");
        std::fs::write(&input, geotiff::write(w, h, &layout, &values, &geotiff::utm_tags())).unwrap();
        let read = ReadOptions::default().with_band(1);
        let hole = values[0][w + 3];
        let choices = [
            (BorderChoices::from(Borders::both(Border::Wrap)), None),
            (BorderChoices::both(BorderChoice::Auto), None),
            (BorderChoices::from(Borders { x: Border::Clamp, y: Border::Mirror }), Some(hole)),
        ];
        for (borders, nodata) in choices {
            let what = format!("{layout:?}, {borders:?}, nodata {nodata:?}");
            let how = (MapSpacing::FromFile, borders, nodata);
            let (a, was_streamed) = convert_in_map_units(&input, &dir.path().join("s.exr"), &read, how, false);
            assert!(was_streamed, "{what}: a band streams in map units");
            streamed += 1;
            let (b, _) = convert_in_map_units(&input, &dir.path().join("w.exr"), &read, how, true);
            assert!(a == b, "{what}: the streamed output differs from the whole image's");
        }
    }
    assert!(streamed >= 3 * layouts().len(), "{streamed}");
}

/// PNG (8- and 16-bit gray, 8-bit RGB through luma) and EXR heights in map
/// units with a given pixel size stream, and give the whole image's bytes.
#[test]
fn png_and_exr_in_map_units_stream_the_whole_image_normals() {
    use normalfit::io::{ExrDepth, ExrOptions, PngDepth, PngOptions, encode_gray, encode_normals};
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (41, 29);
    let wave = |i: usize| {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        0.5 + 0.4 * (x * 0.3).sin() * (y * 0.2).cos()
    };
    let write = |name: &str, encode: &dyn Fn(&mut std::fs::File)| {
        let path = dir.path().join(name);
        encode(&mut std::fs::File::create(&path).unwrap());
        path
    };
    let gray8: Vec<u8> = (0..w * h).map(|i| (wave(i) * 255.0).round() as u8).collect();
    let gray16: Vec<u16> = (0..w * h).map(|i| (wave(i) * 65535.0).round() as u16).collect();
    let rgb8: Vec<[u8; 3]> = (0..w * h).map(|i| [gray8[i], gray8[(i + 7) % (w * h)], 40]).collect();
    let floats: Vec<f32> = (0..w * h).map(|i| (300.0 * wave(i)) as f32).collect();
    let inputs = [
        write("g8.png", &|f| encode_gray(&gray8, w, h, &PngOptions::new(PngDepth::Eight).into(), f).unwrap()),
        write("g16.png", &|f| encode_gray(&gray16, w, h, &PngOptions::new(PngDepth::Sixteen).into(), f).unwrap()),
        write("rgb8.png", &|f| encode_normals(&rgb8, None, w, h, &PngOptions::new(PngDepth::Eight).into(), f).unwrap()),
        write("f.exr", &|f| encode_gray(&floats, w, h, &ExrOptions::new(ExrDepth::Float).into(), f).unwrap()),
    ];
    for input in &inputs {
        for borders in [Borders::both(Border::Wrap), Borders { x: Border::Mirror, y: Border::Clamp }] {
            let what = format!("{}, {borders:?}", input.display());
            let how = (MapSpacing::Given { x: 2.0, y: 3.0 }, BorderChoices::from(borders), None);
            let read = ReadOptions::default();
            let (a, streamed) = convert_in_map_units(input, &dir.path().join("s.exr"), &read, how, false);
            assert!(streamed, "{what}: did not stream");
            let (b, _) = convert_in_map_units(input, &dir.path().join("w.exr"), &read, how, true);
            assert!(a == b, "{what}: the streamed output differs from the whole image's");
        }
    }
}

/// A float32 GeoTIFF of `w` × `h` heights, north-up, 10 m texels.
fn dem(path: &Path, w: usize, h: usize) {
    let layout =
        Layout { kind: Kind::F32, bands: 1, planar: false, tile: Some((16, 16)), rows_per_strip: 5, photometric: 1 };
    let values = vec![
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                f64::from((200.0 + 40.0 * (x * 0.25).sin() * (y * 0.15).cos() + 3.0 * x) as f32)
            })
            .collect(),
    ];
    std::fs::write(path, geotiff::write(w, h, &layout, &values, &geotiff::utm_tags())).unwrap();
}

#[test]
fn the_lit_view_streams_the_whole_views_greys_and_keeps_the_georeferencing() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dem.tif");
    dem(&input, 45, 38);
    let read = ReadOptions::default();
    let fit = Options::new().with_strength(Strength::Scale(0.1));
    let mut pictures = Vec::new();
    for (sun, borders) in [
        (SunChoice::Georeferenced(Sun::default()), Borders::both(Border::Clamp)),
        (SunChoice::Always(Sun::new(200.0, 30.0).unwrap()), Borders::both(Border::Wrap)),
        (SunChoice::Off, Borders { x: Border::Mirror, y: Border::Wrap }),
    ] {
        let opts = LitOptions::new().with_fit(fit.clone().with_borders(borders)).with_sun(sun);
        let out = dir.path().join("lit.png");
        let done = lit_file(Input::Path(&input), &read, &opts, Output::file(&out))
            .inspect(|done| assert!(done.streamed, "a float GeoTIFF streams"))
            .unwrap();
        assert_eq!(done.sidecars.len(), 2, "world file and .aux.xml");
        let streamed = read_path(&out, &read).unwrap().heights(None).unwrap();
        let whole = lit_view(&read_path(&input, &read).unwrap(), &opts).unwrap();
        let whole: Vec<f32> = whole.pixels.iter().map(|&g| f32::from(g) / 255.0).collect();
        assert_eq!(streamed, whole, "{sun:?}, {borders:?}");
        pictures.push(whole);
    }
    // The sun and the texture light draw different pictures.
    assert!(pictures[0] != pictures[2]);
}

#[test]
fn a_world_file_puts_the_texel_centres_where_the_geotiff_does() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dem.tif");
    dem(&input, 20, 12);
    let out = dir.path().join("n.png");
    let summary = Conversion::new().convert_file(&input, &out).unwrap();
    assert!(summary.streamed);
    let pgw = dir.path().join("n.pgw");
    assert_eq!(summary.sidecars, [pgw.clone(), dir.path().join("n.png.aux.xml")]);
    // utm_tags: 30 m texels, tiepoint (0, 0) at (500000, 4650000), PixelIsArea.
    let georef = read_path(&input, &ReadOptions::default()).unwrap().georef.unwrap();
    let t = georef.affine().unwrap();
    let (cx, cy) = t.apply(0.5, 0.5);
    let lines: Vec<f64> = std::fs::read_to_string(&pgw).unwrap().lines().map(|l| l.parse().unwrap()).collect();
    assert_eq!(lines, [t.a, t.d, t.b, t.e, cx, cy]);
    let aux = std::fs::read_to_string(dir.path().join("n.png.aux.xml")).unwrap();
    assert!(aux.contains(&format!("<SRS>EPSG:{}</SRS>", georef.epsg.unwrap())), "{aux}");
    // An EXR gets none (GDAL reads no EXR where it is Debian's), nor does a
    // PNG of a file without georeferencing.
    let summary = Conversion::new().convert_file(&input, &dir.path().join("n.exr")).unwrap();
    assert!(summary.sidecars.is_empty());
    assert!(!dir.path().join("n.erw").exists());
}

#[test]
fn pixel_is_point_centres_are_the_tiepoint_itself() {
    let mut georef = normalfit::io::Georef::default();
    georef.pixel_scale = Some([2.0, 3.0, 0.0]);
    georef.tiepoints = vec![[0.0, 0.0, 0.0, 100.0, 200.0, 0.0]];
    georef.raster_type = Some(normalfit::io::RasterType::PixelIsPoint);
    assert_eq!(normalfit::io::sidecar::world_file(&georef).unwrap(), "2.0\n0.0\n0.0\n-3.0\n100.0\n200.0\n");
    georef.raster_type = Some(normalfit::io::RasterType::PixelIsArea);
    assert_eq!(normalfit::io::sidecar::world_file(&georef).unwrap(), "2.0\n0.0\n0.0\n-3.0\n101.0\n198.5\n");
    assert_eq!(normalfit::io::sidecar::world_file_path(Path::new("a/b.png")), Path::new("a/b.pgw"));
    let _ = GeoTag::Ascii(0, String::new());
}
