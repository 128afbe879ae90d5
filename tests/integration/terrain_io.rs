//! Terrain inputs through the library's read API (issue 17): GeoTIFF
//! elevation of every sample type, striped and tiled, one band or several
//! (chunky or planar), its georeferencing; RAW heightmaps; heights packed
//! in RGB tiles. Every fixture is made here and every expected value is
//! computed here from the values written, not by the reader.

use crate::common;

use std::io::Cursor;

use common::geotiff::{self, GeoTag, Kind, Layout};
use normalfit::Error;
use normalfit::io::{
    ByteOrder, InputFormat, ModelType, PackedElevation, RasterType, RawOptions, ReadOptions, SampleType, decode,
    metres_per_degree, read_path,
};
use normalfit::samples::Samples;

fn f64s(samples: &Samples) -> Vec<f64> {
    (0..samples.len()).map(|i| samples.height(i).unwrap()).collect()
}

/// What a stored value of `kind` is in contract units (SPEC §1 and
/// docs/terrain.md): 8- and 16-bit unsigned and every signed or 32-bit
/// integer value / (2^bits − 1), floats as stored.
fn contract(kind: Kind, v: f64) -> f64 {
    match kind {
        Kind::U8 => v / 255.0,
        Kind::U16 | Kind::I16 => v / 65535.0,
        Kind::U32 | Kind::I32 => v / 4_294_967_295.0,
        Kind::F32 | Kind::F64 => v,
    }
}

fn sample_type(kind: Kind) -> SampleType {
    match kind {
        Kind::U8 => SampleType::Int { bits: 8 },
        Kind::U16 => SampleType::Int { bits: 16 },
        Kind::U32 => SampleType::Int { bits: 32 },
        Kind::I16 => SampleType::SignedInt { bits: 16 },
        Kind::I32 => SampleType::SignedInt { bits: 32 },
        Kind::F32 | Kind::F64 => SampleType::Float,
    }
}

/// Every layout: each sample type, 1 and 3 bands, chunky and planar,
/// strips (of 5 rows, the last short) and 16 × 16 tiles (cut by the edges
/// of a 37 × 23 image).
fn layouts() -> Vec<Layout> {
    let mut all = Vec::new();
    for kind in Kind::ALL {
        for bands in [1, 3] {
            for planar in [false, true] {
                if bands == 1 && planar {
                    continue;
                }
                for tile in [None, Some((16, 16))] {
                    all.push(Layout { kind, bands, planar, tile, rows_per_strip: 5, photometric: 1 });
                }
            }
        }
    }
    all
}

#[test]
fn every_sample_type_layout_and_band_reads_its_stored_values() {
    let (w, h) = (37, 23);
    for layout in layouts() {
        let values = geotiff::band_values(&layout, w, h);
        let bytes = geotiff::write(w, h, &layout, &values, &[]);
        let bands: Vec<Option<u32>> = std::iter::once(None).chain((1..=layout.bands as u32).map(Some)).collect();
        for band in bands {
            let opts = match band {
                Some(b) => ReadOptions::default().with_band(b),
                None => ReadOptions::default(),
            };
            let what = format!("{layout:?} band {band:?}");
            let raster = decode(&bytes, &opts).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_eq!((raster.width, raster.height, raster.format.clone()), (w, h, InputFormat::Tiff), "{what}");
            assert_eq!(raster.sample, sample_type(layout.kind), "{what}");
            assert_eq!(raster.planes.len(), 1, "{what}: one band is read");
            assert!(raster.georef.is_none(), "{what}: no geo tags, no georef");
            // Without a band, the first.
            let want = &values[band.map_or(0, |b| b as usize - 1)];
            let heights = f64s(&raster.clone().into_heights(None).unwrap());
            for (i, (&got, &v)) in heights.iter().zip(want).enumerate() {
                let expect = contract(layout.kind, v);
                assert!((got - expect).abs() <= 1e-15 * expect.abs(), "{what} texel {i}: {got} vs {expect}");
            }
            let stored = f64s(&raster.into_stored_heights(None).unwrap());
            assert_eq!(&stored, want, "{what}: the stored values come back exactly");
        }
    }
}

#[test]
fn an_rgb_tiff_keeps_its_colours_without_a_band_and_gives_one_with() {
    // 8-bit RGB goes to `image` as before (luma by default), and --band
    // picks a channel whatever the photometric interpretation says.
    let (w, h) = (6, 4);
    let layout = Layout { kind: Kind::U8, bands: 3, planar: false, tile: None, rows_per_strip: 2, photometric: 2 };
    let values = geotiff::band_values(&layout, w, h);
    let bytes = geotiff::write(w, h, &layout, &values, &[]);
    let rgb = decode(&bytes, &ReadOptions::default()).unwrap();
    assert_eq!(rgb.planes.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(), ["R", "G", "B"]);
    let g = decode(&bytes, &ReadOptions::default().with_band(2)).unwrap();
    assert_eq!(f64s(&g.planes[0].data).iter().map(|h| (h * 255.0).round()).collect::<Vec<_>>(), values[1]);
    // A 16-bit signed RGB, which `image` refuses, reads its first band.
    let layout = Layout { kind: Kind::I16, ..layout };
    let values = geotiff::band_values(&layout, w, h);
    let bytes = geotiff::write(w, h, &layout, &values, &[]);
    let first = decode(&bytes, &ReadOptions::default()).unwrap();
    assert_eq!(f64s(&first.into_stored_heights(None).unwrap()), values[0]);
}

#[test]
fn projected_georeferencing_is_read() {
    let (w, h) = (5, 4);
    let layout = geotiff::Layout::gray(Kind::I16);
    let values = geotiff::band_values(&layout, w, h);
    let raster =
        decode(&geotiff::write(w, h, &layout, &values, &geotiff::utm_tags()), &ReadOptions::default()).unwrap();
    let g = raster.georef.expect("geo tags read");
    assert_eq!(g.pixel_scale, Some([30.0, 30.0, 0.0]));
    assert_eq!(g.tiepoints, vec![[0.0, 0.0, 0.0, 500_000.0, 4_500_000.0, 0.0]]);
    assert_eq!(g.model, Some(ModelType::Projected));
    assert_eq!(g.raster_type, Some(RasterType::PixelIsArea));
    assert_eq!(g.epsg, Some(32633));
    assert_eq!(g.linear_unit, Some(9001));
    assert_eq!(g.nodata, Some(-32768.0));
    assert_eq!(g.pixel_size(), Some((30.0, -30.0)), "y negative: rows go south");
    assert_eq!(g.spacing(), Some((30.0, 30.0)));
    assert_eq!(g.spacing_metres(0.0), Some((30.0, 30.0)));
    let t = g.affine().unwrap();
    assert_eq!(t.apply(0.0, 0.0), (500_000.0, 4_500_000.0));
    assert_eq!(t.apply(5.0, 4.0), (500_150.0, 4_499_880.0));
    assert!(!g.is_geographic());
}

#[test]
fn unequal_spacing_feet_and_a_transformation_matrix() {
    let (w, h) = (3, 2);
    let layout = geotiff::Layout::gray(Kind::F32);
    let values = geotiff::band_values(&layout, w, h);
    let read = |tags: Vec<GeoTag>| {
        decode(&geotiff::write(w, h, &layout, &values, &tags), &ReadOptions::default()).unwrap().georef.unwrap()
    };
    // 2.5 × 4 US survey feet.
    let g = read(vec![
        GeoTag::Doubles(33550, vec![2.5, 4.0, 1.0]),
        GeoTag::Doubles(33922, vec![1.0, 2.0, 0.0, 1000.0, 2000.0, 0.0]),
        GeoTag::Shorts(34735, vec![1, 1, 0, 2, 1024, 0, 1, 1, 3076, 0, 1, 9003]),
    ]);
    assert_eq!(g.pixel_size(), Some((2.5, -4.0)));
    let foot = 1200.0 / 3937.0;
    assert_eq!(g.spacing_metres(7.0), Some((2.5 * foot, 4.0 * foot)));
    // The tiepoint names raster (1, 2): raster (0, 0) is one column west
    // and two rows north of it.
    assert_eq!(g.affine().unwrap().apply(0.0, 0.0), (997.5, 2008.0));
    assert_eq!(g.epsg, None, "no code given");

    // A rotated raster: 30° turn of 10 m pixels. The matrix wins over a
    // pixel scale, as in GDAL.
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let m =
        vec![10.0 * c, -10.0 * s, 0.0, 100.0, -10.0 * s, -10.0 * c, 0.0, 200.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let g = read(vec![GeoTag::Doubles(34264, m), GeoTag::Doubles(33550, vec![1.0, 1.0, 0.0])]);
    assert_eq!(g.pixel_size(), None, "rotated: no per-axis size");
    let (sx, sy) = g.spacing().unwrap();
    assert!((sx - 10.0).abs() < 1e-12 && (sy - 10.0).abs() < 1e-12, "{sx} {sy}");
    let (x, y) = g.affine().unwrap().apply(1.0, 0.0);
    assert!((x - (100.0 + 10.0 * c)).abs() < 1e-12 && (y - (200.0 - 10.0 * s)).abs() < 1e-12);
}

/// The length of a degree by the series expansions of the meridian arc and
/// the parallel's radius on WGS84 (the classic "111132.954 − 559.822 cos 2φ
/// …" and "111412.84 cos φ − 93.5 cos 3φ …"), independent of the
/// closed-form radii the library uses.
fn series_degree(lat: f64) -> (f64, f64) {
    let p = lat.to_radians();
    let north = 111_132.954 - 559.822 * (2.0 * p).cos() + 1.175 * (4.0 * p).cos() - 0.0023 * (6.0 * p).cos();
    let east = 111_412.84 * p.cos() - 93.5 * (3.0 * p).cos() + 0.118 * (5.0 * p).cos();
    (east, north)
}

#[test]
fn a_degree_in_metres_matches_published_tables_and_the_series() {
    // Published WGS84 lengths of a degree (km, to the metre): latitude
    // 0°, 15°, 30°, 45°, 60°, 75°, 90°.
    let table = [
        (0.0, 111.320, 110.574),
        (15.0, 107.551, 110.649),
        (30.0, 96.486, 110.852),
        (45.0, 78.847, 111.132),
        (60.0, 55.800, 111.412),
        (75.0, 28.902, 111.618),
        (90.0, 0.0, 111.694),
    ];
    for (lat, east_km, north_km) in table {
        let (east, north) = metres_per_degree(lat);
        assert!((east - east_km * 1000.0).abs() < 1.0, "{lat}°: east {east}");
        assert!((north - north_km * 1000.0).abs() < 1.0, "{lat}°: north {north}");
        assert_eq!(metres_per_degree(-lat), (east, north), "symmetric about the equator");
    }
    for tenth in 0..=900 {
        let lat = f64::from(tenth) / 10.0;
        let (east, north) = metres_per_degree(lat);
        let (se, sn) = series_degree(lat);
        assert!((east - se).abs() < 0.05, "{lat}°: east {east} vs series {se}");
        assert!((north - sn).abs() < 0.05, "{lat}°: north {north} vs series {sn}");
    }
    // The equator's exact values: a·π/180 and a(1 − e²)·π/180.
    let (east, north) = metres_per_degree(0.0);
    assert!((east - 111_319.490_793_273_6).abs() < 1e-6, "{east}");
    assert!((north - 110_574.275_821_594_4).abs() < 1e-6, "{north}");
}

#[test]
fn geographic_spacing_is_converted_at_each_rows_latitude() {
    // 1 arc-second pixels from 10° E, 46° N, WGS84 (EPSG 4326).
    let (w, h) = (4, 3);
    let layout = geotiff::Layout::gray(Kind::F32);
    let values = geotiff::band_values(&layout, w, h);
    let arc = 1.0 / 3600.0;
    let tags = vec![
        GeoTag::Doubles(33550, vec![arc, arc, 0.0]),
        GeoTag::Doubles(33922, vec![0.0, 0.0, 0.0, 10.0, 46.0, 0.0]),
        GeoTag::Shorts(34735, vec![1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326]),
        GeoTag::Ascii(42113, "nan".into()),
    ];
    let g = decode(&geotiff::write(w, h, &layout, &values, &tags), &ReadOptions::default()).unwrap().georef.unwrap();
    assert!(g.is_geographic());
    assert_eq!(g.epsg, Some(4326));
    assert!(g.nodata.unwrap().is_nan());
    assert_eq!(g.pixel_size(), Some((arc, -arc)));
    for row in 0..h {
        let lat = 46.0 - (row as f64 + 0.5) * arc;
        let (east, north) = g.spacing_metres(row as f64).unwrap();
        let (se, sn) = series_degree(lat);
        assert!((east - se * arc).abs() < 1e-4, "row {row}: {east} vs {}", se * arc);
        assert!((north - sn * arc).abs() < 1e-4, "row {row}: {north} vs {}", sn * arc);
        // About 21.5 m by 30.9 m at 46° N.
        assert!((21.0..22.0).contains(&east) && (30.5..31.5).contains(&north), "{east} {north}");
    }
}

/// A raster known by its GDAL geotransform and CRS (an xarray
/// DataArray's) gets the spacing the same raster's GeoTIFF gets, bit for
/// bit: projected and geographic (one per row); rotated and irregular
/// grids are refused in one line naming why.
#[test]
fn a_geotransform_gives_the_files_spacing() {
    use normalfit::Spacing;
    use normalfit::units::{Crs, centres_geotransform, geotransform_spacing, map_spacing};
    let (w, h) = (4, 3);
    let layout = geotiff::Layout::gray(Kind::F32);
    let values = geotiff::band_values(&layout, w, h);
    let arc = 1.0 / 3600.0;
    let read = |scale: [f64; 2], origin: [f64; 2], keys: Vec<u16>| {
        let tags = vec![
            GeoTag::Doubles(33550, vec![scale[0], scale[1], 0.0]),
            GeoTag::Doubles(33922, vec![0.0, 0.0, 0.0, origin[0], origin[1], 0.0]),
            GeoTag::Shorts(34735, keys),
        ];
        let raster = decode(&geotiff::write(w, h, &layout, &values, &tags), &ReadOptions::default()).unwrap();
        map_spacing(raster.georef.as_ref(), h).unwrap()
    };
    let geographic = read([arc, arc], [10.0, 46.0], vec![1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326]);
    let given = geotransform_spacing([10.0, arc, 0.0, 46.0, 0.0, -arc], Crs::Geographic { unit: 9122 }, h).unwrap();
    assert!(matches!(given, Spacing::Rows(_)));
    for row in 0..h {
        assert_eq!(given.at(row).map(f64::to_bits), geographic.at(row).map(f64::to_bits), "row {row}");
    }
    // Feet: 30 ft columns, 36 ft rows, in metres.
    let feet = read([30.0, 36.0], [5e5, 5e6], vec![1, 1, 0, 2, 1024, 0, 1, 1, 3076, 0, 1, 9002]);
    let given = geotransform_spacing([5e5, 30.0, 0.0, 5e6, 0.0, -36.0], Crs::Projected { unit: 9002 }, h).unwrap();
    assert_eq!(given, feet);
    assert_eq!(given, Spacing::Uniform { x: 30.0 * 0.3048, y: 36.0 * 0.3048 });
    let unknown = geotransform_spacing([0.0, 2.0, 0.0, 0.0, 0.0, -3.0], Crs::Unknown, h).unwrap();
    assert_eq!(unknown, Spacing::Uniform { x: 2.0, y: 3.0 });
    // 30° counter-clockwise: x per column cos 30°, y per column sin 30°.
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let rotated = [0.0, 30.0 * c, 30.0 * s, 0.0, 30.0 * s, -30.0 * c];
    let e = geotransform_spacing(rotated, Crs::Projected { unit: 9001 }, h).unwrap_err().to_string();
    assert!(e.contains("rotated 30.000° counter-clockwise from north-up") && !e.contains('\n'), "{e}");
    let e = geotransform_spacing([0.0, 1.0, 0.0, 0.0, 0.0, -1.0], Crs::Projected { unit: 9093 }, h).unwrap_err();
    assert!(e.to_string().contains("EPSG 9093"), "{e}");
    // Texel centres: the corner half a step before the first.
    assert_eq!(centres_geotransform(&[11.0, 13.0, 15.0], &[9.0, 6.0]).unwrap(), [10.0, 2.0, 0.0, 10.5, 0.0, -3.0]);
    let e = centres_geotransform(&[0.0, 1.0, 2.5], &[0.0, 1.0]).unwrap_err().to_string();
    assert!(e.contains("the x coordinates are not equally spaced: from index 0 to 1 the step is 1"), "{e}");
    let e = centres_geotransform(&[0.0, 1.0], &[4.0]).unwrap_err().to_string();
    assert!(e.contains("the y coordinates are one"), "{e}");
}

#[test]
fn bad_geo_tags_are_one_line_errors() {
    let (w, h) = (2, 2);
    let layout = geotiff::Layout::gray(Kind::F32);
    let values = geotiff::band_values(&layout, w, h);
    let fails = |tags: Vec<GeoTag>, says: &str| {
        let e = decode(&geotiff::write(w, h, &layout, &values, &tags), &ReadOptions::default()).unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, Error::Decode(_)), "{text}");
        assert!(text.contains(says), "{text} should say {says}");
        assert!(!text.contains('\n'), "{text}");
    };
    fails(vec![GeoTag::Ascii(42113, "-9999x".into())], "GDAL_NODATA tag (42113) holds '-9999x', not a number");
    fails(vec![GeoTag::Doubles(33550, vec![1.0, 2.0, 3.0, 4.0])], "ModelPixelScale tag holds 4 values");
    fails(vec![GeoTag::Doubles(33922, vec![1.0; 5])], "ModelTiepoint tag holds 5 values");
    fails(vec![GeoTag::Doubles(34264, vec![1.0; 12])], "ModelTransformation tag holds 12 values");
    fails(vec![GeoTag::Shorts(34735, vec![1, 1, 0, 3, 1024, 0, 1, 1])], "GeoKeyDirectory tag: 3 keys announced");
    fails(vec![GeoTag::Shorts(34735, vec![2, 1, 0, 0])], "GeoKeyDirectory tag: version 2");
    // A nodata with spaces and a terminating NUL, as some writers leave it.
    let tags = vec![GeoTag::Ascii(42113, " -9999 ".into())];
    let r = decode(&geotiff::write(w, h, &layout, &values, &tags), &ReadOptions::default()).unwrap();
    assert_eq!(r.georef.unwrap().nodata, Some(-9999.0));
}

#[test]
fn band_and_sample_format_errors() {
    let (w, h) = (4, 3);
    let layout =
        Layout { kind: Kind::I16, bands: 3, planar: true, tile: Some((16, 16)), rows_per_strip: 5, photometric: 1 };
    let values = geotiff::band_values(&layout, w, h);
    let bytes = geotiff::write(w, h, &layout, &values, &[]);
    let e = decode(&bytes, &ReadOptions::default().with_band(4)).unwrap_err();
    assert!(matches!(&e, Error::Unsupported(m) if m == "band 4 asked for, but the file has 3 bands"), "{e}");
    let e = decode(&bytes, &ReadOptions::default().with_band(0)).unwrap_err();
    assert!(matches!(&e, Error::InvalidOption(m) if m.contains("bands count from 1")), "{e}");
    // A band of a format without bands.
    let png = rgb_png(&[[1, 2, 3]], 1, 1);
    let e = decode(&png, &ReadOptions::default().with_band(1)).unwrap_err();
    assert!(matches!(&e, Error::Unsupported(m) if m.contains("png files have no bands (only TIFF has)")), "{e}");

    // A sample format the reader does not take: 12-bit integers, 8-bit
    // floats (SampleFormat 3 with 8 bits), complex integers (5).
    let mut odd =
        geotiff::write(w, h, &Layout::gray(Kind::U16), &geotiff::band_values(&Layout::gray(Kind::U16), w, h), &[]);
    patch_short_tag(&mut odd, 339, 5);
    let e = decode(&odd, &ReadOptions::default()).unwrap_err();
    assert!(matches!(&e, Error::Unsupported(_)), "{e}");
    let mut float8 =
        geotiff::write(w, h, &Layout::gray(Kind::U8), &geotiff::band_values(&Layout::gray(Kind::U8), w, h), &[]);
    patch_short_tag(&mut float8, 339, 3);
    let e = decode(&float8, &ReadOptions::default()).unwrap_err();
    assert!(matches!(&e, Error::Unsupported(m) if m.contains("8-bit float samples are not read")), "{e}");

    // Truncated in its data: a decode error, on one line.
    let cut = &bytes[..bytes.len() / 2];
    let e = decode(cut, &ReadOptions::default()).unwrap_err();
    assert!(matches!(&e, Error::Decode(_)), "{e}");
    assert!(!e.to_string().contains('\n'));
}

/// Sets the value of a SHORT tag held inline in the first IFD of a
/// little- or big-endian classic TIFF (in place).
fn patch_short_tag(bytes: &mut [u8], tag: u16, value: u16) {
    let le = bytes[0] == b'I';
    let u16_at = |b: &[u8], at: usize| {
        if le { u16::from_le_bytes([b[at], b[at + 1]]) } else { u16::from_be_bytes([b[at], b[at + 1]]) }
    };
    let u32_at = |b: &[u8], at: usize| {
        let a = [b[at], b[at + 1], b[at + 2], b[at + 3]];
        if le { u32::from_le_bytes(a) } else { u32::from_be_bytes(a) }
    };
    let ifd = u32_at(bytes, 4) as usize;
    let count = u16_at(bytes, ifd) as usize;
    for k in 0..count {
        let entry = ifd + 2 + 12 * k;
        if u16_at(bytes, entry) == tag {
            let v = if le { value.to_le_bytes() } else { value.to_be_bytes() };
            bytes[entry + 8..entry + 10].copy_from_slice(&v);
            return;
        }
    }
    panic!("no tag {tag}");
}

// ---------------------------------------------------------------------------
// RAW heightmaps.

fn u16s(samples: &Samples) -> Vec<u16> {
    match samples {
        Samples::U16(v) => v.clone(),
        other => panic!("16-bit samples expected, got {other:?}"),
    }
}

#[test]
fn raw_files_by_extension_square_or_sized_either_byte_order() {
    let dir = tempfile::tempdir().unwrap();
    let values: Vec<u16> = (0..9 * 9).map(|i| (i * 809 % 65536) as u16).collect();
    let le: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let be: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
    for name in ["terrain.raw", "terrain.r16", "TERRAIN.R16"] {
        let path = dir.path().join(name);
        std::fs::write(&path, &le).unwrap();
        let r = read_path(&path, &ReadOptions::default()).unwrap();
        assert_eq!((r.width, r.height, r.format.clone()), (9, 9, InputFormat::Raw), "{name}");
        assert_eq!(r.sample, SampleType::Int { bits: 16 });
        assert_eq!(u16s(&r.planes[0].data), values, "{name}");
        // Contract units as a 16-bit PNG's: value / 65535.
        let h = f64s(&r.clone().into_heights(None).unwrap());
        assert_eq!(h[1], f64::from(values[1]) / 65535.0);
        assert_eq!(
            f64s(&r.into_stored_heights(None).unwrap()),
            values.iter().map(|&v| f64::from(v)).collect::<Vec<_>>()
        );
    }
    let path = dir.path().join("mac.raw");
    std::fs::write(&path, &be).unwrap();
    let big = ReadOptions::default().with_raw(RawOptions::default().with_byte_order(ByteOrder::Big));
    assert_eq!(u16s(&read_path(&path, &big).unwrap().planes[0].data), values);

    // 8 bits: a square of bytes, or named .r8.
    let bytes: Vec<u8> = (0..25).map(|i| (i * 11) as u8).collect();
    for name in ["small.raw", "small.r8"] {
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).unwrap();
        let r = read_path(&path, &ReadOptions::default()).unwrap();
        assert_eq!((r.width, r.height, r.sample), (5, 5, SampleType::Int { bits: 8 }), "{name}");
        assert_eq!(r.planes[0].data, Samples::U8(bytes.clone()));
    }
    // A size given: 4 × 2 at 16 bits, the bytes also given to `decode`.
    let rect: Vec<u16> = (0..8).map(|i| 1000 * i).collect();
    let rect_le: Vec<u8> = rect.iter().flat_map(|v| v.to_le_bytes()).collect();
    let sized = ReadOptions::default().with_raw(RawOptions::default().with_size(4, 2));
    let r = decode(&rect_le, &sized).unwrap();
    assert_eq!((r.width, r.height), (4, 2));
    assert_eq!(u16s(&r.planes[0].data), rect);
    // With a RAW layout, a file whose extension names no format is RAW;
    // one named as another format is read by its content.
    let bin = dir.path().join("heights.bin");
    std::fs::write(&bin, &rect_le).unwrap();
    assert_eq!(read_path(&bin, &sized).unwrap().format, InputFormat::Raw);
    let png = dir.path().join("tile.png");
    std::fs::write(&png, rgb_png(&[[1, 2, 3]], 1, 1)).unwrap();
    assert_eq!(read_path(&png, &sized).unwrap().format, InputFormat::Png);
    // Without one, RAW bytes are not recognised by content.
    assert!(read_path(&bin, &ReadOptions::default()).is_err());
}

#[test]
fn raw_lengths_that_do_not_fit_say_what_would() {
    let dir = tempfile::tempdir().unwrap();
    let check = |name: &str, len: usize, opts: &ReadOptions, says: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, vec![7u8; len]).unwrap();
        let e = read_path(&path, opts).unwrap_err();
        assert!(matches!(&e, Error::Decode(m) if m == says), "{name}: {e}");
    };
    let any = ReadOptions::default();
    check(
        "a.raw",
        10,
        &any,
        "RAW heightmap of 10 bytes is not a square of 8- or 16-bit samples (n² bytes at 8 bits, 2·n² at 16): give its width and height",
    );
    // 16 bytes are 4² bytes, but .r16 says 16 bits, and 8 is no square.
    check(
        "b.r16",
        16,
        &any,
        "RAW heightmap of 16 bytes is not a square of 16-bit samples (n² bytes at 8 bits, 2·n² at 16): give its width and height",
    );
    check(
        "c.r8",
        8,
        &any,
        "RAW heightmap of 8 bytes is not a square of 8-bit samples (n² bytes at 8 bits, 2·n² at 16): give its width and height",
    );
    let sized = ReadOptions::default().with_raw(RawOptions::default().with_size(1025, 1025));
    check(
        "d.raw",
        2 * 1025 * 1025 - 1,
        &sized,
        "RAW heightmap of 2101249 bytes does not hold 1025×1025 8- or 16-bit samples (that takes 1050625 bytes at 8 bits or 2101250 bytes at 16 bits)",
    );
    check(
        "e.r16",
        1025 * 1025,
        &sized,
        "RAW heightmap of 1050625 bytes does not hold 1025×1025 16-bit samples (that takes 2101250 bytes at 16 bits)",
    );
    let path = dir.path().join("empty.r16");
    std::fs::write(&path, b"").unwrap();
    assert!(matches!(read_path(&path, &any), Err(Error::Decode(m)) if m == "file is empty"));
    let e = decode(&[0; 8], &ReadOptions::default().with_raw(RawOptions::default().with_size(0, 4))).unwrap_err();
    assert!(matches!(e, Error::InvalidOption(_)), "{e}");
    // Past the texel limit, refused before any buffer.
    let e = decode(&[0; 32], &ReadOptions::default().with_max_texels(15).with_raw(RawOptions::default())).unwrap_err();
    assert!(matches!(e, Error::Limits(_)), "{e}");
}

// ---------------------------------------------------------------------------
// Heights packed in RGB tiles.

fn rgb_png(pixels: &[[u8; 3]], w: u32, h: u32) -> Vec<u8> {
    let flat: Vec<u8> = pixels.iter().flatten().copied().collect();
    let img = image::RgbImage::from_raw(w, h, flat).unwrap();
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// Pixels that cover the packings' ranges: each byte at 0, mid and 255.
fn tile_pixels() -> Vec<[u8; 3]> {
    let levels = [0u8, 1, 127, 128, 254, 255];
    let mut px = Vec::new();
    for r in levels {
        for g in levels {
            for b in levels {
                px.push([r, g, b]);
            }
        }
    }
    px
}

#[test]
fn terrain_rgb_and_terrarium_tiles_unpack_to_metres() {
    let px = tile_pixels();
    let (w, h) = (px.len() as u32 / 6, 6);
    let png = rgb_png(&px, w, h);
    // Terrain-RGB in integer decimetres first, so the expected value is
    // one rounding from exact: (−100000 + 24-bit value) / 10.
    let terrain_rgb: Vec<f64> = px
        .iter()
        .map(|p| (-100_000 + ((i64::from(p[0]) << 16) | (i64::from(p[1]) << 8) | i64::from(p[2]))) as f64 / 10.0)
        .collect();
    // Terrarium in 256ths of a metre, exact in f64.
    let terrarium: Vec<f64> = px
        .iter()
        .map(|p| ((i64::from(p[0]) << 16) + (i64::from(p[1]) << 8) + i64::from(p[2]) - (32_768 << 8)) as f64 / 256.0)
        .collect();
    for (packing, want) in [(PackedElevation::TerrainRgb, &terrain_rgb), (PackedElevation::Terrarium, &terrarium)] {
        let r = decode(&png, &ReadOptions::default().with_decode(packing)).unwrap();
        assert_eq!((r.sample, r.planes.len()), (SampleType::Float, 1), "{packing}");
        let got = f64s(&r.planes[0].data);
        for (i, (&g, &e)) in got.iter().zip(want.iter()).enumerate() {
            assert!((g - e).abs() <= 1e-9, "{packing} texel {i} {:?}: {g} vs {e}", px[i]);
        }
    }
    // The ends of each range.
    assert_eq!(PackedElevation::TerrainRgb.metres(0, 0, 0), -10_000.0);
    assert!((PackedElevation::TerrainRgb.metres(255, 255, 255) - 1_667_721.5).abs() < 1e-6);
    assert_eq!(PackedElevation::Terrarium.metres(128, 0, 0), 0.0);
    assert_eq!(PackedElevation::Terrarium.metres(0, 0, 0), -32_768.0);
    assert_eq!(PackedElevation::Terrarium.metres(255, 255, 255), 32_767.0 + 255.0 / 256.0);
    // Names as the command line gives them.
    assert_eq!("terrain-rgb".parse::<PackedElevation>().unwrap(), PackedElevation::TerrainRgb);
    assert_eq!("Terrarium".parse::<PackedElevation>().unwrap(), PackedElevation::Terrarium);
    assert!("mapzen-ish".parse::<PackedElevation>().is_err());
}

#[test]
fn a_lossless_webp_tile_unpacks_as_its_png_does() {
    let px = tile_pixels();
    let (w, h) = (px.len() as u32 / 6, 6);
    let flat: Vec<u8> = px.iter().flatten().copied().collect();
    let img = image::RgbImage::from_raw(w, h, flat).unwrap();
    let mut webp = Cursor::new(Vec::new());
    img.write_to(&mut webp, image::ImageFormat::WebP).unwrap();
    let opts = ReadOptions::default().with_decode(PackedElevation::Terrarium);
    let from_webp = decode(&webp.into_inner(), &opts).unwrap();
    let from_png = decode(&rgb_png(&px, w, h), &opts).unwrap();
    assert_eq!(from_webp.format, InputFormat::WebP);
    assert_eq!(from_webp.planes, from_png.planes);
}

#[test]
fn packed_tiles_must_be_8_bit_rgb_png_or_webp() {
    let opts = ReadOptions::default().with_decode(PackedElevation::TerrainRgb);
    let gray = {
        let img = image::GrayImage::from_raw(2, 1, vec![1, 2]).unwrap();
        let mut out = Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png).unwrap();
        out.into_inner()
    };
    let e = decode(&gray, &opts).unwrap_err();
    assert!(
        matches!(&e, Error::Unsupported(m) if m == "terrain-rgb tiles hold 8-bit RGB; this one has channels Y"),
        "{e}"
    );
    let deep = {
        let img = image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(1, 1, vec![1u16, 2, 3]).unwrap();
        let mut out = Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png).unwrap();
        out.into_inner()
    };
    let e = decode(&deep, &opts).unwrap_err();
    assert!(
        matches!(&e, Error::Unsupported(m) if m == "terrain-rgb tiles hold 8-bit RGB; this one has 16-bit integer samples"),
        "{e}"
    );
    let layout = Layout { kind: Kind::U8, bands: 3, planar: false, tile: None, rows_per_strip: 1, photometric: 2 };
    let tif = geotiff::write(1, 1, &layout, &[vec![1.0], vec![2.0], vec![3.0]], &[]);
    let e = decode(&tif, &opts).unwrap_err();
    assert!(
        matches!(&e, Error::Unsupported(m) if m == "terrain-rgb heights are unpacked from PNG or WebP tiles, not from tiff files"),
        "{e}"
    );
}
