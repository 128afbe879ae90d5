//! Elevation packed into the R, G and B bytes of web map tiles: 24 bits
//! of height in an 8-bit RGB image, because browsers decode PNG and WebP
//! but no 16-bit or float raster. Read as a picture (luma of R, G, B) the
//! tile gives nonsense; unpacked, float heights in metres.
//!
//! * Mapbox Terrain-RGB (also MapTiler's terrain-rgb tiles):
//!   h = −10000 + (R · 65536 + G · 256 + B) · 0.1 m.
//! * Terrarium (Mapzen, the tiles AWS's Terrain Tiles serve):
//!   h = R · 256 + G + B / 256 − 32768 m.
//!
//! The heights are computed in f64 and kept as f64: Terrain-RGB's 0.1 m
//! steps are not binary fractions, and rounding them to f32 would move
//! heights above 2 km by up to 0.1 mm for no gain.

use crate::error::{Error, Result};
use crate::options::named_values;
use crate::par::prelude::*;
use crate::samples::Samples;

use crate::io::{InputFormat, Plane, Raster, SampleType, par_collect};

/// How an RGB tile packs heights (`--decode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum PackedElevation {
    /// Mapbox Terrain-RGB: −10000 + (R · 65536 + G · 256 + B) · 0.1 m.
    TerrainRgb,
    /// Terrarium: R · 256 + G + B / 256 − 32768 m.
    Terrarium,
}

named_values!(PackedElevation, "elevation packing", { TerrainRgb => "terrain-rgb" | "mapbox", Terrarium => "terrarium" });

impl PackedElevation {
    /// The height in metres of one texel's stored R, G and B.
    #[must_use]
    pub fn metres(self, r: u8, g: u8, b: u8) -> f64 {
        let (r, g, b) = (f64::from(r), f64::from(g), f64::from(b));
        match self {
            PackedElevation::TerrainRgb => -10000.0 + (r * 65536.0 + g * 256.0 + b) * 0.1,
            PackedElevation::Terrarium => r * 256.0 + g + b / 256.0 - 32768.0,
        }
    }
}

/// Refuses bytes a packing cannot be read from before they are decoded: a
/// lossy WebP, whose compression moves every byte a little, and a height
/// by up to 6553.6 m when R moves by 1 (Terrain-RGB; 256 m for Terrarium).
/// The format is checked after decoding ([`unpack`]), for every source.
///
/// Errors: [`Error::Unsupported`] for a WebP that is not lossless.
pub(super) fn check_bytes(format: &InputFormat, bytes: &[u8], packing: PackedElevation) -> Result<()> {
    if *format == InputFormat::WebP && !webp_is_lossless(bytes) {
        return Err(Error::Unsupported(format!(
            "{packing} heights are unpacked from lossless WebP tiles only: this one is lossy (VP8), \
             which changes the packed bytes"
        )));
    }
    Ok(())
}

/// Whether a WebP holds lossless image data only: a `VP8L` chunk and no
/// lossy `VP8 ` one, at the top level or in an animation's frames (RIFF
/// chunks: a four-byte name, a little-endian length, the data padded to
/// an even length). `ALPH` (an alpha plane) only goes with lossy data.
/// `image` decodes both kinds without saying which it read, so the chunk
/// names are looked at here.
fn webp_is_lossless(bytes: &[u8]) -> bool {
    /// (lossless chunks, lossy chunks) among the chunks in `data`.
    fn count(mut data: &[u8], depth: u8) -> (usize, usize) {
        let (mut lossless, mut lossy) = (0, 0);
        while data.len() >= 8 {
            let (name, len) = (&data[..4], u32::from_le_bytes([data[4], data[5], data[6], data[7]]) as usize);
            let body = &data[8..8 + len.min(data.len() - 8)];
            match name {
                b"VP8L" => lossless += 1,
                b"VP8 " | b"ALPH" => lossy += 1,
                // A frame: 16 bytes of placement, then its own chunks.
                b"ANMF" if depth == 0 && body.len() >= 16 => {
                    let (a, b) = count(&body[16..], 1);
                    lossless += a;
                    lossy += b;
                }
                _ => {}
            }
            data = &data[(8 + len + (len & 1)).min(data.len())..];
        }
        (lossless, lossy)
    }
    match bytes.get(..12) {
        Some(head) if &head[..4] == b"RIFF" && &head[8..] == b"WEBP" => {
            let (lossless, lossy) = count(&bytes[12..], 0);
            lossless > 0 && lossy == 0
        }
        _ => false,
    }
}

/// The raster's R, G and B bytes unpacked to one plane of heights in
/// metres (alpha, if any, is dropped: the packings give it no meaning).
///
/// Errors: [`Error::Unsupported`] for a format tiles do not come in (only
/// PNG and WebP, lossless, keep the bytes exact), an image that is not
/// 8-bit RGB.
pub(super) fn unpack(raster: Raster, packing: PackedElevation) -> Result<Raster> {
    if !matches!(raster.format, InputFormat::Png | InputFormat::WebP) {
        return Err(Error::Unsupported(format!(
            "{packing} heights are unpacked from PNG or WebP tiles, not from {} files",
            raster.format
        )));
    }
    if raster.sample != (SampleType::Int { bits: 8 }) {
        return Err(Error::Unsupported(format!("{packing} tiles hold 8-bit RGB; this one has {}", raster.sample)));
    }
    let plane = |name: &str| match raster.plane(name).map(|p| &p.data) {
        Some(Samples::U8(v)) => Ok(v.as_slice()),
        _ => Err(Error::Unsupported(format!(
            "{packing} tiles hold 8-bit RGB; this one has channels {}",
            raster.planes.iter().map(|p| p.name.as_str()).collect::<Vec<_>>().join(", ")
        ))),
    };
    let (r, g, b) = (plane("R")?, plane("G")?, plane("B")?);
    let texels = r.len();
    let heights = par_collect(
        texels,
        r.par_iter().zip(g.par_iter()).zip(b.par_iter()).map(|((&r, &g), &b)| packing.metres(r, g, b)),
    )?;
    Ok(Raster {
        width: raster.width,
        height: raster.height,
        format: raster.format.clone(),
        sample: SampleType::Float,
        planes: vec![Plane { name: "Y".into(), data: Samples::F64(heights) }],
        georef: raster.georef.clone(),
    })
}
