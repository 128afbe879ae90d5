//! Streaming conversion of PNG files: rows go from the decoder through the
//! fit to the encoder, so memory grows with the width and the patch size,
//! not with the image's height.
//!
//! Three stages run at once: a thread decodes rows into bands of heights,
//! a thread fits each band (its rows in parallel on rayon's pool), and the
//! caller's thread filters and deflates the finished rows into the output.
//! The result is the same, byte for byte, as decoding the whole image,
//! calling [`normals_into`](crate::normals_into) and encoding it: the fit
//! is cut into the same tiles either way ([`BandFit`]).
//!
//! A wrap across the top and bottom needs the image's last rows before its
//! first output row: the caller reads the file once more for them first
//! ([`PngRows::read_tail`]). PNG cannot seek, so that pass decodes the whole
//! file; it is also where a tiling check can be made on the way.

use std::fs::File;
use std::io::{BufReader, Write};
use std::path::Path;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

use super::read::{Channel, ReadOptions, check_size};
use super::write::PngCompression;
use crate::error::{Error, Result};
use crate::fit::{BandFit, FromNormal};
use crate::options::{Border, Options};

/// Rec. 709 luma weights of R, G and B, as the whole-image reader uses.
const LUMA: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// The rows of a PNG file, top to bottom, as heights in contract units.
pub struct PngRows {
    reader: png::Reader<BufReader<File>>,
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
    /// Errors: [`Error::Io`] if the file cannot be opened, [`Error::Decode`]
    /// for a corrupt header, [`Error::Limits`] for a size above
    /// `opts.max_texels`, [`Error::Unsupported`] for a missing channel.
    pub fn open(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<PngRows>> {
        let mut file = BufReader::with_capacity(1 << 16, File::open(path)?);
        let magic = std::io::BufRead::fill_buf(&mut file)?;
        if !magic.starts_with(b"\x89PNG\r\n\x1a\n") {
            return Ok(None);
        }
        // The decoder's own buffers are a few rows; the limit guards them.
        let mut decoder = png::Decoder::new_with_limits(file, png::Limits { bytes: 1 << 28 });
        decoder.set_transformations(png::Transformations::EXPAND);
        let reader = decoder.read_info().map_err(png_error)?;
        let info = reader.info();
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
        let pick = match channel {
            Some(Channel::A) => {
                Pick::Channel(alpha.ok_or_else(|| Error::Unsupported("image has no alpha channel".into()))?)
            }
            _ if gray => Pick::Channel(0),
            None | Some(Channel::Luma) => Pick::Luma,
            Some(Channel::R) => Pick::Channel(0),
            Some(Channel::G) => Pick::Channel(1),
            Some(Channel::B) => Pick::Channel(2),
        };
        Ok(Some(PngRows {
            reader,
            width: width as usize,
            height: height as usize,
            layout: RowLayout { channels, bytes, pick },
            next: 0,
        }))
    }

    /// Columns.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Whether the file stores more than 8 bits per sample.
    #[must_use]
    pub fn more_than_8_bits(&self) -> bool {
        self.layout.bytes == 2
    }

    /// Decodes the next row into `out` (`width` heights).
    ///
    /// Errors: [`Error::Decode`] for corrupt or truncated data, or when all
    /// rows have been read.
    pub fn next_row(&mut self, out: &mut [f32]) -> Result<()> {
        let layout = self.layout;
        let row = self.reader.next_row().map_err(png_error)?;
        let row =
            row.ok_or_else(|| Error::Decode(format!("image data ends after {} of {} rows", self.next, self.height)))?;
        let data = row.data();
        let stride = layout.channels * layout.bytes;
        if data.len() != stride * out.len() {
            return Err(Error::Decode(format!("row of {} bytes for {} texels", data.len(), out.len())));
        }
        let sample = |px: &[u8], c: usize| -> f32 {
            if layout.bytes == 1 {
                f32::from(px[c]) / 255.0
            } else {
                f32::from(u16::from_be_bytes([px[2 * c], px[2 * c + 1]])) / 65535.0
            }
        };
        let texels = data.chunks_exact(stride);
        match layout.pick {
            Pick::Channel(c) => out.iter_mut().zip(texels).for_each(|(o, px)| *o = sample(px, c)),
            Pick::Luma => out.iter_mut().zip(texels).for_each(|(o, px)| {
                let [r, g, b] = [0, 1, 2].map(|c| f64::from(sample(px, c)));
                *o = (LUMA[0] * r + LUMA[1] * g + LUMA[2] * b) as f32;
            }),
        }
        self.next += 1;
        Ok(())
    }

    /// Reads every row, giving each to `visit`, and returns the last
    /// `rows` rows (fewer if the image is shorter): the first pass of a
    /// conversion that wraps across the top and bottom.
    pub fn read_tail(mut self, rows: usize, mut visit: impl FnMut(&[f32])) -> Result<Vec<f32>> {
        let (w, h) = (self.width, self.height);
        let keep = rows.min(h);
        let mut tail = vec![0.0f32; keep * w];
        let mut row = vec![0.0f32; w];
        for y in 0..h {
            self.next_row(&mut row)?;
            visit(&row);
            if y + keep >= h {
                let slot = y + keep - h;
                tail[slot * w..][..w].copy_from_slice(&row);
            }
        }
        Ok(tail)
    }
}

/// How the streamed normal map is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PngDepth {
    /// 8-bit RGB.
    Eight,
    /// 16-bit RGB.
    Sixteen,
}

/// Converts the rows of `rows` to a PNG normal map written to `out`.
///
/// `tail` holds the image's last N/2 rows ([`PngRows::read_tail`] of a
/// first pass) and is needed when `opts` wraps in y; other borders find
/// their rows in the stream.
///
/// Errors: those of decoding, [`Error::InvalidOption`] for bad options or
/// a wrap in y without `tail`, [`Error::Io`] / [`Error::Encode`] if writing
/// fails.
pub fn convert_png(
    rows: PngRows,
    tail: Option<&[f32]>,
    opts: &Options,
    depth: PngDepth,
    compression: PngCompression,
    out: &mut dyn Write,
) -> Result<()> {
    match depth {
        PngDepth::Eight => convert_as::<[u8; 3]>(rows, tail, opts, compression, out),
        PngDepth::Sixteen => convert_as::<[u16; 3]>(rows, tail, opts, compression, out),
    }
}

/// A texel type the streamed PNG can hold, with its big-endian bytes.
trait PngTexel: FromNormal + Default {
    const DEPTH: png::BitDepth;
    fn put(texels: &[Self], bytes: &mut Vec<u8>);
}

impl PngTexel for [u8; 3] {
    const DEPTH: png::BitDepth = png::BitDepth::Eight;
    fn put(texels: &[Self], bytes: &mut Vec<u8>) {
        bytes.clear();
        bytes.extend_from_slice(texels.as_flattened());
    }
}

impl PngTexel for [u16; 3] {
    const DEPTH: png::BitDepth = png::BitDepth::Sixteen;
    fn put(texels: &[Self], bytes: &mut Vec<u8>) {
        bytes.clear();
        bytes.extend(texels.as_flattened().iter().flat_map(|v| v.to_be_bytes()));
    }
}

/// A band of rows between stages: its first row and its values.
type Band<T> = Result<(usize, Vec<T>)>;

fn convert_as<T: PngTexel>(
    mut rows: PngRows,
    tail: Option<&[f32]>,
    opts: &Options,
    compression: PngCompression,
    out: &mut dyn Write,
) -> Result<()> {
    let (w, h) = (rows.width, rows.height);
    let fit = BandFit::new(w, h, opts)?;
    let (band, r) = (fit.band_rows(), fit.radius());
    let wraps_y = opts.borders.y == Border::Wrap;
    let tail = match tail {
        Some(t) if t.len() == r.min(h) * w => Some(t),
        Some(t) => return Err(Error::BufferSize { expected: r.min(h) * w, actual: t.len() }),
        None if wraps_y && r > 0 => {
            return Err(Error::InvalidOption("a wrap in y needs the image's last rows from a first pass".into()));
        }
        None => None,
    };

    let mut encoder = png::Encoder::new(out, w as u32, h as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(T::DEPTH);
    encoder.set_compression(compression.to_png());
    // As `image` writes PNGs (`crate::io::encode_png_rgb8`), so both paths
    // give the same file.
    encoder.set_filter(png::Filter::Adaptive);
    let mut writer = encoder.write_header().map_err(png_encode_error)?;
    let mut stream = writer.stream_writer().map_err(png_encode_error)?;

    // Two bands in flight between stages keep every stage busy without
    // holding more than a few bands.
    let (heights_tx, heights_rx) = sync_channel::<Band<f32>>(2);
    let (normals_tx, normals_rx) = sync_channel::<Band<T>>(2);
    std::thread::scope(|scope| -> Result<()> {
        scope.spawn(move || decode_stage(&mut rows, band, &heights_tx));
        scope.spawn(move || fit_stage(&fit, w, h, tail, heights_rx, &normals_tx));
        let mut bytes = Vec::new();
        for message in normals_rx {
            let (_, texels) = message?;
            T::put(&texels, &mut bytes);
            stream.write_all(&bytes)?;
        }
        Ok(())
    })?;
    stream.finish().map_err(png_encode_error)?;
    writer.finish().map_err(png_encode_error)
}

/// Decodes bands of `band` rows and sends them on; stops at the first
/// error (sent on) or when the receiver is gone.
fn decode_stage(rows: &mut PngRows, band: usize, tx: &SyncSender<Band<f32>>) {
    let (w, h) = (rows.width, rows.height);
    for y0 in (0..h).step_by(band) {
        let n = band.min(h - y0);
        let mut heights = vec![0.0f32; n * w];
        let result = heights.chunks_exact_mut(w).try_for_each(|row| rows.next_row(row));
        let failed = result.is_err();
        if tx.send(result.map(|()| (y0, heights))).is_err() || failed {
            return;
        }
    }
}

/// Fits each band once the rows it reads are in, and sends it on.
fn fit_stage<T: PngTexel>(
    fit: &BandFit,
    w: usize,
    h: usize,
    tail: Option<&[f32]>,
    rx: Receiver<Band<f32>>,
    tx: &SyncSender<Band<T>>,
) {
    let r = fit.radius();
    // Rows lo .. lo + window.len() / w of the image, and a copy of its
    // first rows for a wrap at the bottom (they leave the window early).
    let mut window: Vec<f32> = Vec::new();
    let mut lo = 0;
    let mut head: Vec<f32> = Vec::new();
    let mut incoming = rx.into_iter();
    for rows in fit.bands() {
        let (y0, y1) = (rows.start, rows.end);
        let needed = (y1 + r).min(h);
        while lo + window.len() / w < needed {
            match incoming.next() {
                Some(Ok((_, rows))) => window.extend_from_slice(&rows),
                Some(Err(e)) => {
                    let _ = tx.send(Err(e));
                    return;
                }
                None => {
                    let _ = tx.send(Err(Error::Decode("image data ends early".into())));
                    return;
                }
            }
            if head.is_empty() {
                head.extend_from_slice(&window[..r.min(h) * w]);
            }
        }
        let hi = lo + window.len() / w;
        let row = |y: usize| -> &[f32] {
            if (lo..hi).contains(&y) {
                &window[(y - lo) * w..][..w]
            } else if y < r {
                &head[y * w..][..w]
            } else {
                // Only a wrap at the top reads below the window's end.
                let t = tail.expect("a wrap in y comes with the tail");
                &t[(y + r.min(h) - h) * w..][..w]
            }
        };
        let mut normals = vec![T::default(); (y1 - y0) * w];
        let result = fit.fit_band(rows, &row, &mut normals);
        let failed = result.is_err();
        if tx.send(result.map(|()| (y0, normals))).is_err() || failed {
            return;
        }
        // The next band reads from r rows above its start.
        let keep_from = (y1.saturating_sub(r)).max(lo);
        window.drain(..(keep_from - lo) * w);
        lo = keep_from;
    }
}

fn png_error(e: png::DecodingError) -> Error {
    match e {
        png::DecodingError::IoError(e) if e.kind() != std::io::ErrorKind::UnexpectedEof => Error::Io(e),
        png::DecodingError::LimitsExceeded => Error::Limits("the png decoder needs more memory than allowed".into()),
        other => Error::Decode(crate::error::one_line(&other.to_string())),
    }
}

fn png_encode_error(e: png::EncodingError) -> Error {
    match e {
        png::EncodingError::IoError(e) => Error::Io(e),
        other => Error::Encode(other.to_string()),
    }
}
