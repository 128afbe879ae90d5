//! TIFF and GeoTIFF rows in ([`TiffRows`]): one band, a row of strips or
//! tiles at a time.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use super::TiffBand;
use crate::error::{Error, Result};
use crate::io::read::{Channel, Georef, SeekableBufReader, raw_layout_for};
use crate::io::rows::RowSource;
use crate::io::{ReadOptions, SampleType};

/// The rows of one band of a TIFF file, top to bottom, as heights: the
/// band [`crate::io::read`] decodes with the `tiff` crate (float, half,
/// 32- and 64-bit and signed integers, and any layout with
/// [`ReadOptions::band`]), striped or tiled, chunky or planar, every
/// compression `tiff` reads.
///
/// A row of chunks (one strip, or the tiles across the image) is decoded
/// when its first row is asked for, so memory holds one such row: a
/// 4096-wide float32 GeoTIFF in 256-row tiles, 4 MiB. A file written as
/// a single strip is a single chunk, and is held whole. The values, and
/// so the normals, are the whole-image reader's, bit for bit.
pub struct TiffRows {
    band: TiffBand<SeekableBufReader<File>>,
    /// The samples of the current row of chunks, packed.
    current: Vec<u8>,
    /// Its first row.
    current_y0: usize,
    /// Rows in it (0 before the first is read).
    current_rows: usize,
    /// The next row handed out.
    next: usize,
}

/// The signatures of classic and big TIFF, both byte orders.
const TIFF_MAGIC: [[u8; 4]; 4] = [*b"II*\0", *b"MM\0*", *b"II+\0", *b"MM\0+"];

impl TiffRows {
    /// Opens `path` for streaming if it is a TIFF whose band is read by
    /// the `tiff` crate (see [`TiffRows`]); `Ok(None)` otherwise (not a
    /// TIFF, a TIFF `image` reads, a channel, layer, packing or RAW layout
    /// asked for), and the caller reads the image whole, which reports
    /// what is wrong. Reads the header and tags only.
    ///
    /// Errors: [`Error::Io`](crate::Error::Io) if the file cannot be opened; those of the
    /// whole-image reader for the same file: [`Error::Unsupported`](crate::Error::Unsupported) for a
    /// sample format not read or a band past the last, [`Error::Limits`](crate::Error::Limits)
    /// for a size above `opts.max_texels`, [`Error::Decode`](crate::Error::Decode) for a bad geo
    /// tag or chunk table, [`Error::InvalidOption`](crate::Error::InvalidOption) for options
    /// [`ReadOptions::validate`] refuses.
    pub fn open(path: &Path, opts: &ReadOptions, channel: Option<Channel>) -> Result<Option<TiffRows>> {
        Self::open_from(path, opts, channel.as_ref(), 0)
    }

    /// The last `rows` rows of `path` (fewer if the image is shorter),
    /// decoding only the chunks that hold them: the tail a wrap in y needs
    /// for the top rows.
    ///
    /// Errors: as [`TiffRows::open`], and [`Error::Unsupported`](crate::Error::Unsupported) if the
    /// file cannot stream.
    pub fn last_rows(path: &Path, opts: &ReadOptions, channel: Option<Channel>, rows: usize) -> Result<Vec<f64>> {
        let probe = Self::open_from(path, opts, channel.as_ref(), 0)?.ok_or_else(not_streamable)?;
        let (w, h) = probe.band.size();
        drop(probe);
        let keep = rows.min(h);
        let mut source = Self::open_from(path, opts, channel.as_ref(), h - keep)?.ok_or_else(not_streamable)?;
        let mut tail = crate::io::rows::zeroed(keep * w)?;
        tail.chunks_exact_mut(w.max(1)).try_for_each(|row| source.next_row(row))?;
        Ok(tail)
    }

    fn open_from(path: &Path, opts: &ReadOptions, channel: Option<&Channel>, first_row: usize) -> Result<Option<Self>> {
        // A channel is the whole-image reader's rule to apply (or refuse);
        // so are a layer, a packing and a RAW layout.
        if channel.is_some() || opts.layer.is_some() || opts.decode.is_some() || raw_layout_for(path, opts).is_some() {
            return Ok(None);
        }
        opts.validate()?;
        crate::io::read::formats::check_extension(path)?;
        let mut file = File::open(path)?;
        let mut magic = [0u8; 4];
        if file.read_exact(&mut magic).is_err() || !TIFF_MAGIC.contains(&magic) {
            return Ok(None);
        }
        let Some(band) = TiffBand::open(SeekableBufReader::with_capacity(1 << 16, File::open(path)?)?, opts)? else {
            return Ok(None);
        };
        let per = band.rows_per_chunk();
        Ok(Some(TiffRows {
            band,
            current: Vec::new(),
            current_y0: first_row - first_row % per,
            current_rows: 0,
            next: first_row,
        }))
    }

    /// What was stored.
    #[must_use]
    pub fn sample(&self) -> SampleType {
        self.band.sample()
    }

    /// The file's georeferencing, if it has the tags.
    #[must_use]
    pub fn georef(&self) -> Option<&Georef> {
        self.band.georef()
    }

    /// Where the packed samples of row `next` are in `current`, loading
    /// its row of chunks first; moves on to the next row.
    fn next_row_bytes(&mut self) -> Result<std::ops::Range<usize>> {
        let (w, h) = self.band.size();
        let y = self.next;
        if y >= h {
            return Err(Error::Decode(format!("all {h} rows have been read")));
        }
        if self.current_rows == 0 || y >= self.current_y0 + self.current_rows {
            let per = self.band.rows_per_chunk();
            let k = y / per;
            self.band.read_chunk_row(k, &mut self.current)?;
            self.current_y0 = k * per;
            self.current_rows = per.min(h - self.current_y0);
        }
        self.next += 1;
        let size = self.band.sample_bytes();
        let start = (y - self.current_y0) * w * size;
        Ok(start..start + w * size)
    }
}

fn not_streamable() -> Error {
    Error::Unsupported("only TIFF bands read by the tiff crate can be read by rows".into())
}

impl RowSource for TiffRows {
    fn width(&self) -> usize {
        self.band.size().0
    }

    fn height(&self) -> usize {
        self.band.size().1
    }

    fn unit(&self) -> f64 {
        self.band.unit()
    }

    fn row_value(&self, v: f64) -> f64 {
        self.band.row_value(v)
    }

    fn next_row(&mut self, out: &mut [f64]) -> Result<()> {
        let w = self.width();
        if out.len() != w {
            return Err(Error::BufferSize { expected: w, actual: out.len() });
        }
        let row = self.next_row_bytes()?;
        self.band.values(&self.current[row], out);
        Ok(())
    }

    fn stored_scale(&self) -> (f64, bool) {
        // Integers given in contract units (signed, 32-bit): value / (2^bits − 1).
        match self.sample() {
            sample @ (SampleType::Int { bits } | SampleType::SignedInt { bits }) if self.unit() == 1.0 => {
                (sample.stored_per_unit(), bits <= 32)
            }
            _ => (1.0, false),
        }
    }

    fn georef(&self) -> Option<&Georef> {
        self.band.georef()
    }

    fn exact_in_f32(&self) -> bool {
        self.band.exact_in_f32()
    }

    fn next_row_f32(&mut self, out: &mut [f32]) -> Result<()> {
        let w = self.width();
        if out.len() != w {
            return Err(Error::BufferSize { expected: w, actual: out.len() });
        }
        let row = self.next_row_bytes()?;
        self.band.values_f32(&self.current[row], out);
        Ok(())
    }
}
