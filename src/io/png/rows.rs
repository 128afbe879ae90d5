//! A PNG file's rows, decoded one at a time ([`PngRows`]): one channel's
//! samples as stored, or luma in contract units, for the streaming
//! pipeline ([`crate::pipeline`]).

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use super::zlib::{IdatCount, IdatWatch, decode_options, finish_checked, png_error};
use super::{PNG_SIGNATURE, check_png_header, check_png_palette};
use crate::error::{Error, Result};
use crate::io::read::{Channel, Source, select_channel};
use crate::io::rows::RowSource;
use crate::io::{InputFormat, ReadOptions, check_size, no_layers};
use crate::samples::{Sample, luma};

/// The rows of a PNG file, top to bottom: one channel's samples as stored,
/// or luma in contract units ([`RowSource`]).
pub struct PngRows {
    reader: png::Reader<IdatWatch<BufReader<File>>>,
    /// The image data the decoder has read, for [`finish_checked`].
    idat: IdatCount,
    /// The file, opened again if its image data must be checked again.
    path: PathBuf,
    width: usize,
    height: usize,
    layout: RowLayout,
    /// Rows handed out so far.
    next: usize,
}

/// How one decoded row turns into heights.
#[derive(Clone, Copy)]
struct RowLayout {
    /// Samples per texel.
    channels: usize,
    /// Bytes per sample (1 or 2).
    bytes: usize,
    pick: Pick,
}

#[derive(Clone, Copy)]
enum Pick {
    /// One stored channel, by index.
    Channel(usize),
    /// Luma of channels 0, 1, 2.
    Luma,
}

impl PngRows {
    /// Opens `path` for streaming if it is a PNG that can stream (not
    /// interlaced: Adam7 rows arrive in seven passes); `Ok(None)` otherwise,
    /// and the caller reads the image whole. Reads only the header.
    ///
    /// Errors: [`Error::Io`](crate::Error::Io) if the file cannot be opened, [`Error::Decode`](crate::Error::Decode)
    /// for a corrupt header, [`Error::Limits`](crate::Error::Limits) for a size above
    /// `opts.max_texels`, [`Error::Unsupported`](crate::Error::Unsupported) for a missing channel or
    /// a layer asked for (PNG has none). The rows read later may fail with
    /// [`Error::Decode`](crate::Error::Decode); the last one also checks the rest of the file
    /// up to IEND and the image data's checksum (zlib's Adler-32), as a
    /// whole-image decoder does.
    pub fn open(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<PngRows>> {
        // A band, a packing (Terrain-RGB tiles are PNGs) or a RAW layout is
        // the whole-image reader's to apply, or to refuse.
        if !opts.may_stream(path) {
            return Ok(None);
        }
        crate::io::read::formats::check_extension(path)?;
        let mut file = BufReader::with_capacity(1 << 16, File::open(path)?);
        let start = std::io::BufRead::fill_buf(&mut file)?;
        if !start.starts_with(&PNG_SIGNATURE) {
            return Ok(None);
        }
        if let Some(layer) = &opts.layer {
            return Err(no_layers(&InputFormat::Png, layer));
        }
        check_png_header(start, opts)?;
        // The decoder's own buffers are a few rows; the limit guards them.
        let (file, idat) = IdatWatch::new(file);
        let mut decoder = png::Decoder::new_with_options(file, decode_options());
        decoder.set_limits(png::Limits { bytes: 1 << 28 });
        decoder.set_transformations(png::Transformations::EXPAND);
        let reader = decoder.read_info().map_err(png_error)?;
        let info = reader.info();
        check_png_palette(info)?;
        let (width, height) = (info.width, info.height);
        check_size(u64::from(width), u64::from(height), opts)?;
        if info.interlaced {
            return Ok(None);
        }
        let (color, depth) = reader.output_color_type();
        let bytes = match depth {
            png::BitDepth::Eight => 1,
            png::BitDepth::Sixteen => 2,
            _ => return Ok(None),
        };
        let channels = color.samples();
        let gray = channels <= 2;
        let alpha = matches!(channels, 2 | 4).then_some(channels - 1);
        // The whole-image rule on the planes this PNG decodes to: the
        // same choice and the same errors, by construction.
        let names: &[&str] = match (gray, alpha.is_some()) {
            (true, false) => &["Y"],
            (true, true) => &["Y", "A"],
            (false, false) => &["R", "G", "B"],
            (false, true) => &["R", "G", "B", "A"],
        };
        let pick = match select_channel(names, channel.as_ref(), &InputFormat::Png)? {
            Source::Plane(c) => Pick::Channel(c),
            Source::Luma(_) => Pick::Luma,
        };
        Ok(Some(PngRows {
            reader,
            idat,
            path: path.to_path_buf(),
            width: width as usize,
            height: height as usize,
            layout: RowLayout { channels, bytes, pick },
            next: 0,
        }))
    }

    /// Whether the file stores more than 8 bits per sample.
    #[must_use]
    pub fn more_than_8_bits(&self) -> bool {
        self.layout.bytes == 2
    }
}

impl RowSource for PngRows {
    fn width(&self) -> usize {
        self.width
    }

    fn height(&self) -> usize {
        self.height
    }

    fn unit(&self) -> f64 {
        match (self.layout.pick, self.layout.bytes) {
            (Pick::Luma, _) => 1.0,
            (Pick::Channel(_), 1) => u8::UNIT,
            (Pick::Channel(_), _) => u16::UNIT,
        }
    }

    fn next_row(&mut self, out: &mut [f64]) -> Result<()> {
        let layout = self.layout;
        // The stored value, and for luma each channel's height, by the
        // formulas the whole-image reader uses ([`crate::samples`]).
        let value = move |px: &[u8], c: usize| -> f64 {
            if layout.bytes == 1 { f64::from(px[c]) } else { f64::from(u16::from_be_bytes([px[2 * c], px[2 * c + 1]])) }
        };
        let unit = if layout.bytes == 1 { u8::UNIT } else { u16::UNIT };
        match layout.pick {
            Pick::Channel(c) => self.decode_row(out, |px| value(px, c)),
            Pick::Luma => {
                self.decode_row(out, |px| luma(value(px, 0) * unit, value(px, 1) * unit, value(px, 2) * unit))
            }
        }
    }

    /// Luma is made in contract units: stored, it is 2^bits − 1 times
    /// that, as the whole image's luma is ([`RowSource::stored_scale`]).
    fn stored_scale(&self) -> (f64, bool) {
        match (self.layout.pick, self.layout.bytes) {
            (Pick::Channel(_), _) => (1.0, false),
            (Pick::Luma, 1) => (255.0, false),
            (Pick::Luma, _) => (65535.0, false),
        }
    }

    /// A picked channel's integers, which `f32` holds exactly.
    fn exact_in_f32(&self) -> bool {
        matches!(self.layout.pick, Pick::Channel(_))
    }

    fn next_row_f32(&mut self, out: &mut [f32]) -> Result<()> {
        let layout = self.layout;
        let value = move |px: &[u8], c: usize| -> f32 {
            if layout.bytes == 1 { f32::from(px[c]) } else { f32::from(u16::from_be_bytes([px[2 * c], px[2 * c + 1]])) }
        };
        match (layout.pick, layout.channels, layout.bytes) {
            // Gray: texels of a constant size, a loop that vectorises (with
            // the size a variable, it took a sixth of the decoding thread).
            (Pick::Channel(_), 1, 1) => self.decode_row_with(out, |data, out| {
                out.iter_mut().zip(data).for_each(|(o, &v)| *o = f32::from(v));
            }),
            (Pick::Channel(_), 1, _) => self.decode_row_with(out, |data, out| {
                let (samples, _) = data.as_chunks::<2>();
                out.iter_mut().zip(samples).for_each(|(o, &v)| *o = f32::from(u16::from_be_bytes(v)));
            }),
            (Pick::Channel(c), _, _) => self.decode_row(out, |px| value(px, c)),
            // Not exact: luma is made in f64 (see `exact_in_f32`).
            (Pick::Luma, _, _) => {
                let mut row = vec![0.0f64; out.len()];
                self.next_row(&mut row)?;
                out.iter_mut().zip(&row).for_each(|(o, &v)| *o = v as f32);
                Ok(())
            }
        }
    }
}

impl PngRows {
    /// Decodes the next row into `out`, one value a texel from its
    /// samples by `texel`; after the last row, reads the rest of the file.
    fn decode_row<V>(&mut self, out: &mut [V], texel: impl Fn(&[u8]) -> V) -> Result<()> {
        let stride = self.layout.channels * self.layout.bytes;
        self.decode_row_with(out, |data, out| {
            out.iter_mut().zip(data.chunks_exact(stride)).for_each(|(o, px)| *o = texel(px));
        })
    }

    /// Decodes the next row into `out` by `convert`, which gets the row's
    /// bytes (as many texels as `out` holds); after the last row, reads the
    /// rest of the file.
    fn decode_row_with<V>(&mut self, out: &mut [V], convert: impl FnOnce(&[u8], &mut [V])) -> Result<()> {
        let layout = self.layout;
        let row = self.reader.next_row().map_err(png_error)?;
        let row =
            row.ok_or_else(|| Error::Decode(format!("image data ends after {} of {} rows", self.next, self.height)))?;
        let data = row.data();
        let stride = layout.channels * layout.bytes;
        if data.len() != stride * out.len() {
            return Err(Error::Decode(format!("row of {} bytes for {} texels", data.len(), out.len())));
        }
        convert(data, out);
        self.next += 1;
        if self.next == self.height {
            // The rest of the file is read too, as a whole-image decoder
            // reads it: a bad CRC in the last IDAT chunk, a file cut
            // before IEND, or image data whose checksum does not match,
            // is the same error either way, and comes before the output
            // is put in place.
            let path = &self.path;
            let at_last_row = self.idat.get();
            finish_checked(&mut self.reader, &self.idat, at_last_row, || Ok(BufReader::new(File::open(path)?)))?;
        }
        Ok(())
    }
}
