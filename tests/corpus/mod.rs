//! Files built byte by byte for the hostile-input and awkward-input tests,
//! and a way to run the binary that never waits forever, under a 1 GiB
//! address-space limit.
//!
//! PNG, OpenEXR and TIFF are written here by hand rather than by their
//! crates' encoders, so that every field (a CRC, a window corner, a filter
//! byte) can be set to exactly the wrong value a test needs. Each writer
//! is checked by a test that its untouched output reads, so a broken file
//! fails for the reason the test gives it and no other.

#![allow(dead_code)]

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

// ---------------------------------------------------------------------------
// PNG

/// One chunk: length, type, data, CRC of type and data.
pub fn png_chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    png_chunk_with_crc(kind, data, crc.finalize())
}

/// One chunk with the CRC given (right or wrong).
pub fn png_chunk_with_crc(kind: &[u8; 4], data: &[u8], crc: u32) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() + 12);
    out.extend((data.len() as u32).to_be_bytes());
    out.extend(kind);
    out.extend(data);
    out.extend(crc.to_be_bytes());
    out
}

pub const PNG_SIGNATURE: &[u8; 8] = b"\x89PNG\r\n\x1a\n";

/// IHDR data: width, height, bit depth, colour type, no interlace.
pub fn ihdr(width: u32, height: u32, bit_depth: u8, color_type: u8) -> Vec<u8> {
    let mut d = Vec::with_capacity(13);
    d.extend(width.to_be_bytes());
    d.extend(height.to_be_bytes());
    d.extend([bit_depth, color_type, 0, 0, 0]);
    d
}

/// The filtered scan lines of an image: each row is a filter byte (0, none)
/// and `row(y)`.
pub fn scanlines(height: usize, row: impl Fn(usize) -> Vec<u8>) -> Vec<u8> {
    let mut raw = Vec::new();
    for y in 0..height {
        raw.push(0);
        raw.extend(row(y));
    }
    raw
}

/// A whole PNG: signature, IHDR, the extra chunks (PLTE, tRNS), one IDAT
/// of `zlib`, IEND.
pub fn png_file(ihdr_data: &[u8], extra: &[Vec<u8>], zlib: &[u8]) -> Vec<u8> {
    let mut out = PNG_SIGNATURE.to_vec();
    out.extend(png_chunk(b"IHDR", ihdr_data));
    for c in extra {
        out.extend(c);
    }
    out.extend(png_chunk(b"IDAT", zlib));
    out.extend(png_chunk(b"IEND", &[]));
    out
}

/// An 8-bit gray PNG, pixel (x, y) = `value(x, y)`.
pub fn png_gray8(width: u32, height: u32, value: impl Fn(usize, usize) -> u8) -> Vec<u8> {
    let raw = scanlines(height as usize, |y| (0..width as usize).map(|x| value(x, y)).collect());
    png_file(&ihdr(width, height, 8, 0), &[], &fdeflate::compress_to_vec(&raw))
}

/// A 16-bit gray PNG, pixel (x, y) = `value(x, y)`.
pub fn png_gray16(width: u32, height: u32, value: impl Fn(usize, usize) -> u16) -> Vec<u8> {
    let raw = scanlines(height as usize, |y| (0..width as usize).flat_map(|x| value(x, y).to_be_bytes()).collect());
    png_file(&ihdr(width, height, 16, 0), &[], &fdeflate::compress_to_vec(&raw))
}

/// IHDR data like [`ihdr`]'s, with the interlace method Adam7.
pub fn ihdr_adam7(width: u32, height: u32, bit_depth: u8, color_type: u8) -> Vec<u8> {
    let mut d = ihdr(width, height, bit_depth, color_type);
    d[12] = 1;
    d
}

/// The filtered scan lines of an Adam7-interlaced image: its seven passes
/// in order, each row a filter byte (0, none) and pixel (x, y) as the
/// bytes `pixel` gives. A pass with no pixels has no rows.
pub fn adam7_scanlines(width: usize, height: usize, pixel: impl Fn(usize, usize) -> Vec<u8>) -> Vec<u8> {
    const PASSES: [(usize, usize, usize, usize); 7] =
        [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)];
    let mut raw = Vec::new();
    for (x0, y0, dx, dy) in PASSES {
        if x0 >= width || y0 >= height {
            continue;
        }
        for y in (y0..height).step_by(dy) {
            raw.push(0);
            for x in (x0..width).step_by(dx) {
                raw.extend(pixel(x, y));
            }
        }
    }
    raw
}

/// `png` (one IDAT chunk) with the last four bytes of its zlib stream,
/// the Adler-32 of the image data, inverted when `corrupt`, and the IDAT
/// CRC computed for the new bytes, so the checksum is all that is wrong.
/// With `own_chunk`, those four bytes go in an IDAT chunk of their own,
/// after the one holding the rest (a decoder that stops reading at the
/// image's last byte never sees them).
pub fn png_adler_case(png: &[u8], corrupt: bool, own_chunk: bool) -> Vec<u8> {
    let at = find_chunk(png, b"IDAT");
    let len = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
    let mut zlib = png[at + 8..at + 8 + len].to_vec();
    if corrupt {
        for b in &mut zlib[len - 4..] {
            *b = !*b;
        }
    }
    let mut out = png[..at].to_vec();
    if own_chunk {
        out.extend(png_chunk(b"IDAT", &zlib[..len - 4]));
        out.extend(png_chunk(b"IDAT", &zlib[len - 4..]));
    } else {
        out.extend(png_chunk(b"IDAT", &zlib));
    }
    out.extend(&png[at + 12 + len..]);
    out
}

/// Where a chunk of this type starts in a PNG (its length field).
pub fn find_chunk(png: &[u8], kind: &[u8; 4]) -> usize {
    let mut at = 8;
    while at + 8 <= png.len() {
        let len = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
        if &png[at + 4..at + 8] == kind {
            return at;
        }
        at += 12 + len;
    }
    panic!("no {} chunk", String::from_utf8_lossy(kind));
}

// ---------------------------------------------------------------------------
// OpenEXR, single part, scan lines, uncompressed: every header field set
// by the test.

/// OpenEXR sample types as stored in a channel list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExrSample {
    U32 = 0,
    F16 = 1,
    F32 = 2,
}

impl ExrSample {
    fn bytes(self) -> usize {
        match self {
            ExrSample::F16 => 2,
            ExrSample::U32 | ExrSample::F32 => 4,
        }
    }
}

/// What a hand-made EXR holds. `channels` must be sorted by name, as the
/// format requires; values are given per channel, row-major, as f32 (u32
/// channels take them as integers).
pub struct ExrSpec {
    pub channels: Vec<(String, ExrSample)>,
    /// x min, y min, x max, y max (inclusive).
    pub data_window: [i32; 4],
    pub display_window: [i32; 4],
    /// 0: none.
    pub compression: u8,
}

impl ExrSpec {
    /// One float channel `Y`, window (0, 0) – (w − 1, h − 1).
    pub fn gray(width: i32, height: i32) -> ExrSpec {
        let window = [0, 0, width - 1, height - 1];
        ExrSpec {
            channels: vec![("Y".into(), ExrSample::F32)],
            data_window: window,
            display_window: window,
            compression: 0,
        }
    }

    pub fn width(&self) -> usize {
        (self.data_window[2] - self.data_window[0] + 1) as usize
    }

    pub fn height(&self) -> usize {
        (self.data_window[3] - self.data_window[1] + 1) as usize
    }

    /// The header: magic, version, attributes, the closing null byte.
    pub fn header(&self) -> Vec<u8> {
        let mut out = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
        let mut chlist = Vec::new();
        for (name, sample) in &self.channels {
            chlist.extend(name.as_bytes());
            chlist.push(0);
            chlist.extend((*sample as i32).to_le_bytes());
            chlist.extend([0, 0, 0, 0]); // pLinear, reserved
            chlist.extend(1i32.to_le_bytes());
            chlist.extend(1i32.to_le_bytes());
        }
        chlist.push(0);
        let boxed = |b: [i32; 4]| b.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
        exr_attribute(&mut out, "channels", "chlist", &chlist);
        exr_attribute(&mut out, "compression", "compression", &[self.compression]);
        exr_attribute(&mut out, "dataWindow", "box2i", &boxed(self.data_window));
        exr_attribute(&mut out, "displayWindow", "box2i", &boxed(self.display_window));
        exr_attribute(&mut out, "lineOrder", "lineOrder", &[0]);
        exr_attribute(&mut out, "pixelAspectRatio", "float", &1.0f32.to_le_bytes());
        exr_attribute(&mut out, "screenWindowCenter", "v2f", &[0; 8]);
        exr_attribute(&mut out, "screenWindowWidth", "float", &1.0f32.to_le_bytes());
        out.push(0);
        out
    }

    /// The whole file, one scan line per chunk (uncompressed), channel
    /// `c`'s value at (x, y) from `planes[c][y * width + x]`.
    pub fn file(&self, planes: &[Vec<f32>]) -> Vec<u8> {
        assert_eq!(self.compression, 0, "the hand writer stores lines uncompressed");
        let (w, h) = (self.width(), self.height());
        let mut out = self.header();
        let line_bytes: usize = self.channels.iter().map(|(_, s)| s.bytes() * w).sum();
        let table_start = out.len();
        let first_chunk = table_start + 8 * h;
        for y in 0..h {
            out.extend(((first_chunk + y * (8 + line_bytes)) as u64).to_le_bytes());
        }
        for y in 0..h {
            out.extend((self.data_window[1] + y as i32).to_le_bytes());
            out.extend((line_bytes as i32).to_le_bytes());
            for ((_, sample), plane) in self.channels.iter().zip(planes) {
                for &v in &plane[y * w..][..w] {
                    match sample {
                        ExrSample::F32 => out.extend(v.to_le_bytes()),
                        ExrSample::F16 => out.extend(exr::prelude::f16::from_f32(v).to_bits().to_le_bytes()),
                        ExrSample::U32 => out.extend((v as u32).to_le_bytes()),
                    }
                }
            }
        }
        out
    }
}

fn exr_attribute(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
    out.extend(name.as_bytes());
    out.push(0);
    out.extend(kind.as_bytes());
    out.push(0);
    out.extend((value.len() as i32).to_le_bytes());
    out.extend(value);
}

/// Where the value of attribute `name` sits in a single-part EXR's header
/// (start and length), and where the header ends (after its null byte).
pub fn exr_find_attribute(file: &[u8], name: &str) -> (Option<(usize, usize)>, usize) {
    let mut at = 8;
    let mut found = None;
    let cstr = |at: usize| -> (String, usize) {
        let end = at + file[at..].iter().position(|&b| b == 0).unwrap();
        (String::from_utf8_lossy(&file[at..end]).into_owned(), end + 1)
    };
    loop {
        let (attribute, next) = cstr(at);
        if attribute.is_empty() {
            return (found, next);
        }
        let (_, next) = cstr(next);
        let size = i32::from_le_bytes(file[next..next + 4].try_into().unwrap()) as usize;
        if attribute == name {
            found = Some((next + 4, size));
        }
        at = next + 4 + size;
    }
}

/// The file with attribute `name`'s value replaced by `value` (same size).
pub fn exr_set_attribute(file: &[u8], name: &str, value: &[u8]) -> Vec<u8> {
    let (Some((at, len)), _) = exr_find_attribute(file, name) else { panic!("no attribute {name}") };
    assert_eq!(len, value.len(), "attribute {name} keeps its size");
    let mut out = file.to_vec();
    out[at..at + len].copy_from_slice(value);
    out
}

/// A box2i attribute value.
pub fn box2i(b: [i32; 4]) -> Vec<u8> {
    b.iter().flat_map(|v| v.to_le_bytes()).collect()
}

// ---------------------------------------------------------------------------
// TIFF, classic little-endian, one strip.

/// A one-strip gray TIFF: `bits` per sample, sample format 1 (unsigned)
/// or 3 (float), the header claiming `width` × `height` whatever `data`
/// holds.
pub fn tiff_gray(width: u32, height: u32, bits: u16, sample_format: u16, data: &[u8]) -> Vec<u8> {
    tiff_gray_tagged(width, height, bits, sample_format, data, &[])
}

/// One more tag for [`tiff_gray_tagged`]: its number (above 339), TIFF
/// type (3 SHORT, 2 ASCII, 12 DOUBLE), the count its directory entry
/// claims (true or forged) and its value's bytes.
pub struct ExtraTag {
    pub tag: u16,
    pub kind: u16,
    pub count: u32,
    pub bytes: Vec<u8>,
}

impl ExtraTag {
    /// DOUBLEs, counted truly.
    pub fn doubles(tag: u16, values: &[f64]) -> ExtraTag {
        ExtraTag {
            tag,
            kind: 12,
            count: values.len() as u32,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }

    /// SHORTs, counted truly.
    pub fn shorts(tag: u16, values: &[u16]) -> ExtraTag {
        ExtraTag {
            tag,
            kind: 3,
            count: values.len() as u32,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }

    /// The same value with the count its entry claims set to `count`.
    pub fn claiming(self, count: u32) -> ExtraTag {
        ExtraTag { count, ..self }
    }
}

/// [`tiff_gray`] with `extra` tags after its own (GeoTIFF's, GDAL's): a
/// value of more than 4 bytes is stored after the directory, where its
/// entry points.
pub fn tiff_gray_tagged(
    width: u32,
    height: u32,
    bits: u16,
    sample_format: u16,
    data: &[u8],
    extra: &[ExtraTag],
) -> Vec<u8> {
    const SHORT: u16 = 3;
    const LONG: u16 = 4;
    let entries: [(u16, u16, u32); 10] = [
        (256, LONG, width),
        (257, LONG, height),
        (258, SHORT, u32::from(bits)),
        (259, SHORT, 1),
        (262, SHORT, 1),
        (273, LONG, 0), // strip offset, filled in below
        (277, SHORT, 1),
        (278, LONG, height),
        (279, LONG, data.len() as u32),
        (339, SHORT, u32::from(sample_format)),
    ];
    let count = entries.len() + extra.len();
    let ifd_len = 2 + count * 12 + 4;
    // The values that do not fit an entry, then the strip.
    let mut values = Vec::new();
    let mut value_at = Vec::new();
    for tag in extra {
        value_at.push((8 + ifd_len + values.len()) as u32);
        if tag.bytes.len() > 4 {
            values.extend(&tag.bytes);
            values.resize(values.len().next_multiple_of(2), 0);
        }
    }
    let data_at = (8 + ifd_len + values.len()) as u32;
    let mut out = b"II*\0".to_vec();
    out.extend(8u32.to_le_bytes());
    out.extend((count as u16).to_le_bytes());
    for (tag, kind, value) in entries {
        let value = if tag == 273 { data_at } else { value };
        out.extend(tag.to_le_bytes());
        out.extend(kind.to_le_bytes());
        out.extend(1u32.to_le_bytes());
        match kind {
            SHORT => {
                out.extend((value as u16).to_le_bytes());
                out.extend([0, 0]);
            }
            _ => out.extend(value.to_le_bytes()),
        }
    }
    for (tag, at) in extra.iter().zip(value_at) {
        out.extend(tag.tag.to_le_bytes());
        out.extend(tag.kind.to_le_bytes());
        out.extend(tag.count.to_le_bytes());
        if tag.bytes.len() > 4 {
            out.extend(at.to_le_bytes());
        } else {
            let mut inline = tag.bytes.clone();
            inline.resize(4, 0);
            out.extend(inline);
        }
    }
    out.extend(0u32.to_le_bytes());
    out.extend(values);
    out.extend(data);
    out
}

// ---------------------------------------------------------------------------
// Running the binary

/// How long one run of the binary may take. Every run in these tests is
/// of a small file or one refused from its header: a few milliseconds
/// alone, so this bound only trips on a hang (the machine may be busy).
pub const TIME_LIMIT: Duration = Duration::from_secs(60);

/// What one run of the binary did.
pub struct Run {
    /// The exit code; `None` if a signal ended the process.
    pub code: Option<i32>,
    pub signal: Option<i32>,
    pub stdout: String,
    pub stderr: String,
}

impl Run {
    /// Standard error's lines, less a batch's closing summary line, which
    /// is not a message about a file.
    pub fn stderr_lines(&self) -> Vec<&str> {
        self.stderr.lines().filter(|l| !is_summary(l)).collect()
    }

    /// A batch's summary line: `normalfit: C converted, S skipped, F failed
    /// in T s` (`shaded`, `checked` for `shade` and `tiling`).
    pub fn summary(&self) -> Option<&str> {
        self.stderr.lines().find(|l| is_summary(l))
    }
}

fn is_summary(line: &str) -> bool {
    let words: Vec<&str> = line.split(' ').collect();
    matches!(
        words[..],
        ["normalfit:", c, "converted," | "shaded," | "checked,", s, "skipped,", f, "failed", "in", t, "s"]
            if [c, s, f].iter().all(|n| n.parse::<usize>().is_ok()) && t.parse::<f64>().is_ok()
    )
}

/// The address space every run of the corpus may take (`ulimit -v`):
/// 1 GiB, under which every case must still be refused in one line or
/// converted, never end in an aborted allocation (issue 32).
pub const ADDRESS_SPACE: u64 = 1 << 30;

/// Runs the binary with `args` (standard input from `stdin` if given),
/// under [`ADDRESS_SPACE`], killing it if it outlives [`TIME_LIMIT`]: a
/// test that hangs fails instead of waiting forever.
pub fn run_bin(args: &[&std::ffi::OsStr], stdin: Option<&Path>) -> Run {
    use std::os::unix::process::ExitStatusExt;
    // sh sets the limit, then becomes the binary ("$0", "$@": the
    // arguments pass through unquoted by any shell).
    let mut command = Command::new("sh");
    let limit = format!("ulimit -v {} && exec \"$0\" \"$@\"", ADDRESS_SPACE / 1024);
    command.arg("-c").arg(limit).arg(env!("CARGO_BIN_EXE_normalfit"));
    command.args(args).stdout(Stdio::piped()).stderr(Stdio::piped());
    command.stdin(match stdin {
        Some(path) => Stdio::from(std::fs::File::open(path).unwrap()),
        None => Stdio::null(),
    });
    let mut child = command.spawn().expect("the binary starts");
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let out_reader = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = out.read_to_end(&mut s);
        s
    });
    let err_reader = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = err.read_to_end(&mut s);
        s
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > TIME_LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("normalfit {args:?} ran for more than {TIME_LIMIT:?}: killed (it must never hang)");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Run {
        code: status.code(),
        signal: status.signal(),
        stdout: String::from_utf8_lossy(&out_reader.join().unwrap()).into_owned(),
        stderr: String::from_utf8_lossy(&err_reader.join().unwrap()).into_owned(),
    }
}

/// The names in a folder, sorted.
pub fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}
