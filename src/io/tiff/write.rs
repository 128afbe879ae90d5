//! TIFF output: normal maps, lit views and one-channel maps as TIFF, a
//! GeoTIFF when the source was one, so the result overlays its source in
//! QGIS and every GDAL-based tool without sidecar files.
//!
//! The files are what GDAL writes by default: uncompressed, striped (one
//! row a strip), samples interleaved. Uncompressed, a TIFF is written at
//! the speed of the disk, like `gdaldem`'s own outputs; `gdal_translate
//! -co COMPRESS=DEFLATE` compresses one when space matters more. The
//! georeferencing tags (ModelPixelScale, ModelTiepoint,
//! ModelTransformation, the GeoKey directory and its double and ASCII
//! parameters) are copied from the source as stored, so a user-defined
//! coordinate system survives too. Files beyond 4 GiB are BigTIFF.

use std::io::{BufWriter, Seek, Write};

use tiff::encoder::colortype::{
    ColorType, Gray8, Gray16, Gray32Float, RGB8, RGB16, RGB32Float, RGBA8, RGBA16, RGBA32Float,
};
use tiff::encoder::{TiffEncoder, TiffKind, TiffKindBig, TiffKindStandard, TiffValue};
use tiff::tags::Tag;

use crate::error::{Error, Result};
use crate::io::encoding::TiffTags;
use crate::io::encoding::{Layout, TiffOptions};
use crate::io::read::georef::tags;
use crate::io::texels::{Container, Sample, StoreInPlace, lay_out};
use crate::par::prelude::*;

/// A sample type TIFF output stores: `u8` and `u16` (unsigned integers)
/// and `f32` (IEEE floats), in one, three (RGB) or four (RGB and an
/// unassociated alpha) channels.
pub(crate) trait TiffSample: Copy + Send + Sync + 'static
where
    [Self]: TiffValue,
{
    /// Runs `write_image` with the colour type of `channels` such samples.
    fn write<W: Write + Seek, K: TiffKind, F: Fill<Self>>(
        encoder: &mut TiffEncoder<W, K>,
        size: (u32, u32),
        channels: usize,
        tags: TiffTags<'_>,
        fill: F,
    ) -> Result<()>;
}

/// What hands the rows of an image to the writer: it calls its argument
/// with whole rows, top to bottom, any number at a time.
pub(crate) trait Fill<S>: FnOnce(&mut dyn FnMut(&[S]) -> Result<()>) -> Result<()> {}

impl<S, F: FnOnce(&mut dyn FnMut(&[S]) -> Result<()>) -> Result<()>> Fill<S> for F {}

macro_rules! tiff_sample {
    ($sample:ty, $gray:ty, $rgb:ty, $rgba:ty) => {
        impl TiffSample for $sample {
            fn write<W: Write + Seek, K: TiffKind, F: Fill<Self>>(
                encoder: &mut TiffEncoder<W, K>,
                size: (u32, u32),
                channels: usize,
                tags: TiffTags<'_>,
                fill: F,
            ) -> Result<()> {
                match channels {
                    1 => write_image::<$gray, W, K, F>(encoder, size, tags, fill),
                    3 => write_image::<$rgb, W, K, F>(encoder, size, tags, fill),
                    4 => write_image::<$rgba, W, K, F>(encoder, size, tags, fill),
                    n => Err(Error::Encode(format!("a TIFF is written with 1, 3 or 4 channels, not {n}"))),
                }
            }
        }
    };
}

tiff_sample!(u8, Gray8, RGB8, RGBA8);
tiff_sample!(u16, Gray16, RGB16, RGBA16);
tiff_sample!(f32, Gray32Float, RGB32Float, RGBA32Float);

/// Writes a `width` × `height` TIFF of `channels` samples a texel, whose
/// rows `fill` pushes (texel after texel, each texel's samples in order),
/// any number of whole rows at a time: a row is written as soon as it
/// comes, so memory holds none of the image. A BigTIFF when the samples
/// take more than a classic TIFF can address.
///
/// Errors: [`Error::Encode`] for a zero size, rows that are not whole or
/// not all there, or a size TIFF cannot hold; [`Error::Io`] if `out`
/// fails; any error of `fill`, which stops the writing.
pub(crate) fn write_tiff_rows<S: TiffSample, W: Write + Seek>(
    out: W,
    (width, height): (usize, usize),
    channels: usize,
    tags: TiffTags<'_>,
    fill: impl Fill<S>,
) -> Result<()>
where
    [S]: TiffValue,
{
    let too_large = || Error::Encode(format!("{width} × {height} texels are beyond what TIFF can hold"));
    let size = (u32::try_from(width).map_err(|_| too_large())?, u32::try_from(height).map_err(|_| too_large())?);
    if width == 0 || height == 0 {
        return Err(Error::Encode("image has zero size".into()));
    }
    // Classic TIFF addresses 4 GiB; the strip tables and tags need room
    // beside the samples.
    let bytes = (width as u64 * height as u64 * channels as u64 * size_of::<S>() as u64)
        .saturating_add(16 * height as u64 + (1 << 20));
    // A strip is a row, and a write of its own: to ext4, 4096 writes of
    // 48 KiB (a 4096-wide float map's rows) took 25 to 40 ms more processor
    // time than the same bytes a mebibyte at a time, more than the copy
    // into this buffer costs.
    let mut buffered = BufWriter::with_capacity(1 << 20, out);
    if bytes <= u64::from(u32::MAX) {
        let mut encoder = TiffEncoder::<_, TiffKindStandard>::new_generic(&mut buffered).map_err(from_tiff_error)?;
        S::write(&mut encoder, size, channels, tags, fill)?;
    } else {
        let mut encoder = TiffEncoder::<_, TiffKindBig>::new_generic(&mut buffered).map_err(from_tiff_error)?;
        S::write(&mut encoder, size, channels, tags, fill)?;
    }
    // Written out here, where an error is still reported (dropping the
    // buffer would lose it).
    buffered.flush()?;
    Ok(())
}

/// [`write_tiff_rows`] for the colour type `C`.
fn write_image<C: ColorType, W: Write + Seek, K: TiffKind, F: Fill<C::Inner>>(
    encoder: &mut TiffEncoder<W, K>,
    (width, height): (u32, u32),
    tags: TiffTags<'_>,
    fill: F,
) -> Result<()>
where
    [C::Inner]: TiffValue,
{
    let channels = C::BITS_PER_SAMPLE.len();
    let mut image = encoder.new_image::<C>(width, height).map_err(from_tiff_error)?;
    // One row a strip, as GDAL writes striped files: every row goes out
    // as it comes.
    image.rows_per_strip(1).map_err(from_tiff_error)?;
    let dir = image.encoder();
    if channels == 4 {
        // The fourth sample is an unassociated alpha.
        dir.write_tag(Tag::ExtraSamples, &[2u16][..]).map_err(from_tiff_error)?;
    }
    if let Some(georef) = tags.georef {
        let stored = &georef.stored;
        let doubles = [
            (tags::MODEL_PIXEL_SCALE, &stored.pixel_scale),
            (tags::MODEL_TIEPOINT, &stored.tiepoints),
            (tags::MODEL_TRANSFORMATION, &stored.transformation),
            (tags::GEO_DOUBLE_PARAMS, &stored.double_params),
        ];
        for (code, values) in doubles.into_iter().filter(|(_, v)| !v.is_empty()) {
            dir.write_tag(Tag::from_u16_exhaustive(code), &values[..]).map_err(from_tiff_error)?;
        }
        if !stored.key_directory.is_empty() {
            let keys = &stored.key_directory[..];
            dir.write_tag(Tag::from_u16_exhaustive(tags::GEO_KEY_DIRECTORY), keys).map_err(from_tiff_error)?;
        }
        if !stored.ascii_params.is_empty() {
            let text = stored.ascii_params.as_str();
            dir.write_tag(Tag::from_u16_exhaustive(tags::GEO_ASCII_PARAMS), text).map_err(from_tiff_error)?;
        }
    }
    if let Some(nodata) = tags.nodata {
        // GDAL's own spelling: the shortest text that reads back.
        let text = if nodata.is_nan() { "nan".to_owned() } else { format!("{nodata:?}") };
        let text = text.strip_suffix(".0").unwrap_or(&text);
        dir.write_tag(Tag::from_u16_exhaustive(tags::GDAL_NODATA), text).map_err(from_tiff_error)?;
    }
    let row_len = width as usize * channels;
    let mut rows_written = 0usize;
    fill(&mut |rows| {
        if !rows.len().is_multiple_of(row_len) || rows_written + rows.len() / row_len > height as usize {
            return Err(Error::Encode(format!("{} samples are not whole rows of the image", rows.len())));
        }
        for row in rows.chunks_exact(row_len) {
            image.write_strip(row).map_err(from_tiff_error)?;
        }
        rows_written += rows.len() / row_len;
        Ok(())
    })?;
    if rows_written != height as usize {
        return Err(Error::Encode(format!("only {rows_written} of {height} rows were written")));
    }
    image.finish().map_err(from_tiff_error)
}

/// An encoder's error as ours: the writer's I/O errors as they are, the
/// rest (sizes and limits of the format) as encoding errors.
fn from_tiff_error(e: tiff::TiffError) -> Error {
    match e {
        tiff::TiffError::IoError(e) => Error::Io(e),
        other => Error::Encode(format!("tiff: {other}")),
    }
}

/// Rows of a TIFF handed to its writer at a time, from an image in memory.
const TIFF_BAND_ROWS: usize = 256;

/// A TIFF normal map: its samples laid out as in a PNG (red-green maps
/// with B = 0), each band's normals changed in place by `store` if given
/// (float samples: (n + 1)/2), in parallel, before they are laid out.
pub(crate) fn tiff_normals<S: TiffSample + Sample>(
    texels: &[[S; 3]],
    heights: &[f32],
    size: (usize, usize),
    options: &TiffOptions,
    store: Option<StoreInPlace<'_, S>>,
    tags: TiffTags<'_>,
    out: impl Write + Seek,
) -> Result<()>
where
    [S]: tiff::encoder::TiffValue,
{
    let layout = options.layout;
    let channels = layout.png_samples();
    let rows = size.0.saturating_mul(TIFF_BAND_ROWS).max(1);
    write_tiff_rows(out, size, channels, tags, |push| {
        if layout == Layout::Rgb && store.is_none() {
            // Written as they are: no copy of the image.
            return texels.as_flattened().chunks(rows * 3).try_for_each(push);
        }
        let (mut stored, mut samples) = (Vec::new(), Vec::new());
        texels.chunks(rows).enumerate().try_for_each(|(k, band)| {
            let band_heights = if heights.is_empty() { heights } else { &heights[k * rows..][..band.len()] };
            let band = match store {
                Some(store) => {
                    stored.clear();
                    stored.extend_from_slice(band);
                    stored.par_chunks_mut(1 << 14).for_each(store);
                    &stored[..]
                }
                None => band,
            };
            samples.clear();
            lay_out(band, band_heights, layout, Container::Png, &mut samples);
            push(&samples)
        })
    })
}

/// A one-channel TIFF.
pub(crate) fn tiff_gray<S: TiffSample>(
    values: &[S],
    size: (usize, usize),
    tags: TiffTags<'_>,
    out: impl Write + Seek,
) -> Result<()>
where
    [S]: tiff::encoder::TiffValue,
{
    let rows = size.0.saturating_mul(TIFF_BAND_ROWS).max(1);
    write_tiff_rows(out, size, 1, tags, |push| values.chunks(rows).try_for_each(push))
}

#[cfg(test)]
mod tests {
    use std::io::{self, Cursor, Seek, SeekFrom, Write};

    use super::*;

    /// A file that takes `room` bytes, then refuses, as a full disk does.
    struct Full {
        file: Cursor<Vec<u8>>,
        room: u64,
    }

    impl Write for Full {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.file.position() + buf.len() as u64 > self.room {
                return Err(io::Error::new(io::ErrorKind::StorageFull, "no space left"));
            }
            self.file.write(buf)
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl Seek for Full {
        fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
            self.file.seek(to)
        }
    }

    /// The rows are kept in a buffer before they reach the file: a write
    /// that fails when the buffer is written out, at the end, is still
    /// an error, and a whole file is written when there is room.
    #[test]
    fn a_write_that_fails_when_the_buffer_goes_out_is_an_error() {
        let (w, h) = (64, 32);
        let rows: Vec<f32> = (0..w * h * 3).map(|i| i as f32).collect();
        let write = |room| {
            let mut out = Full { file: Cursor::new(Vec::new()), room };
            let result = write_tiff_rows(&mut out, (w, h), 3, TiffTags::default(), |push| push(&rows));
            (result, out.file.into_inner())
        };
        let (whole, bytes) = write(u64::MAX);
        whole.unwrap();
        // Samples, strip tables, tags: less than the buffer holds.
        assert!(bytes.len() > rows.len() * 4 && bytes.len() < 1 << 20, "{} bytes", bytes.len());
        // Out of room halfway, or for the last byte only (what only the
        // final write-out of the buffer finds).
        for room in [bytes.len() / 2, bytes.len() - 1] {
            let (full, _) = write(room as u64);
            assert!(matches!(full, Err(Error::Io(e)) if e.kind() == io::ErrorKind::StorageFull), "room {room}");
        }
    }
}
