//! File formats: every input is made here, PNGs by hand (so the decoder is
//! checked against the PNG spec, not against `image`'s own encoder), the
//! rest with `image` and `exr`.

use std::io::Cursor;

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec, Vec2, WritableImage, f16,
};
use image::ImageEncoder;
use normalfit::Error;
use normalfit::io::read::formats::{self, FORMATS};
use normalfit::io::{
    Channel, ExrDepth, ExrOptions, InputFormat, Layout, PngCompression, PngDepth, PngOptions, Raster, ReadOptions,
    SampleType, decode, encode_gray, encode_normals, read_path, write_atomically,
};

// ---------------------------------------------------------------------------
// A minimal PNG writer: stored (uncompressed) deflate, CRC-32, Adler-32.

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffff_u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

fn adler32(bytes: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    for &x in bytes {
        a = (a + u32::from(x)) % 65521;
        b = (b + a) % 65521;
    }
    (b << 16) | a
}

/// zlib stream of stored deflate blocks.
fn zlib_stored(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = if data.is_empty() { vec![&[]] } else { data.chunks(65535).collect() };
    for (i, block) in blocks.iter().enumerate() {
        out.push(u8::from(i + 1 == blocks.len()));
        let len = block.len() as u16;
        out.extend(len.to_le_bytes());
        out.extend((!len).to_le_bytes());
        out.extend(*block);
    }
    out.extend(adler32(data).to_be_bytes());
    out
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend((data.len() as u32).to_be_bytes());
    let mut body = kind.to_vec();
    body.extend(data);
    out.extend(&body);
    out.extend(crc32(&body).to_be_bytes());
}

/// What a hand-made PNG holds.
struct PngSpec {
    width: u32,
    height: u32,
    color_type: u8,
    bit_depth: u8,
    interlaced: bool,
    plte: Option<Vec<u8>>,
    trns: Option<Vec<u8>>,
}

impl PngSpec {
    fn new(width: u32, height: u32, color_type: u8, bit_depth: u8) -> Self {
        PngSpec { width, height, color_type, bit_depth, interlaced: false, plte: None, trns: None }
    }

    fn header(&self) -> Vec<u8> {
        let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
        let mut ihdr = Vec::new();
        ihdr.extend(self.width.to_be_bytes());
        ihdr.extend(self.height.to_be_bytes());
        ihdr.extend([self.bit_depth, self.color_type, 0, 0, u8::from(self.interlaced)]);
        chunk(&mut out, b"IHDR", &ihdr);
        if let Some(p) = &self.plte {
            chunk(&mut out, b"PLTE", p);
        }
        if let Some(t) = &self.trns {
            chunk(&mut out, b"tRNS", t);
        }
        out
    }

    /// The file, pixel (x, y) given as its bytes (big-endian for 16 bits),
    /// every row with filter type 0.
    fn encode(&self, pixel: impl Fn(usize, usize) -> Vec<u8>) -> Vec<u8> {
        let (w, h) = (self.width as usize, self.height as usize);
        let passes: &[(usize, usize, usize, usize)] = if self.interlaced {
            &[(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)]
        } else {
            &[(0, 0, 1, 1)]
        };
        let mut raw = Vec::new();
        for &(x0, y0, dx, dy) in passes {
            if x0 >= w || y0 >= h {
                continue; // an empty pass has no rows at all
            }
            for y in (y0..h).step_by(dy) {
                raw.push(0);
                for x in (x0..w).step_by(dx) {
                    raw.extend(pixel(x, y));
                }
            }
        }
        let mut out = self.header();
        chunk(&mut out, b"IDAT", &zlib_stored(&raw));
        chunk(&mut out, b"IEND", &[]);
        out
    }
}

fn read(bytes: &[u8]) -> Raster {
    match decode(bytes, &ReadOptions::default()) {
        Ok(r) => r,
        Err(e) => panic!("decode failed: {e}"),
    }
}

fn names(r: &Raster) -> Vec<&str> {
    r.planes.iter().map(|p| p.name.as_str()).collect()
}

/// A plane's heights in contract units, as f32.
fn data(r: &Raster, name: &str) -> Vec<f32> {
    r.plane(name).unwrap_or_else(|| panic!("no plane {name}")).data.to_f32().unwrap()
}

/// Luma of heights in contract units, in f64 (the fit's heights), then
/// rounded to f32 as [`Raster::heights`] gives it.
fn luma(r: f64, g: f64, b: f64) -> f32 {
    (0.2126 * r + 0.7152 * g + 0.0722 * b) as f32
}

fn is_unsupported(e: &Error) -> bool {
    matches!(e, Error::Unsupported(_))
}

// ---------------------------------------------------------------------------
// PNG

#[test]
fn png_gray8_values_and_channels() {
    let v = [0u8, 1, 128, 200, 254, 255];
    let bytes = PngSpec::new(3, 2, 0, 8).encode(|x, y| vec![v[y * 3 + x]]);
    let r = read(&bytes);
    assert_eq!((r.width, r.height), (3, 2));
    assert_eq!(r.format, InputFormat::Png);
    assert_eq!(r.format.to_string(), "png");
    assert_eq!(r.sample, SampleType::Int { bits: 8 });
    assert!(!r.sample.more_than_8_bits());
    assert_eq!(names(&r), ["Y"]);
    let expected: Vec<f32> = v.iter().map(|&b| f32::from(b) / 255.0).collect();
    assert_eq!(data(&r, "Y"), expected);
    assert_eq!(data(&r, "Y")[5], 1.0);
    for c in [None, Some(Channel::Luma), Some(Channel::R), Some(Channel::G), Some(Channel::B)] {
        assert_eq!(r.heights(c.clone()).unwrap(), expected, "{c:?}");
    }
    assert!(is_unsupported(&r.heights(Some(Channel::A)).unwrap_err()));
    assert_eq!(r.into_heights(None).unwrap().into_f32().unwrap(), expected);
}

#[test]
fn png_gray16_exact_values() {
    let v = [0u16, 1, 32768, 65535];
    let bytes = PngSpec::new(2, 2, 0, 16).encode(|x, y| v[y * 2 + x].to_be_bytes().to_vec());
    let r = read(&bytes);
    assert_eq!(r.sample, SampleType::Int { bits: 16 });
    assert!(r.sample.more_than_8_bits());
    let h = r.heights(None).unwrap();
    assert_eq!(h[0], 0.0);
    assert_eq!(h[1], 1.0 / 65535.0);
    assert_eq!(h[2], 32768.0 / 65535.0);
    assert_eq!(h[3], 1.0);
}

#[test]
fn png_gray_alpha_8_and_16() {
    let r8 = read(&PngSpec::new(2, 1, 4, 8).encode(|x, _| vec![10 + x as u8, 250 - x as u8]));
    assert_eq!(names(&r8), ["Y", "A"]);
    assert_eq!(r8.heights(None).unwrap(), [10.0 / 255.0, 11.0 / 255.0]);
    assert_eq!(r8.heights(Some(Channel::R)).unwrap(), [10.0 / 255.0, 11.0 / 255.0]);
    assert_eq!(r8.heights(Some(Channel::A)).unwrap(), [250.0 / 255.0, 249.0 / 255.0]);

    let r16 = read(&PngSpec::new(2, 1, 4, 16).encode(|x, _| {
        let (g, a) = if x == 0 { (300u16, 65535u16) } else { (65535, 32768) };
        [g.to_be_bytes(), a.to_be_bytes()].concat()
    }));
    assert_eq!(r16.sample, SampleType::Int { bits: 16 });
    assert_eq!(names(&r16), ["Y", "A"]);
    assert_eq!(r16.heights(None).unwrap(), [300.0 / 65535.0, 1.0]);
    assert_eq!(r16.heights(Some(Channel::A)).unwrap(), [1.0, 32768.0 / 65535.0]);
}

/// Pixel (x, y) of the colour test images: every channel differs.
fn rgba8(x: usize, y: usize) -> [u8; 4] {
    let i = (y * 3 + x) as u8;
    [10 + i, 100 + 3 * i, 200 + 5 * i, 7 * i]
}

#[test]
fn png_rgb8_luma_and_channels() {
    let r = read(&PngSpec::new(3, 2, 2, 8).encode(|x, y| rgba8(x, y)[..3].to_vec()));
    assert_eq!(names(&r), ["R", "G", "B"]);
    let f = |v: u8| f32::from(v) / 255.0;
    let expect = |c: usize| (0..6).map(|i| f(rgba8(i % 3, i / 3)[c])).collect::<Vec<_>>();
    assert_eq!(r.heights(Some(Channel::R)).unwrap(), expect(0));
    assert_eq!(r.heights(Some(Channel::G)).unwrap(), expect(1));
    assert_eq!(r.heights(Some(Channel::B)).unwrap(), expect(2));
    let height = |c: usize, i: usize| f64::from(rgba8(i % 3, i / 3)[c]) / 255.0;
    let lum: Vec<f32> = (0..6).map(|i| luma(height(0, i), height(1, i), height(2, i))).collect();
    assert_eq!(r.heights(None).unwrap(), lum);
    assert_eq!(r.heights(Some(Channel::Luma)).unwrap(), lum);
    // The weights, not an average: pure green is 0.7152.
    let g = read(&PngSpec::new(1, 1, 2, 8).encode(|_, _| vec![0, 255, 0]));
    assert_eq!(g.heights(None).unwrap(), [0.7152]);
    let e = r.heights(Some(Channel::A)).unwrap_err();
    assert!(is_unsupported(&e), "{e}");
    assert!(e.to_string().contains("alpha"), "{e}");
}

#[test]
fn png_rgba8_and_rgb16_rgba16() {
    let r = read(&PngSpec::new(3, 2, 6, 8).encode(|x, y| rgba8(x, y).to_vec()));
    assert_eq!(names(&r), ["R", "G", "B", "A"]);
    assert_eq!(data(&r, "A")[4], f32::from(rgba8(1, 1)[3]) / 255.0);
    assert_eq!(r.heights(Some(Channel::A)).unwrap(), data(&r, "A"));
    assert_eq!(r.heights(None).unwrap()[0], luma(10.0 / 255.0, 100.0 / 255.0, 200.0 / 255.0));

    let px16 = [1u16, 32768, 65535, 4660];
    let r = read(&PngSpec::new(1, 1, 2, 16).encode(|_, _| px16[..3].iter().flat_map(|v| v.to_be_bytes()).collect()));
    assert_eq!(names(&r), ["R", "G", "B"]);
    assert_eq!(r.sample, SampleType::Int { bits: 16 });
    assert_eq!(data(&r, "R"), [1.0 / 65535.0]);
    assert_eq!(data(&r, "G"), [32768.0 / 65535.0]);
    assert_eq!(data(&r, "B"), [1.0]);

    let r = read(&PngSpec::new(1, 1, 6, 16).encode(|_, _| px16.iter().flat_map(|v| v.to_be_bytes()).collect()));
    assert_eq!(names(&r), ["R", "G", "B", "A"]);
    assert_eq!(r.heights(Some(Channel::A)).unwrap(), [4660.0 / 65535.0]);
}

#[test]
fn png_palette_expands_to_rgb_and_rgba() {
    let mut spec = PngSpec::new(2, 2, 3, 8);
    spec.plte = Some(vec![255, 0, 0, 0, 255, 0, 0, 0, 255, 10, 20, 30]);
    let bytes = spec.encode(|x, y| vec![(y * 2 + x) as u8]);
    let r = read(&bytes);
    assert_eq!(names(&r), ["R", "G", "B"]);
    assert_eq!(r.sample, SampleType::Int { bits: 8 });
    let h = r.heights(None).unwrap();
    assert_eq!(h[..3], [0.2126, 0.7152, 0.0722]);
    assert_eq!(h[3], luma(10.0 / 255.0, 20.0 / 255.0, 30.0 / 255.0));
    assert_eq!(r.heights(Some(Channel::B)).unwrap(), [0.0, 0.0, 1.0, 30.0 / 255.0]);

    spec.trns = Some(vec![0, 51, 255]);
    let r = read(&spec.encode(|x, y| vec![(y * 2 + x) as u8]));
    assert_eq!(names(&r), ["R", "G", "B", "A"]);
    assert_eq!(r.heights(Some(Channel::A)).unwrap(), [0.0, 0.2, 1.0, 1.0]);
}

#[test]
fn png_interlaced_reads_like_plain() {
    let pixel = |x: usize, y: usize| vec![(x * 17 + y * 31) as u8];
    let mut spec = PngSpec::new(13, 11, 0, 8);
    let plain = read(&spec.encode(pixel));
    spec.interlaced = true;
    let adam7 = spec.encode(pixel);
    assert_ne!(adam7, spec.encode(|_, _| vec![0]), "test image is not constant");
    let interlaced = read(&adam7);
    assert_eq!(interlaced, plain);
    assert_eq!(data(&interlaced, "Y")[5 * 13 + 7], f32::from(pixel(7, 5)[0]) / 255.0);
}

// ---------------------------------------------------------------------------
// Other formats `image` reads

fn encoded(color: image::ExtendedColorType, w: u32, h: u32, buf: &[u8], format: &str) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    match format {
        "tiff" => image::codecs::tiff::TiffEncoder::new(&mut out).write_image(buf, w, h, color),
        "jpeg" => image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 100).write_image(buf, w, h, color),
        "tga" => image::codecs::tga::TgaEncoder::new(&mut out).write_image(buf, w, h, color),
        "bmp" => image::codecs::bmp::BmpEncoder::new(&mut out).write_image(buf, w, h, color),
        "webp" => image::codecs::webp::WebPEncoder::new_lossless(&mut out).write_image(buf, w, h, color),
        _ => unreachable!(),
    }
    .unwrap();
    out.into_inner()
}

#[test]
fn tiff_16_bit_gray() {
    let v = [0u16, 32768, 65535, 12345];
    let buf: Vec<u8> = v.iter().flat_map(|s| s.to_ne_bytes()).collect();
    let r = read(&encoded(image::ExtendedColorType::L16, 2, 2, &buf, "tiff"));
    assert_eq!(r.format, InputFormat::Tiff);
    assert_eq!(r.sample, SampleType::Int { bits: 16 });
    assert_eq!(names(&r), ["Y"]);
    let expected: Vec<f32> = v.iter().map(|&s| f32::from(s) / 65535.0).collect();
    assert_eq!(r.heights(None).unwrap(), expected);
}

/// `image` writes and reads RGB float TIFF, but not one-channel float TIFF
/// (its decoder rejects `Gray(32)`), so only the RGB case is tested here.
#[test]
fn tiff_float_rgb_values_unchanged() {
    let v = [-2.5f32, 0.125, 1000.0, 1e-7, 3.0, -0.0];
    let buf: Vec<u8> = v.iter().flat_map(|s| s.to_ne_bytes()).collect();
    let r = read(&encoded(image::ExtendedColorType::Rgb32F, 2, 1, &buf, "tiff"));
    assert_eq!(r.sample, SampleType::Float);
    assert!(r.sample.more_than_8_bits());
    assert_eq!(data(&r, "R"), [-2.5, 1e-7]);
    assert_eq!(data(&r, "G"), [0.125, 3.0]);
    assert_eq!(data(&r, "B"), [1000.0, -0.0]);
}

/// A JPEG named `.png` is refused by its path (the extension names
/// another format than the content: a mix-up upstream); its bytes, or the
/// file under a name that names no format, are read by content.
#[test]
fn jpeg_named_png_is_refused_and_its_bytes_read_by_content() {
    let buf = vec![100u8; 16 * 16];
    let bytes = encoded(image::ExtendedColorType::L8, 16, 16, &buf, "jpeg");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("height.png");
    std::fs::write(&path, &bytes).unwrap();
    let e = read_path(&path, &ReadOptions::default()).unwrap_err();
    assert!(
        matches!(&e, Error::Misnamed { extension, content } if extension == "png" && *content == InputFormat::Jpeg.info().name)
    );
    assert!(e.to_string().starts_with("is named .png but its content is jpeg: rename it"), "{e}");
    let unnamed = dir.path().join("height");
    std::fs::write(&unnamed, &bytes).unwrap();
    assert_eq!(read_path(&unnamed, &ReadOptions::default()).unwrap(), decode(&bytes, &ReadOptions::default()).unwrap());
    let r = decode(&bytes, &ReadOptions::default()).unwrap();
    assert_eq!(r.format, InputFormat::Jpeg);
    assert_eq!(r.format.to_string(), "jpeg");
    assert_eq!(names(&r), ["Y"]);
    assert_eq!(r.sample, SampleType::Int { bits: 8 });
    for h in r.heights(None).unwrap() {
        assert!((h - 100.0 / 255.0).abs() <= 1.5 / 255.0, "{h}");
    }
}

#[test]
fn read_path_missing_file_is_io_error() {
    let dir = tempfile::tempdir().unwrap();
    let e = read_path(&dir.path().join("none.png"), &ReadOptions::default()).unwrap_err();
    assert!(matches!(e, Error::Io(_)), "{e}");
}

#[test]
fn tga_bmp_webp_lossless_values() {
    let buf: Vec<u8> = (0..4 * 3 * 3).map(|i| (i * 7) as u8).collect();
    for (format, expect) in [("tga", InputFormat::Tga), ("bmp", InputFormat::Bmp), ("webp", InputFormat::WebP)] {
        let r = read(&encoded(image::ExtendedColorType::Rgb8, 4, 3, &buf, format));
        assert_eq!(r.format, expect);
        assert_eq!((r.width, r.height), (4, 3));
        assert_eq!(names(&r), ["R", "G", "B"], "{format}");
        let g: Vec<f32> = buf.iter().skip(1).step_by(3).map(|&v| f32::from(v) / 255.0).collect();
        assert_eq!(r.heights(Some(Channel::G)).unwrap(), g, "{format}");
    }
}

// ---------------------------------------------------------------------------
// The registry of formats: content sniffing, extensions and names all come
// from one list.

/// A small RGB image (4 × 3) written as `format`: PNG by hand, OpenEXR by
/// `exr`, the rest by `image`'s encoders.
fn written_as(format: &InputFormat) -> Vec<u8> {
    let rgb: Vec<u8> = (0..4 * 3 * 3).map(|i| (i * 7) as u8).collect();
    let image_format = match format {
        InputFormat::Png => return PngSpec::new(4, 3, 2, 8).encode(|x, y| rgb[(y * 4 + x) * 3..][..3].to_vec()),
        InputFormat::Exr => return exr_bytes((4, 3), (0, 0), vec![f32_channel("Y", &[0.5; 12])]),
        InputFormat::Jpeg => image::ImageFormat::Jpeg,
        InputFormat::Tiff => image::ImageFormat::Tiff,
        InputFormat::Tga => image::ImageFormat::Tga,
        InputFormat::Bmp => image::ImageFormat::Bmp,
        InputFormat::WebP => image::ImageFormat::WebP,
        InputFormat::Gif => image::ImageFormat::Gif,
        InputFormat::Hdr => image::ImageFormat::Hdr,
        InputFormat::Pnm => image::ImageFormat::Pnm,
        InputFormat::Qoi => image::ImageFormat::Qoi,
        other => panic!("no writer for {other} here: add one"),
    };
    let picture = image::RgbImage::from_raw(4, 3, rgb).unwrap();
    let picture = match image_format {
        // Radiance HDR holds floats only.
        image::ImageFormat::Hdr => image::DynamicImage::ImageRgb32F(image::DynamicImage::from(picture).to_rgb32f()),
        _ => image::DynamicImage::ImageRgb8(picture),
    };
    let mut out = Cursor::new(Vec::new());
    picture.write_to(&mut out, image_format).unwrap();
    out.into_inner()
}

#[test]
fn every_registered_format_is_recognised_by_its_content_and_read_as_itself() {
    assert_eq!(FORMATS.len(), 12);
    for info in FORMATS {
        if info.format == InputFormat::Raw {
            // Bare samples: nothing to recognise, named by the caller
            // (tests/integration/terrain_io.rs reads them).
            assert!(!info.has_signature());
            let raw = ReadOptions::default().with_raw(normalfit::io::RawOptions::default().with_size(4, 3));
            let r = decode(&[7u8; 12], &raw).unwrap();
            assert_eq!((r.format.clone(), r.width, r.height), (InputFormat::Raw, 4, 3));
            assert_eq!(r.format.to_string(), info.name);
            assert_eq!(InputFormat::sniff(&[7u8; 16]), None);
            continue;
        }
        let bytes = written_as(&info.format);
        // TGA has no signature: it is found by its header parsing, last.
        let sniffed = info.has_signature().then(|| info.format.clone());
        assert_eq!(InputFormat::sniff(&bytes), sniffed, "{}", info.name);
        assert_eq!(InputFormat::sniff(&bytes[..16]), sniffed, "{}: 16 bytes are enough", info.name);
        let r = read(&bytes);
        assert_eq!(r.format, info.format, "{}", info.name);
        assert_eq!((r.width, r.height), (4, 3), "{}", info.name);
        assert_eq!(r.format.to_string(), info.name);
        assert_eq!(r.format.info().format, info.format);
    }
}

#[test]
fn every_extension_names_one_format_in_any_case() {
    let mut seen = std::collections::HashSet::new();
    for info in FORMATS {
        assert!(!info.extensions.is_empty(), "{}", info.name);
        for ext in info.extensions {
            assert!(seen.insert(*ext), ".{ext} names two formats");
            assert_eq!(InputFormat::from_extension(ext), Some(info.format.clone()), ".{ext}");
            assert_eq!(InputFormat::from_extension(&ext.to_uppercase()), Some(info.format.clone()), ".{ext}");
        }
    }
    // The extensions the folder search missed before the registry (issue 13).
    for (ext, format) in [("pgm", InputFormat::Pnm), ("hdr", InputFormat::Hdr), ("gif", InputFormat::Gif)] {
        assert_eq!(InputFormat::from_extension(ext), Some(format), ".{ext}");
    }
    assert_eq!(InputFormat::from_extension("qoi"), Some(InputFormat::Qoi));
    assert_eq!(InputFormat::from_extension("Tif"), Some(InputFormat::Tiff));
    for ext in ["", "txt", "pn", "pngx", "exr.bak", "ico", "dds"] {
        assert_eq!(InputFormat::from_extension(ext), None, ".{ext}");
    }
}

#[test]
fn help_and_errors_name_the_registered_formats() {
    assert_eq!(
        formats::names(),
        "PNG, OpenEXR, TIFF, JPEG, TGA, BMP, WebP, GIF, Radiance HDR, PNM, QOI, RAW heightmap"
    );
    let e = decode(b"just some text, not an image\n", &ReadOptions::default()).unwrap_err();
    assert!(matches!(&e, Error::Decode(m) if m.ends_with(&format!("normalfit reads {}", formats::names()))), "{e}");
    // A format `image` knows by its signature but normalfit does not read.
    let ico = [0u8, 0, 1, 0, 1, 0, 16, 16, 0, 0, 1, 0, 32, 0, 0, 0];
    let e = decode(&ico, &ReadOptions::default()).unwrap_err();
    assert!(
        matches!(&e, Error::Unsupported(m) if m.starts_with("ico images are not read; normalfit reads PNG")),
        "{e}"
    );
    let e = decode(&written_as(&InputFormat::Gif), &ReadOptions::default().with_layer("x")).unwrap_err();
    assert!(matches!(&e, Error::Unsupported(m) if m.contains("gif files have no layers")), "{e}");
}

/// docs/convert.md says which extensions a folder's search takes: the
/// registry's, every one.
#[test]
fn the_docs_list_every_extension_a_folder_search_takes() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/convert.md")).unwrap();
    let doc = doc.split_whitespace().collect::<Vec<_>>().join(" ");
    let listed: Vec<String> = FORMATS.iter().flat_map(|f| f.extensions.iter()).map(|ext| format!("`{ext}`")).collect();
    assert!(doc.contains(&format!("one the reader takes: {};", listed.join(", "))), "docs/convert.md: {listed:?}");
}

// ---------------------------------------------------------------------------
// Gray TIFF that `image` refuses (float, half, 32-bit and signed samples),
// made with `tiff`'s encoder and, for what it cannot write, by hand.

fn tiff_gray<C>(w: u32, h: u32, samples: &[C::Inner], compression: tiff::encoder::Compression) -> Vec<u8>
where
    C: tiff::encoder::colortype::ColorType,
    [C::Inner]: tiff::encoder::TiffValue,
{
    let mut out = Cursor::new(Vec::new());
    tiff::encoder::TiffEncoder::new(&mut out)
        .unwrap()
        .with_compression(compression)
        .write_image::<C>(w, h, samples)
        .unwrap();
    out.into_inner()
}

fn bigtiff_gray<C>(w: u32, h: u32, samples: &[C::Inner]) -> Vec<u8>
where
    C: tiff::encoder::colortype::ColorType,
    [C::Inner]: tiff::encoder::TiffValue,
{
    let mut out = Cursor::new(Vec::new());
    tiff::encoder::TiffEncoder::new_big(&mut out).unwrap().write_image::<C>(w, h, samples).unwrap();
    let bytes = out.into_inner();
    assert_eq!(&bytes[..4], b"II+\0");
    bytes
}

fn tiff_f32(w: u32, h: u32, v: &[f32]) -> Vec<u8> {
    tiff_gray::<tiff::encoder::colortype::Gray32Float>(w, h, v, tiff::encoder::Compression::Uncompressed)
}

/// A one-strip uncompressed gray TIFF written by hand: header, the IFD,
/// then the samples, so a cut anywhere after the IFD leaves a header that
/// parses and pixel data that ends early.
struct TiffSpec {
    width: u32,
    height: u32,
    bits: u16,
    /// TIFF SampleFormat: 1 unsigned, 2 signed, 3 float.
    sample_format: u16,
    big_endian: bool,
}

impl TiffSpec {
    fn new(width: u32, height: u32, bits: u16, sample_format: u16, big_endian: bool) -> Self {
        TiffSpec { width, height, bits, sample_format, big_endian }
    }

    /// The file; `data` is the samples, already in the file's byte order.
    fn encode(&self, data: &[u8]) -> Vec<u8> {
        let short = |v: u16| if self.big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
        let long = |v: u32| if self.big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
        const SHORT: u16 = 3;
        const LONG: u16 = 4;
        let entries: [(u16, u16, u32); 10] = [
            (256, LONG, self.width),
            (257, LONG, self.height),
            (258, SHORT, u32::from(self.bits)),
            (259, SHORT, 1), // no compression
            (262, SHORT, 1), // black is zero
            (273, LONG, 8 + 2 + 12 * 10 + 4),
            (277, SHORT, 1), // one sample per pixel
            (278, LONG, self.height),
            (279, LONG, data.len() as u32),
            (339, SHORT, u32::from(self.sample_format)),
        ];
        let mut out = if self.big_endian { b"MM\0*".to_vec() } else { b"II*\0".to_vec() };
        out.extend(long(8));
        out.extend(short(entries.len() as u16));
        for (tag, kind, value) in entries {
            out.extend(short(tag));
            out.extend(short(kind));
            out.extend(long(1));
            if kind == SHORT {
                out.extend(short(value as u16));
                out.extend([0, 0]);
            } else {
                out.extend(long(value));
            }
        }
        out.extend(long(0)); // no next IFD
        out.extend(data);
        out
    }
}

#[test]
fn tiff_float32_gray_values_as_stored() {
    let v = [-2.5f32, 0.125, 1000.0, 1e-7, 3.0, -0.0, 123_456.79, f32::MIN_POSITIVE];
    let plain = tiff_f32(4, 2, &v);
    let r = read(&plain);
    assert_eq!((r.width, r.height), (4, 2));
    assert_eq!(r.format, InputFormat::Tiff);
    assert_eq!(r.sample, SampleType::Float);
    assert!(r.sample.more_than_8_bits());
    assert_eq!(names(&r), ["Y"]);
    assert_eq!(data(&r, "Y"), v);
    assert!(data(&r, "Y")[5].is_sign_negative(), "-0.0 stays -0.0");
    for c in [None, Some(Channel::Luma), Some(Channel::R), Some(Channel::G), Some(Channel::B)] {
        assert_eq!(r.heights(c.clone()).unwrap(), v, "{c:?}");
    }
    assert!(is_unsupported(&r.heights(Some(Channel::A)).unwrap_err()));
    assert_eq!(r.clone().into_heights(None).unwrap().into_f32().unwrap(), v);
    use tiff::encoder::{Compression, DeflateLevel, colortype::Gray32Float};
    for compression in [Compression::Lzw, Compression::Deflate(DeflateLevel::Best), Compression::Packbits] {
        let packed = tiff_gray::<Gray32Float>(4, 2, &v, compression);
        assert_ne!(packed, plain);
        assert_eq!(read(&packed), r);
    }
}

#[test]
fn tiff_float32_gray_many_strips_and_both_byte_orders() {
    // 70 rows: `tiff` writes several strips of 8 KiB or less.
    let (w, h) = (50u32, 70u32);
    let v: Vec<f32> = (0..w * h).map(|i| (i as f32 * 0.37).sin() * 400.0 - 12.5).collect();
    let r = read(&tiff_f32(w, h, &v));
    assert_eq!((r.width, r.height), (50, 70));
    assert_eq!(r.heights(None).unwrap(), v);
    for big_endian in [false, true] {
        let bytes: Vec<u8> =
            v.iter().flat_map(|x| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() }).collect();
        let r = read(&TiffSpec::new(w, h, 32, 3, big_endian).encode(&bytes));
        assert_eq!(r.heights(None).unwrap(), v, "big endian: {big_endian}");
    }
}

#[test]
fn tiff_float64_gray_is_kept_in_f64_and_its_f32_view_rounds() {
    let v = [0.1f64, -1.0 / 3.0, 1e-30, 8848.86, -0.0, 1.0];
    let r =
        read(&tiff_gray::<tiff::encoder::colortype::Gray64Float>(3, 2, &v, tiff::encoder::Compression::Uncompressed));
    assert_eq!(r.sample, SampleType::Float);
    assert_eq!(names(&r), ["Y"]);
    let expected: Vec<f32> = v.iter().map(|&x| x as f32).collect();
    assert_eq!(r.heights(None).unwrap(), expected);
    // The fit reads the doubles themselves.
    assert_eq!(r.clone().into_heights(None).unwrap(), normalfit::Samples::F64(v.to_vec()));

    // Beyond f32's range a double is a height neither the f32 view (for
    // checks and previews) nor the fit holds (the fit's sums are sized for
    // heights up to f32's range at any gain; 1e300 overflowed them, a
    // fuzz finding): an error that names the texel, like any infinity.
    let big = [0.0f64, 1.0, 2.0, -1e39, 4.0, 5.0];
    let r =
        read(&tiff_gray::<tiff::encoder::colortype::Gray64Float>(3, 2, &big, tiff::encoder::Compression::Uncompressed));
    assert_eq!(data(&r, "Y")[3], f32::NEG_INFINITY);
    let e = r.heights(None).unwrap_err();
    assert!(matches!(e, Error::NonFiniteHeight { x: 0, y: 1 }), "{e}");
    let e = r.into_heights(None).unwrap_err();
    assert!(matches!(e, Error::NonFiniteHeight { x: 0, y: 1 }), "{e}");

    // Big-endian doubles, by hand.
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_be_bytes()).collect();
    assert_eq!(read(&TiffSpec::new(3, 2, 64, 3, true).encode(&bytes)).heights(None).unwrap(), expected);
}

#[test]
fn tiff_half_float_gray_by_hand() {
    let v = [0.5f32, -2.0, 0.099_975_586, 65504.0, -0.000_061_035_156, 0.0];
    for big_endian in [false, true] {
        let bytes: Vec<u8> = v
            .iter()
            .flat_map(|&x| {
                let bits = f16::from_f32(x).to_bits();
                if big_endian { bits.to_be_bytes() } else { bits.to_le_bytes() }
            })
            .collect();
        let r = read(&TiffSpec::new(2, 3, 16, 3, big_endian).encode(&bytes));
        assert_eq!(r.format, InputFormat::Tiff);
        assert_eq!(r.sample, SampleType::Float);
        assert_eq!(r.heights(None).unwrap(), v, "big endian: {big_endian}");
    }
}

#[test]
fn tiff_uint32_gray_is_value_over_2_pow_32_minus_1() {
    let v = [0u32, 1, 1 << 31, u32::MAX, 123_456_789, 65535];
    let r = read(&tiff_gray::<tiff::encoder::colortype::Gray32>(2, 3, &v, tiff::encoder::Compression::Uncompressed));
    assert_eq!(r.sample, SampleType::Int { bits: 32 });
    assert!(r.sample.more_than_8_bits());
    assert_eq!(names(&r), ["Y"]);
    let expected: Vec<f32> = v.iter().map(|&n| (f64::from(n) / 4_294_967_295.0) as f32).collect();
    let h = r.heights(None).unwrap();
    assert_eq!(h, expected);
    assert_eq!((h[0], h[3]), (0.0, 1.0));
    assert_eq!(h[2], 0.5, "2^31 / (2^32 − 1) rounds to 0.5 in f32");
}

#[test]
fn tiff_signed_gray_is_value_over_2_pow_bits_minus_1() {
    use tiff::encoder::Compression::Uncompressed;
    use tiff::encoder::colortype::{GrayI8, GrayI16, GrayI32};
    let r = read(&tiff_gray::<GrayI8>(4, 1, &[i8::MIN, -1, 0, i8::MAX], Uncompressed));
    assert_eq!(r.sample, SampleType::SignedInt { bits: 8 });
    assert!(!r.sample.more_than_8_bits());
    assert_eq!(r.heights(None).unwrap(), [-128.0 / 255.0, -1.0 / 255.0, 0.0, 127.0 / 255.0]);

    let v16 = [i16::MIN, -300, 0, 1, i16::MAX, 12345];
    let r = read(&tiff_gray::<GrayI16>(3, 2, &v16, Uncompressed));
    assert_eq!(r.sample, SampleType::SignedInt { bits: 16 });
    assert!(r.sample.more_than_8_bits());
    let expected: Vec<f32> = v16.iter().map(|&n| f32::from(n) / 65535.0).collect();
    assert_eq!(r.heights(None).unwrap(), expected);
    // The same map stored unsigned with an offset of 2^15 (read by `image`)
    // differs by a constant only, so its normals are the same.
    let shifted: Vec<u16> = v16.iter().map(|&n| (i32::from(n) + 32768) as u16).collect();
    let u = read(&tiff_gray::<tiff::encoder::colortype::Gray16>(3, 2, &shifted, Uncompressed));
    assert_eq!(u.sample, SampleType::Int { bits: 16 });
    for (hu, hs) in u.heights(None).unwrap().iter().zip(r.heights(None).unwrap()) {
        assert!((f64::from(*hu) - f64::from(hs) - 32768.0 / 65535.0).abs() < 1e-7, "{hu} {hs}");
    }

    let v32 = [i32::MIN, -1, 0, i32::MAX];
    let r = read(&tiff_gray::<GrayI32>(2, 2, &v32, Uncompressed));
    assert_eq!(r.sample, SampleType::SignedInt { bits: 32 });
    let expected: Vec<f32> = v32.iter().map(|&n| (f64::from(n) / 4_294_967_295.0) as f32).collect();
    assert_eq!(r.heights(None).unwrap(), expected);

    // Big-endian signed 16-bit, by hand (a DEM layout).
    let bytes: Vec<u8> = v16.iter().flat_map(|n| n.to_be_bytes()).collect();
    let r = read(&TiffSpec::new(3, 2, 16, 2, true).encode(&bytes));
    assert_eq!(r.heights(None).unwrap(), v16.iter().map(|&n| f32::from(n) / 65535.0).collect::<Vec<_>>());
}

#[test]
fn tiff_64_bit_integers_and_bigtiff() {
    use tiff::encoder::Compression::Uncompressed;
    use tiff::encoder::colortype::{Gray16, Gray32Float, Gray64, GrayI64};
    // 64-bit integers are divided in f64 (2^64 − 1 rounds to 2^64 there).
    let r = read(&tiff_gray::<Gray64>(3, 1, &[0, 1 << 63, u64::MAX], Uncompressed));
    assert_eq!(r.sample, SampleType::Int { bits: 64 });
    assert_eq!(r.heights(None).unwrap(), [0.0, 0.5, 1.0]);
    let r = read(&tiff_gray::<GrayI64>(3, 1, &[i64::MIN, 0, 1 << 62], Uncompressed));
    assert_eq!(r.sample, SampleType::SignedInt { bits: 64 });
    assert_eq!(r.heights(None).unwrap(), [-0.5, 0.0, 0.25]);

    // BigTIFF: float gray through `tiff`, 16-bit gray through `image`.
    let v = [1.5f32, -0.25, 1e6, 0.0];
    let r = read(&bigtiff_gray::<Gray32Float>(2, 2, &v));
    assert_eq!((r.format.clone(), r.sample), (InputFormat::Tiff, SampleType::Float));
    assert_eq!(r.heights(None).unwrap(), v);
    let r = read(&bigtiff_gray::<Gray16>(2, 1, &[0, 65535]));
    assert_eq!((r.format.clone(), r.sample), (InputFormat::Tiff, SampleType::Int { bits: 16 }));
    assert_eq!(r.heights(None).unwrap(), [0.0, 1.0]);
}

#[test]
fn tiff_8_and_16_bit_gray_stay_with_image() {
    // What `image` read before still reads the same way.
    let r = read(&TiffSpec::new(3, 1, 8, 1, true).encode(&[0, 128, 255]));
    assert_eq!(r.sample, SampleType::Int { bits: 8 });
    assert_eq!(r.heights(None).unwrap(), [0.0, 128.0 / 255.0, 1.0]);
    let r = read(&TiffSpec::new(2, 1, 16, 1, true).encode(&[0x01, 0x02, 0xff, 0xff]));
    assert_eq!(r.sample, SampleType::Int { bits: 16 });
    assert_eq!(r.heights(None).unwrap(), [258.0 / 65535.0, 1.0]);
}

#[test]
fn tiff_float_nan_and_inf_name_the_first_texel() {
    let mut v = vec![0.25f32; 12];
    v[2 * 4] = f32::INFINITY; // (0, 2)
    v[4 + 2] = f32::NAN; // (2, 1), first in row order
    let r = read(&tiff_f32(4, 3, &v));
    assert!(data(&r, "Y")[6].is_nan(), "planes keep the NaN");
    for e in [r.heights(None).unwrap_err(), r.clone().into_heights(None).unwrap_err()] {
        assert!(matches!(e, Error::NonFiniteHeight { x: 2, y: 1 }), "{e}");
    }
}

#[test]
fn tiff_float_max_texels_is_the_limit() {
    let file = tiff_f32(4, 4, &[0.5; 16]);
    let e = decode(&file, &ReadOptions::default().with_max_texels(15)).unwrap_err();
    assert!(matches!(e, Error::Limits(_)), "{e}");
    assert_eq!(decode(&file, &ReadOptions::default().with_max_texels(16)).unwrap().heights(None).unwrap(), [0.5; 16]);
    let file =
        tiff_gray::<tiff::encoder::colortype::Gray64Float>(4, 4, &[0.5; 16], tiff::encoder::Compression::Uncompressed);
    assert!(matches!(decode(&file, &ReadOptions::default().with_max_texels(15)).unwrap_err(), Error::Limits(_)));
    assert!(decode(&file, &ReadOptions::default().with_max_texels(16)).is_ok());
}

#[test]
fn tiff_float_header_claiming_huge_size_fails_fast_on_limits() {
    // The header claims 10^10 float texels; the data is 64 bytes.
    for big_endian in [false, true] {
        let file = TiffSpec::new(100_000, 100_000, 32, 3, big_endian).encode(&[0; 64]);
        // Limits, not a decode error: refused from the header, before any
        // pixel buffer exists.
        let e = decode(&file, &ReadOptions::default()).unwrap_err();
        assert!(matches!(e, Error::Limits(_)), "{e}");
    }
    // Zero size is a decode error.
    for (w, h) in [(0, 4), (4, 0)] {
        let e = decode(&TiffSpec::new(w, h, 32, 3, false).encode(&[]), &ReadOptions::default()).unwrap_err();
        assert!(matches!(e, Error::Decode(_)), "{w}×{h}: {e}");
    }
}

#[test]
fn truncated_float_tiff_is_a_decode_error() {
    // The encoder writes the pixels first and the IFD last; the hand-made
    // file has its IFD first, so cuts there end inside the pixel data.
    let v: Vec<f32> = (0..24).map(|i| i as f32 - 7.5).collect();
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    for file in [tiff_f32(6, 4, &v), TiffSpec::new(6, 4, 32, 3, false).encode(&bytes)] {
        assert_eq!(read(&file).heights(None).unwrap(), v);
        for len in 1..file.len() {
            let e = decode(&file[..len], &ReadOptions::default()).unwrap_err();
            assert!(matches!(e, Error::Decode(_)), "prefix {len}: {e}");
        }
    }
}

// ---------------------------------------------------------------------------
// OpenEXR

fn exr_bytes(size: (usize, usize), position: (i32, i32), channels: Vec<AnyChannel<FlatSamples>>) -> Vec<u8> {
    let attributes = LayerAttributes { layer_position: Vec2(position.0, position.1), ..LayerAttributes::default() };
    let layer = Layer::new(size, attributes, Encoding::UNCOMPRESSED, AnyChannels::sort(SmallVec::from_vec(channels)));
    let mut out = Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut out).unwrap();
    out.into_inner()
}

fn f32_channel(name: &str, v: &[f32]) -> AnyChannel<FlatSamples> {
    AnyChannel::new(name, FlatSamples::F32(v.to_vec()))
}

#[test]
fn exr_single_channel_half_float_u32() {
    let v = [0.5f32, -1.25, 1000.0, 0.0, 2.0, 0.099_975_586];
    for samples in [
        FlatSamples::F32(v.to_vec()),
        FlatSamples::F16(v.iter().map(|&x| f16::from_f32(x)).collect()),
        FlatSamples::U32(vec![0, 1, 65535, 16_777_216, 7, 3]),
    ] {
        let expected: Vec<f32> = match &samples {
            FlatSamples::F32(s) => s.clone(),
            FlatSamples::F16(s) => s.iter().map(|h| h.to_f32()).collect(),
            FlatSamples::U32(s) => s.iter().map(|&n| n as f32).collect(),
        };
        let r = read(&exr_bytes((3, 2), (0, 0), vec![AnyChannel::new("height", samples)]));
        assert_eq!(r.format, InputFormat::Exr);
        assert_eq!(r.format.to_string(), "exr");
        assert_eq!(r.sample, SampleType::Float);
        assert_eq!(names(&r), ["height"]);
        assert_eq!(r.heights(None).unwrap(), expected);
        assert_eq!(r.heights(Some(Channel::R)).unwrap(), expected);
        assert!(is_unsupported(&r.heights(Some(Channel::A)).unwrap_err()));
    }
    // Half really is half: 0.1 is stored as the nearest half.
    let r =
        read(&exr_bytes((1, 1), (0, 0), vec![AnyChannel::new("height", FlatSamples::F16(vec![f16::from_f32(0.1)]))]));
    assert_eq!(r.heights(None).unwrap(), [0.099_975_586]);
}

#[test]
fn exr_prefers_y_and_explicit_channel_overrides() {
    let r = read(&exr_bytes(
        (2, 1),
        (0, 0),
        vec![
            f32_channel("R", &[1.0, 2.0]),
            f32_channel("G", &[3.0, 4.0]),
            f32_channel("B", &[5.0, 6.0]),
            f32_channel("Y", &[7.0, 8.0]),
        ],
    ));
    assert_eq!(r.heights(None).unwrap(), [7.0, 8.0]);
    assert_eq!(r.heights(Some(Channel::Luma)).unwrap(), [7.0, 8.0]);
    assert_eq!(r.heights(Some(Channel::R)).unwrap(), [1.0, 2.0]);
    assert_eq!(r.heights(Some(Channel::B)).unwrap(), [5.0, 6.0]);
}

#[test]
fn exr_rgb_uses_luma_and_layer_names_match() {
    let (red, green, blue) = ([1.0f32, 0.3, -2.0], [0.0f32, 0.6, 10.0], [0.0f32, 0.9, 0.5]);
    let expected: Vec<f32> = (0..3).map(|i| luma(f64::from(red[i]), f64::from(green[i]), f64::from(blue[i]))).collect();
    let r = read(&exr_bytes(
        (3, 1),
        (0, 0),
        vec![f32_channel("R", &red), f32_channel("G", &green), f32_channel("B", &blue)],
    ));
    assert_eq!(r.heights(None).unwrap(), expected);
    assert_eq!(r.heights(None).unwrap()[0], 0.2126);

    let r = read(&exr_bytes(
        (3, 1),
        (0, 0),
        vec![
            f32_channel("diffuse.r", &red),
            f32_channel("diffuse.g", &green),
            f32_channel("diffuse.b", &blue),
            f32_channel("diffuse.A", &[0.25, 0.5, 0.75]),
        ],
    ));
    assert_eq!(r.heights(None).unwrap(), expected);
    assert_eq!(r.heights(Some(Channel::G)).unwrap(), green);
    assert_eq!(r.heights(Some(Channel::A)).unwrap(), [0.25, 0.5, 0.75]);
    assert_eq!(r.into_heights(Some(Channel::B)).unwrap().into_f32().unwrap(), blue);
}

#[test]
fn exr_without_usable_channels_names_them() {
    let r = read(&exr_bytes((1, 1), (0, 0), vec![f32_channel("depth", &[1.0]), f32_channel("mask", &[0.0])]));
    let e = r.heights(None).unwrap_err();
    assert!(is_unsupported(&e), "{e}");
    let m = e.to_string();
    assert!(m.contains("depth") && m.contains("mask"), "{m}");
    assert!(r.heights(Some(Channel::G)).is_err());
}

#[test]
fn exr_offset_data_window_is_the_image() {
    let v: Vec<f32> = (0..12).map(|i| i as f32 * 0.5).collect();
    let r = read(&exr_bytes((4, 3), (10, -7), vec![f32_channel("Y", &v)]));
    assert_eq!((r.width, r.height), (4, 3));
    assert_eq!(r.heights(None).unwrap(), v);
}

#[test]
fn exr_nan_and_inf_name_the_first_texel() {
    let mut v = vec![0.0f32; 12];
    v[2 * 4] = f32::INFINITY; // (0, 2)
    v[4 + 3] = f32::NAN; // (3, 1), first in row order
    let r = read(&exr_bytes((4, 3), (0, 0), vec![f32_channel("height", &v)]));
    assert!(data(&r, "height")[7].is_nan(), "planes keep the NaN");
    for e in [r.heights(None).unwrap_err(), r.clone().into_heights(None).unwrap_err()] {
        assert!(matches!(e, Error::NonFiniteHeight { x: 3, y: 1 }), "{e}");
    }
    // A NaN in a channel that is not the height does not matter.
    let r = read(&exr_bytes((1, 1), (0, 0), vec![f32_channel("Y", &[1.0]), f32_channel("A", &[f32::NAN])]));
    assert_eq!(r.heights(None).unwrap(), [1.0]);
    assert!(matches!(r.heights(Some(Channel::A)).unwrap_err(), Error::NonFiniteHeight { x: 0, y: 0 }));
}

// ---------------------------------------------------------------------------
// Bad input: always an error, never a panic, never a huge allocation

#[test]
fn empty_text_and_truncated_inputs_are_errors() {
    let e = decode(&[], &ReadOptions::default()).unwrap_err();
    assert!(matches!(&e, Error::Decode(m) if m == "file is empty"), "{e}");
    let e = decode(b"just some text, not an image\n", &ReadOptions::default()).unwrap_err();
    assert!(matches!(&e, Error::Decode(m) if m.starts_with("not a recognised image format")), "{e}");

    let png = PngSpec::new(5, 4, 2, 8).encode(|x, y| vec![x as u8, y as u8, 9]);
    read(&png);
    for len in 1..png.len() - 12 {
        // Everything short of the IEND chunk lacks pixel data.
        assert!(decode(&png[..len], &ReadOptions::default()).is_err(), "prefix {len}");
    }
    let exr = exr_bytes((3, 3), (0, 0), vec![f32_channel("Y", &[0.5; 9])]);
    read(&exr);
    for len in 1..exr.len() {
        assert!(decode(&exr[..len], &ReadOptions::default()).is_err(), "exr prefix {len}");
    }
}

#[test]
fn png_header_claiming_huge_size_fails_fast_on_limits() {
    // The header claims 10^10 texels; the data is a few bytes.
    let mut png = PngSpec::new(100_000, 100_000, 0, 8).header();
    chunk(&mut png, b"IDAT", &zlib_stored(&[0; 64]));
    chunk(&mut png, b"IEND", &[]);
    // Limits, not a decode error: refused from the header, before any
    // pixel buffer exists.
    let e = decode(&png, &ReadOptions::default()).unwrap_err();
    assert!(matches!(e, Error::Limits(_)), "{e}");
}

#[test]
fn exr_header_claiming_huge_size_fails_on_limits() {
    let mut exr = exr_bytes((2, 2), (0, 0), vec![f32_channel("Y", &[0.0; 4])]);
    let key = b"dataWindow\0box2i\0";
    let at = exr.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    exr[at + 8..at + 12].copy_from_slice(&99_999i32.to_le_bytes());
    exr[at + 12..at + 16].copy_from_slice(&99_999i32.to_le_bytes());
    let e = decode(&exr, &ReadOptions::default()).unwrap_err();
    assert!(matches!(e, Error::Limits(_)), "{e}");
}

#[test]
fn max_texels_option_is_the_limit() {
    let png = PngSpec::new(4, 4, 0, 8).encode(|_, _| vec![1]);
    let e = decode(&png, &ReadOptions::default().with_max_texels(15)).unwrap_err();
    assert!(matches!(e, Error::Limits(_)), "{e}");
    assert!(decode(&png, &ReadOptions::default().with_max_texels(16)).is_ok());
    let exr = exr_bytes((4, 4), (0, 0), vec![f32_channel("Y", &[0.0; 16])]);
    let e = decode(&exr, &ReadOptions::default().with_max_texels(15)).unwrap_err();
    assert!(matches!(e, Error::Limits(_)), "{e}");
    assert_eq!(ReadOptions::default().max_texels, 1 << 30);
}

#[test]
fn zero_size_png_is_an_error() {
    for (w, h) in [(0, 4), (4, 0)] {
        let png = PngSpec::new(w, h, 0, 8).encode(|_, _| vec![0]);
        assert!(decode(&png, &ReadOptions::default()).is_err(), "{w}×{h}");
    }
}

// ---------------------------------------------------------------------------
// Encoders, checked through the (independently tested) decoder

/// A PNG encoding of `depth` bits with these settings.
fn png(depth: PngDepth, compression: PngCompression, layout: Layout) -> normalfit::io::Encoding {
    PngOptions::new(depth).with_compression(compression).with_layout(layout).into()
}

/// An EXR encoding that stores the values given as they are (signed).
fn exr_as_given(depth: ExrDepth, layout: Layout) -> normalfit::io::Encoding {
    ExrOptions::new(depth).with_signed(true).with_layout(layout).into()
}

#[test]
fn png_rgb8_round_trip() {
    let texels: Vec<[u8; 3]> = (0..15).map(|i| [i * 17, 255 - i, 128]).collect();
    for compression in [PngCompression::Fast, PngCompression::Default, PngCompression::Best] {
        let mut out = Cursor::new(Vec::new());
        encode_normals(&texels, None, 5, 3, &png(PngDepth::Eight, compression, Layout::Rgb), &mut out).unwrap();
        let r = read(out.get_ref());
        assert_eq!((r.format.clone(), r.width, r.height), (InputFormat::Png, 5, 3));
        assert_eq!(r.sample, SampleType::Int { bits: 8 });
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let expected: Vec<f32> = texels.iter().map(|t| f32::from(t[c]) / 255.0).collect();
            assert_eq!(data(&r, name), expected);
        }
    }
}

#[test]
fn png_rgb16_round_trip_keeps_byte_order() {
    let texels: Vec<[u16; 3]> = vec![[0x0102, 32768, 65535], [0, 1, 0xff00], [0x00ff, 12345, 54321]];
    let mut out = Cursor::new(Vec::new());
    encode_normals(&texels, None, 3, 1, &normalfit::io::Encoding::png16(), &mut out).unwrap();
    let r = read(out.get_ref());
    assert_eq!(r.sample, SampleType::Int { bits: 16 });
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        let back: Vec<u16> = data(&r, name).iter().map(|&h| (h * 65535.0).round() as u16).collect();
        let expected: Vec<u16> = texels.iter().map(|t| t[c]).collect();
        assert_eq!(back, expected, "{name}");
    }
}

/// Normals given as f32 and written to a PNG are quantised by the fit's
/// own rule, c = round(max (n + 1)/2), written here plainly; to an EXR,
/// (n + 1)/2 or n itself with `signed`.
#[test]
fn float_normals_are_stored_as_each_encoding_says() {
    let normals: Vec<[f32; 3]> =
        vec![[0.0, 0.0, 1.0], [-1.0, 1.0, 0.0], [0.6, -0.8, 0.0], [0.1234, -0.5, 0.857], [0.999, -0.999, 0.04]];
    for (depth, max) in [(PngDepth::Eight, 255.0), (PngDepth::Sixteen, 65535.0)] {
        let mut out = Cursor::new(Vec::new());
        encode_normals(&normals, None, 5, 1, &png(depth, PngCompression::Fast, Layout::Rgb), &mut out).unwrap();
        let r = read(out.get_ref());
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let back: Vec<f64> = data(&r, name).iter().map(|&v| (f64::from(v) * max).round()).collect();
            let want: Vec<f64> = normals.iter().map(|n| ((f64::from(n[c]) + 1.0) / 2.0 * max).round()).collect();
            assert_eq!(back, want, "{depth:?} {name}");
        }
    }
    for signed in [false, true] {
        let mut out = Cursor::new(Vec::new());
        let encoding = ExrOptions::new(ExrDepth::Float).with_signed(signed).into();
        encode_normals(&normals, None, 5, 1, &encoding, &mut out).unwrap();
        let r = read(out.get_ref());
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let want: Vec<f32> = normals.iter().map(|n| if signed { n[c] } else { (n[c] + 1.0) * 0.5 }).collect();
            assert_eq!(data(&r, name), want, "signed {signed} {name}");
        }
    }
}

#[test]
fn texels_the_encoding_does_not_store_are_refused() {
    let t8 = [[0u8; 3]; 4];
    let t16 = [[0u16; 3]; 4];
    let out = || Cursor::new(Vec::new());
    for e in [
        encode_normals(&t8, None, 2, 2, &normalfit::io::Encoding::png16(), out()).unwrap_err(),
        encode_normals(&t8, None, 2, 2, &normalfit::io::Encoding::exr(), out()).unwrap_err(),
        encode_normals(&t16, None, 2, 2, &normalfit::io::Encoding::png8(), out()).unwrap_err(),
        encode_gray(&[0u8; 4], 2, 2, &normalfit::io::Encoding::png16(), out()).unwrap_err(),
        encode_gray(&[0.0f32; 4], 2, 2, &normalfit::io::Encoding::png8(), out()).unwrap_err(),
    ] {
        assert!(matches!(e, Error::InvalidOption(_)), "{e}");
    }
}

/// RGBA with the heights in alpha (rounded, clamped to [0, 1]), opaque
/// RGBA, and RGB with blue 0 for red-green, at 8 and 16 bits.
#[test]
fn png_layouts_put_heights_one_or_zero_where_they_say() {
    let heights = [0.0f32, 0.5, 1.0, -0.25, 1.75, 0.2];
    let t8: Vec<[u8; 3]> = (0..6).map(|i| [i * 40, 200 - i * 30, 255 - i]).collect();
    let t16: Vec<[u16; 3]> = t8.iter().map(|t| t.map(|v| u16::from(v) * 250 + 3)).collect();
    let max = |bits| if bits == 8 { 255.0 } else { 65535.0 };
    for bits in [8, 16] {
        for layout in [Layout::RgbHeight, Layout::RgbOpaque, Layout::Rg] {
            let mut out = Cursor::new(Vec::new());
            if bits == 8 {
                let encoding = png(PngDepth::Eight, PngCompression::Fast, layout);
                encode_normals(&t8, Some(&heights), 3, 2, &encoding, &mut out).unwrap();
            } else {
                let encoding = png(PngDepth::Sixteen, PngCompression::Fast, layout);
                encode_normals(&t16, Some(&heights), 3, 2, &encoding, &mut out).unwrap();
            }
            let r = read(out.get_ref());
            assert_eq!(r.sample, SampleType::Int { bits });
            let stored =
                |name: &str| -> Vec<f64> { data(&r, name).iter().map(|&v| f64::from(v) * max(bits)).collect() };
            let red: Vec<f64> =
                (0..6).map(|k| if bits == 8 { f64::from(t8[k][0]) } else { f64::from(t16[k][0]) }).collect();
            assert_eq!(stored("R").iter().map(|v| v.round()).collect::<Vec<_>>(), red, "{layout:?} {bits}");
            match layout {
                Layout::RgbHeight => {
                    let want: Vec<f64> =
                        heights.iter().map(|&h| (f64::from(h).clamp(0.0, 1.0) * max(bits)).round()).collect();
                    assert_eq!(stored("A").iter().map(|v| v.round()).collect::<Vec<_>>(), want, "{bits}");
                }
                Layout::RgbOpaque => assert!(stored("A").iter().all(|&a| a.round() == max(bits))),
                _ => {
                    assert_eq!(names(&r), ["R", "G", "B"], "red-green stays an RGB file");
                    assert!(stored("B").iter().all(|&b| b == 0.0));
                }
            }
        }
    }
    let with_heights = png(PngDepth::Eight, PngCompression::Fast, Layout::RgbHeight);
    let e = encode_normals(&t8, None, 3, 2, &with_heights, Cursor::new(Vec::new())).unwrap_err();
    assert!(matches!(e, Error::InvalidOption(_)), "{e}");
    let e = encode_normals(&t8, Some(&heights[..5]), 3, 2, &with_heights, Cursor::new(Vec::new())).unwrap_err();
    assert!(matches!(e, Error::BufferSize { expected: 6, actual: 5 }), "{e}");
}

#[test]
fn exr_layouts_name_their_channels_and_keep_heights_as_they_are() {
    let heights = [-3.5f32, 0.25, 1000.0, 0.0];
    let texels: Vec<[f32; 3]> = (0..4).map(|i| [i as f32 * 0.1, 0.5 - i as f32 * 0.1, 0.9]).collect();
    for (layout, want) in [
        (Layout::RgbHeight, &["A", "B", "G", "R"][..]),
        (Layout::RgbOpaque, &["A", "B", "G", "R"][..]),
        (Layout::Rg, &["G", "R"][..]),
    ] {
        let mut out = Cursor::new(Vec::new());
        encode_normals(&texels, Some(&heights), 2, 2, &exr_as_given(ExrDepth::Float, layout), &mut out).unwrap();
        let r = read(&out.into_inner());
        assert_eq!(names(&r), want, "{layout:?}");
        assert_eq!(data(&r, "G"), texels.iter().map(|t| t[1]).collect::<Vec<_>>());
        match layout {
            Layout::RgbHeight => assert_eq!(data(&r, "A"), heights.to_vec()),
            Layout::RgbOpaque => assert_eq!(data(&r, "A"), vec![1.0; 4]),
            _ => {}
        }
    }
}

#[test]
fn gray_maps_round_trip() {
    let values: Vec<u16> = vec![0, 1, 300, 65535, 40000, 7];
    let mut out = Cursor::new(Vec::new());
    encode_gray(&values, 2, 3, &normalfit::io::Encoding::png16(), &mut out).unwrap();
    let r = read(out.get_ref());
    assert_eq!((names(&r), r.sample), (vec!["Y"], SampleType::Int { bits: 16 }));
    let back: Vec<u16> = data(&r, "Y").iter().map(|&v| (v * 65535.0).round() as u16).collect();
    assert_eq!(back, values);
    let floats = [0.0f32, 1e-7, 0.5, 3.25];
    let mut out = Cursor::new(Vec::new());
    encode_gray(&floats, 4, 1, &normalfit::io::Encoding::exr(), &mut out).unwrap();
    let r = read(&out.into_inner());
    assert_eq!(names(&r), ["Y"]);
    assert_eq!(data(&r, "Y"), floats.to_vec());
}

#[test]
fn png_gray8_round_trip() {
    let texels: Vec<u8> = (0..12).map(|i| i * 21).collect();
    let mut out = Cursor::new(Vec::new());
    encode_gray(&texels, 4, 3, &png(PngDepth::Eight, PngCompression::Best, Layout::Rgb), &mut out).unwrap();
    let r = read(out.get_ref());
    assert_eq!((r.width, r.height, r.sample), (4, 3, SampleType::Int { bits: 8 }));
    assert_eq!(r.planes.len(), 1, "one gray plane");
    let expected: Vec<f32> = texels.iter().map(|&t| f32::from(t) / 255.0).collect();
    assert_eq!(r.planes[0].data.to_f32().unwrap(), expected);
    let e = encode_gray(&texels, 5, 3, &normalfit::io::Encoding::png8(), Cursor::new(Vec::new())).unwrap_err();
    assert!(matches!(e, Error::BufferSize { expected: 15, actual: 12 }), "{e}");
}

#[test]
fn encoders_reject_wrong_buffer_sizes() {
    let out = || Cursor::new(Vec::new());
    let e = encode_normals(&[[0u8; 3]; 5], None, 2, 3, &normalfit::io::Encoding::png8(), out()).unwrap_err();
    assert!(matches!(e, Error::BufferSize { expected: 6, actual: 5 }), "{e}");
    let e = encode_normals(&[[0u16; 3]; 7], None, 2, 3, &normalfit::io::Encoding::png16(), out()).unwrap_err();
    assert!(matches!(e, Error::BufferSize { expected: 6, actual: 7 }), "{e}");
    let e = encode_normals(&[[0.0f32; 3]; 1], None, 2, 3, &normalfit::io::Encoding::exr(), out()).unwrap_err();
    assert!(matches!(e, Error::BufferSize { expected: 6, actual: 1 }), "{e}");
    assert!(encode_normals::<[u8; 3]>(&[], None, 0, 0, &normalfit::io::Encoding::png8(), out()).is_err());
}

#[test]
fn exr_round_trip_float_and_half() {
    let texels: Vec<[f32; 3]> = (0..6).map(|i| [i as f32 * 0.1 - 0.3, -0.999, 1.0 / (i as f32 + 3.0)]).collect();
    for depth in [ExrDepth::Float, ExrDepth::Half] {
        let mut out = Cursor::new(Vec::new());
        encode_normals(&texels, None, 3, 2, &exr_as_given(depth, Layout::Rgb), &mut out).unwrap();
        let r = read(&out.into_inner());
        assert_eq!((r.width, r.height), (3, 2));
        assert_eq!(names(&r), ["B", "G", "R"]);
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let expected: Vec<f32> = texels
                .iter()
                .map(|t| match depth {
                    ExrDepth::Float => t[c],
                    ExrDepth::Half => f16::from_f32(t[c]).to_f32(),
                    other => panic!("no reference for {other:?}"),
                })
                .collect();
            assert_eq!(data(&r, name), expected, "{depth:?} {name}");
        }
    }
}

// ---------------------------------------------------------------------------
// Atomic writes

fn folder_listing(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}

#[test]
fn write_atomically_replaces_whole_and_cleans_up() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.png");
    std::fs::write(&path, b"old").unwrap();
    let big = vec![7u8; 1 << 20];
    write_atomically(&path, |w| {
        w.write_all(&big)?;
        w.write_all(b"end")?;
        Ok(())
    })
    .unwrap();
    let got = std::fs::read(&path).unwrap();
    assert_eq!(got.len(), big.len() + 3);
    assert!(got.ends_with(b"end"));
    assert_eq!(folder_listing(dir.path()), ["out.png"]);
}

#[test]
fn write_atomically_error_keeps_old_content_and_no_temp() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.exr");
    std::fs::write(&path, b"old content").unwrap();
    let e = write_atomically(&path, |w| {
        w.write_all(b"partial")?;
        // While writing, the new bytes sit in a temporary file beside it.
        assert_eq!(std::fs::read(&path).unwrap(), b"old content");
        Err(Error::Encode("stop".into()))
    })
    .unwrap_err();
    assert!(matches!(e, Error::Encode(_)), "{e}");
    assert_eq!(std::fs::read(&path).unwrap(), b"old content");
    assert_eq!(folder_listing(dir.path()), ["out.exr"]);

    // A new file that fails is not created at all.
    let fresh = dir.path().join("fresh.png");
    assert!(write_atomically(&fresh, |_| Err(Error::Encode("no".into()))).is_err());
    assert!(!fresh.exists());
    assert_eq!(folder_listing(dir.path()), ["out.exr"]);
}

#[test]
fn write_atomically_panic_leaves_no_temp() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.png");
    let result = std::panic::catch_unwind(|| {
        let _ = write_atomically(&path, |w| {
            w.write_all(b"x")?;
            panic!("writer panicked");
        });
    });
    assert!(result.is_err());
    assert!(folder_listing(dir.path()).is_empty());
}

#[test]
fn write_atomically_missing_folder_is_io_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sub").join("x.png");
    let e = write_atomically(&path, |_| Ok(())).unwrap_err();
    assert!(matches!(e, Error::Io(_)), "missing folder is an io error: {e}");
}

#[cfg(unix)]
#[test]
fn write_atomically_gives_ordinary_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain");
    std::fs::File::create(&plain).unwrap();
    let ordinary = std::fs::metadata(&plain).unwrap().permissions().mode() & 0o777;
    let path = dir.path().join("n.png");
    write_atomically(&path, |w| Ok(w.write_all(b"data")?)).unwrap();
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, ordinary, "{mode:o} vs {ordinary:o}");
    assert_ne!(mode, 0o600);
}

#[test]
fn corrupted_files_of_every_format_do_not_panic() {
    let rgb: Vec<u8> = (0..8 * 8 * 3).map(|i| (i * 13) as u8).collect();
    let mut files: Vec<Vec<u8>> = ["tiff", "jpeg", "tga", "bmp", "webp"]
        .iter()
        .map(|f| encoded(image::ExtendedColorType::Rgb8, 8, 8, &rgb, f))
        .collect();
    files.push(PngSpec::new(8, 8, 2, 8).encode(|x, y| vec![x as u8, y as u8, 3]));
    let floats: Vec<f32> = (0..64).map(|i| i as f32 * 0.25 - 3.0).collect();
    files.push(tiff_f32(8, 8, &floats));
    files.push(tiff_gray::<tiff::encoder::colortype::Gray32Float>(8, 8, &floats, tiff::encoder::Compression::Lzw));
    let halves: Vec<u8> = floats.iter().flat_map(|&x| f16::from_f32(x).to_bits().to_be_bytes()).collect();
    files.push(TiffSpec::new(8, 8, 16, 3, true).encode(&halves));
    files.push(exr_bytes((8, 8), (0, 0), vec![f32_channel("Y", &[0.5; 64])]));
    for file in &files {
        for pos in (0..file.len()).step_by(3) {
            for byte in [0x00, 0xff, 0x7f] {
                let mut bad = file.clone();
                bad[pos] = byte;
                // Ok or Err are both fine; a panic fails the test.
                let _ = decode(&bad, &ReadOptions::default());
            }
        }
        for len in (1..file.len()).step_by(7) {
            let _ = decode(&file[..len], &ReadOptions::default());
        }
    }
}
