//! Every OpenEXR layout a renderer writes, read by the whole-image reader
//! (`read_path`) and the streamed one (`ExrRows`) alike, which must agree
//! to the bit, errors included: root RGBA and a depth channel beside
//! layers, root Y beside layers, a depth pass of one channel, channels all
//! in layers, several parts, and luminance/chroma files (subsampled
//! chroma, full-resolution Y). The channel rule is docs/convert.md's: root
//! channels (names without a dot) decide the default; a layer is read by
//! `--layer` or a channel by its full name.
//!
//! The `exr` crate writes the flat files. It cannot write (or read)
//! subsampled channels, so the luminance/chroma files come from a small
//! writer here and from OpenEXR's own library (`tests/data/exr_yc`, made
//! by its `make.py`), whose values the tests know by formula.

use std::path::{Path, PathBuf};

use exr::prelude::{
    AnyChannel, AnyChannels, Blocks, Compression, Encoding, FlatSamples, Image, Layer, LayerAttributes, LineOrder,
    SmallVec, Vec2, WritableImage, f16,
};
use normalfit::io::{Channel, ReadOptions, read_path};
use normalfit::pipeline::{ExrRows, RowSource};
#[cfg(feature = "cli")]
use normalfit::{Options, normals};

// ---------------------------------------------------------------------------
// Reading by both paths

fn read_options(layer: Option<&str>) -> ReadOptions {
    match layer {
        Some(name) => ReadOptions::default().with_layer(name),
        None => ReadOptions::default(),
    }
}

/// The heights the whole-image reader gives, as f32 (exact for these
/// files' half and float samples).
fn whole(path: &Path, layer: Option<&str>, channel: Option<Channel>) -> Result<Vec<f32>, String> {
    read_path(path, &read_options(layer))
        .and_then(|r| r.into_heights(channel))
        .and_then(normalfit::Samples::into_f32)
        .map_err(|e| e.to_string())
}

fn streamed(path: &Path, layer: Option<&str>, channel: Option<Channel>) -> Option<Result<Vec<f32>, String>> {
    let rows = match ExrRows::open(path, &read_options(layer), channel) {
        Ok(Some(rows)) => rows,
        Ok(None) => return None,
        Err(e) => return Some(Err(e.to_string())),
    };
    let mut rows = rows;
    let (w, h) = (rows.width(), rows.height());
    let mut out = vec![0.0f64; w * h];
    let result = out.chunks_exact_mut(w).try_for_each(|row| rows.next_row(row));
    // The rows are f64: exact for half and float samples, so as f32 they
    // compare bit for bit with the whole-image reader's.
    Some(result.map(|()| out.iter().map(|&v| v as f32).collect()).map_err(|e| e.to_string()))
}

/// The heights of `path` by both readers, which must give the same
/// heights or the same error.
fn heights(path: &Path, layer: Option<&str>, channel: Option<Channel>) -> Result<Vec<f32>, String> {
    let what = format!("{path:?} layer {layer:?} channel {channel:?}");
    let streamed = streamed(path, layer, channel.clone()).unwrap_or_else(|| panic!("{what} does not stream"));
    let whole = whole(path, layer, channel);
    assert_eq!(streamed, whole, "{what}: streamed, then whole");
    whole
}

/// An error of both readers, one line, saying `reason`.
fn refused(path: &Path, layer: Option<&str>, channel: Option<Channel>, reason: &str) -> String {
    let e = heights(path, layer, channel.clone()).expect_err(&format!("{path:?} {layer:?} {channel:?} reads"));
    assert!(e.contains(reason), "{e:?} should say {reason:?}");
    assert!(!e.contains('\n'), "{e:?}");
    e
}

fn named(name: &str) -> Option<Channel> {
    Some(Channel::Named(name.into()))
}

/// SPEC §1's luma, in f64, rounded once.
/// Luma in f64, the heights the fit reads.
fn luma64(r: &[f32], g: &[f32], b: &[f32]) -> Vec<f64> {
    (0..r.len()).map(|k| 0.2126 * f64::from(r[k]) + 0.7152 * f64::from(g[k]) + 0.0722 * f64::from(b[k])).collect()
}

/// Luma rounded to f32, as the readers' f32 heights give it.
fn luma(r: &[f32], g: &[f32], b: &[f32]) -> Vec<f32> {
    luma64(r, g, b).iter().map(|&v| v as f32).collect()
}

/// Values that differ between channels (by `seed`) and texels.
fn values(w: usize, h: usize, seed: usize) -> Vec<f32> {
    (0..w * h).map(|k| ((k * (2 * seed + 1) + seed * 7) % 29) as f32 * 0.125 - 1.5).collect()
}

// ---------------------------------------------------------------------------
// Files the `exr` crate writes

fn f32_channel(name: &str, v: &[f32]) -> AnyChannel<FlatSamples> {
    AnyChannel::new(name, FlatSamples::F32(v.to_vec()))
}

fn scan_lines(compression: Compression) -> Encoding {
    Encoding { compression, blocks: Blocks::ScanLines, line_order: LineOrder::Increasing }
}

fn layer(
    w: usize,
    h: usize,
    name: Option<&str>,
    encoding: Encoding,
    channels: Vec<AnyChannel<FlatSamples>>,
) -> Layer<AnyChannels<FlatSamples>> {
    let attributes = name.map_or_else(LayerAttributes::default, LayerAttributes::named);
    Layer::new(Vec2(w, h), attributes, encoding, AnyChannels::sort(SmallVec::from_vec(channels)))
}

fn write_parts(path: &Path, w: usize, h: usize, layers: Vec<Layer<AnyChannels<FlatSamples>>>) {
    let attributes =
        exr::meta::header::ImageAttributes::new(exr::meta::attribute::IntegerBounds::from_dimensions((w, h)));
    Image::from_layers(attributes, layers).write().to_file(path).unwrap();
}

fn write_one(path: &Path, w: usize, h: usize, channels: Vec<AnyChannel<FlatSamples>>) {
    write_parts(path, w, h, vec![layer(w, h, None, scan_lines(Compression::ZIP16), channels)]);
}

/// The file: a renderer's single part with root R, G, B, A and Z,
/// and layers of stereo disparity and a left eye.
#[test]
fn root_rgba_and_z_beside_layers_use_the_root_channels() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (13, 21);
    let v = |seed| values(w, h, seed);
    let (r, g, b, a, z) = (v(1), v(2), v(3), v(4), v(5));
    let (dlx, dly, drx, dry) = (v(6), v(7), v(8), v(9));
    let (lr, lg, lb) = (v(10), v(11), v(12));
    let path = dir.path().join("render.exr");
    write_one(
        &path,
        w,
        h,
        vec![
            f32_channel("R", &r),
            f32_channel("G", &g),
            f32_channel("B", &b),
            f32_channel("A", &a),
            f32_channel("Z", &z),
            f32_channel("disparityL.x", &dlx),
            f32_channel("disparityL.y", &dly),
            f32_channel("disparityR.x", &drx),
            f32_channel("disparityR.y", &dry),
            f32_channel("left.R", &lr),
            f32_channel("left.G", &lg),
            f32_channel("left.B", &lb),
        ],
    );
    let rgb = luma(&r, &g, &b);
    // The default and every spelling of luma: the root R, G, B; no "y" of
    // a layer is taken for the image's Y.
    for channel in [None, Some(Channel::Luma), named("luma"), named("LUMA")] {
        assert_eq!(heights(&path, None, channel).unwrap(), rgb);
    }
    // Keywords pick root channels, in any case.
    for (channel, want) in [(Channel::R, &r), (Channel::G, &g), (Channel::B, &b), (Channel::A, &a)] {
        assert_eq!(&heights(&path, None, Some(channel.clone())).unwrap(), want, "{channel:?}");
        assert_eq!(&heights(&path, None, named(&channel.to_string().to_uppercase())).unwrap(), want);
    }
    // Any channel by its exact name: the depth, a layer's channel.
    assert_eq!(heights(&path, None, named("Z")).unwrap(), z);
    assert_eq!(heights(&path, None, named("disparityL.y")).unwrap(), dly);
    assert_eq!(heights(&path, None, named("disparityR.x")).unwrap(), drx);
    assert_eq!(heights(&path, None, named("left.G")).unwrap(), lg);
    // Then in any case, when only one channel matches.
    assert_eq!(heights(&path, None, named("z")).unwrap(), z);
    assert_eq!(heights(&path, None, named("LEFT.g")).unwrap(), lg);
    // A layer: its channels by the same rule, names within it too.
    assert_eq!(heights(&path, Some("left"), None).unwrap(), luma(&lr, &lg, &lb));
    assert_eq!(heights(&path, Some("left"), named("B")).unwrap(), lb);
    assert_eq!(heights(&path, Some("disparityR"), named("x")).unwrap(), drx);
    assert_eq!(heights(&path, Some("disparityR"), named("disparityR.x")).unwrap(), drx);
    // A name that is not there: the channels, in one line.
    let e = refused(&path, None, named("depth"), "no channel depth (channels: ");
    for name in ["A", "B", "G", "R", "Z", "disparityL.x", "disparityR.y", "left.B"] {
        assert!(e.contains(name), "{e} lists {name}");
    }
    // A layer's channel outside it is not there.
    refused(&path, Some("left"), named("Z"), "no channel Z");
}

#[test]
fn root_y_beside_layers_is_the_height() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (9, 40);
    let (y, nx, ny, nz, dy) = (values(w, h, 1), values(w, h, 2), values(w, h, 3), values(w, h, 4), values(w, h, 5));
    let path = dir.path().join("y.exr");
    write_one(
        &path,
        w,
        h,
        vec![
            f32_channel("Y", &y),
            f32_channel("normal.X", &nx),
            f32_channel("normal.Y", &ny),
            f32_channel("normal.Z", &nz),
            f32_channel("disparity.y", &dy),
        ],
    );
    for channel in [None, Some(Channel::Luma), Some(Channel::R), named("g")] {
        assert_eq!(heights(&path, None, channel).unwrap(), y, "gray: luma, r, g, b give Y");
    }
    assert_eq!(heights(&path, None, named("Y")).unwrap(), y);
    assert_eq!(heights(&path, None, named("normal.Y")).unwrap(), ny);
    refused(&path, None, Some(Channel::A), "no alpha channel");
    // Within the layer "normal", its Y.
    assert_eq!(heights(&path, Some("normal"), None).unwrap(), ny);
    assert_eq!(heights(&path, Some("normal"), named("Z")).unwrap(), nz);
}

#[test]
fn a_depth_pass_of_one_channel_is_the_height() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (17, 5);
    let z = values(w, h, 3);
    // Z alone, as a renderer's depth pass; the same in a layer of its own.
    for (name, channel) in [("z.exr", "Z"), ("depth.exr", "depth.Z"), ("height.exr", "height")] {
        let path = dir.path().join(name);
        write_one(&path, w, h, vec![f32_channel(channel, &z)]);
        for asked in [None, Some(Channel::Luma), Some(Channel::R), named(channel)] {
            assert_eq!(heights(&path, None, asked).unwrap(), z, "{name}");
        }
        refused(&path, None, named("Y"), "no channel Y (channels: ");
        refused(&path, None, Some(Channel::A), "no alpha channel");
    }
    // Depth beside a mask: neither is the height unless named.
    let path = dir.path().join("two.exr");
    let mask = values(w, h, 4);
    write_one(&path, w, h, vec![f32_channel("Z", &z), f32_channel("mask", &mask)]);
    refused(&path, None, None, "no usable height channel: need y, a single channel, or r, g and b (channels: Z, mask)");
    assert_eq!(heights(&path, None, named("Z")).unwrap(), z);
    assert_eq!(heights(&path, None, named("mask")).unwrap(), mask);
}

#[test]
fn channels_all_in_layers_need_a_choice() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (6, 7);
    let (a, b, c) = (values(w, h, 1), values(w, h, 2), values(w, h, 3));
    let path = dir.path().join("layers.exr");
    write_one(&path, w, h, vec![f32_channel("bump.Y", &a), f32_channel("rough.Y", &b), f32_channel("rough.A", &c)]);
    refused(&path, None, None, "every channel is in a layer (bump, rough) and none is at the root");
    refused(&path, None, Some(Channel::A), "every channel is in a layer (bump, rough)");
    assert_eq!(heights(&path, Some("bump"), None).unwrap(), a);
    assert_eq!(heights(&path, Some("rough"), None).unwrap(), b);
    assert_eq!(heights(&path, Some("rough"), Some(Channel::A)).unwrap(), c);
    assert_eq!(heights(&path, None, named("rough.Y")).unwrap(), b);
    // Nested layers that share a prefix are one layer.
    let nested = dir.path().join("nested.exr");
    write_one(&nested, w, h, vec![f32_channel("pass.bump.X", &a), f32_channel("pass.bump.Y", &b)]);
    assert_eq!(heights(&nested, None, None).unwrap(), b);
    assert_eq!(heights(&nested, None, named("X")).unwrap(), a);
}

#[test]
fn several_parts_read_the_first_or_the_one_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (11, 37);
    let v = |seed| values(w, h, seed);
    let (r, g, b, a, z, y, extra) = (v(1), v(2), v(3), v(4), v(5), v(6), v(7));
    let path = dir.path().join("parts.exr");
    let tiled = Encoding {
        compression: Compression::ZIP1,
        blocks: Blocks::Tiles(Vec2(8, 8)),
        line_order: LineOrder::Increasing,
    };
    write_parts(
        &path,
        w,
        h,
        vec![
            layer(
                w,
                h,
                Some("beauty"),
                scan_lines(Compression::PIZ),
                vec![f32_channel("R", &r), f32_channel("G", &g), f32_channel("B", &b), f32_channel("A", &a)],
            ),
            layer(w, h, Some("depth"), scan_lines(Compression::RLE), vec![f32_channel("Z", &z)]),
            layer(
                w,
                h,
                Some("height"),
                scan_lines(Compression::ZIP16),
                vec![f32_channel("Y", &y), f32_channel("extra.Y", &extra)],
            ),
            layer(w, h, Some("tiled"), tiled, vec![f32_channel("Y", &y)]),
        ],
    );
    assert_eq!(heights(&path, None, None).unwrap(), luma(&r, &g, &b), "the first part");
    assert_eq!(heights(&path, Some("beauty"), Some(Channel::A)).unwrap(), a);
    assert_eq!(heights(&path, Some("depth"), None).unwrap(), z);
    assert_eq!(heights(&path, Some("depth"), named("Z")).unwrap(), z);
    assert_eq!(heights(&path, Some("height"), None).unwrap(), y, "root Y beside a layer");
    assert_eq!(heights(&path, Some("height"), named("extra.Y")).unwrap(), extra);
    refused(&path, Some("depth"), named("Y"), "no channel Y (channels: Z)");
    refused(&path, Some("nope"), None, "has no layer nope (layers: beauty, depth, height, extra, tiled)");
    // A tiled part is read whole.
    assert!(streamed(&path, Some("tiled"), None).is_none());
    assert_eq!(whole(&path, Some("tiled"), None).unwrap(), y);
}

// ---------------------------------------------------------------------------
// Luminance/chroma files from OpenEXR's library (tests/data/exr_yc)

fn yc_data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/exr_yc").join(name)
}

/// make.py's values, 24 × 20.
fn yc_formula(f: impl Fn(usize, usize) -> f32) -> Vec<f32> {
    (0..24 * 20).map(|k| f(k % 24, k / 24)).collect()
}

#[test]
fn luminance_chroma_files_from_openexr_read_their_y() {
    let y = yc_formula(|x, y| ((3 * x + 5 * y) % 17) as f32 / 8.0 - 1.0);
    let a = yc_formula(|x, y| ((x + 2 * y) % 5) as f32 / 4.0);
    for name in ["yc_none.exr", "yc_rle.exr", "yc_zips.exr", "yc_zip.exr", "yca_zip_float_decreasing.exr"] {
        let path = yc_data(name);
        let raster = read_path(&path, &ReadOptions::default()).unwrap();
        assert_eq!((raster.width, raster.height), (24, 20), "{name}");
        let names: Vec<&str> = raster.planes.iter().map(|p| p.name.as_str()).collect();
        let alpha = name.starts_with("yca");
        assert_eq!(names, if alpha { vec!["A", "Y"] } else { vec!["Y"] }, "{name}: the subsampled RY, BY are left out");
        for channel in [None, Some(Channel::Luma), named("Y")] {
            assert_eq!(heights(&path, None, channel).unwrap(), y, "{name}");
        }
        if alpha {
            assert_eq!(heights(&path, None, Some(Channel::A)).unwrap(), a, "{name}");
        }
        refused(&path, None, named("RY"), "no channel RY");
    }
    refused(
        &yc_data("yc_piz.exr"),
        None,
        None,
        "exr file has subsampled channels and PIZ compression: with subsampling (luminance/chroma files), only none, \
         RLE, ZIPS and ZIP are read",
    );
}

// ---------------------------------------------------------------------------
// Luminance/chroma files written here: OpenEXR's scan-line layout by hand,
// for sizes, windows, samplings and parts the files above do not cover.

struct Sub {
    name: &'static str,
    half: bool,
    /// x and y sampling.
    sampling: (usize, usize),
    /// Full-size values; a subsampled channel keeps those at multiples of
    /// its sampling.
    values: Vec<f32>,
}

struct Part {
    name: Option<&'static str>,
    /// 0 none, 1 RLE, 2 ZIPS, 3 ZIP.
    compression: u8,
    /// Sorted by name, as the format requires.
    channels: Vec<Sub>,
}

fn attribute(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
    for s in [name, kind] {
        out.extend(s.as_bytes());
        out.push(0);
    }
    out.extend((value.len() as i32).to_le_bytes());
    out.extend(value);
}

/// OpenEXR's RLE: runs of 3 to 128 equal bytes as (count − 1, byte),
/// anything else as (−n, n bytes).
fn rle(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < data.len() {
        let mut run = 1;
        while i + run < data.len() && data[i + run] == data[i] && run < 128 {
            run += 1;
        }
        if run >= 3 {
            out.push((run - 1) as u8);
            out.push(data[i]);
            i += run;
            continue;
        }
        let start = i;
        while i < data.len()
            && i - start < 127
            && !(i + 2 < data.len() && data[i] == data[i + 1] && data[i] == data[i + 2])
        {
            i += 1;
        }
        out.push((-((i - start) as i32)) as u8);
        out.extend(&data[start..i]);
    }
    out
}

/// A block's raw lines, compressed as OpenEXR does: even bytes, then odd
/// ones; each byte as its difference to the one before plus 128; then RLE
/// or zlib. Stored raw when that is not smaller.
fn compress(raw: &[u8], compression: u8) -> Vec<u8> {
    if compression == 0 {
        return raw.to_vec();
    }
    let mut split: Vec<u8> = raw.iter().step_by(2).chain(raw.iter().skip(1).step_by(2)).copied().collect();
    for i in (1..split.len()).rev() {
        split[i] = split[i].wrapping_sub(split[i - 1]).wrapping_add(128);
    }
    let packed = if compression == 1 { rle(&split) } else { miniz_oxide::deflate::compress_to_vec_zlib(&split, 6) };
    if packed.len() < raw.len() { packed } else { raw.to_vec() }
}

/// A scan-line OpenEXR file of `w` × `h` texels from `origin`, one part
/// or several.
fn yc_file(w: usize, h: usize, origin: (i32, i32), parts: &[Part]) -> Vec<u8> {
    let multipart = parts.len() > 1;
    let mut out = vec![0x76, 0x2f, 0x31, 0x01, 2, if multipart { 0x10 } else { 0 }, 0, 0];
    let window: Vec<u8> = [origin.0, origin.1, origin.0 + w as i32 - 1, origin.1 + h as i32 - 1]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let lines = |part: &Part| if part.compression == 3 { 16 } else { 1 };
    for part in parts {
        let mut chlist = Vec::new();
        for c in &part.channels {
            chlist.extend(c.name.as_bytes());
            chlist.push(0);
            chlist.extend(if c.half { 1i32 } else { 2 }.to_le_bytes());
            chlist.extend([0; 4]);
            chlist.extend((c.sampling.0 as i32).to_le_bytes());
            chlist.extend((c.sampling.1 as i32).to_le_bytes());
        }
        chlist.push(0);
        attribute(&mut out, "channels", "chlist", &chlist);
        attribute(&mut out, "compression", "compression", &[part.compression]);
        attribute(&mut out, "dataWindow", "box2i", &window);
        attribute(&mut out, "displayWindow", "box2i", &window);
        attribute(&mut out, "lineOrder", "lineOrder", &[0]);
        attribute(&mut out, "pixelAspectRatio", "float", &1.0f32.to_le_bytes());
        attribute(&mut out, "screenWindowCenter", "v2f", &[0; 8]);
        attribute(&mut out, "screenWindowWidth", "float", &1.0f32.to_le_bytes());
        if multipart {
            attribute(&mut out, "name", "string", part.name.unwrap().as_bytes());
            attribute(&mut out, "type", "string", b"scanlineimage");
            attribute(&mut out, "chunkCount", "int", &(h.div_ceil(lines(part)) as i32).to_le_bytes());
        }
        out.push(0);
    }
    if multipart {
        out.push(0);
    }
    // The chunks, then the offset tables that point at them.
    let mut chunks: Vec<Vec<Vec<u8>>> = Vec::new();
    for (p, part) in parts.iter().enumerate() {
        let mut blocks = Vec::new();
        for y0 in (0..h).step_by(lines(part)) {
            let mut raw = Vec::new();
            for row in y0..(y0 + lines(part)).min(h) {
                let y = origin.1 + row as i32;
                for c in &part.channels {
                    if y.rem_euclid(c.sampling.1 as i32) != 0 {
                        continue;
                    }
                    for x in (0..w).step_by(c.sampling.0) {
                        let v = c.values[row * w + x];
                        if c.half {
                            raw.extend(f16::from_f32(v).to_bits().to_le_bytes());
                        } else {
                            raw.extend(v.to_le_bytes());
                        }
                    }
                }
            }
            let data = compress(&raw, part.compression);
            let mut chunk = Vec::new();
            if multipart {
                chunk.extend((p as i32).to_le_bytes());
            }
            chunk.extend((origin.1 + y0 as i32).to_le_bytes());
            chunk.extend((data.len() as i32).to_le_bytes());
            chunk.extend(data);
            blocks.push(chunk);
        }
        chunks.push(blocks);
    }
    let mut at = out.len() + 8 * chunks.iter().map(Vec::len).sum::<usize>();
    for blocks in &chunks {
        for chunk in blocks {
            out.extend((at as u64).to_le_bytes());
            at += chunk.len();
        }
    }
    out.extend(chunks.into_iter().flatten().flatten());
    out
}

fn sub(name: &'static str, half: bool, sampling: (usize, usize), values: Vec<f32>) -> Sub {
    Sub { name, half, sampling, values }
}

/// Values exact in half.
fn halves(v: Vec<f32>) -> Vec<f32> {
    v.into_iter().map(|x| f16::from_f32(x).to_f32()).collect()
}

fn save(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn luminance_chroma_written_here_every_compression_size_and_window() {
    let dir = tempfile::tempdir().unwrap();
    for (w, h) in [(2, 2), (4, 6), (24, 34), (36, 2)] {
        for origin in [(0, 0), (-4, 6), (8, -18)] {
            for compression in 0..4 {
                // Runs for RLE: Y constant along x in every other row.
                let varied = values(w, h, 1);
                let y: Vec<f32> =
                    (0..w * h).map(|k| if (k / w) % 2 == 0 { (k / w) as f32 * 0.5 } else { varied[k] }).collect();
                let (y, a) = (halves(y), values(w, h, 2));
                let channels = vec![
                    sub("A", false, (1, 1), a.clone()),
                    sub("BY", true, (2, 2), values(w, h, 3)),
                    sub("RY", true, (2, 2), values(w, h, 4)),
                    sub("Y", true, (1, 1), y.clone()),
                ];
                let what = format!("{w}×{h} at {origin:?}, compression {compression}");
                let bytes = yc_file(w, h, origin, &[Part { name: None, compression, channels }]);
                let path = save(dir.path(), "yc.exr", &bytes);
                assert_eq!(heights(&path, None, None).unwrap(), y, "{what}");
                assert_eq!(heights(&path, None, Some(Channel::A)).unwrap(), a, "{what}");
                // The last rows, as a wrap in y asks for them first.
                for rows in [1, 17] {
                    let tail = ExrRows::last_rows(&path, &ReadOptions::default(), None, rows).unwrap();
                    let tail: Vec<f32> = tail.iter().map(|&v| v as f32).collect();
                    assert_eq!(tail, y[(h - rows.min(h)) * w..], "{what}, last {rows} rows");
                }
            }
        }
    }
}

#[test]
fn subsampling_of_any_factor_and_several_parts() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (12, 18);
    // Samplings of 3 × 1, 1 × 3 and 4 × 2 beside a float height.
    let height = values(w, h, 5);
    let channels = || {
        vec![
            sub("C", true, (3, 1), values(w, h, 1)),
            sub("D", false, (1, 3), values(w, h, 2)),
            sub("E", true, (4, 2), values(w, h, 3)),
            sub("height", false, (1, 1), height.clone()),
        ]
    };
    for compression in 0..4 {
        let bytes = yc_file(w, h, (0, -6), &[Part { name: None, compression, channels: channels() }]);
        let path = save(dir.path(), "any.exr", &bytes);
        assert_eq!(heights(&path, None, None).unwrap(), height, "the only full-resolution channel");
        refused(&path, None, named("C"), "no channel C (channels: height)");
    }
    // Two parts: an RGB beauty pass, then a luminance/chroma height.
    let (r, g, b) = (values(w, h, 6), values(w, h, 7), values(w, h, 8));
    let y = halves(values(w, h, 9));
    let parts = [
        Part {
            name: Some("beauty"),
            compression: 3,
            channels: vec![
                sub("B", false, (1, 1), b.clone()),
                sub("G", false, (1, 1), g.clone()),
                sub("R", false, (1, 1), r.clone()),
            ],
        },
        Part {
            name: Some("height"),
            compression: 1,
            channels: vec![
                sub("BY", true, (2, 2), values(w, h, 10)),
                sub("RY", true, (2, 2), values(w, h, 11)),
                sub("Y", true, (1, 1), y.clone()),
            ],
        },
    ];
    let path = save(dir.path(), "parts.exr", &yc_file(w, h, (0, 0), &parts));
    assert_eq!(heights(&path, None, None).unwrap(), luma(&r, &g, &b));
    assert_eq!(heights(&path, Some("beauty"), named("G")).unwrap(), g);
    assert_eq!(heights(&path, Some("height"), None).unwrap(), y);
    refused(&path, Some("albedo"), None, "has no layer albedo (layers: beauty, height)");
}

#[test]
fn broken_luminance_chroma_files_are_clean_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (10, 40);
    let channels = || {
        vec![
            sub("BY", true, (2, 2), values(w, h, 1)),
            sub("RY", true, (2, 2), values(w, h, 2)),
            sub("Y", true, (1, 1), values(w, h, 3)),
        ]
    };
    for compression in 0..4 {
        let good = yc_file(w, h, (0, 0), &[Part { name: None, compression, channels: channels() }]);
        // Every cut: an error, never a panic, from both readers.
        for len in (8..good.len()).step_by(7) {
            let path = save(dir.path(), "cut.exr", &good[..len]);
            assert!(whole(&path, None, None).is_err(), "compression {compression}, cut at {len}");
            assert!(streamed(&path, None, None).is_none_or(|r| r.is_err()), "compression {compression}, cut at {len}");
        }
        // Every byte of the pixel data flipped: an error or other heights.
        let start = good.len() - 40;
        for at in start..good.len() {
            let mut bad = good.clone();
            bad[at] ^= 0x5a;
            let path = save(dir.path(), "flipped.exr", &bad);
            let _ = whole(&path, None, None);
            let _ = streamed(&path, None, None);
        }
    }
    // A sampling that does not divide the window.
    let odd = yc_file(
        w,
        h - 1,
        (0, 0),
        &[Part {
            name: None,
            compression: 0,
            channels: vec![sub("RY", true, (2, 2), values(w, h, 1)), sub("Y", true, (1, 1), values(w, h, 2))],
        }],
    );
    let path = save(dir.path(), "odd.exr", &odd);
    refused(&path, None, None, "channel RY has sampling 2 × 2, which does not divide the data window");

    // Forged headers: a size above the limit, more chunks than the file
    // holds, a chunk larger than its block. Refused before any allocation
    // of the size claimed.
    let good = yc_file(w, h, (0, 0), &[Part { name: None, compression: 3, channels: channels() }]);
    let key = b"dataWindow\0box2i\0";
    let at = good.windows(key.len()).position(|k| k == key).unwrap() + key.len() + 4;
    let with_window = |corners: [i32; 4]| {
        let mut bad = good.clone();
        bad[at..at + 16].copy_from_slice(&corners.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>());
        bad
    };
    let huge = save(dir.path(), "huge.exr", &with_window([0, 0, 99_999, 99_999]));
    refused(&huge, None, None, "too large: 100000 × 100000 is 10000000000 texels");
    let tall = save(dir.path(), "tall.exr", &with_window([0, 0, 9, 99_999]));
    refused(&tall, None, None, "header claims 6250 chunks, more than the file holds");
    // The offset table of the 3 blocks (16 rows each) ends where the
    // first chunk starts: its first entry points 24 bytes past itself.
    let u64_at = |i: usize| u64::from_le_bytes(good[i..i + 8].try_into().unwrap());
    let table = (0..good.len() - 8).find(|&i| u64_at(i) == i as u64 + 24).unwrap();
    let first_chunk = u64_at(table) as usize;
    let mut oversized = good.clone();
    oversized[first_chunk + 4..first_chunk + 8].copy_from_slice(&i32::MAX.to_le_bytes());
    let oversized = save(dir.path(), "oversized.exr", &oversized);
    refused(&oversized, None, None, "invalid exr: the chunk for row 0 holds 2147483647 bytes, more than its");
    let mut beyond = good.clone();
    beyond[table + 16..table + 24].copy_from_slice(&(good.len() as u64 - 2).to_le_bytes());
    let beyond = save(dir.path(), "beyond.exr", &beyond);
    refused(&beyond, None, None, "truncated or corrupt: the file ends before the chunk for row 32");
}

// ---------------------------------------------------------------------------
// The command line: `--channel` with a name, in both readers

#[cfg(feature = "cli")]
/// The normals the binary writes for `input` (from the file, streamed, and
/// from standard input, whole: the same), `--signed` EXR out.
fn cli_normals(input: &Path, extra: &[&str], dir: &Path) -> Result<Vec<[f32; 3]>, String> {
    let out = dir.join("out.exr");
    let mut results = Vec::new();
    for stdin in [false, true] {
        let source = if stdin { "-" } else { crate::common::cli::s(input) };
        let mut args = vec!["convert", source, "-o", crate::common::cli::s(&out), "--signed", "--format", "exr"];
        args.extend(extra);
        let mut command = crate::common::cli::bin();
        command.args(&args);
        if stdin {
            command.stdin(std::fs::File::open(input).unwrap());
        }
        let run = command.output().unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
        results.push(match run.status.code() {
            Some(0) => {
                let raster = read_path(&out, &ReadOptions::default()).unwrap();
                let p = |c: &str| raster.plane(c).unwrap().data.to_f32().unwrap();
                let (r, g, b) = (p("R"), p("G"), p("B"));
                Ok((0..r.len()).map(|k| [r[k], g[k], b[k]]).collect())
            }
            Some(2) => {
                assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
                // "normalfit: FILE: REASON": the file differs between the
                // two runs, the reason must not.
                Err(stderr.trim_end().splitn(3, ": ").nth(2).unwrap_or_default().to_string())
            }
            code => panic!("{args:?} exited {code:?}: {stderr}"),
        });
    }
    let whole = results.pop().unwrap();
    assert_eq!(results.pop().unwrap(), whole, "{input:?} {extra:?}: from the file, then from standard input");
    whole
}

// Runs the program, which needs the `cli` feature.
#[cfg(feature = "cli")]
#[test]
fn channel_names_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (10, 12);
    let (r, g, b, z, dy) = (values(w, h, 1), values(w, h, 2), values(w, h, 3), values(w, h, 4), values(w, h, 5));
    let path = dir.path().join("render.exr");
    write_one(
        &path,
        w,
        h,
        vec![
            f32_channel("R", &r),
            f32_channel("G", &g),
            f32_channel("B", &b),
            f32_channel("Z", &z),
            f32_channel("disparityL.y", &dy),
            f32_channel("disparityR.y", &dy),
        ],
    );
    let fit = |heights: &[f32]| normals(heights, w, h, &Options::default()).unwrap();
    let ok = |extra: &[&str]| cli_normals(&path, extra, dir.path()).unwrap();
    let fit_luma = normals(&luma64(&r, &g, &b), w, h, &Options::default()).unwrap();
    assert_eq!(ok(&[]), fit_luma);
    assert_eq!(ok(&["--channel", "luma"]), fit_luma);
    assert_eq!(ok(&["--channel", "Z"]), fit(&z));
    assert_eq!(ok(&["--channel", "disparityL.y"]), fit(&dy));
    assert_eq!(ok(&["--channel", "g"]), fit(&g));
    assert_eq!(ok(&["--channel", "G"]), fit(&g));
    let e = cli_normals(&path, &["--channel", "height"], dir.path()).unwrap_err();
    assert_eq!(e, "unsupported: no channel height (channels: B, G, R, Z, disparityL.y, disparityR.y)");

    // Other formats take the keywords only, in any case.
    let png = dir.path().join("rgb.png");
    let pixels: Vec<u8> = (0..w * h * 3).map(|k| (k * 37 % 251) as u8).collect();
    image::save_buffer(&png, &pixels, w as u32, h as u32, image::ExtendedColorType::Rgb8).unwrap();
    // The red samples as stored: the fit reads 8-bit values as integers.
    let red: Vec<u8> = (0..w * h).map(|k| pixels[3 * k]).collect();
    assert_eq!(
        cli_normals(&png, &["--channel", "R"], dir.path()).unwrap(),
        normals(&red, w, h, &Options::default()).unwrap()
    );
    let e = cli_normals(&png, &["--channel", "Y"], dir.path()).unwrap_err();
    assert!(e.contains("no channel Y: png images take luma, r, g, b or a"), "{e:?}");

    // A luminance/chroma file from OpenEXR, by its Y.
    let y = yc_formula(|x, y| ((3 * x + 5 * y) % 17) as f32 / 8.0 - 1.0);
    let want = normals(&y, 24, 20, &Options::default()).unwrap();
    assert_eq!(cli_normals(&yc_data("yc_zip.exr"), &[], dir.path()).unwrap(), want);
    assert_eq!(cli_normals(&yc_data("yc_rle.exr"), &["--channel", "Y"], dir.path()).unwrap(), want);
}
