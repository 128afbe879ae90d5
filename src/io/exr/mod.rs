//! OpenEXR, read with the `exr` crate: `image`'s EXR path only gives RGB(A)
//! and rejects single-channel files, the common height map layout. Files
//! with subsampled channels, which `exr` refuses, are read by
//! `subsampled.rs`.

pub(crate) mod rows;
pub(crate) mod subsampled;
pub(crate) mod write;

use std::io::{BufRead, Cursor, Read, Seek, SeekFrom};

use crate::par::prelude::*;

use self::subsampled as exr_subsampled;
use crate::error::{Error, Result};
use crate::io::{InputFormat, Plane, Raster, ReadOptions, SampleType, check_size, message, to_usize};
use crate::memory;
use crate::samples::{Samples, try_vec};

/// The four bytes every OpenEXR file starts with.
pub(crate) const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Decodes an EXR: meta data first (windows and sizes checked), then the
/// layer asked for ([`choose_exr_layer`]) at its largest resolution level,
/// all its channels.
pub(crate) fn decode_exr(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    decode_exr_from(Cursor::new(bytes), bytes.len() as u64, opts)
}

/// [`decode_exr`] of a file of `file_len` bytes read from `read` (at its
/// start), which need not hold it whole: the blocks are read as `exr`
/// decodes them. Reading a 4096² float file this way instead of from its
/// bytes in memory saves their 169 MB and a tenth of the read's time.
pub(crate) fn decode_exr_from<R: BufRead + Seek + Send>(
    mut read: R,
    file_len: u64,
    opts: &ReadOptions,
) -> Result<Raster> {
    let from_start = |read: &mut R| read.seek(SeekFrom::Start(0)).map(|_| ());
    check_exr_windows(&mut read)?;
    from_start(&mut read)?;
    if let Some(headers) = exr_subsampled::read_headers(&mut read).filter(exr_subsampled::Headers::subsampled) {
        return decode_exr_subsampled(read, file_len, headers, opts);
    }
    from_start(&mut read)?;
    let meta = exr::meta::MetaData::read_from_buffered(&mut read, false).map_err(from_exr_error)?;
    check_exr_meta(&meta, file_len, opts)?;
    let choice = choose_exr_layer(&exr_parts(&meta.headers), opts.layer.as_deref())?;
    // `exr` allocates the image itself, and aborts if that fails.
    memory::check_memory("decoding", exr_decode_bytes(&meta.headers[choice.part]))?;
    use exr::prelude::ReadLayers;
    let channels = exr::prelude::read().no_deep_data().largest_resolution_level().all_channels();
    from_start(&mut read)?;
    let image = OnePart { part: choice.part, channels }.all_attributes().from_buffered(read).map_err(from_exr_error)?;
    let (size, channels) = image.layer_data;
    let (width, height) = (size.0, size.1);
    check_size(width as u64, height as u64, opts)?;
    let texels = to_usize((width as u64).saturating_mul(height as u64))?;
    let planes = channels
        .list
        .into_iter()
        .filter(|channel| choice.holds(&channel.name.to_string()))
        .map(|channel| exr_plane(channel, texels))
        .collect::<Result<Vec<_>>>()?;
    Ok(Raster { width, height, format: InputFormat::Exr, sample: SampleType::Float, planes, georef: None })
}

/// Decodes an EXR with subsampled channels, which the `exr` crate refuses
/// (see [`exr_subsampled`]): the full-resolution channels of the layer
/// asked for, block by block. `read` is at the offset tables.
fn decode_exr_subsampled(
    mut read: impl Read + Seek,
    file_len: u64,
    headers: exr_subsampled::Headers,
    opts: &ReadOptions,
) -> Result<Raster> {
    let part = exr_subsampled::ScanLines::open(headers, &mut read, file_len, opts)?;
    let (width, height) = (part.width(), part.height());
    let texels = to_usize((width as u64).saturating_mul(height as u64))?;
    let (wanted, names): (Vec<usize>, Vec<String>) = part.channels().map(|(i, n)| (i, n.to_string())).unzip();
    memory::check_memory("decoding", (texels as u64).saturating_mul(8 * wanted.len() as u64))?;
    // The planes grow block by block, so a header that claims far more
    // texels than the file holds fails at its first missing chunk, before
    // the memory is taken. They are f64, as the streamed rows are: every
    // sample type (half, float, u32) exactly, and the same bits either way.
    let mut planes: Vec<(String, Vec<f64>)> = names.into_iter().map(|name| (name, Vec::new())).collect();
    for y0 in (0..height).step_by(part.lines_per_block()) {
        let block = part.read_block(&mut read, y0, &wanted)?;
        for ((name, data), rows) in planes.iter_mut().zip(block) {
            data.try_reserve(rows.len())
                .map_err(|_| Error::Limits(format!("cannot allocate {texels} values of 8 bytes for channel {name}")))?;
            data.extend_from_slice(&rows);
        }
    }
    let planes = planes.into_iter().map(|(name, data)| Plane { name, data: Samples::F64(data) }).collect();
    Ok(Raster { width, height, format: InputFormat::Exr, sample: SampleType::Float, planes, georef: None })
}

/// Which part of an OpenEXR file, and which of its channels, make the
/// image read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct ExrLayer {
    /// The part (header) index.
    pub part: usize,
    /// Only the channels named `prefix.…`, or all the part's channels.
    pub prefix: Option<String>,
}

impl ExrLayer {
    /// Whether the channel of this name belongs to the layer.
    pub fn holds(&self, channel: &str) -> bool {
        match &self.prefix {
            None => true,
            Some(p) => channel.strip_prefix(p.as_str()).is_some_and(|rest| rest.starts_with('.')),
        }
    }
}

/// What the layer choice needs of one part of an OpenEXR file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct ExrPart {
    /// Its `name` attribute.
    pub name: Option<String>,
    /// Whether it holds deep data.
    pub deep: bool,
    /// Its channels' names.
    pub channels: Vec<String>,
}

/// The parts of a file as the `exr` crate read its headers.
pub(crate) fn exr_parts(headers: &[exr::meta::header::Header]) -> Vec<ExrPart> {
    let part = |h: &exr::meta::header::Header| ExrPart {
        name: h.own_attributes.layer_name.as_ref().map(|n| n.to_string()),
        deep: h.deep,
        channels: h.channels.list.iter().map(|c| c.name.to_string()).collect(),
    };
    headers.iter().map(part).collect()
}

/// Finds the layer `name` among an OpenEXR file's parts (see
/// [`ReadOptions::layer`]): a part of that name, else the first part with
/// channels named `name.…`; `None` is the first part of flat samples.
///
/// Errors: [`Error::Unsupported`] naming the layers there are when none
/// matches, or when every part holds deep data.
pub(crate) fn choose_exr_layer(parts: &[ExrPart], name: Option<&str>) -> Result<ExrLayer> {
    let Some(name) = name else {
        return parts
            .iter()
            .position(|p| !p.deep)
            .map(|part| ExrLayer { part, prefix: None })
            .ok_or_else(|| Error::Unsupported("exr file holds only deep data".into()));
    };
    if let Some(part) = parts.iter().position(|p| p.name.as_deref() == Some(name)) {
        return Ok(ExrLayer { part, prefix: None });
    }
    let group = ExrLayer { part: 0, prefix: Some(name.to_string()) };
    if let Some(part) = parts.iter().position(|p| !p.deep && p.channels.iter().any(|c| group.holds(c))) {
        return Ok(ExrLayer { part, ..group });
    }
    // The names there are: parts, and the channel groups of each part.
    let mut layers: Vec<String> = Vec::new();
    for part in parts {
        layers.extend(part.name.clone());
        for channel in &part.channels {
            if let Some((group, _)) = channel.rsplit_once('.')
                && !layers.iter().any(|l| l == group)
            {
                layers.push(group.to_string());
            }
        }
    }
    let there = if layers.is_empty() {
        "it has none: no part names, no channels named LAYER.X".into()
    } else {
        format!("layers: {}", layers.join(", "))
    };
    Err(Error::Unsupported(format!("exr file has no layer {name} ({there})")))
}

/// The `exr` reader of one part of a file, by index (the crate itself
/// reads the first valid part or all of them).
struct OnePart<C> {
    part: usize,
    channels: C,
}

/// Gathers the blocks of one part.
struct OnePartReader<R> {
    part: usize,
    size: exr::math::Vec2<usize>,
    channels: R,
}

impl<'s, C: exr::image::read::layers::ReadChannels<'s>> exr::image::read::image::ReadLayers<'s> for OnePart<C> {
    type Layers = (exr::math::Vec2<usize>, <C::Reader as exr::image::read::layers::ChannelsReader>::Channels);
    type Reader = OnePartReader<C::Reader>;

    fn create_layers_reader(&'s self, headers: &[exr::meta::header::Header]) -> exr::error::Result<Self::Reader> {
        let header = headers.get(self.part).ok_or_else(|| exr::error::Error::Invalid("layer index".into()))?;
        let channels = self.channels.create_channels_reader(header)?;
        Ok(OnePartReader { part: self.part, size: header.layer_size, channels })
    }
}

impl<R: exr::image::read::layers::ChannelsReader> exr::image::read::image::LayersReader for OnePartReader<R> {
    type Layers = (exr::math::Vec2<usize>, R::Channels);

    fn filter_block(
        &self,
        _: &exr::meta::MetaData,
        tile: exr::block::chunk::TileCoordinates,
        block: exr::block::BlockIndex,
    ) -> bool {
        block.layer == self.part && self.channels.filter_block(tile)
    }

    fn read_block(
        &mut self,
        headers: &[exr::meta::header::Header],
        block: exr::block::UncompressedBlock,
    ) -> exr::error::UnitResult {
        let header = headers.get(self.part).ok_or_else(|| exr::error::Error::Invalid("layer index".into()))?;
        // Only the full-resolution level is read (its blocks alone pass the
        // filter, by the offset table); a block whose own data names
        // another level is corrupt, and `exr` would only notice it in a
        // debug assertion (a panic in debug builds, found by fuzzing).
        if block.index.level != exr::math::Vec2(0, 0) {
            return Err(exr::error::Error::Invalid("block of a resolution level that was not asked for".into()));
        }
        self.channels.read_block(header, block)
    }

    fn into_layers(self) -> Self::Layers {
        (self.size, self.channels.into_channels())
    }
}

/// Checks the data and display windows of every header as stored: each
/// max at least its min. The `exr` crate swaps an inverted window's
/// corners, which would read a broken or forged header as some other
/// image; OpenEXR rejects it, and so does normalfit. Anything else wrong
/// with the header (bytes missing, a name too long) is left to `exr`,
/// which reports it.
pub(crate) fn check_exr_windows(mut read: impl BufRead) -> Result<()> {
    /// Attribute and type names are at most 255 bytes (with long names).
    const NAME_MAX: usize = 256;
    fn name(read: &mut impl BufRead) -> Option<Vec<u8>> {
        let mut out = Vec::new();
        for byte in read.bytes() {
            match byte.ok()? {
                0 => return Some(out),
                b if out.len() < NAME_MAX => out.push(b),
                _ => return None,
            }
        }
        None
    }
    fn i32_le(read: &mut impl Read) -> Option<i32> {
        let mut b = [0u8; 4];
        read.read_exact(&mut b).ok()?;
        Some(i32::from_le_bytes(b))
    }
    let mut start = [0u8; 8];
    if read.read_exact(&mut start).is_err() {
        return Ok(());
    }
    // Version field flags: bit 12 (byte 5, 0x10) is "multi-part".
    let multipart = start[5] & 0x10 != 0;
    loop {
        let mut attributes = 0;
        loop {
            let Some(attribute) = name(&mut read) else { return Ok(()) };
            if attribute.is_empty() {
                break;
            }
            attributes += 1;
            let (Some(kind), Some(size)) = (name(&mut read), i32_le(&mut read)) else { return Ok(()) };
            let window = attribute == b"dataWindow" || attribute == b"displayWindow";
            if window && kind == b"box2i" && size == 16 {
                let corners: Option<Vec<i32>> = (0..4).map(|_| i32_le(&mut read)).collect();
                let Some(&[x_min, y_min, x_max, y_max]) = corners.as_deref() else { return Ok(()) };
                if x_max < x_min || y_max < y_min {
                    let which = if attribute == b"dataWindow" { "data" } else { "display" };
                    return Err(Error::Decode(format!(
                        "exr {which} window is inverted: min ({x_min}, {y_min}), max ({x_max}, {y_max})"
                    )));
                }
            } else {
                let Ok(size) = u64::try_from(size) else { return Ok(()) };
                let skipped = std::io::copy(&mut (&mut read).take(size), &mut std::io::sink()).unwrap_or(0);
                if skipped != size {
                    return Ok(());
                }
            }
        }
        // A multi-part file ends its list of headers with an empty one.
        if !multipart || attributes == 0 {
            return Ok(());
        }
    }
}

/// Checks every layer's data window against the limit, from the header of
/// a file of `file_len` bytes. Every layer, not just the first: `exr`
/// reads all offset tables, whose length follows from each layer's size.
/// The offset tables are stored in the file, so an honest file holds 8
/// bytes per chunk; a header claiming more chunks than that is forged.
pub(crate) fn check_exr_meta(meta: &exr::meta::MetaData, file_len: u64, opts: &ReadOptions) -> Result<()> {
    if meta.headers.is_empty() {
        return Err(Error::Decode("exr file has no layers".into()));
    }
    let mut chunks: u64 = 0;
    for header in &meta.headers {
        let size = header.layer_size;
        check_size(size.0 as u64, size.1 as u64, opts)?;
        chunks = chunks.saturating_add(header.chunk_count as u64);
    }
    if chunks.saturating_mul(8) > file_len {
        return Err(Error::Decode(format!(
            "truncated or corrupt: header claims {chunks} chunks, more than the file holds"
        )));
    }
    Ok(())
}

/// One EXR channel as a plane: half and float as stored, u32 as its number.
fn exr_plane(channel: exr::prelude::AnyChannel<exr::prelude::FlatSamples>, texels: usize) -> Result<Plane> {
    use exr::prelude::FlatSamples;
    let name = channel.name.to_string();
    let data = match channel.sample_data {
        FlatSamples::F32(v) => Samples::F32(v),
        FlatSamples::F16(v) => {
            let mut out = try_vec(v.len())?;
            out.par_extend(v.par_iter().map(|h| h.to_f32()));
            Samples::F32(out)
        }
        FlatSamples::U32(v) => {
            // SPEC treats EXR as a float image: the value is the height.
            // f64 holds every u32 exactly (f32 would round above 2^24).
            let mut out = try_vec(v.len())?;
            out.par_extend(v.par_iter().map(|&n| f64::from(n)));
            Samples::F64(out)
        }
    };
    if data.len() != texels {
        return Err(Error::Unsupported(format!(
            "channel {name} is subsampled ({} samples for {texels} texels)",
            data.len()
        )));
    }
    Ok(Plane { name, data })
}

/// Maps `exr`'s errors onto ours. Its I/O errors are nearly always the
/// data ending early (from memory they can be nothing else; from a file,
/// the system's own failures are rare), and the message says which.
pub(crate) fn from_exr_error(e: exr::error::Error) -> Error {
    use exr::error::Error as E;
    match e {
        E::NotSupported(m) => Error::Unsupported(format!("exr: {}", message(&m))),
        // `exr` reports every read past the end of the data so.
        E::Invalid(m) if m == "reference to missing bytes" => {
            Error::Decode("truncated or corrupt: the file ends before the data its header refers to".into())
        }
        E::Invalid(m) => Error::Decode(format!("invalid exr: {}", message(&m))),
        E::Io(e) => Error::Decode(format!("truncated or corrupt: {}", message(&e.to_string()))),
        E::Aborted => Error::Decode("reading was aborted".into()),
    }
}

/// The bytes the `exr` crate holds for a whole-image read of the part
/// `header` describes (every channel at full resolution, as stored), plus
/// one converted `f32` plane for half or u32 channels.
fn exr_decode_bytes(header: &exr::meta::header::Header) -> u64 {
    let texels = (header.layer_size.0 as u64).saturating_mul(header.layer_size.1 as u64);
    let stored: u64 = header
        .channels
        .list
        .iter()
        .map(|c| texels.saturating_mul(c.sample_type.bytes_per_sample() as u64))
        .fold(0, u64::saturating_add);
    let all_f32 = header.channels.list.iter().all(|c| c.sample_type == exr::meta::attribute::SampleType::F32);
    let converted = if all_f32 { 0 } else { texels.saturating_mul(4) };
    stored.saturating_add(converted)
}
