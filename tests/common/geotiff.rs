//! GeoTIFFs made in the tests with the `tiff` crate's directory encoder:
//! every sample type, one band or several, chunky or planar, striped or
//! tiled, with the GeoTIFF and GDAL tags. The encoder's image writer makes
//! striped chunky files of its fixed colour types only, so the strips and
//! tiles are laid out here and written with `write_data`, and the tags with
//! `write_tag`; the bytes are the tiff crate's.
// Each test file uses its own subset.
#![allow(dead_code)]

use std::io::Cursor;

use tiff::encoder::TiffEncoder;
use tiff::tags::Tag;

/// A sample type: its TIFF SampleFormat code and bits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    U8,
    U16,
    I16,
    U32,
    I32,
    F32,
    F64,
}

impl Kind {
    pub const ALL: [Kind; 7] = [Kind::U8, Kind::U16, Kind::I16, Kind::U32, Kind::I32, Kind::F32, Kind::F64];

    pub fn bytes(self) -> usize {
        match self {
            Kind::U8 => 1,
            Kind::U16 | Kind::I16 => 2,
            Kind::U32 | Kind::I32 | Kind::F32 => 4,
            Kind::F64 => 8,
        }
    }

    /// TIFF's SampleFormat: 1 unsigned, 2 signed, 3 float.
    pub fn format(self) -> u16 {
        match self {
            Kind::U8 | Kind::U16 | Kind::U32 => 1,
            Kind::I16 | Kind::I32 => 2,
            Kind::F32 | Kind::F64 => 3,
        }
    }

    /// A stored value for texel `i` of band `b`, varied over the type's
    /// range (negative for signed and float types), and exactly
    /// representable in the type.
    pub fn value(self, i: usize, b: usize) -> f64 {
        let k = ((i * 7919 + b * 104_729) % 10_007) as f64;
        match self {
            Kind::U8 => ((i * 37 + b * 101) % 256) as f64,
            Kind::U16 => ((i * 7919 + b * 104_729) % 65_536) as f64,
            Kind::I16 => ((i * 7919 + b * 104_729) % 65_536) as f64 - 32_768.0,
            Kind::U32 => k * 429_000.0 + b as f64,
            Kind::I32 => k * 429_000.0 - 2_147_000_000.0 + b as f64,
            Kind::F32 => (k - 5000.0) * 0.125 + 1500.0 * b as f64,
            Kind::F64 => (k - 5000.0) * 0.1 + 1e-9 * i as f64 + 1500.0 * b as f64,
        }
    }

    /// The native-endian bytes of a value (the encoder writes the machine's
    /// byte order and says so in the header).
    pub fn ne_bytes(self, v: f64) -> Vec<u8> {
        match self {
            Kind::U8 => vec![v as u8],
            Kind::U16 => (v as u16).to_ne_bytes().to_vec(),
            Kind::I16 => (v as i16).to_ne_bytes().to_vec(),
            Kind::U32 => (v as u32).to_ne_bytes().to_vec(),
            Kind::I32 => (v as i32).to_ne_bytes().to_vec(),
            Kind::F32 => (v as f32).to_ne_bytes().to_vec(),
            Kind::F64 => v.to_ne_bytes().to_vec(),
        }
    }
}

/// How the samples are laid out in the file.
#[derive(Clone, Copy, Debug)]
pub struct Layout {
    pub kind: Kind,
    pub bands: usize,
    /// PlanarConfiguration 2 (a plane per band) instead of 1 (interleaved).
    pub planar: bool,
    /// Tiles of this size instead of strips.
    pub tile: Option<(usize, usize)>,
    /// Rows per strip, for strips.
    pub rows_per_strip: usize,
    /// PhotometricInterpretation: 1 BlackIsZero, 2 RGB.
    pub photometric: u16,
}

impl Layout {
    pub fn gray(kind: Kind) -> Layout {
        Layout { kind, bands: 1, planar: false, tile: None, rows_per_strip: 5, photometric: 1 }
    }
}

/// A tag to add: its number and value.
pub enum GeoTag {
    Doubles(u16, Vec<f64>),
    Shorts(u16, Vec<u16>),
    Ascii(u16, String),
}

/// The stored values of every band, `values[b][y * w + x]`, for a layout.
pub fn band_values(layout: &Layout, w: usize, h: usize) -> Vec<Vec<f64>> {
    (0..layout.bands).map(|b| (0..w * h).map(|i| layout.kind.value(i, b)).collect()).collect()
}

/// A TIFF of `values` (one vector per band, row-major) laid out as
/// `layout`, with `tags`.
pub fn write(w: usize, h: usize, layout: &Layout, values: &[Vec<f64>], tags: &[GeoTag]) -> Vec<u8> {
    let kind = layout.kind;
    let size = kind.bytes();
    let sample = |b: usize, x: usize, y: usize| -> Vec<u8> {
        if x < w && y < h { kind.ne_bytes(values[b][y * w + x]) } else { vec![0; size] }
    };
    // The chunks (strips or tiles) in TIFF's order: for planar, all of
    // band 0's, then band 1's, …
    let (cw, ch) = layout.tile.unwrap_or((w, layout.rows_per_strip));
    let (across, down) = (w.div_ceil(cw), h.div_ceil(ch));
    let planes: Vec<Vec<usize>> =
        if layout.planar { (0..layout.bands).map(|b| vec![b]).collect() } else { vec![(0..layout.bands).collect()] };
    let mut chunks: Vec<Vec<u8>> = Vec::new();
    for bands in &planes {
        for cy in 0..down {
            for cx in 0..across {
                let mut chunk = Vec::new();
                // A strip's last one holds only the rows left; tiles are whole.
                let rows = if layout.tile.is_some() { ch } else { ch.min(h - cy * ch) };
                for y in cy * ch..cy * ch + rows {
                    for x in cx * cw..cx * cw + cw {
                        for &b in bands {
                            chunk.extend(sample(b, x, y));
                        }
                    }
                }
                chunks.push(chunk);
            }
        }
    }
    let mut out = Cursor::new(Vec::new());
    {
        let mut encoder = TiffEncoder::new(&mut out).unwrap();
        let mut dir = encoder.image_directory().unwrap();
        let offsets: Vec<u32> = chunks.iter().map(|c| dir.write_data(c.as_slice()).unwrap() as u32).collect();
        let counts: Vec<u32> = chunks.iter().map(|c| c.len() as u32).collect();
        let bands = layout.bands as u16;
        dir.write_tag(Tag::ImageWidth, w as u32).unwrap();
        dir.write_tag(Tag::ImageLength, h as u32).unwrap();
        dir.write_tag(Tag::BitsPerSample, vec![(size * 8) as u16; layout.bands].as_slice()).unwrap();
        dir.write_tag(Tag::Compression, 1u16).unwrap();
        dir.write_tag(Tag::PhotometricInterpretation, layout.photometric).unwrap();
        dir.write_tag(Tag::SamplesPerPixel, bands).unwrap();
        dir.write_tag(Tag::PlanarConfiguration, if layout.planar { 2u16 } else { 1u16 }).unwrap();
        dir.write_tag(Tag::SampleFormat, vec![kind.format(); layout.bands].as_slice()).unwrap();
        let extra = layout.bands.saturating_sub(if layout.photometric == 2 { 3 } else { 1 });
        if extra > 0 {
            // Unspecified extra samples: bands, not alpha.
            dir.write_tag(Tag::ExtraSamples, vec![0u16; extra].as_slice()).unwrap();
        }
        match layout.tile {
            Some((tw, th)) => {
                dir.write_tag(Tag::TileWidth, tw as u32).unwrap();
                dir.write_tag(Tag::TileLength, th as u32).unwrap();
                dir.write_tag(Tag::TileOffsets, offsets.as_slice()).unwrap();
                dir.write_tag(Tag::TileByteCounts, counts.as_slice()).unwrap();
            }
            None => {
                dir.write_tag(Tag::RowsPerStrip, layout.rows_per_strip as u32).unwrap();
                dir.write_tag(Tag::StripOffsets, offsets.as_slice()).unwrap();
                dir.write_tag(Tag::StripByteCounts, counts.as_slice()).unwrap();
            }
        }
        for tag in tags {
            match tag {
                GeoTag::Doubles(code, v) => dir.write_tag(Tag::Unknown(*code), v.as_slice()).unwrap(),
                GeoTag::Shorts(code, v) => dir.write_tag(Tag::Unknown(*code), v.as_slice()).unwrap(),
                GeoTag::Ascii(code, text) => dir.write_tag(Tag::Unknown(*code), text.as_str()).unwrap(),
            }
        }
        dir.finish().unwrap();
    }
    out.into_inner()
}

/// The tags of a projected DEM: 30 m pixels from (500000, 4500000), UTM
/// zone 33N (EPSG 32633) in metres, PixelIsArea, nodata −32768.
pub fn utm_tags() -> Vec<GeoTag> {
    vec![
        GeoTag::Doubles(33550, vec![30.0, 30.0, 0.0]),
        GeoTag::Doubles(33922, vec![0.0, 0.0, 0.0, 500_000.0, 4_500_000.0, 0.0]),
        GeoTag::Shorts(34735, vec![1, 1, 0, 4, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32633, 3076, 0, 1, 9001]),
        GeoTag::Ascii(42113, "-32768".into()),
    ]
}
