//! Hostile input: a corpus of broken, forged and hostile files, generated
//! here from valid ones broken precisely (a CRC, a header field, a cut),
//! each run through the binary with a time limit: `convert` alone, from
//! standard input and in a batch between good files; `tiling` alone and in
//! a batch.
//!
//! What every case must give (SPEC §4, docs/bad-input.md): exit code 2,
//! not a signal (no abort, no kill); exactly one line on standard error,
//! `normalfit: <file>: <reason>`, whose reason says what is wrong; no
//! output and no temporary file; and the good files of the batch
//! converted (or checked) as if the bad one were not there.
//!
//! `cargo test --test integration hostile:: -- --nocapture` prints the corpus and the
//! message each case gives.

use crate::corpus;

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use corpus::*;
use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec, Vec2, WritableImage,
};
use image::ImageEncoder;

/// One bad input.
struct Case {
    /// The file's name, extension included (a wrong one is part of some cases).
    name: String,
    bytes: Vec<u8>,
    /// The message must contain one of these (compared in lower case):
    /// the reason, not just "error".
    reason: &'static [&'static str],
    /// Extra arguments for every run (`--max-texels`, `--layer`).
    args: Vec<String>,
    /// Whether the batch runs apply: not when `args` would refuse the
    /// good files too (`--layer` on a PNG).
    batch: bool,
}

fn case(name: &str, bytes: Vec<u8>, reason: &'static [&'static str]) -> Case {
    Case { name: name.into(), bytes, reason, args: Vec::new(), batch: true }
}

fn with_args(mut c: Case, args: &[&str]) -> Case {
    c.args = args.iter().map(|s| s.to_string()).collect();
    c
}

const ADLER: &[&str] = &["zlib checksum (adler-32) does not match"];
const TRUNCATED: &[&str] = &["truncated", "end of file", "not enough bytes", "not have enough data"];
const TOO_LARGE: &[&str] = &["too large"];
/// A file named for another format is refused for its name; the same bytes
/// on standard input, for what is wrong inside.
const MISNAMED_OR_TRUNCATED: &[&str] =
    &["is named", "truncated", "end of file", "not enough bytes", "not have enough data"];

// ---------------------------------------------------------------------------
// The corpus

/// The PNG every PNG case starts from: 16 × 16, 8-bit gray, a gradient.
fn base_png_raw() -> Vec<u8> {
    scanlines(16, |y| (0..16).map(|x| (x * 16 + y) as u8).collect())
}

fn base_png() -> Vec<u8> {
    png_file(&ihdr(16, 16, 8, 0), &[], &fdeflate::compress_to_vec(&base_png_raw()))
}

/// The 16-bit twin of [`base_png`]: 16 × 16 gray, a gradient.
fn base_png16() -> Vec<u8> {
    let raw = scanlines(16, |y| (0..16).flat_map(|x| ((x * 4096 + y * 37) as u16).to_be_bytes()).collect());
    png_file(&ihdr(16, 16, 16, 0), &[], &fdeflate::compress_to_vec(&raw))
}

/// [`base_png`] (8 bits) or [`base_png16`] (16), Adam7-interlaced: decoded
/// whole, never streamed.
fn base_png_adam7(bits: u8) -> Vec<u8> {
    let raw = match bits {
        8 => adam7_scanlines(16, 16, |x, y| vec![(x * 16 + y) as u8]),
        _ => adam7_scanlines(16, 16, |x, y| ((x * 4096 + y * 37) as u16).to_be_bytes().to_vec()),
    };
    png_file(&ihdr_adam7(16, 16, bits, 0), &[], &fdeflate::compress_to_vec(&raw))
}

/// An 8 × 8 palette PNG of two colours.
fn base_palette_png() -> Vec<u8> {
    let raw = scanlines(8, |y| (0..8).map(|x| ((x + y) % 2) as u8).collect());
    let plte = png_chunk(b"PLTE", &[0, 0, 0, 255, 255, 255]);
    png_file(&ihdr(8, 8, 8, 3), &[plte], &fdeflate::compress_to_vec(&raw))
}

/// A zlib stream: header, then `deflate` as given, no checksum needed for
/// the errors these make.
fn zlib_raw(deflate: &[u8]) -> Vec<u8> {
    let mut out = vec![0x78, 0x01];
    out.extend(deflate);
    out.extend([0, 0, 0, 0]);
    out
}

/// A deflate stream of `len` zero bytes, compressed as it is written (never
/// held whole).
fn zeros_deflated(len: usize) -> Vec<u8> {
    let mut compressor = fdeflate::Compressor::new(Vec::new()).unwrap();
    let block = vec![0u8; 1 << 16];
    let mut left = len;
    while left > 0 {
        let n = left.min(block.len());
        compressor.write_data(&block[..n]).unwrap();
        left -= n;
    }
    compressor.finish().unwrap()
}

fn png_cases() -> Vec<Case> {
    let good = base_png();
    let ihdr_at = find_chunk(&good, b"IHDR");
    let idat_at = find_chunk(&good, b"IDAT");
    let iend_at = find_chunk(&good, b"IEND");
    let idat_len = u32::from_be_bytes(good[idat_at..idat_at + 4].try_into().unwrap()) as usize;
    let flip = |at: usize| {
        let mut b = good.clone();
        b[at] ^= 0x5a;
        b
    };
    let with_ihdr = |w: u32, h: u32, depth: u8, color: u8, zlib: &[u8]| png_file(&ihdr(w, h, depth, color), &[], zlib);
    let filtered = |filter: u8| {
        let mut raw = base_png_raw();
        raw[3 * 17] = filter; // row 3's filter byte
        png_file(&ihdr(16, 16, 8, 0), &[], &fdeflate::compress_to_vec(&raw))
    };
    let palette = base_palette_png();
    let plte_at = find_chunk(&palette, b"PLTE");
    let mut bad_plte = palette.clone();
    bad_plte[plte_at + 8 + 6 + 1] ^= 0xff; // the CRC after the 6 palette bytes

    // A stored block whose length and its complement disagree.
    let mut stored = vec![0x01];
    stored.extend(5u16.to_le_bytes());
    stored.extend(0x1234u16.to_le_bytes());
    stored.extend([0; 5]);
    let few_zeros = fdeflate::compress_to_vec(&vec![0u8; 1 << 22]);

    vec![
        case("empty.png", Vec::new(), &["file is empty"]),
        case("text.png", b"width,height\n16,16\nnot an image at all\n".to_vec(), &["not a recognised image format"]),
        case("png_signature_only.png", good[..8].to_vec(), TRUNCATED),
        case("png_cut_in_ihdr.png", good[..ihdr_at + 14].to_vec(), TRUNCATED),
        case("png_cut_in_idat.png", good[..idat_at + 8 + idat_len / 2].to_vec(), TRUNCATED),
        case("png_cut_before_iend.png", good[..iend_at].to_vec(), TRUNCATED),
        case("png_truncated_named.exr", good[..idat_at + 8 + idat_len / 2].to_vec(), MISNAMED_OR_TRUNCATED),
        case("png_bad_crc_ihdr.png", flip(ihdr_at + 8 + 13), &["crc error", "ihdr"]),
        case("png_bad_crc_idat.png", flip(idat_at + 8 + idat_len), &["crc error"]),
        case("png_bad_crc_plte.png", bad_plte, &["crc error"]),
        case("png_deflate_bad_block_type.png", with_ihdr(16, 16, 8, 0, &zlib_raw(&[0x07, 0, 0])), &["deflate"]),
        case("png_deflate_bad_zlib_header.png", with_ihdr(16, 16, 8, 0, &[0x12, 0x34, 0, 0, 0, 0]), &["zlib"]),
        case("png_deflate_stored_length_mismatch.png", with_ihdr(16, 16, 8, 0, &zlib_raw(&stored)), &["deflate"]),
        // The image data's checksum wrong and nothing else: streamed (not
        // interlaced) and decoded whole (interlaced), 8- and 16-bit, the
        // checksum in the last IDAT chunk or in one of its own, after the
        // bytes of the image's last row.
        case("png_adler32_wrong.png", png_adler_case(&good, true, false), ADLER),
        case("png_adler32_wrong_16_bit.png", png_adler_case(&base_png16(), true, false), ADLER),
        case("png_adler32_wrong_interlaced.png", png_adler_case(&base_png_adam7(8), true, false), ADLER),
        case("png_adler32_wrong_interlaced_16_bit.png", png_adler_case(&base_png_adam7(16), true, false), ADLER),
        case("png_adler32_wrong_own_idat.png", png_adler_case(&good, true, true), ADLER),
        case("png_adler32_wrong_own_idat_interlaced.png", png_adler_case(&base_png_adam7(8), true, true), ADLER),
        case("png_filter_type_5.png", filtered(5), &["filter"]),
        case("png_filter_type_255.png", filtered(255), &["filter"]),
        case("png_ihdr_100000x100000.png", with_ihdr(100_000, 100_000, 8, 0, &few_zeros), TOO_LARGE),
        case("png_width_2_pow_31.png", with_ihdr(1 << 31, 1, 8, 0, &few_zeros), &["2^31"]),
        case("png_width_2_pow_31_minus_1.png", with_ihdr((1 << 31) - 1, 1, 8, 0, &few_zeros), TOO_LARGE),
        // 65535² 16-bit RGBA would inflate to 34 GB; the header is refused
        // before a byte of it is inflated.
        case("png_bomb_65535x65535.png", with_ihdr(65535, 65535, 16, 6, &few_zeros), TOO_LARGE),
        // A complete, valid 16384² image of zeros: 268 MB from a few
        // hundred KB. Within the default limit; refused with a lower one.
        with_args(
            case(
                "png_bomb_16384x16384_with_max_texels.png",
                with_ihdr(16384, 16384, 8, 0, &zeros_deflated(16384 * 16385)),
                TOO_LARGE,
            ),
            &["--max-texels", "1000000"],
        ),
        case("png_zero_width.png", with_ihdr(0, 16, 8, 0, &few_zeros), &["zero size"]),
        case("png_zero_height.png", with_ihdr(16, 0, 8, 0, &few_zeros), &["zero size"]),
        case("png_bit_depth_7.png", with_ihdr(16, 16, 7, 0, &few_zeros), &["bit depth"]),
        case("png_color_type_5.png", with_ihdr(16, 16, 8, 5, &few_zeros), &["color type", "colour type"]),
        case("png_palette_without_plte.png", with_ihdr(8, 8, 8, 3, &few_zeros), &["palette"]),
        case(
            "png_no_idat.png",
            {
                let mut b = PNG_SIGNATURE.to_vec();
                b.extend(png_chunk(b"IHDR", &ihdr(16, 16, 8, 0)));
                b.extend(png_chunk(b"IEND", &[]));
                b
            },
            &["idat"],
        ),
        Case {
            batch: false,
            ..with_args(case("png_asked_for_a_layer.png", good.clone(), &["no layers"]), &["--layer", "height"])
        },
    ]
}

/// The EXR every hand-made EXR case starts from: 8 × 6, one float channel
/// `Y`, uncompressed scan lines.
fn base_exr_spec() -> ExrSpec {
    ExrSpec::gray(8, 6)
}

fn base_exr_plane() -> Vec<f32> {
    (0..48).map(|k| (k % 8) as f32 * 0.1 + (k / 8) as f32 * 0.05).collect()
}

fn base_exr() -> Vec<u8> {
    base_exr_spec().file(&[base_exr_plane()])
}

/// A 16 × 16 EXR written by the `exr` crate, ZIP-compressed.
fn zip_exr() -> Vec<u8> {
    let values: Vec<f32> = (0..256).map(|k| (k % 16) as f32 * 0.25).collect();
    let channel = AnyChannel::new("Y", FlatSamples::F32(values));
    let channels = AnyChannels::sort(SmallVec::from_vec(vec![channel]));
    let encoding = Encoding {
        compression: exr::compression::Compression::ZIP16,
        blocks: exr::image::Blocks::ScanLines,
        line_order: exr::meta::attribute::LineOrder::Increasing,
    };
    let layer = Layer::new(Vec2(16, 16), LayerAttributes::default(), encoding, channels);
    let mut bytes = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut bytes).unwrap();
    bytes.into_inner()
}

fn exr_cases() -> Vec<Case> {
    let good = base_exr();
    let (_, header_len) = exr_find_attribute(&good, "channels");
    let table = header_len; // 6 offsets of 8 bytes
    let first_chunk = table + 6 * 8;
    let set = |name: &str, value: &[u8]| exr_set_attribute(&good, name, value);
    let patched = |at: usize, value: &[u8]| {
        let mut b = good.clone();
        b[at..at + value.len()].copy_from_slice(value);
        b
    };
    let with_plane = |spec: ExrSpec, plane: Vec<f32>| spec.file(&[plane]);
    let mut nan = base_exr_plane();
    nan[2 * 8 + 3] = f32::NAN;
    let mut inf = base_exr_plane();
    inf[4 * 8 + 5] = f32::INFINITY;
    let mut nan_offset = base_exr_plane();
    nan_offset[8 + 2] = f32::NAN;
    let offset_window = [-5, 7, 2, 12];
    let offset_spec = ExrSpec { data_window: offset_window, display_window: offset_window, ..base_exr_spec() };
    let no_channels = ExrSpec { channels: Vec::new(), ..base_exr_spec() }.file(&[]);

    let zip = zip_exr();
    let (_, zip_header_len) = exr_find_attribute(&zip, "channels");
    let zip_chunk = u64::from_le_bytes(zip[zip_header_len..zip_header_len + 8].try_into().unwrap()) as usize;
    let mut zip_garbled = zip.clone();
    for b in &mut zip_garbled[zip_chunk + 8..zip_chunk + 24] {
        *b ^= 0xa5;
    }

    vec![
        case("text.exr", b"this is not an exr file\n".to_vec(), &["not a recognised image format"]),
        case("exr_magic_only.exr", good[..4].to_vec(), TRUNCATED),
        case("exr_cut_in_header.exr", good[..header_len / 2].to_vec(), TRUNCATED),
        case("exr_cut_in_offset_table.exr", good[..table + 12].to_vec(), TRUNCATED),
        case("exr_cut_in_pixels.exr", good[..good.len() - 10].to_vec(), TRUNCATED),
        case("exr_no_channels.exr", no_channels, &["channel"]),
        case("exr_inverted_data_window.exr", set("dataWindow", &box2i([7, 0, 0, 5])), &["data window is inverted"]),
        case(
            "exr_inverted_display_window.exr",
            set("displayWindow", &box2i([0, 5, 7, 0])),
            &["display window is inverted"],
        ),
        case("exr_huge_data_window.exr", set("dataWindow", &box2i([0, 0, 999_999_999, 999_999_999])), TOO_LARGE),
        case("exr_window_beyond_i32.exr", set("dataWindow", &box2i([i32::MIN, 0, i32::MAX, 5])), &["window"]),
        // 30000 rows of 8: under the texel limit, but an offset table of
        // 240 KB in a file of a few hundred bytes.
        case("exr_more_chunks_than_file.exr", set("dataWindow", &box2i([0, 0, 7, 29_999])), &["chunks"]),
        case("exr_unknown_compression.exr", set("compression", &[42]), &["compression"]),
        case("exr_offset_beyond_file.exr", patched(table, &(1u64 << 40).to_le_bytes()), TRUNCATED),
        case("exr_chunk_size_huge.exr", patched(first_chunk + 4, &i32::MAX.to_le_bytes()), &["block"]),
        case(
            "exr_chunk_row_outside_window.exr",
            patched(first_chunk, &1000i32.to_le_bytes()),
            &["block", "chunk", "offset", "row"],
        ),
        case("exr_zip_data_garbled.exr", zip_garbled, &["compress", "zip", "deflate", "inflat"]),
        case("exr_nan_height.exr", with_plane(base_exr_spec(), nan), &["(x 3, y 2) is nan or infinite"]),
        case("exr_infinite_height.exr", with_plane(base_exr_spec(), inf), &["(x 5, y 4) is nan or infinite"]),
        case("exr_nan_in_offset_window.exr", with_plane(offset_spec, nan_offset), &["(x 2, y 1) is nan or infinite"]),
        case("exr_truncated_named.png", good[..good.len() - 10].to_vec(), MISNAMED_OR_TRUNCATED),
        Case {
            batch: false,
            ..with_args(case("exr_missing_layer.exr", good.clone(), &["no layer nope"]), &["--layer", "nope"])
        },
        with_args(
            case("exr_over_max_texels.exr", ExrSpec::gray(16, 16).file(&[vec![0.5; 256]]), TOO_LARGE),
            &["--max-texels", "100"],
        ),
    ]
}

fn jpeg(width: u32, height: u32) -> Vec<u8> {
    let pixels: Vec<u8> = (0..width * height).map(|k| (k * 7 % 256) as u8).collect();
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new(&mut out)
        .write_image(&pixels, width, height, image::ExtendedColorType::L8)
        .unwrap();
    out
}

fn bmp(width: u32, height: u32) -> Vec<u8> {
    let pixels: Vec<u8> = (0..width * height * 3).map(|k| (k * 5 % 256) as u8).collect();
    let mut out = Vec::new();
    image::codecs::bmp::BmpEncoder::new(&mut out)
        .write_image(&pixels, width, height, image::ExtendedColorType::Rgb8)
        .unwrap();
    out
}

fn other_cases() -> Vec<Case> {
    let good_jpeg = jpeg(16, 16);
    let sof = good_jpeg.windows(2).position(|m| m == [0xff, 0xc0]).expect("a baseline SOF marker");
    let mut huge_jpeg = good_jpeg.clone();
    // SOF0: marker, length (2), precision (1), height (2), width (2).
    huge_jpeg[sof + 5..sof + 9].copy_from_slice(&[0xff, 0xff, 0xff, 0xff]);
    let good_bmp = bmp(16, 16);
    let mut huge_bmp = good_bmp.clone();
    huge_bmp[18..22].copy_from_slice(&100_000i32.to_le_bytes());
    huge_bmp[22..26].copy_from_slice(&100_000i32.to_le_bytes());
    let gray_tiff = tiff_gray(16, 16, 8, 1, &[100; 256]);
    let float_tiff = tiff_gray(16, 16, 32, 3, &[0; 1024]);
    vec![
        case("tiff_8_bit_claiming_100000x100000.tif", tiff_gray(100_000, 100_000, 8, 1, &[0; 64]), TOO_LARGE),
        case("tiff_float_claiming_100000x100000.tif", tiff_gray(100_000, 100_000, 32, 3, &[0; 64]), TOO_LARGE),
        case("tiff_truncated_strip.tif", gray_tiff[..gray_tiff.len() - 100].to_vec(), TRUNCATED),
        case("tiff_float_truncated_strip.tif", float_tiff[..float_tiff.len() - 100].to_vec(), TRUNCATED),
        case("jpeg_claiming_65535x65535.jpg", huge_jpeg, TOO_LARGE),
        case("jpeg_truncated.jpg", good_jpeg[..good_jpeg.len() / 2].to_vec(), TRUNCATED),
        case("bmp_claiming_100000x100000.bmp", huge_bmp, TOO_LARGE),
        with_args(case("jpeg_over_max_texels.jpg", good_jpeg, TOO_LARGE), &["--max-texels", "100"]),
        with_args(case("tiff_over_max_texels.tif", gray_tiff, TOO_LARGE), &["--max-texels", "100"]),
        with_args(case("bmp_over_max_texels.bmp", good_bmp, TOO_LARGE), &["--max-texels", "100"]),
    ]
}

/// GeoTIFFs whose georeferencing is broken: values that are not numbers,
/// a pixel without size, counts no GeoTIFF has. Read wrong they would
/// place texels nowhere and be copied into every output's georeferencing;
/// a forged count would reach the TIFF decoder, which allocates by it or,
/// for a text tag, prints a line of debug output of its own.
fn geotiff_cases() -> Vec<Case> {
    const SCALE: u16 = 33550;
    const TIEPOINT: u16 = 33922;
    const TRANSFORMATION: u16 = 34264;
    const KEYS: u16 = 34735;
    const ASCII_PARAMS: u16 = 34737;
    const NODATA: u16 = 42113;
    let geotiff = |tags: Vec<ExtraTag>| tiff_gray_tagged(16, 16, 32, 3, &[0; 1024], &tags);
    let scale = |s: [f64; 3]| ExtraTag::doubles(SCALE, &s);
    let tiepoint = |x: f64| ExtraTag::doubles(TIEPOINT, &[0.0, 0.0, 0.0, x, 4_000_000.0, 0.0]);
    let good_scale = || scale([10.0, 10.0, 0.0]);
    let transformation = |a: f64, e: f64, last: f64| {
        ExtraTag::doubles(
            TRANSFORMATION,
            &[a, 0.0, 0.0, 500_000.0, 0.0, e, 0.0, 4e6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, last],
        )
    };
    let keys = || ExtraTag::shorts(KEYS, &[1, 1, 0, 1, 1024, 0, 1, 1]);
    let text = |tag: u16, claimed: u32| ExtraTag { tag, kind: 2, count: claimed, bytes: b"-9999\0".to_vec() };
    vec![
        case(
            "geotiff_nan_tiepoint.tif",
            geotiff(vec![good_scale(), tiepoint(f64::NAN)]),
            &["modeltiepoint tag: value 4 of 6 is nan"],
        ),
        case(
            "geotiff_infinite_tiepoint.tif",
            geotiff(vec![good_scale(), tiepoint(f64::INFINITY)]),
            &["modeltiepoint tag: value 4 of 6 is inf"],
        ),
        case(
            "geotiff_nan_pixel_scale.tif",
            geotiff(vec![scale([f64::NAN, 10.0, 0.0]), tiepoint(5.0)]),
            &["modelpixelscale tag: value 1 of 3 is nan"],
        ),
        case(
            "geotiff_infinite_pixel_scale.tif",
            geotiff(vec![scale([10.0, f64::NEG_INFINITY, 0.0]), tiepoint(5.0)]),
            &["modelpixelscale tag: value 2 of 3 is -inf"],
        ),
        case(
            "geotiff_zero_pixel_scale.tif",
            geotiff(vec![scale([0.0, 10.0, 0.0]), tiepoint(5.0)]),
            &["modelpixelscale tag: a texel of 0 × 10 has no size"],
        ),
        case(
            "geotiff_nan_transformation.tif",
            geotiff(vec![transformation(10.0, -10.0, f64::NAN)]),
            &["modeltransformation tag: value 16 of 16 is nan"],
        ),
        case(
            "geotiff_flat_transformation.tif",
            geotiff(vec![transformation(10.0, 0.0, 1.0)]),
            &["modeltransformation tag: it maps the raster onto a line"],
        ),
        case(
            "geotiff_tiepoint_count_2_pow_31.tif",
            geotiff(vec![good_scale(), tiepoint(5.0).claiming(i32::MAX as u32)]),
            &["modeltiepoint tag holds 2147483647 values, geotiff gives it at most 393216"],
        ),
        case(
            "geotiff_key_count_2_pow_30.tif",
            geotiff(vec![keys().claiming(1 << 30)]),
            &["geokeydirectory tag holds 1073741824 values, geotiff gives it at most 262144"],
        ),
        case(
            "geotiff_ascii_params_count_2_pow_31.tif",
            geotiff(vec![keys(), text(ASCII_PARAMS, i32::MAX as u32)]),
            &["geoasciiparams tag holds 2147483647 values, geotiff gives it at most 65535"],
        ),
        // A header describing a million float texels over a strip of 1 KiB:
        // refused before the 4 MB are allocated (the fuzzers' 6.8 GB case).
        case(
            "tiff_header_past_its_strip.tif",
            tiff_gray_tagged(1000, 1000, 32, 3, &[0; 1024], &[]),
            &["tiff strips or tiles of 1024 bytes in all cannot hold the 4000000 bytes of samples"],
        ),
        case(
            "geotiff_nodata_count_2_pow_31.tif",
            geotiff(vec![text(NODATA, i32::MAX as u32)]),
            &["gdal_nodata tag holds 2147483647 values, geotiff gives it at most 1024"],
        ),
    ]
}

/// A lossy WebP: the 1×1 VP8 image browsers are probed with.
const LOSSY_WEBP: &[u8] = &[
    0x52, 0x49, 0x46, 0x46, 0x22, 0x00, 0x00, 0x00, 0x57, 0x45, 0x42, 0x50, 0x56, 0x50, 0x38, 0x20, 0x16, 0x00, 0x00,
    0x00, 0x30, 0x01, 0x00, 0x9d, 0x01, 0x2a, 0x01, 0x00, 0x01, 0x00, 0x0e, 0xc0, 0xfe, 0x25, 0xa4, 0x00, 0x03, 0x70,
    0x00, 0x00, 0x00, 0x00,
];

/// Files refused for what the options ask of them; not in batches, whose
/// good files the options do not fit.
fn option_cases() -> Vec<Case> {
    vec![
        // Packed heights need exact bytes: a lossy tile is refused before
        // it is decoded.
        Case {
            batch: false,
            ..with_args(
                case("webp_lossy_decoded_as_terrarium.webp", LOSSY_WEBP.to_vec(), &["this one is lossy"]),
                &["--decode", "terrarium"],
            )
        },
        // (2^32 − 1)(2^32 + 1) texels: 16-bit samples take more bytes than
        // a 64-bit count holds, said so rather than saturated.
        Case {
            batch: false,
            ..with_args(
                case("raw_size_past_2_pow_64_bytes.raw", vec![0; 16], &["2^64 bytes or more at 16 bits"]),
                &["--size", "4294967295x4294967297"],
            )
        },
    ]
}

fn all_cases() -> Vec<Case> {
    let mut cases = png_cases();
    cases.extend(exr_cases());
    cases.extend(other_cases());
    cases.extend(geotiff_cases());
    cases.extend(option_cases());
    cases
}

// ---------------------------------------------------------------------------
// Running the cases

/// The good files each batch holds: they tile (constant), so they give no
/// warning, and the bad file's line is the only one on standard error.
struct Good {
    png: PathBuf,
    exr: PathBuf,
}

impl Good {
    fn write(dir: &Path) -> Good {
        std::fs::create_dir_all(dir).unwrap();
        let png = dir.join("good_a.png");
        std::fs::write(&png, png_gray8(8, 8, |_, _| 90)).unwrap();
        let exr = dir.join("good_b.exr");
        std::fs::write(&exr, ExrSpec::gray(8, 8).file(&[vec![0.25; 64]])).unwrap();
        Good { png, exr }
    }
}

fn os<S: AsRef<OsStr> + ?Sized>(s: &S) -> &OsStr {
    s.as_ref()
}

/// Checks that a run refused the case: exit 2 and not a signal, one line
/// on standard error naming `subject` and giving the case's reason, and
/// `other_lines` lines on standard output (the good files of a batch).
/// Returns the reason given.
fn expect_refusal(
    case: &Case,
    how: &str,
    run: &Run,
    subject: &str,
    other_lines: usize,
    problems: &mut Vec<String>,
) -> Option<String> {
    if let Some(signal) = run.signal {
        problems.push(format!("{how}: killed by signal {signal} (an abort or a crash)"));
        return None;
    }
    if run.code != Some(2) {
        problems.push(format!("{how}: exit {:?}, want 2; stderr {:?}", run.code, run.stderr));
    }
    if run.stderr.contains("panicked") || run.stderr.contains("RUST_BACKTRACE") {
        problems.push(format!("{how}: a panic: {:?}", run.stderr));
    }
    if run.stdout.lines().count() != other_lines {
        problems.push(format!("{how}: stdout {:?}", run.stdout));
    }
    let lines = run.stderr_lines();
    if lines.len() != 1 {
        problems.push(format!("{how}: want one line on stderr, got {lines:?}"));
    }
    let prefix = format!("normalfit: {subject}: ");
    let Some(line) = lines.iter().find(|l| l.starts_with(&prefix)) else {
        problems.push(format!("{how}: no line names {subject}: {lines:?}"));
        return None;
    };
    let reason = &line[prefix.len()..];
    // Words, not Rust values or 309-digit numbers (issue 32, point 6).
    let digits = reason.split(|c: char| !c.is_ascii_digit()).map(str::len).max().unwrap_or(0);
    if ["Some(", "None", "Ok(", "Err(", " { ", "::"].iter().any(|d| reason.contains(d)) || digits > 20 {
        problems.push(format!("{how}: reason {reason:?} shows a Rust value or a number of {digits} digits"));
    }
    if !case.reason.iter().any(|r| reason.to_lowercase().contains(r)) {
        problems.push(format!("{how}: reason {reason:?} says none of {:?}", case.reason));
    }
    Some(reason.to_string())
}

/// Runs one case every way; returns the message it gave and what went wrong.
fn check(case: &Case, good: &Good, root: &Path) -> (String, Vec<String>) {
    let mut problems = Vec::new();
    let mut message = String::new();
    let dir = root.join(case.name.replace('.', "_"));
    let inputs = dir.join("in");
    std::fs::create_dir_all(&inputs).unwrap();
    let path = inputs.join(&case.name);
    std::fs::write(&path, &case.bytes).unwrap();
    let extra: Vec<&OsStr> = case.args.iter().map(os).collect();
    let name = path.display().to_string();

    // convert, output beside the input: nothing may appear there.
    let mut args = vec![os("convert"), path.as_os_str()];
    args.extend(&extra);
    if let Some(line) = expect_refusal(case, "convert", &run_bin(&args, None), &name, 0, &mut problems) {
        message = line;
    }
    if files_in(&inputs) != [case.name.clone()] {
        problems.push(format!("convert left files beside the input: {:?}", files_in(&inputs)));
    }

    // tiling.
    let mut args = vec![os("tiling"), path.as_os_str()];
    args.extend(&extra);
    expect_refusal(case, "tiling", &run_bin(&args, None), &name, 0, &mut problems);

    // convert from standard input, which is decoded whole.
    let out = dir.join("stdin_out");
    std::fs::create_dir_all(&out).unwrap();
    let target = out.join("from_stdin.png");
    let mut args = vec![os("convert"), os("-"), os("-o"), target.as_os_str()];
    args.extend(&extra);
    expect_refusal(case, "convert from stdin", &run_bin(&args, Some(&path)), "<standard input>", 0, &mut problems);
    if !files_in(&out).is_empty() {
        problems.push(format!("convert from stdin left {:?}", files_in(&out)));
    }

    if case.batch {
        // convert: good, bad, good into a folder.
        let out = dir.join("batch_out");
        let mut args = vec![os("convert"), good.png.as_os_str(), path.as_os_str(), good.exr.as_os_str(), os("-o")];
        args.push(out.as_os_str());
        args.extend(&extra);
        let run = run_bin(&args, None);
        expect_refusal(case, "convert batch", &run, &name, 0, &mut problems);
        if !run.summary().is_some_and(|l| l.starts_with("normalfit: 2 converted, 0 skipped, 1 failed in ")) {
            problems.push(format!("convert batch: no summary of 2 converted and 1 failed: {:?}", run.stderr));
        }
        let written = if out.is_dir() { files_in(&out) } else { Vec::new() };
        if written != ["good_a_normal.png", "good_b_normal.exr"] {
            problems.push(format!("convert batch wrote {written:?}, want the two good outputs only"));
        } else {
            for file in &written {
                let raster = normalfit::io::read_path(&out.join(file), &normalfit::io::ReadOptions::default()).unwrap();
                let flat = ["R", "G", "B"]
                    .map(|c| raster.plane(c).map_or(f32::NAN, |p| p.data.height(0).unwrap_or(f64::NAN) as f32));
                let want: &[f32] =
                    if file.ends_with(".png") { &[128.0 / 255.0, 128.0 / 255.0, 1.0] } else { &[0.5, 0.5, 1.0] };
                if raster.width != 8 || raster.height != 8 || flat != want {
                    problems.push(format!("convert batch: {file} is not the flat 8 × 8 map: {flat:?}"));
                }
            }
        }

        // tiling: good, bad, good.
        let mut args = vec![os("tiling"), good.png.as_os_str(), path.as_os_str(), good.exr.as_os_str()];
        args.extend(&extra);
        let run = run_bin(&args, None);
        expect_refusal(case, "tiling batch", &run, &name, 2, &mut problems);
        let reported: Vec<&str> = run.stdout.lines().collect();
        let tiles =
            |p: &Path, line: Option<&&str>| line.is_some_and(|l| l.starts_with(&format!("{}: tiles", p.display())));
        if !tiles(&good.png, reported.first()) || !tiles(&good.exr, reported.get(1)) {
            problems.push(format!("tiling batch: the good files were not both reported: {reported:?}"));
        }
    }
    (message, problems)
}

#[test]
fn every_bad_input_is_refused_with_one_line_and_exit_2() {
    let cases = all_cases();
    let mut names: Vec<&str> = cases.iter().map(|c| c.name.as_str()).collect();
    names.sort();
    names.dedup();
    assert_eq!(names.len(), cases.len(), "case names are unique");

    let root = tempfile::tempdir().unwrap();
    let good = Good::write(&root.path().join("good"));
    println!("hostile corpus: {} cases", cases.len());
    let mut failures = Vec::new();
    for case in &cases {
        let (message, problems) = check(case, &good, root.path());
        println!("{:<48} {:>9} B  {message}", case.name, case.bytes.len());
        for p in problems {
            failures.push(format!("{}: {p}", case.name));
        }
    }
    assert!(failures.is_empty(), "{} problems:\n{}", failures.len(), failures.join("\n"));
}

/// Every case breaks one thing in a file that is otherwise good: the
/// files they start from convert.
#[test]
fn the_unbroken_files_convert() {
    let dir = tempfile::tempdir().unwrap();
    let bases: Vec<(&str, Vec<u8>)> = vec![
        ("base.png", base_png()),
        ("base_palette.png", base_palette_png()),
        ("base16.png", base_png16()),
        ("base_interlaced.png", base_png_adam7(8)),
        ("base_interlaced16.png", base_png_adam7(16)),
        ("base_adler32_own_idat.png", png_adler_case(&base_png(), false, true)),
        ("base_adler32_own_idat_interlaced.png", png_adler_case(&base_png_adam7(8), false, true)),
        ("base.exr", base_exr()),
        ("base_zip.exr", zip_exr()),
        ("base_offset_window.exr", {
            let w = [-5, 7, 2, 12];
            ExrSpec { data_window: w, display_window: w, ..base_exr_spec() }.file(&[base_exr_plane()])
        }),
        ("base.tif", tiff_gray(16, 16, 8, 1, &[100; 256])),
        ("base_float.tif", tiff_gray(16, 16, 32, 3, &[0; 1024])),
        ("base_geotiff.tif", {
            let tags = [
                ExtraTag::doubles(33550, &[10.0, 10.0, 0.0]),
                ExtraTag::doubles(33922, &[0.0, 0.0, 0.0, 5.0, 4_000_000.0, 0.0]),
                ExtraTag::shorts(34735, &[1, 1, 0, 1, 1024, 0, 1, 1]),
                ExtraTag { tag: 34737, kind: 2, count: 6, bytes: b"-9999\0".to_vec() },
            ];
            tiff_gray_tagged(16, 16, 32, 3, &[0; 1024], &tags)
        }),
        ("base_geotiff_transformation.tif", {
            let m = [10.0, 0.0, 0.0, 5e5, 0.0, -10.0, 0.0, 4e6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
            tiff_gray_tagged(16, 16, 32, 3, &[0; 1024], &[ExtraTag::doubles(34264, &m)])
        }),
        ("base.jpg", jpeg(16, 16)),
        ("base.bmp", bmp(16, 16)),
        ("base_bomb.png", png_file(&ihdr(1024, 1024, 8, 0), &[], &zeros_deflated(1024 * 1025))),
    ];
    for (name, bytes) in bases {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let out = dir.path().join(format!("{name}_out.png"));
        for command in
            [vec![os("convert"), path.as_os_str(), os("-o"), out.as_os_str()], vec![os("tiling"), path.as_os_str()]]
        {
            let run = run_bin(&command, None);
            assert!(matches!(run.code, Some(0 | 1)), "{name} {command:?}: {:?} {}", run.code, run.stderr);
            assert!(!run.stderr.contains("normalfit: ") || run.stderr.contains("warning"), "{name}: {}", run.stderr);
        }
    }
}
