//! A PNG encoder fed band by band: the rows PNG-filtered
//! ([`crate::io::png::stream`]) and deflated in pieces
//! ([`crate::io::png::deflate`]) in parallel on the fit's side, written on
//! the caller's thread.
//!
//! Why not the `png` crate's `StreamWriter`: it takes rows in order, so a
//! wrap in y (the default border) needs the image's last rows before its
//! first, a whole first pass over the input; ours writes the top rows
//! last, into room kept after the header, in one pass, and filters and
//! deflates rows in parallel while the next band is fitted. Measured on a
//! 4096² 16-bit PNG, 8-bit output, wrap, fast setting, medians of 7
//! alternating runs on 2 cores (`cargo run --release --example
//! png_stream_bench -- 4096 7`): ours 0.200 s, StreamWriter with the same
//! filter (Avg) and deflate (fdeflate) 0.485 s, with its adaptive filter
//! 0.521 s; the same 10.1 MiB (9.7 MiB adaptive), the same texels. The
//! format is small and pinned by this module's tests (decoded by the `png`
//! crate at every depth, layout and filter setting, chunk CRCs, IDAT
//! splits, the stored top rows, the same bytes whatever the threads).

use std::borrow::Cow;
use std::io::{Read, Seek, Write};
use std::ops::Range;

use super::{BandStage, Extra, RowSource, Stages, checked_tail, run};
use crate::error::{Error, Result};
use crate::fit::quadratic::CurvatureBands;
use crate::fit::{BandFit, FromNormal};
use crate::io::encoding::{Layout, PngCompression, PngDepth, PngOptions};
use crate::io::png::deflate::{Checksum, FINAL_BLOCK, Piece, Pieces, ZLIB_HEADER, stored_len};
use crate::io::png::stream::{Idat, filter_rows, write_chunk, write_first_idat, write_signature_and_header};
use crate::io::png::write::PngSample;
use crate::io::texels::{Container, lay_out};
use crate::options::Options;

/// How `convert_as` writes: its compression, whether the top rows come
/// last (into room kept after the header), and its channels.
#[derive(Clone, Copy)]
struct Writing {
    compression: PngCompression,
    deferred: bool,
    layout: Layout,
}

/// Converts the rows of `rows` to a PNG normal map written in order to
/// `out`, which need not seek (a pipe).
///
/// `tail` holds the image's last N/2 rows ([`RowSource::read_tail`] of a
/// first pass, or [`ExrRows::last_rows`](super::ExrRows::last_rows)) and is
/// needed when `opts` wraps in y; other borders find their rows in the
/// stream. Every decoded row is also given to `visit` (a tiling check,
/// say).
///
/// Errors: those of decoding, [`Error::InvalidOption`] for bad options or
/// a wrap in y without `tail`, [`Error::Io`] if writing fails.
pub fn convert_png(
    rows: impl RowSource,
    tail: Option<&[f64]>,
    opts: &Options,
    output: impl Into<PngOptions>,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut dyn Write,
) -> Result<()> {
    convert_png_counting(rows, tail, opts, output, visit, out).map(|_| ())
}

/// [`convert_png`], returning the count of missing texels (holes, with
/// [`Options::nodata`]).
pub(crate) fn convert_png_counting(
    rows: impl RowSource,
    tail: Option<&[f64]>,
    opts: &Options,
    output: impl Into<PngOptions>,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut dyn Write,
) -> Result<usize> {
    let tail = checked_tail(tail, rows.width(), rows.height(), opts)?;
    let PngOptions { depth, compression, layout } = output.into();
    let how = Writing { compression, deferred: false, layout };
    let (_, missing) = match depth {
        PngDepth::Eight => convert_normals::<u8, _, _>(rows, tail, opts, visit, out, how),
        PngDepth::Sixteen => convert_normals::<u16, _, _>(rows, tail, opts, visit, out, how),
    }?;
    out.flush()?;
    Ok(missing)
}

/// Like [`convert_png`], in one pass over the input whatever the borders,
/// into an output that can seek (a file).
///
/// The top N/2 rows, the only ones that need the image's last rows with a
/// wrap in y, are fitted last: the file keeps room for them after the
/// header, stored uncompressed (N/2 rows, a small part of the file), and
/// they are written there once the last rows have been read.
pub fn convert_png_seekable<W: Write + Seek>(
    rows: impl RowSource,
    opts: &Options,
    output: impl Into<PngOptions>,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut W,
) -> Result<()> {
    convert_png_seekable_counting(rows, opts, output, visit, out).map(|_| ())
}

/// [`convert_png_seekable`], returning the count of missing texels.
pub(crate) fn convert_png_seekable_counting<W: Write + Seek>(
    rows: impl RowSource,
    opts: &Options,
    output: impl Into<PngOptions>,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut W,
) -> Result<usize> {
    let start = out.stream_position()?;
    let PngOptions { depth, compression, layout } = output.into();
    let how = Writing { compression, deferred: true, layout };
    let (first_idat, missing) = match depth {
        PngDepth::Eight => convert_normals::<u8, _, _>(rows, None, opts, visit, out, how),
        PngDepth::Sixteen => convert_normals::<u16, _, _>(rows, None, opts, visit, out, how),
    }?;
    write_first_idat(out, start, &first_idat)?;
    Ok(missing)
}

/// The codec floor of [`convert_png_seekable`] into an 8-bit RGB PNG
/// (`opts`' fit, the fast compression): the same run, the rows decoded on
/// their thread, the bands filtered and deflated in pieces on every core
/// and written as the conversion writes them, with the fit replaced by a
/// copy of `texels`, normals made beforehand (row after row). The
/// conversion's time over this one's is what its fit adds to decoding
/// and encoding, overlapped as they are (`examples/codec_floor.rs`
/// measures both). Given the conversion's own normals, the file is the
/// conversion's, byte for byte. For that measurement only.
///
/// Errors: those of decoding, [`Error::BufferSize`] when `texels` do not
/// cover the image, [`Error::Io`] if writing fails.
#[doc(hidden)]
pub fn png_codec_floor<W: Write + Seek>(
    rows: impl RowSource,
    opts: &Options,
    texels: &[[u8; 3]],
    out: &mut W,
) -> Result<()> {
    let len = crate::samples::image_len(rows.width(), rows.height())?;
    if texels.len() != len {
        return Err(Error::BufferSize { expected: len, actual: texels.len() });
    }
    let start = out.stream_position()?;
    let (first_idat, _) =
        convert_as(rows, None, opts, |_| {}, out, (PngCompression::Fast, true), GivenTexels { texels })?;
    write_first_idat(out, start, &first_idat)
}

/// Texels made beforehand, for [`png_codec_floor`].
struct GivenTexels<'a> {
    texels: &'a [[u8; 3]],
}

/// The bands of the fit a conversion would run, each filled by a copy of
/// the texels given.
struct GivenBands<'a> {
    fit: BandFit,
    texels: &'a [[u8; 3]],
}

impl<'a> PngTexels for GivenTexels<'a> {
    type Normal = [u8; 3];
    type Fit = GivenBands<'a>;
    fn fit(&self, (w, h): (usize, usize), opts: &Options, unit: f64) -> Result<GivenBands<'a>> {
        Ok(GivenBands { fit: BandFit::new(w, h, opts)?.with_unit(unit), texels: self.texels })
    }
    fn bits(&self) -> u8 {
        8
    }
    fn samples(&self) -> usize {
        3
    }
    fn needs_heights(&self) -> Extra {
        Extra::None
    }
    fn raw<'b>(&self, normals: &'b mut [[u8; 3]], _: &[f32]) -> Cow<'b, [u8]> {
        Cow::Borrowed(normals.as_flattened())
    }
}

impl BandStage<[u8; 3]> for GivenBands<'_> {
    fn width(&self) -> usize {
        self.fit.width()
    }
    fn height(&self) -> usize {
        self.fit.height()
    }
    fn radius(&self) -> usize {
        self.fit.radius()
    }
    fn band_rows(&self) -> usize {
        self.fit.band_rows()
    }
    fn has_nodata(&self) -> bool {
        false
    }
    fn missing(&self) -> usize {
        0
    }
    fn band_list(&self) -> Vec<Range<usize>> {
        self.fit.bands().collect()
    }
    fn work_bytes<H: crate::samples::Sample>(&self) -> u64 {
        0
    }
    fn fit_into<'r, H: crate::samples::Sample>(
        &self,
        rows: Range<usize>,
        _: &(dyn Fn(usize) -> &'r [H] + Sync),
        out: &mut [[u8; 3]],
        _: &mut [bool],
    ) -> Result<()> {
        let w = self.fit.width();
        out.copy_from_slice(&self.texels[rows.start * w..rows.end * w]);
        Ok(())
    }
}

/// The lit view of the rows of `rows` (see [`crate::shade`]): the fit's
/// normals lit by `lamp`, an 8-bit gray PNG written to `out` in one pass,
/// the top rows last as [`convert_png_seekable`] writes them. The grey of
/// every texel is the whole-image view's.
pub(crate) fn shade_png_seekable<W: Write + Seek>(
    rows: impl RowSource,
    opts: &Options,
    lamp: crate::light::Lamp,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut W,
) -> Result<usize> {
    let start = out.stream_position()?;
    // One filter (Avg) for every row: choosing per row was a tenth of a
    // streamed lit view's processor time.
    let holes = opts.nodata.is_some();
    let (first_idat, missing) = match lamp.is_sun() {
        true => {
            convert_as(rows, None, opts, visit, out, (PngCompression::Fast, true), LitTexels::<true> { lamp, holes })?
        }
        false => {
            convert_as(rows, None, opts, visit, out, (PngCompression::Fast, true), LitTexels::<false> { lamp, holes })?
        }
    };
    write_first_idat(out, start, &first_idat)?;
    Ok(missing)
}

/// The curvature of the rows of `rows` ([`CurvatureBands`]) as an 8- or
/// 16-bit gray PNG of the artist's codes
/// ([`encode`](crate::fit::quadratic::encode), `range` white), written to
/// `out` in one pass, the top rows last as [`convert_png_seekable`]
/// writes them. Returns the count of holes (mid-grey).
pub(crate) fn curvature_png_seekable<W: Write + Seek>(
    rows: impl RowSource,
    opts: &Options,
    (depth, compression): (PngDepth, PngCompression),
    range: f64,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut W,
) -> Result<usize> {
    let start = out.stream_position()?;
    let texels = CurvatureTexels { range, sixteen: depth == PngDepth::Sixteen };
    let (first_idat, missing) = convert_as(rows, None, opts, visit, out, (compression, true), texels)?;
    write_first_idat(out, start, &first_idat)?;
    Ok(missing)
}

/// Curvatures as the artist's gray codes, 8 or 16 bits.
struct CurvatureTexels {
    range: f64,
    sixteen: bool,
}

impl PngTexels for CurvatureTexels {
    type Normal = f32;
    type Fit = CurvatureBands;
    fn fit(&self, (w, h): (usize, usize), opts: &Options, unit: f64) -> Result<CurvatureBands> {
        Ok(CurvatureBands::new(w, h, opts)?.with_unit(unit))
    }
    fn bits(&self) -> u8 {
        if self.sixteen { 16 } else { 8 }
    }
    fn samples(&self) -> usize {
        1
    }
    fn needs_heights(&self) -> Extra {
        Extra::None
    }
    fn raw<'a>(&self, values: &'a mut [f32], _: &[f32]) -> Cow<'a, [u8]> {
        use crate::fit::quadratic::encode;
        Cow::Owned(match self.sixteen {
            true => values.iter().flat_map(|&k| (encode(k, self.range, 65535) as u16).to_be_bytes()).collect(),
            false => values.iter().map(|&k| encode(k, self.range, 255) as u8).collect(),
        })
    }
}

/// Normals lit by a lamp: one gray byte a texel (`SUN`: the GIS sun's,
/// [`crate::light::Grey`]).
struct LitTexels<const SUN: bool> {
    lamp: crate::light::Lamp,
    /// With holes: missing texels are grey 0 (gdaldem's nodata).
    holes: bool,
}

impl<const SUN: bool> PngTexels for LitTexels<SUN> {
    type Normal = crate::light::Grey<SUN>;
    type Fit = BandFit;
    fn fit(&self, (w, h): (usize, usize), opts: &Options, unit: f64) -> Result<BandFit> {
        Ok(BandFit::new(w, h, opts)?.with_unit(unit).lit(self.lamp))
    }
    fn bits(&self) -> u8 {
        8
    }
    fn samples(&self) -> usize {
        1
    }
    fn needs_heights(&self) -> Extra {
        if self.holes { Extra::Valid } else { Extra::None }
    }
    fn raw<'a>(&self, texels: &'a mut [crate::light::Grey<SUN>], valid: &[f32]) -> Cow<'a, [u8]> {
        let mut grey: Vec<u8> = texels.iter().map(|g| g.0).collect();
        super::holes_grey(valid, &mut grey);
        Cow::Owned(grey)
    }
}

/// What a streamed PNG's texels are made of: the fit's texels of a band
/// (`Normal`, one per texel) turned into the bytes a PNG row stores.
pub(super) trait PngTexels: Send {
    /// The fit's texel type.
    type Normal: Default + Clone + Send;
    /// The fit that makes them.
    type Fit: BandStage<Self::Normal>;
    /// The fit of a `w` × `h` image whose row value 1 is `unit`.
    fn fit(&self, size: (usize, usize), opts: &Options, unit: f64) -> Result<Self::Fit>;
    /// Bits per sample, and samples per texel (the PNG's colour type).
    fn bits(&self) -> u8;
    fn samples(&self) -> usize;
    /// What [`PngTexels::raw`] takes beside the texels.
    fn needs_heights(&self) -> Extra;
    /// A band's texels (and its heights, when asked for) as the PNG's
    /// unfiltered bytes, row after row.
    fn raw<'a>(&self, normals: &'a mut [Self::Normal], heights: &[f32]) -> Cow<'a, [u8]>;
}

/// A normal map's texels, in a layout, as samples of type `S`.
struct NormalTexels<S> {
    layout: Layout,
    _sample: std::marker::PhantomData<S>,
}

impl<S: PngSample> PngTexels for NormalTexels<S>
where
    [S; 3]: FromNormal + Default,
{
    type Normal = [S; 3];
    type Fit = BandFit;
    fn fit(&self, (w, h): (usize, usize), opts: &Options, unit: f64) -> Result<BandFit> {
        Ok(BandFit::new(w, h, opts)?.with_unit(unit))
    }
    fn bits(&self) -> u8 {
        S::BITS
    }
    fn samples(&self) -> usize {
        self.layout.png_samples()
    }
    fn needs_heights(&self) -> Extra {
        Extra::of(self.layout)
    }
    fn raw<'a>(&self, normals: &'a mut [[S; 3]], heights: &[f32]) -> Cow<'a, [u8]> {
        if self.layout == Layout::Rgb {
            S::be_bytes(normals.as_flattened())
        } else {
            let mut laid_out = Vec::with_capacity(normals.len() * self.samples());
            lay_out(normals, heights, self.layout, Container::Png, &mut laid_out);
            Cow::Owned(S::be_bytes(&laid_out).into_owned())
        }
    }
}

/// [`convert_as`] for a normal map of samples `S`.
fn convert_normals<S: PngSample, R: RowSource, W: Write + ?Sized>(
    rows: R,
    tail: Option<&[f64]>,
    opts: &Options,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut W,
    how: Writing,
) -> Result<(Vec<u8>, usize)>
where
    [S; 3]: FromNormal + Default,
{
    let texels = NormalTexels::<S> { layout: how.layout, _sample: std::marker::PhantomData };
    convert_as(rows, tail, opts, visit, out, (how.compression, how.deferred), texels)
}

/// Streams the PNG into `out`. With `deferred`, the top N/2 rows are
/// fitted last: `out` gets room for the first IDAT chunk after the header,
/// and the chunk's data (zlib header and the top rows, stored) is returned
/// for the caller to write there; otherwise everything is written in order
/// and nothing is returned.
pub(super) fn convert_as<P: PngTexels, R: RowSource, W: Write + ?Sized>(
    rows: R,
    tail: Option<&[f64]>,
    opts: &Options,
    visit: impl FnMut(&[f32]) + Send,
    out: &mut W,
    (compression, deferred): (PngCompression, bool),
    texels: P,
) -> Result<(Vec<u8>, usize)> {
    let (w, h) = (rows.width(), rows.height());
    let fit = texels.fit((w, h), opts, rows.unit())?;
    let (bits, samples) = (texels.bits(), texels.samples());
    let texel_bytes = samples * usize::from(bits / 8);
    let stride = texel_bytes * w;
    let top_len = fit.radius().min(h) * (stride + 1);

    write_signature_and_header(out, w, h, bits, samples)?;
    if deferred {
        // Room for the first IDAT chunk: zlib header and the top rows as
        // stored blocks, filled in at the end.
        let room = 12 + ZLIB_HEADER.len() + stored_len(top_len);
        std::io::copy(&mut std::io::repeat(0).take(room as u64), out)?;
    }
    let mut idat = Idat { out: &mut *out, buf: Vec::new() };
    if !deferred {
        idat.push(&ZLIB_HEADER)?;
    }
    // The checksum of the rows written in order, and the top rows when
    // deferred.
    let mut rest = Checksum::EMPTY;
    let mut top = None;

    // Deflate is fdeflate's at every setting: on filtered normal maps it is
    // as small as zlib's levels (measured on a 4096² map, adaptive filters:
    // 19.9 MiB, against 20.5 MiB for zlib level 9 at 20 times the time),
    // so what a smaller file costs is choosing each row's filter.
    let adaptive = compression != PngCompression::Fast;
    // The last row of the band before, which the next band's first row is
    // filtered against.
    let mut prior: Option<Vec<u8>> = None;
    // The filtered rows, filled again band after band: a new buffer each
    // band would be zeroed first (1 to 2 % of a 32768² conversion).
    let mut filtered = Vec::new();
    let mut pieces = Pieces::new(!adaptive);
    // Pieces' buffers, once written, come back to be filled again (their
    // pages mapped already): 16 at most, 4 MiB.
    let (spare_tx, spare_rx) = std::sync::mpsc::sync_channel::<Vec<u8>>(16);
    let needs_heights = texels.needs_heights();
    let prepare = move |rows: Range<usize>, normals: &mut [P::Normal], heights: Vec<f32>| -> Vec<Piece> {
        let raw = texels.raw(normals, &heights);
        if deferred && rows.start == 0 {
            // Stored as they are: filter type 0 before each row.
            let unfiltered: Vec<u8> =
                raw.chunks_exact(stride).flat_map(|row| std::iter::once(0).chain(row.iter().copied())).collect();
            vec![Piece::stored(&unfiltered, Vec::new())]
        } else {
            filtered =
                filter_rows(&raw, stride, texel_bytes, prior.as_deref(), adaptive, std::mem::take(&mut filtered));
            prior = Some(raw[raw.len() - stride..].to_vec());
            pieces.push(&filtered, rows.end == h, || spare_rx.try_recv().ok())
        }
    };
    let consume = |y0: usize, pieces: Vec<Piece>| -> Result<()> {
        for piece in pieces {
            if deferred && y0 == 0 {
                top = Some(piece);
            } else {
                idat.push(&piece.bytes)?;
                rest = rest.then(piece.sum);
                // Dropped when enough are waiting already.
                let _ = spare_tx.try_send(piece.bytes);
            }
        }
        Ok(())
    };
    run(rows, &fit, tail, (deferred, needs_heights), visit, Stages { prepare, consume })?;
    let mut first_idat = Vec::new();
    let adler = if deferred {
        let top: Piece = top
            .filter(|t| t.sum.len == top_len as u64)
            .ok_or_else(|| Error::Encode("the top rows were not fitted".into()))?;
        first_idat.extend_from_slice(&ZLIB_HEADER);
        first_idat.extend_from_slice(&top.bytes);
        top.sum.then(rest).adler
    } else {
        rest.adler
    };
    idat.push(&FINAL_BLOCK)?;
    idat.push(&adler.to_be_bytes())?;
    idat.flush_chunk()?;
    write_chunk(out, b"IEND", &[])?;
    Ok((first_idat, fit.missing()))
}

#[cfg(test)]
mod tests {
    //! The encoder on its own: every depth, channel layout and filter
    //! setting it writes, in order (`convert_png`) and top rows last
    //! (`convert_png_seekable`), decoded by the `png` crate and compared
    //! with the whole-image fit; chunk lengths and CRCs checked by a CRC
    //! written out here; the IDAT stream split into chunks and inflated
    //! whole; the filter byte of every row.

    use super::*;
    use crate::fit::FitRequest;
    use crate::io::png::stream::{AVG, IDAT_BYTES, NONE, PAETH, SUB, UP};

    /// Heights from memory, 16-bit.
    struct Rows {
        heights: Vec<u16>,
        width: usize,
        next: usize,
    }

    impl RowSource for Rows {
        fn width(&self) -> usize {
            self.width
        }
        fn height(&self) -> usize {
            self.heights.len() / self.width
        }
        fn unit(&self) -> f64 {
            1.0 / 65535.0
        }
        fn next_row(&mut self, out: &mut [f64]) -> Result<()> {
            let row = &self.heights[self.next * self.width..][..self.width];
            out.iter_mut().zip(row).for_each(|(o, &v)| *o = f64::from(v));
            self.next += 1;
            Ok(())
        }
    }

    /// Smooth relief with grain (`grain` 0: smooth only), different per seed.
    fn heights(w: usize, h: usize, grain: u64) -> Vec<u16> {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f64, (k / w) as f64);
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let noise = if grain == 0 { 0 } else { state % grain };
                let v = 30000.0 + 9000.0 * (x * 0.21).sin() + 7000.0 * (y * 0.13 + x * 0.05).cos();
                v as u16 + noise as u16
            })
            .collect()
    }

    /// CRC-32 (PNG, ISO 3309) bit by bit: no table, no library.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 == 1 { (crc >> 1) ^ 0xedb8_8320 } else { crc >> 1 };
            }
        }
        !crc
    }

    /// The chunks of a PNG file as (type, data), every length and CRC checked.
    fn chunks(file: &[u8]) -> Vec<([u8; 4], &[u8])> {
        assert_eq!(&file[..8], b"\x89PNG\r\n\x1a\n");
        let mut rest = &file[8..];
        let mut out = Vec::new();
        while !rest.is_empty() {
            let len = u32::from_be_bytes(rest[..4].try_into().unwrap()) as usize;
            let kind: [u8; 4] = rest[4..8].try_into().unwrap();
            let data = &rest[8..8 + len];
            let crc = u32::from_be_bytes(rest[8 + len..12 + len].try_into().unwrap());
            assert_eq!(crc, crc32(&rest[4..8 + len]), "CRC of chunk {}", String::from_utf8_lossy(&kind));
            out.push((kind, data));
            rest = &rest[12 + len..];
        }
        out
    }

    /// Encodes `heights` both ways with these options.
    fn both_ways(heights: &[u16], w: usize, opts: &Options, png: PngOptions) -> [Vec<u8>; 2] {
        let rows = || Rows { heights: heights.to_vec(), width: w, next: 0 };
        let h = heights.len() / w;
        let tail_rows = BandFit::new(w, h, opts).unwrap().radius();
        let tail: Vec<f64> = heights[(h - tail_rows.min(h)) * w..].iter().map(|&v| f64::from(v)).collect();
        let mut in_order = Vec::new();
        convert_png(rows(), Some(&tail), opts, png, |_| {}, &mut in_order).unwrap();
        let mut seekable = std::io::Cursor::new(Vec::new());
        convert_png_seekable(rows(), opts, png, |_| {}, &mut seekable).unwrap();
        [in_order, seekable.into_inner()]
    }

    /// The codec floor given the fit's own normals writes the conversion's
    /// file, byte for byte, over several bands (the same filtering,
    /// pieces and top rows last); texels that do not cover the image are
    /// an error.
    #[test]
    fn the_codec_floor_writes_the_conversions_file() {
        let (w, h) = (700, 90);
        let heights = heights(w, h, 97);
        let opts = Options::new().with_strength(crate::options::Strength::Scale(3.0));
        let rows = || Rows { heights: heights.clone(), width: w, next: 0 };
        let mut normals = vec![[0u8; 3]; w * h];
        FitRequest::new(&opts).normals_into(&heights, w, h, &mut normals).unwrap();
        let mut converted = std::io::Cursor::new(Vec::new());
        convert_png_seekable(rows(), &opts, PngOptions::new(PngDepth::Eight), |_| {}, &mut converted).unwrap();
        let mut floor = std::io::Cursor::new(Vec::new());
        png_codec_floor(rows(), &opts, &normals, &mut floor).unwrap();
        assert!(floor.get_ref() == converted.get_ref(), "the same bytes");
        // Other texels, another file: the copy is what is written.
        normals[w * h / 2] = [0, 0, 0];
        let mut other = std::io::Cursor::new(Vec::new());
        png_codec_floor(rows(), &opts, &normals, &mut other).unwrap();
        assert!(other.get_ref() != converted.get_ref());
        let short = png_codec_floor(rows(), &opts, &normals[1..], &mut std::io::Cursor::new(Vec::new()));
        assert!(matches!(short, Err(Error::BufferSize { .. })), "{short:?}");
    }

    #[test]
    fn every_depth_layout_and_filter_decodes_to_the_whole_image_fit() {
        let (w, h) = (45, 38);
        let heights = heights(w, h, 0);
        let opts = Options::new().with_patch(5).with_strength(crate::options::Strength::Scale(2.0));
        let mut want8 = vec![[0u8; 3]; w * h];
        FitRequest::new(&opts).normals_into(&heights, w, h, &mut want8).unwrap();
        let mut want16 = vec![[0u16; 3]; w * h];
        FitRequest::new(&opts).normals_into(&heights, w, h, &mut want16).unwrap();
        for depth in [PngDepth::Eight, PngDepth::Sixteen] {
            for layout in [Layout::Rgb, Layout::RgbHeight, Layout::RgbOpaque, Layout::Rg] {
                for compression in [PngCompression::Fast, PngCompression::Default] {
                    let png = PngOptions::new(depth).with_layout(layout).with_compression(compression);
                    for (way, file) in both_ways(&heights, w, &opts, png).iter().enumerate() {
                        let what = format!("{depth:?} {layout:?} {compression:?}, way {way}");
                        let mut reader = png::Decoder::new(std::io::Cursor::new(file)).read_info().unwrap();
                        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
                        let info = reader.next_frame(&mut buf).unwrap();
                        let samples = if matches!(layout, Layout::RgbHeight | Layout::RgbOpaque) { 4 } else { 3 };
                        let colour = if samples == 4 { png::ColorType::Rgba } else { png::ColorType::Rgb };
                        assert_eq!((info.width, info.height, info.color_type), (w as u32, h as u32, colour), "{what}");
                        // Every sample as a number, whatever the depth.
                        let got: Vec<u32> = match depth {
                            PngDepth::Eight => buf.iter().map(|&b| u32::from(b)).collect(),
                            PngDepth::Sixteen => {
                                buf.chunks_exact(2).map(|b| u32::from(u16::from_be_bytes([b[0], b[1]]))).collect()
                            }
                        };
                        let max = if depth == PngDepth::Eight { 255 } else { 65535 };
                        for (k, texel) in got.chunks_exact(samples).enumerate() {
                            let want: [u32; 3] = match depth {
                                PngDepth::Eight => want8[k].map(u32::from),
                                PngDepth::Sixteen => want16[k].map(u32::from),
                            };
                            let blue = if layout == Layout::Rg { 0 } else { want[2] };
                            assert_eq!(texel[..3], [want[0], want[1], blue], "{what}, texel {k}");
                            match layout {
                                Layout::RgbOpaque => assert_eq!(texel[3], max, "{what}"),
                                Layout::RgbHeight => {
                                    let height = f64::from(heights[k]) / 65535.0 * f64::from(max);
                                    assert!((f64::from(texel[3]) - height).abs() <= 0.5 + 1e-9, "{what}, texel {k}");
                                }
                                _ => {}
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn chunks_carry_their_crcs_and_the_idat_stream_splits_and_inflates_whole() {
        // Grain that deflate cannot take away: several IDAT chunks.
        let (w, h) = (640, 512);
        let heights = heights(w, h, 4000);
        let opts = Options::new().with_patch(3).with_strength(crate::options::Strength::Scale(40.0));
        let png = PngOptions::new(PngDepth::Sixteen).with_layout(Layout::RgbHeight);
        for (way, file) in both_ways(&heights, w, &opts, png).iter().enumerate() {
            let chunks = chunks(file);
            let kinds: Vec<&[u8; 4]> = chunks.iter().map(|(k, _)| k).collect();
            assert_eq!(kinds.first(), Some(&b"IHDR"), "way {way}");
            assert_eq!(kinds.last(), Some(&b"IEND"), "way {way}");
            let idats: Vec<&[u8]> = chunks.iter().filter(|(k, _)| k == b"IDAT").map(|(_, d)| *d).collect();
            assert_eq!(idats.len() + 2, chunks.len(), "way {way}: IHDR, the IDATs one after another, IEND");
            assert!(idats.len() >= 3, "way {way}: {} IDAT chunks", idats.len());
            // Cut once about IDAT_BYTES are buffered; the seekable way's
            // first chunk is the room kept for the top rows.
            let full = &idats[way..idats.len() - 1];
            assert!(full.iter().all(|d| d.len() >= IDAT_BYTES), "way {way}");
            if way == 1 {
                assert_eq!(idats[0].len(), 2 + stored_len(w * 8 + 1), "way 1: zlib header and one stored row");
            }
            // The zlib stream across the chunks, its Adler-32 checked by the inflater.
            let stream: Vec<u8> = idats.concat();
            let raw = fdeflate::decompress_to_vec(&stream).unwrap();
            let stride = w * 4 * 2;
            assert_eq!(raw.len(), h * (stride + 1), "way {way}");
            // Filter bytes: the fast setting uses Sub for the first row it
            // filters and Avg after; the seekable way stores its top rows
            // (N/2 = 1) unfiltered.
            let filters: Vec<u8> = raw.chunks_exact(stride + 1).map(|r| r[0]).collect();
            match way {
                0 => assert_eq!(filters[0], SUB),
                _ => assert_eq!(filters[..2], [NONE, SUB]),
            }
            assert!(filters[2..].iter().all(|&f| f == AVG), "way {way}");
        }
    }

    #[test]
    fn the_adaptive_setting_decodes_to_the_same_texels_choosing_filters_per_row() {
        let (w, h) = (96, 80);
        let heights = heights(w, h, 300);
        let opts = Options::new().with_patch(3).with_strength(crate::options::Strength::Scale(8.0));
        let fast = both_ways(&heights, w, &opts, PngOptions::new(PngDepth::Eight));
        let small =
            both_ways(&heights, w, &opts, PngOptions::new(PngDepth::Eight).with_compression(PngCompression::Default));
        let decode = |file: &[u8]| {
            let mut reader = png::Decoder::new(std::io::Cursor::new(file)).read_info().unwrap();
            let mut buf = vec![0; reader.output_buffer_size().unwrap()];
            reader.next_frame(&mut buf).unwrap();
            buf
        };
        for way in 0..2 {
            assert!(decode(&fast[way]) == decode(&small[way]), "way {way}");
            let idat: Vec<u8> =
                chunks(&small[way]).into_iter().filter(|(k, _)| k == b"IDAT").flat_map(|(_, d)| d.to_vec()).collect();
            let raw = fdeflate::decompress_to_vec(&idat).unwrap();
            let mut used: Vec<u8> = raw.chunks_exact(w * 3 + 1).map(|r| r[0]).collect();
            used.sort_unstable();
            used.dedup();
            // More than one filter, one of them looking at the row above.
            let looks_up = used.iter().any(|&f| matches!(f, UP | AVG | PAETH));
            assert!(used.len() >= 2 && looks_up && used.iter().all(|&f| f <= PAETH), "way {way}: filters {used:?}");
        }
    }

    /// The file's bytes, not only its texels, do not depend on the number
    /// of threads, which sets the rows of a band: deflate's pieces lie at
    /// fixed places of the stream.
    #[cfg(feature = "parallel")]
    #[test]
    fn the_bytes_do_not_depend_on_the_number_of_threads() {
        // Rows of 3 · 6 · 1500 bytes: a 16-bit band of 2 × 64 rows holds
        // several pieces, and pieces cross bands.
        let (w, h) = (1500, 300);
        let heights = heights(w, h, 40);
        let opts = Options::new().with_patch(5).with_strength(crate::options::Strength::Scale(30.0));
        for depth in [PngDepth::Eight, PngDepth::Sixteen] {
            for compression in [PngCompression::Fast, PngCompression::Default] {
                let png = PngOptions::new(depth).with_compression(compression);
                let run = |threads: usize| {
                    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                    pool.install(|| both_ways(&heights, w, &opts, png))
                };
                let serial = run(1);
                for threads in [2, 3, 5] {
                    assert!(run(threads) == serial, "{depth:?} {compression:?}, {threads} threads");
                }
            }
        }
    }
}
