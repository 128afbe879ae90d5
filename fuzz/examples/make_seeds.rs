//! Writes the seed corpus: one small valid file for every layout the reader
//! takes, so the fuzzers start inside every decoder instead of having to
//! discover each format's magic and header.
//!
//! ```text
//! cd fuzz && cargo run --example make_seeds -- seeds
//! ```
//!
//! Deterministic: the same files every run, so `git status` shows a change
//! only when this program changes. Images are 4×4 to 16×16; the whole
//! folder stays a few tens of KB.
//!
//! Every target derives its options from a case's last two bytes (see
//! `src/lib.rs`), and for most formats those are a fixed trailer (PNG's
//! IEND CRC, JPEG's EOI). A few seeds therefore repeat a file with two
//! bytes appended, which the decoders ignore, to start from other options
//! too.
//!
//! The targets with seeds of their own (geotiff_tags, raw_sizes,
//! rgb_packed, inverse, python_entry) get them in `seeds/TARGET`: their
//! options come from more trailing bytes ([`Pick`](normalfit_fuzz::Pick)),
//! which these seeds set on purpose ([`options`]).

use std::io::Cursor;
use std::path::{Path, PathBuf};

use exr::prelude::{
    AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples, Image, Layer, LayerAttributes, Levels, LineOrder, SmallVec,
    Vec2, WritableImage, f16,
};
use image::{ExtendedColorType, ImageEncoder, ImageFormat};

/// A smooth test surface in [0, 1]: a bump plus a ramp along x, so the
/// normals vary and the x wrap has a seam while y tiles.
fn height(x: usize, y: usize, w: usize, h: usize) -> f32 {
    let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
    let bump = (std::f32::consts::TAU * v).cos() * 0.25 + 0.25;
    (0.5 * u + bump).clamp(0.0, 1.0)
}

fn heights(w: usize, h: usize) -> Vec<f32> {
    (0..w * h).map(|k| height(k % w, k / w, w, h)).collect()
}

/// Integer samples of the surface, `bits` deep.
fn ints(w: usize, h: usize, bits: u32) -> Vec<u32> {
    let top = ((1u64 << bits) - 1) as f32;
    heights(w, h).iter().map(|&v| (v * top).round() as u32).collect()
}

/// RGB(A) bytes: R the surface, G its mirror, B a constant, A a gradient.
fn rgb8(w: usize, h: usize, alpha: bool) -> Vec<u8> {
    let mut out = Vec::new();
    for (k, v) in ints(w, h, 8).into_iter().enumerate() {
        out.extend([v as u8, 255 - v as u8, 96]);
        if alpha {
            out.push((k * 255 / (w * h)) as u8);
        }
    }
    out
}

struct Seeds {
    dir: PathBuf,
    total: usize,
}

impl Seeds {
    fn put(&mut self, name: &str, bytes: &[u8]) {
        std::fs::write(self.dir.join(name), bytes).expect("write a seed");
        self.total += bytes.len();
    }

    /// The file, and the file with `tails` appended one at a time (see the
    /// module docs).
    fn put_with_tails(&mut self, name: &str, bytes: &[u8], tails: &[[u8; 2]]) {
        self.put(name, bytes);
        let (stem, ext) = name.rsplit_once('.').expect("seed names have an extension");
        for (i, tail) in tails.iter().enumerate() {
            let mut b = bytes.to_vec();
            b.extend(tail);
            self.put(&format!("{stem}-opts{}.{ext}", i + 1), &b);
        }
    }
}

// ---------------------------------------------------------------------------
// PNG: the `png` crate for every colour type and depth; Adam7 by hand,
// since the crate writes only non-interlaced images.

fn png(
    w: u32,
    h: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
    setup: impl FnOnce(&mut png::Encoder<&mut Vec<u8>>),
) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        setup(&mut enc);
        let mut writer = enc.write_header().expect("png header");
        writer.write_image_data(data).expect("png data");
    }
    out
}

/// Samples of `bits` (1, 2, 4) packed into bytes, rows padded to a byte.
fn packed(samples: &[u32], w: usize, bits: u32) -> Vec<u8> {
    let mut out = Vec::new();
    for row in samples.chunks(w) {
        let mut byte = 0u8;
        let mut used = 0;
        for &s in row {
            byte |= (s as u8) << (8 - bits - used);
            used += bits;
            if used == 8 {
                out.push(byte);
                (byte, used) = (0, 0);
            }
        }
        if used > 0 {
            out.push(byte);
        }
    }
    out
}

fn png_chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend((data.len() as u32).to_be_bytes());
    let start = out.len();
    out.extend(kind);
    out.extend(data);
    let crc = crc32fast::hash(&out[start..]);
    out.extend(crc.to_be_bytes());
}

/// An Adam7-interlaced PNG of 8- or 16-bit samples, `texel(x, y)` giving
/// each texel's bytes.
fn png_interlaced(w: usize, h: usize, color_type: u8, depth: u8, texel: impl Fn(usize, usize) -> Vec<u8>) -> Vec<u8> {
    const PASSES: [(usize, usize, usize, usize); 7] =
        [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)];
    let mut raw = Vec::new();
    for (x0, y0, dx, dy) in PASSES {
        if x0 >= w || y0 >= h {
            continue; // an empty pass has no rows, not even filter bytes
        }
        for y in (y0..h).step_by(dy) {
            raw.push(0);
            for x in (x0..w).step_by(dx) {
                raw.extend(texel(x, y));
            }
        }
    }
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend((w as u32).to_be_bytes());
    ihdr.extend((h as u32).to_be_bytes());
    ihdr.extend([depth, color_type, 0, 0, 1]);
    png_chunk(&mut out, b"IHDR", &ihdr);
    png_chunk(&mut out, b"IDAT", &fdeflate::compress_to_vec(&raw));
    png_chunk(&mut out, b"IEND", &[]);
    out
}

fn pngs(s: &mut Seeds) {
    use png::{BitDepth as D, ColorType as C};
    let (w, h) = (8, 8);
    let g8: Vec<u8> = ints(w, h, 8).iter().map(|&v| v as u8).collect();
    let g16: Vec<u8> = ints(w, h, 16).iter().flat_map(|&v| (v as u16).to_be_bytes()).collect();
    let (w32, h32) = (w as u32, h as u32);
    s.put_with_tails(
        "png-gray8.png",
        &png(w32, h32, C::Grayscale, D::Eight, &g8, |_| {}),
        &[[0x91, 0x05], [0x2e, 0xb3]],
    );
    s.put_with_tails("png-gray16.png", &png(w32, h32, C::Grayscale, D::Sixteen, &g16, |_| {}), &[[0x44, 0x21]]);
    for bits in [1u32, 2, 4] {
        let depth = [D::One, D::Two, D::Four][bits.trailing_zeros() as usize];
        let data = packed(&ints(w, h, bits), w, bits);
        s.put(&format!("png-gray{bits}.png"), &png(w32, h32, C::Grayscale, depth, &data, |_| {}));
    }
    // Gray with a transparent value: EXPAND turns tRNS into alpha.
    s.put("png-gray8-trns.png", &png(w32, h32, C::Grayscale, D::Eight, &g8, |e| e.set_trns(vec![0, 128])));
    let ga8: Vec<u8> = g8.iter().flat_map(|&v| [v, 255 - v]).collect();
    s.put("png-gray-alpha8.png", &png(w32, h32, C::GrayscaleAlpha, D::Eight, &ga8, |_| {}));
    let ga16: Vec<u8> = g16.chunks(2).flat_map(|v| [v[0], v[1], 0xff, v[0]]).collect();
    s.put("png-gray-alpha16.png", &png(w32, h32, C::GrayscaleAlpha, D::Sixteen, &ga16, |_| {}));
    s.put_with_tails("png-rgb8.png", &png(w32, h32, C::Rgb, D::Eight, &rgb8(w, h, false), |_| {}), &[[0x03, 0x7a]]);
    let rgb16: Vec<u8> = rgb8(w, h, false).iter().flat_map(|&v| [v, v ^ 0x5a]).collect();
    s.put("png-rgb16.png", &png(w32, h32, C::Rgb, D::Sixteen, &rgb16, |_| {}));
    s.put("png-rgba8.png", &png(w32, h32, C::Rgba, D::Eight, &rgb8(w, h, true), |_| {}));
    let rgba16: Vec<u8> = rgb8(w, h, true).iter().flat_map(|&v| [v, 0x11]).collect();
    s.put("png-rgba16.png", &png(w32, h32, C::Rgba, D::Sixteen, &rgba16, |_| {}));
    // Palette: 8-bit indices into 16 grays, and 4-bit with transparency.
    let palette: Vec<u8> = (0..16u8).flat_map(|i| [i * 17, 255 - i * 17, i * 8]).collect();
    let idx8: Vec<u8> = ints(w, h, 4).iter().map(|&v| v as u8).collect();
    s.put("png-palette8.png", &png(w32, h32, C::Indexed, D::Eight, &idx8, |e| e.set_palette(palette.clone())));
    let idx4 = packed(&ints(w, h, 4), w, 4);
    let trns: Vec<u8> = (0..16u8).map(|i| 255 - i * 8).collect();
    s.put(
        "png-palette4-trns.png",
        &png(w32, h32, C::Indexed, D::Four, &idx4, |e| {
            e.set_palette(palette.clone());
            e.set_trns(trns.clone());
        }),
    );
    // Adam7, with sizes that leave some passes empty or partial.
    let (iw, ih) = (7, 5);
    let gi = ints(iw, ih, 8);
    s.put("png-interlaced-gray8.png", &png_interlaced(iw, ih, 0, 8, |x, y| vec![gi[y * iw + x] as u8]));
    let gi16 = ints(iw, ih, 16);
    s.put(
        "png-interlaced-gray16.png",
        &png_interlaced(iw, ih, 0, 16, |x, y| (gi16[y * iw + x] as u16).to_be_bytes().to_vec()),
    );
    let ri = rgb8(iw, ih, true);
    s.put("png-interlaced-rgba8.png", &png_interlaced(iw, ih, 6, 8, |x, y| ri[(y * iw + x) * 4..][..4].to_vec()));
    // One texel: the smallest image there is.
    s.put("png-1x1.png", &png(1, 1, C::Grayscale, D::Eight, &[200], |_| {}));
}

// ---------------------------------------------------------------------------
// OpenEXR: half, float and u32 samples; scan lines and tiles; several
// compressions; several layers; mip levels.

fn exr_layer(
    w: usize,
    h: usize,
    name: Option<&str>,
    encoding: Encoding,
    channels: Vec<AnyChannel<FlatSamples>>,
) -> Layer<AnyChannels<FlatSamples>> {
    let attributes = name.map_or_else(LayerAttributes::default, LayerAttributes::named);
    Layer::new((w, h), attributes, encoding, AnyChannels::sort(SmallVec::from_vec(channels)))
}

fn exr_bytes(layers: Vec<Layer<AnyChannels<FlatSamples>>>) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    Image::from_layers(
        exr::prelude::ImageAttributes::new(exr::prelude::IntegerBounds::from_dimensions(layers[0].size)),
        layers,
    )
    .write()
    .to_buffered(&mut out)
    .expect("exr");
    out.into_inner()
}

fn half(v: &[f32]) -> FlatSamples {
    FlatSamples::F16(v.iter().map(|&x| f16::from_f32(x)).collect())
}

fn exrs(s: &mut Seeds) {
    use exr::compression::Compression as Z;
    let (w, h) = (8, 6);
    let hv = heights(w, h);
    let enc = |compression, blocks| Encoding { compression, blocks, line_order: LineOrder::Increasing };
    let scan = |c| enc(c, Blocks::ScanLines);
    let tiles = |c| enc(c, Blocks::Tiles(Vec2(4, 4)));

    let y_half = AnyChannel::new("Y", half(&hv));
    s.put_with_tails(
        "exr-y-half-scan.exr",
        &exr_bytes(vec![exr_layer(w, h, None, scan(Z::Uncompressed), vec![y_half])]),
        &[[0x77, 0x0c]],
    );
    let height_f32 = AnyChannel::new("height", FlatSamples::F32(hv.iter().map(|v| v * 1000.0 - 300.0).collect()));
    s.put("exr-height-float-zip.exr", &exr_bytes(vec![exr_layer(w, h, None, scan(Z::ZIP16), vec![height_f32])]));
    let u32s = AnyChannel::new("Z", FlatSamples::U32(ints(w, h, 12)));
    s.put("exr-u32-rle.exr", &exr_bytes(vec![exr_layer(w, h, None, scan(Z::RLE), vec![u32s])]));
    let rgb = |r: &[f32]| {
        vec![
            AnyChannel::new("R", half(r)),
            AnyChannel::new("G", half(&r.iter().map(|v| 1.0 - v).collect::<Vec<_>>())),
            AnyChannel::new("B", FlatSamples::F32(vec![0.25; r.len()])),
        ]
    };
    s.put("exr-rgb-tiled-piz.exr", &exr_bytes(vec![exr_layer(w, h, None, tiles(Z::PIZ), rgb(&hv))]));
    let mut rgba = rgb(&hv);
    rgba.push(AnyChannel::new("A", half(&vec![1.0; w * h])));
    s.put("exr-rgba-tiled-pxr24.exr", &exr_bytes(vec![exr_layer(w, h, None, tiles(Z::PXR24), rgba)]));
    s.put("exr-rgb-b44.exr", &exr_bytes(vec![exr_layer(w, h, None, scan(Z::B44), rgb(&hv))]));
    // Two named layers: channels "diffuse.R" … and a height layer.
    let diffuse = exr_layer(w, h, Some("diffuse"), scan(Z::ZIP1), rgb(&hv));
    let bump = exr_layer(w, h, Some("bump"), scan(Z::RLE), vec![AnyChannel::new("Y", FlatSamples::F32(hv.clone()))]);
    s.put("exr-two-layers.exr", &exr_bytes(vec![diffuse, bump]));

    // Mip levels, tiled: the reader takes the largest.
    let rounding = exr::math::RoundingMode::Down;
    let levels: Vec<FlatSamples> =
        exr::meta::mip_map_levels(rounding, Vec2(w, h)).map(|(_, size)| half(&heights(size.0, size.1))).collect();
    let mip = AnyChannel::new("Y", Levels::Mip { level_data: levels, rounding_mode: rounding });
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        tiles(Z::ZIP1),
        AnyChannels::sort(SmallVec::from_vec(vec![mip])),
    );
    let mut out = Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut out).expect("mip exr");
    s.put("exr-mip-tiled.exr", &out.into_inner());
}

// ---------------------------------------------------------------------------
// TIFF: the gray layouts read by the `tiff` crate directly, and the ones
// left to `image`.

fn tiff<C>(w: u32, h: u32, samples: &[C::Inner], compression: tiff::encoder::Compression, big: bool) -> Vec<u8>
where
    C: tiff::encoder::colortype::ColorType,
    [C::Inner]: tiff::encoder::TiffValue,
{
    let mut out = Cursor::new(Vec::new());
    if big {
        tiff::encoder::TiffEncoder::new_big(&mut out)
            .expect("bigtiff")
            .write_image::<C>(w, h, samples)
            .expect("bigtiff");
    } else {
        tiff::encoder::TiffEncoder::new(&mut out)
            .expect("tiff")
            .with_compression(compression)
            .write_image::<C>(w, h, samples)
            .expect("tiff");
    }
    out.into_inner()
}

fn tiffs(s: &mut Seeds) {
    use tiff::encoder::Compression as Z;
    use tiff::encoder::colortype as c;
    let (w, h) = (6u32, 5u32);
    let (wu, hu) = (w as usize, h as usize);
    let f: Vec<f32> = heights(wu, hu);
    s.put_with_tails("tiff-gray-f32.tif", &tiff::<c::Gray32Float>(w, h, &f, Z::Uncompressed, false), &[[0x10, 0x9c]]);
    s.put("tiff-gray-f32-lzw.tif", &tiff::<c::Gray32Float>(w, h, &f, Z::Lzw, false));
    let d: Vec<f64> = f.iter().map(|&v| f64::from(v) * 50.0).collect();
    s.put("tiff-gray-f64-deflate.tif", &tiff::<c::Gray64Float>(w, h, &d, Z::Deflate(Default::default()), false));
    let u16s: Vec<u16> = ints(wu, hu, 16).iter().map(|&v| v as u16).collect();
    s.put("tiff-gray-u16.tif", &tiff::<c::Gray16>(w, h, &u16s, Z::Uncompressed, false));
    s.put("tiff-gray-u16-packbits.tif", &tiff::<c::Gray16>(w, h, &u16s, Z::Packbits, false));
    let u8s: Vec<u8> = ints(wu, hu, 8).iter().map(|&v| v as u8).collect();
    s.put("tiff-gray-u8.tif", &tiff::<c::Gray8>(w, h, &u8s, Z::Uncompressed, false));
    let u32s: Vec<u32> = ints(wu, hu, 32);
    s.put("tiff-gray-u32.tif", &tiff::<c::Gray32>(w, h, &u32s, Z::Uncompressed, false));
    let u64s: Vec<u64> = u32s.iter().map(|&v| u64::from(v) << 32).collect();
    s.put("tiff-gray-u64-big.tif", &tiff::<c::Gray64>(w, h, &u64s, Z::Uncompressed, true));
    let i8s: Vec<i8> = u8s.iter().map(|&v| (i16::from(v) - 128) as i8).collect();
    s.put("tiff-gray-i8.tif", &tiff::<c::GrayI8>(w, h, &i8s, Z::Uncompressed, false));
    let i16s: Vec<i16> = u16s.iter().map(|&v| (i32::from(v) - 32768) as i16).collect();
    s.put("tiff-gray-i16.tif", &tiff::<c::GrayI16>(w, h, &i16s, Z::Uncompressed, false));
    let i32s: Vec<i32> = u32s.iter().map(|&v| (i64::from(v) - (1 << 31)) as i32).collect();
    s.put("tiff-gray-i32.tif", &tiff::<c::GrayI32>(w, h, &i32s, Z::Uncompressed, false));
    let i64s: Vec<i64> = i32s.iter().map(|&v| i64::from(v) << 32).collect();
    s.put("tiff-gray-i64.tif", &tiff::<c::GrayI64>(w, h, &i64s, Z::Uncompressed, false));
    s.put("tiff-rgb8.tif", &tiff::<c::RGB8>(w, h, &rgb8(wu, hu, false), Z::Uncompressed, false));
    let rgbf: Vec<f32> = rgb8(wu, hu, false).iter().map(|&v| f32::from(v) / 255.0).collect();
    s.put("tiff-rgb-f32.tif", &tiff::<c::RGB32Float>(w, h, &rgbf, Z::Uncompressed, false));
}

// ---------------------------------------------------------------------------
// Everything else `image` reads, through its own encoders.

fn encoded(format: ImageFormat, w: usize, h: usize, color: ExtendedColorType, buf: &[u8]) -> Vec<u8> {
    use image::codecs::*;
    let mut out = Vec::new();
    let (w, h) = (w as u32, h as u32);
    match format {
        ImageFormat::Jpeg => jpeg::JpegEncoder::new_with_quality(&mut out, 90).write_image(buf, w, h, color),
        ImageFormat::Bmp => bmp::BmpEncoder::new(&mut out).write_image(buf, w, h, color),
        ImageFormat::Tga => tga::TgaEncoder::new(&mut out).write_image(buf, w, h, color),
        ImageFormat::WebP => webp::WebPEncoder::new_lossless(&mut out).write_image(buf, w, h, color),
        ImageFormat::Gif => gif::GifEncoder::new(&mut out).write_image(buf, w, h, color),
        ImageFormat::Hdr => hdr::HdrEncoder::new(&mut out).write_image(buf, w, h, color),
        ImageFormat::Pnm => pnm::PnmEncoder::new(&mut out).write_image(buf, w, h, color),
        ImageFormat::Qoi => qoi::QoiEncoder::new(&mut out).write_image(buf, w, h, color),
        other => panic!("no seed for {other:?}"),
    }
    .expect("encode a seed");
    out
}

fn others(s: &mut Seeds) {
    use ExtendedColorType as E;
    use ImageFormat as F;
    let (w, h) = (8, 8);
    let g8: Vec<u8> = ints(w, h, 8).iter().map(|&v| v as u8).collect();
    let rgb = rgb8(w, h, false);
    let rgba = rgb8(w, h, true);
    s.put_with_tails("jpeg-gray.jpg", &encoded(F::Jpeg, w, h, E::L8, &g8), &[[0x58, 0x16]]);
    s.put("jpeg-rgb.jpg", &encoded(F::Jpeg, w, h, E::Rgb8, &rgb));
    // 16×16 with 4:2:0 chroma: more than one MCU.
    let (jw, jh) = (16, 16);
    s.put("jpeg-rgb-16.jpg", &encoded(F::Jpeg, jw, jh, E::Rgb8, &rgb8(jw, jh, false)));
    s.put("bmp-rgb.bmp", &encoded(F::Bmp, w, h, E::Rgb8, &rgb));
    s.put("bmp-rgba.bmp", &encoded(F::Bmp, w, h, E::Rgba8, &rgba));
    s.put("bmp-gray.bmp", &encoded(F::Bmp, w, h, E::L8, &g8));
    s.put("tga-gray.tga", &encoded(F::Tga, w, h, E::L8, &g8));
    s.put("tga-rgb.tga", &encoded(F::Tga, w, h, E::Rgb8, &rgb));
    s.put("tga-rgba.tga", &encoded(F::Tga, w, h, E::Rgba8, &rgba));
    s.put("webp-rgba-lossless.webp", &encoded(F::WebP, w, h, E::Rgba8, &rgba));
    s.put("gif-rgba.gif", &encoded(F::Gif, w, h, E::Rgba8, &rgba));
    let rgbf: Vec<u8> = rgb.iter().flat_map(|&v| (f32::from(v) / 64.0).to_ne_bytes()).collect();
    s.put("hdr-rgb.hdr", &encoded(F::Hdr, w, h, E::Rgb32F, &rgbf));
    s.put("pnm-gray.pgm", &encoded(F::Pnm, w, h, E::L8, &g8));
    s.put("pnm-rgb.ppm", &encoded(F::Pnm, w, h, E::Rgb8, &rgb));
    let g16: Vec<u8> = ints(w, h, 16).iter().flat_map(|&v| (v as u16).to_ne_bytes()).collect();
    s.put("pnm-gray16.pgm", &encoded(F::Pnm, w, h, E::L16, &g16));
    s.put("qoi-rgba.qoi", &encoded(F::Qoi, w, h, E::Rgba8, &rgba));
}

// ---------------------------------------------------------------------------
// The seeds of the targets with options in more trailing bytes: each is a
// payload with its options appended (or, for RAW and arrays, whose every
// byte is a sample, the options as its last bytes).

/// `k` bytes that [`normalfit_fuzz::Pick`] reads back as these choices,
/// in order: (value, out of n).
fn options(k: usize, choices: &[(usize, usize)]) -> Vec<u8> {
    let (mut v, mut base) = (0u128, 1u128);
    for &(c, n) in choices {
        assert!(c < n, "choice {c} of {n}");
        v += c as u128 * base;
        base *= n as u128;
    }
    assert!(v < 1u128 << (8 * k), "the choices need more than {k} bytes");
    v.to_le_bytes()[..k].to_vec()
}

fn with(mut payload: Vec<u8>, tail: &[u8]) -> Vec<u8> {
    payload.extend_from_slice(tail);
    payload
}

/// A GeoTIFF tag's value.
enum Geo {
    D(Vec<f64>),
    S(Vec<u16>),
    A(&'static str),
}

fn geotiff<C>(w: u32, h: u32, samples: &[C::Inner], tags: &[(u16, Geo)]) -> Vec<u8>
where
    C: tiff::encoder::colortype::ColorType,
    [C::Inner]: tiff::encoder::TiffValue,
{
    let mut out = Cursor::new(Vec::new());
    let mut enc = tiff::encoder::TiffEncoder::new(&mut out).expect("tiff");
    let mut image = enc.new_image::<C>(w, h).expect("tiff image");
    for (code, value) in tags {
        let tag = tiff::tags::Tag::Unknown(*code);
        match value {
            Geo::D(d) => image.encoder().write_tag(tag, &d[..]),
            Geo::S(s) => image.encoder().write_tag(tag, &s[..]),
            Geo::A(a) => image.encoder().write_tag(tag, *a),
        }
        .expect("a GeoTIFF tag");
    }
    image.write_data(samples).expect("tiff data");
    out.into_inner()
}

/// geotiff_tags: nodata tag (2), band (4), output (3), sun (3), then the
/// fit (patch 3, borders 3 × 3, fit 2, convention 2, invert 2, gain 3).
fn geo_options(nodata_tag: bool, band: usize, format: usize, patch: usize) -> Vec<u8> {
    let c = [
        (usize::from(nodata_tag), 2),
        (band, 4),
        (format, 3),
        (format % 3, 3),
        (patch, 3),
        (band % 3, 3),
        (format, 3),
        (0, 2),
        (band % 2, 2),
        (0, 2),
        (patch % 3, 3),
    ];
    options(4, &c)
}

fn geotiffs(s: &mut Seeds) {
    use Geo::{A, D, S};
    use tiff::encoder::colortype as c;
    let (w, h) = (6u32, 5u32);
    let (wu, hu) = (w as usize, h as usize);
    let metres: Vec<f32> = heights(wu, hu).iter().map(|v| 200.0 + 150.0 * v).collect();
    let i16s: Vec<i16> = metres.iter().map(|&v| v as i16).collect();
    let u16s: Vec<u16> = ints(wu, hu, 16).iter().map(|&v| v as u16).collect();
    let keys = |k: &[[u16; 2]]| {
        let mut d = vec![1, 1, 0, k.len() as u16];
        for [id, v] in k {
            d.extend([*id, 0, 1, *v]);
        }
        S(d)
    };
    let utm = || [(33550, D(vec![30.0, 30.0, 0.0])), (33922, D(vec![0.0, 0.0, 0.0, 500_000.0, 4_600_000.0, 0.0]))];
    let [sc, tp] = utm();
    let proj =
        geotiff::<c::Gray32Float>(w, h, &metres, &[sc, tp, (34735, keys(&[[1024, 1], [1025, 1], [3072, 32633]]))]);
    s.put("utm-f32.tif", &with(proj.clone(), &geo_options(true, 0, 0, 0)));
    s.put("utm-f32-tiff.tif", &with(proj.clone(), &geo_options(true, 0, 1, 1)));
    s.put("utm-f32-exr.tif", &with(proj, &geo_options(false, 1, 2, 2)));
    let [sc, tp] = utm();
    let feet = keys(&[[1024, 1], [3072, 2263], [3076, 9002], [4096, 5703], [4099, 9002]]);
    s.put(
        "feet-i16.tif",
        &with(geotiff::<c::GrayI16>(w, h, &i16s, &[sc, tp, (34735, feet)]), &geo_options(true, 0, 1, 0)),
    );
    let arc = 1.0 / 3600.0;
    let geo = |lat: f64, unit: Option<u16>, point: bool| {
        let mut k = vec![[1024, 2], [2048, 4326]];
        if point {
            k.push([1025, 2]);
        }
        if let Some(u) = unit {
            k.push([2054, u]);
        }
        [(33550, D(vec![arc, arc, 0.0])), (33922, D(vec![0.0, 0.0, 0.0, 10.0, lat, 0.0])), (34735, keys(&k))]
    };
    let mut holes = metres.clone();
    holes[7] = f32::NAN;
    let [a, b, k] = geo(46.0, None, false);
    s.put(
        "geographic-nan.tif",
        &with(geotiff::<c::Gray32Float>(w, h, &holes, &[a, b, k, (42113, A("nan"))]), &geo_options(true, 0, 0, 1)),
    );
    let [a, b, k] = geo(-89.99, Some(9102), true);
    s.put(
        "geographic-pole-point.tif",
        &with(geotiff::<c::Gray32Float>(w, h, &metres, &[a, b, k]), &geo_options(true, 0, 1, 2)),
    );
    let [_, b, k] = geo(0.5, Some(9101), false);
    let radians = (33550, D(vec![1e-6, 1e-6, 0.0]));
    s.put(
        "geographic-radians.tif",
        &with(geotiff::<c::Gray32Float>(w, h, &metres, &[radians, b, k]), &geo_options(true, 0, 2, 0)),
    );
    let m = vec![2.0, 0.0, 0.0, 100.0, 0.0, -3.0, 0.0, 200.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    s.put(
        "transform-f32.tif",
        &with(
            geotiff::<c::Gray32Float>(w, h, &metres, &[(34264, D(m)), (34735, keys(&[[1024, 1]]))]),
            &geo_options(true, 0, 1, 1),
        ),
    );
    let rotated = vec![2.0, 0.5, 0.0, 100.0, 0.5, -3.0, 0.0, 200.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    s.put(
        "rotated-f32.tif",
        &with(geotiff::<c::Gray32Float>(w, h, &metres, &[(34264, D(rotated))]), &geo_options(true, 0, 0, 0)),
    );
    let mut dem = i16s.clone();
    dem[3] = -9999;
    dem[20] = -9999;
    let [sc, tp] = utm();
    s.put(
        "nodata-i16.tif",
        &with(
            geotiff::<c::GrayI16>(w, h, &dem, &[sc, tp, (34735, keys(&[[1024, 1]])), (42113, A("-9999"))]),
            &geo_options(true, 0, 1, 0),
        ),
    );
    s.put(
        "two-value-scale-u16.tif",
        &with(
            geotiff::<c::Gray16>(w, h, &u16s, &[(33550, D(vec![10.0, 10.0])), (33922, D(vec![0.0; 6]))]),
            &geo_options(true, 0, 0, 2),
        ),
    );
    let [sc, tp] = utm();
    s.put(
        "geocentric.tif",
        &with(
            geotiff::<c::Gray32Float>(w, h, &metres, &[sc, tp, (34735, keys(&[[1024, 3]]))]),
            &geo_options(true, 0, 0, 0),
        ),
    );
    let [sc, tp] = utm();
    let mut citation = vec![1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 32767, 3073, 34737, 9, 0];
    citation.extend([3074, 34736, 1, 0]);
    citation[3] = 4;
    s.put(
        "user-defined.tif",
        &with(
            geotiff::<c::Gray32Float>(
                w,
                h,
                &metres,
                &[sc, tp, (34735, S(citation)), (34736, D(vec![0.9996])), (34737, A("Local TM|"))],
            ),
            &geo_options(false, 0, 1, 0),
        ),
    );
    let [sc, tp] = utm();
    let rgb: Vec<f32> = metres.iter().flat_map(|&v| [v, v * 0.5, 1.0]).collect();
    s.put(
        "three-bands-f32.tif",
        &with(
            geotiff::<c::RGB32Float>(w, h, &rgb, &[sc, tp, (34735, keys(&[[1024, 1]]))]),
            &geo_options(true, 3, 0, 0),
        ),
    );
    let [sc, tp] = utm();
    s.put(
        "vertical-unknown-u16.tif",
        &with(
            geotiff::<c::Gray16>(w, h, &u16s, &[sc, tp, (34735, keys(&[[1024, 1], [4099, 9999]]))]),
            &geo_options(true, 0, 0, 1),
        ),
    );
}

/// raw_sizes: bits (8), size (4: none, a width twice, huge), its values,
/// order (2), texel limit (4), extension (4), then the fit.
fn raw_options(bits: usize, size: &[(usize, usize)], order: usize, limit: usize, ext: usize) -> Vec<u8> {
    let mut c = vec![(bits, 8)];
    c.extend_from_slice(size);
    c.extend([
        (order, 2),
        (limit, 4),
        (ext, 4),
        (bits % 3, 3),
        (order, 3),
        (ext % 3, 3),
        (0, 2),
        (order, 2),
        (0, 2),
        (0, 2),
    ]);
    options(8, &c)
}

fn raws(s: &mut Seeds) {
    // Samples of the surface, `len` bytes, the options their last 8.
    let raw = |len: usize, tail: Vec<u8>| {
        let mut v: Vec<u8> = ints(len, 1, 8).iter().map(|&v| v as u8).collect();
        v.truncate(len - tail.len());
        with(v, &tail)
    };
    // bits: None, 8, 16, None, 0, 12, 32, 255; sizes: HUGE's indices.
    s.put("square8.raw", &raw(64, raw_options(0, &[(0, 4)], 0, 0, 0)));
    s.put("square16-be.raw", &raw(128, raw_options(2, &[(0, 4)], 1, 0, 2)));
    s.put("sized-6x5-r8.raw", &raw(30, raw_options(1, &[(1, 4), (5, 64), (0, 2)], 0, 0, 1)));
    s.put("sized-10x4-16.raw", &raw(80, raw_options(2, &[(2, 4), (9, 64), (0, 2)], 0, 1, 3)));
    s.put("sized-short.raw", &raw(45, raw_options(0, &[(1, 4), (7, 64), (1, 2)], 1, 3, 0)));
    s.put("huge-2e62x2.raw", &raw(32, raw_options(2, &[(3, 4), (4, 8), (2, 8)], 0, 3, 0)));
    s.put("huge-max-x1.raw", &raw(32, raw_options(0, &[(3, 4), (7, 8), (1, 8)], 0, 3, 3)));
    s.put("huge-2e31x2e32.raw", &raw(32, raw_options(1, &[(3, 4), (2, 8), (3, 8)], 1, 2, 0)));
    s.put("zero-width.raw", &raw(32, raw_options(0, &[(3, 4), (0, 8), (1, 8)], 0, 0, 0)));
    s.put("bits12.raw", &raw(36, raw_options(5, &[(0, 4)], 0, 0, 0)));
    s.put("bits0.raw", &raw(16, raw_options(4, &[(1, 4), (3, 64), (0, 2)], 0, 0, 3)));
    let mut text = b"16\xc3\x971".to_vec();
    text.extend(vec![7u8; 11]);
    s.put("text-size.raw", &with(text, &raw_options(1, &[(2, 4), (15, 64), (0, 2)], 0, 0, 3)));
}

/// rgb_packed: packing (2), pixel size (4), output (3), then the fit.
fn packed_options(packing: usize, pixel: usize, format: usize) -> Vec<u8> {
    options(
        3,
        &[
            (packing, 2),
            (pixel, 4),
            (format, 3),
            (pixel % 3, 3),
            (format, 3),
            (packing, 3),
            (0, 2),
            (0, 2),
            (0, 2),
            (pixel % 3, 3),
        ],
    )
}

fn packed_tiles(s: &mut Seeds) {
    use png::{BitDepth as D, ColorType as C};
    let (w, h) = (8usize, 8usize);
    let metres: Vec<f64> = heights(w, h).iter().map(|&v| 300.0 + 1200.0 * f64::from(v)).collect();
    let terrain_rgb: Vec<[u8; 3]> = metres
        .iter()
        .map(|m| {
            let v = ((m + 10000.0) * 10.0).round() as u32;
            [(v >> 16) as u8, (v >> 8) as u8, v as u8]
        })
        .collect();
    let terrarium: Vec<[u8; 3]> = metres
        .iter()
        .map(|m| {
            let v = m + 32768.0;
            [(v / 256.0) as u8, (v as u32 % 256) as u8, ((v.fract()) * 256.0) as u8]
        })
        .collect();
    let flat = |t: &[[u8; 3]], alpha: bool| -> Vec<u8> {
        t.iter().flat_map(|p| if alpha { vec![p[0], p[1], p[2], 255] } else { p.to_vec() }).collect()
    };
    let (w32, h32) = (w as u32, h as u32);
    let tile = png(w32, h32, C::Rgb, D::Eight, &flat(&terrain_rgb, false), |_| {});
    s.put("terrain-rgb.png", &with(tile.clone(), &packed_options(0, 0, 0)));
    s.put("terrain-rgb-exr.png", &with(tile.clone(), &packed_options(0, 1, 1)));
    s.put("terrain-rgb-as-terrarium.png", &with(tile, &packed_options(1, 2, 2)));
    let rgba = png(w32, h32, C::Rgba, D::Eight, &flat(&terrain_rgb, true), |_| {});
    s.put("terrain-rgba.png", &with(rgba, &packed_options(0, 3, 0)));
    let tile = png(w32, h32, C::Rgb, D::Eight, &flat(&terrarium, false), |_| {});
    s.put("terrarium.png", &with(tile, &packed_options(1, 0, 0)));
    let webp = encoded(ImageFormat::WebP, w, h, ExtendedColorType::Rgba8, &flat(&terrarium, true));
    s.put("terrarium-lossless.webp", &with(webp, &packed_options(1, 1, 2)));
    let gray: Vec<u8> = ints(w, h, 8).iter().map(|&v| v as u8).collect();
    s.put("gray.png", &with(png(w32, h32, C::Grayscale, D::Eight, &gray, |_| {}), &packed_options(0, 0, 0)));
    let rgb16: Vec<u8> = flat(&terrain_rgb, false).iter().flat_map(|&v| [v, 0]).collect();
    s.put("rgb16.png", &with(png(w32, h32, C::Rgb, D::Sixteen, &rgb16, |_| {}), &packed_options(0, 0, 0)));
    let palette: Vec<u8> = terrarium.iter().take(16).flat_map(|p| p.to_vec()).collect();
    let idx: Vec<u8> = (0..w * h).map(|k| (k % 16) as u8).collect();
    s.put(
        "palette.png",
        &with(png(w32, h32, C::Indexed, D::Eight, &idx, |e| e.set_palette(palette)), &packed_options(1, 0, 1)),
    );
    let jpeg = encoded(ImageFormat::Jpeg, w, h, ExtendedColorType::Rgb8, &flat(&terrain_rgb, false));
    s.put("terrain-rgb.jpg", &with(jpeg, &packed_options(0, 0, 0)));
}

/// inverse: kind (4: f32, f64, u8, u16), width − 1 (24), model (3),
/// convention (3), step (4), then the fit (gain of 6).
fn inverse_options(kind: usize, w: usize, model: usize, convention: usize, step: usize, fit: [usize; 7]) -> Vec<u8> {
    let [patch, bx, by, f, conv, invert, gain] = fit;
    let c = [
        (kind, 4),
        (w - 1, 24),
        (model, 3),
        (convention, 3),
        (step, 4),
        (patch, 3),
        (bx, 3),
        (by, 3),
        (f, 2),
        (conv, 2),
        (invert, 2),
        (gain, 6),
    ];
    options(6, &c)
}

fn normal_maps(s: &mut Seeds) {
    use normalfit::{Border, Borders, Convention, Fit, Options};
    let (w, h) = (8usize, 6usize);
    let surface: Vec<f32> = heights(w, h).iter().map(|v| 3.0 * v).collect();
    let modes = [Border::Wrap, Border::Clamp, Border::Mirror];
    let made = |fit: [usize; 7]| {
        let [patch, bx, by, f, conv, invert, _] = fit;
        let opts = Options::new()
            .with_patch([3, 5, 9][patch])
            .with_borders(Borders { x: modes[bx], y: modes[by] })
            .with_fit([Fit::Orthogonal, Fit::Vertical][f])
            .with_convention([Convention::OpenGl, Convention::DirectX][conv])
            .with_invert(invert == 1);
        normalfit::normals(&surface, w, h, &opts).expect("the seed surface fits")
    };
    let encode = |kind: usize, n: &[[f32; 3]]| -> Vec<u8> {
        n.iter()
            .flatten()
            .flat_map(|&c| match kind {
                0 => c.to_le_bytes().to_vec(),
                1 => f64::from(c).to_le_bytes().to_vec(),
                2 => vec![((c + 1.0) * 127.5).round() as u8],
                _ => (((c + 1.0) * 32767.5).round() as u16).to_le_bytes().to_vec(),
            })
            .collect()
    };
    let mut put = |name: &str, kind: usize, model: usize, convention: usize, step: usize, fit: [usize; 7]| {
        let n = made(fit);
        s.put(name, &with(encode(kind, &n), &inverse_options(kind, w, model, convention, step, fit)));
    };
    put("f32-ortho-wrap.bin", 0, 0, 0, 0, [0, 0, 0, 0, 0, 0, 0]);
    put("f32-vertical-clamp5-dx.bin", 0, 0, 1, 1, [1, 1, 1, 1, 1, 0, 1]);
    put("f64-generic-mirror.bin", 1, 2, 0, 1, [0, 2, 2, 1, 0, 0, 0]);
    put("u8-auto-9.bin", 2, 0, 2, 0, [2, 2, 0, 0, 0, 1, 3]);
    put("u16-step-clamp.bin", 3, 0, 0, 2, [0, 1, 2, 0, 0, 0, 2]);
    put("u8-ortho-clamp3.bin", 2, 1, 0, 0, [0, 1, 1, 0, 0, 0, 0]);
    put("f32-tiny-gain.bin", 0, 0, 0, 0, [0, 0, 0, 1, 0, 0, 4]);
    put("f32-huge-gain.bin", 0, 0, 0, 3, [0, 2, 0, 0, 0, 0, 5]);
    // Texels without a slope: facing down, NaN, zero.
    let mut n = made([0; 7]);
    n[3] = [0.0, 0.0, -1.0];
    n[10] = [f32::NAN, 0.0, 1.0];
    n[17] = [0.0; 3];
    s.put("f32-bad-texels.bin", &with(encode(0, &n), &inverse_options(0, w, 0, 0, 0, [0; 7])));
    // One column: the same normals read 1 wide.
    let n = made([0; 7]);
    s.put("f32-one-column.bin", &with(encode(0, &n), &inverse_options(0, 1, 0, 0, 0, [1, 2, 1, 0, 0, 0, 0])));
}

/// python_entry: dtype (4), width (33), channels (4), patch (8), fit (2),
/// convention (2), borders (4 × 4), scale (8), relief (4), nodata (4),
/// pixel size (8), output (3), residual (2), holes (2), window (8, 8, 8,
/// 8), threshold (5), kind (3), light (4), tile (2).
fn array_options(dtype: usize, w: usize, c: [usize; 20]) -> Vec<u8> {
    let n = [4, 8, 2, 2, 4, 4, 8, 4, 4, 8, 3, 2, 2, 8, 8, 8, 8, 5, 3, 4];
    let mut choices = vec![(dtype, 4), (w, 33)];
    choices.extend(c.iter().zip(n).map(|(&c, n)| (c, n)));
    choices.push((0, 2));
    options(8, &choices)
}

fn arrays(s: &mut Seeds) {
    let (w, h) = (12usize, 8usize);
    let surface = heights(w, h);
    let bytes = |dtype: usize| -> Vec<u8> {
        surface
            .iter()
            .flat_map(|&v| match dtype {
                0 => vec![(v * 255.0) as u8],
                1 => ((v * 65535.0) as u16).to_le_bytes().to_vec(),
                2 => (200.0 + 50.0 * v).to_le_bytes().to_vec(),
                _ => (f64::from(v) * 7.0).to_le_bytes().to_vec(),
            })
            .collect()
    };
    let mut put = |name: &str, dtype: usize, c: [usize; 20]| {
        let mut b = bytes(dtype);
        let tail = array_options(dtype, w, c);
        let keep = b.len() - tail.len();
        b.truncate(keep);
        s.put(name, &with(b, &tail));
    };
    //                          ch patch fit cv bx by sc rl nd px out res holes ox oy ww wh thr kind light
    put("u8-defaults.bin", 0, [0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 0, 2, 1, 4, 3, 0, 0, 0]);
    put("u16-auto-borders.bin", 1, [0, 1, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 0, 0, 7, 7, 0, 1, 1]);
    put("f32-map-units.bin", 2, [0, 0, 0, 1, 2, 3, 1, 0, 0, 3, 0, 0, 0, 3, 2, 5, 4, 0, 1, 2]);
    put("f32-nodata-holes.bin", 2, [0, 2, 0, 0, 3, 3, 0, 2, 2, 0, 0, 1, 1, 1, 1, 6, 5, 1, 1, 0]);
    put("f64-relief.bin", 3, [2, 0, 1, 0, 1, 2, 0, 2, 0, 2, 2, 0, 0, 0, 0, 3, 3, 2, 2, 3]);
    put("u8-rgb-normal.bin", 0, [2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 0, 2, 0]);
    put("u16-patch1023.bin", 1, [0, 7, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    put("f32-bad-options.bin", 2, [1, 5, 0, 0, 1, 1, 4, 2, 0, 5, 0, 0, 0, 0, 0, 0, 0, 3, 0, 3]);
    put("f64-pixel-extremes.bin", 3, [3, 1, 1, 1, 2, 1, 2, 0, 3, 6, 0, 1, 0, 4, 4, 2, 2, 4, 0, 1]);
    put("f32-scale-1e31.bin", 2, [0, 0, 0, 0, 1, 1, 6, 0, 0, 7, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0]);
}

fn main() {
    let dir = std::env::args_os().nth(1).map_or_else(|| PathBuf::from("seeds"), PathBuf::from);
    std::fs::create_dir_all(&dir).expect("create the seed folder");
    let mut seeds = Seeds { dir: dir.clone(), total: 0 };
    pngs(&mut seeds);
    exrs(&mut seeds);
    tiffs(&mut seeds);
    others(&mut seeds);
    let count = std::fs::read_dir(&dir)
        .map(|d| d.filter(|e| e.as_ref().is_ok_and(|e| e.path().is_file())).count())
        .unwrap_or(0);
    println!("{count} seeds, {} bytes, in {}", seeds.total, Path::new(&dir).display());
    type Maker = fn(&mut Seeds);
    let targets: [(&str, Maker); 5] = [
        ("geotiff_tags", geotiffs),
        ("raw_sizes", raws),
        ("rgb_packed", packed_tiles),
        ("inverse", normal_maps),
        ("python_entry", arrays),
    ];
    for (target, make) in targets {
        let sub = dir.join(target);
        std::fs::create_dir_all(&sub).expect("create a target's seed folder");
        let mut seeds = Seeds { dir: sub.clone(), total: 0 };
        make(&mut seeds);
        let count = std::fs::read_dir(&sub).map(|d| d.count()).unwrap_or(0);
        println!("{count} seeds, {} bytes, in {}", seeds.total, sub.display());
    }
}
