//! Streaming OpenEXR (`ExrRows`, `convert_exr`) gives exactly what the
//! whole-image path gives: the same heights row by row, for every
//! compression, sample type and line order; and the same output file, byte
//! for byte, as fitting the whole image and calling `encode_normals`.

use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, Blocks, Compression, Encoding, FlatSamples, Image, Layer, LayerAttributes, LineOrder,
    SmallVec, WritableImage, f16,
};
use normalfit::io::{Channel, ExrDepth, Layout, ReadOptions, encode_normals, read_path};
use normalfit::pipeline::{ExrOptions, ExrRows, PngDepth, RowSource, convert_exr, convert_png_seekable};
use normalfit::{Border, Borders, FitRequest, Options, Strength};

/// Heights with detail in both directions and no symmetry.
fn field(w: usize, h: usize, seed: u32) -> Vec<f32> {
    let mut s = seed.wrapping_mul(2_654_435_761) | 1;
    (0..w * h)
        .map(|k| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            let (x, y) = ((k % w) as f32, (k / w) as f32);
            0.5 + 0.3 * (x * 0.21 + y * 0.07).sin() * (y * 0.13).cos() + 0.05 * (s >> 8) as f32 / (1 << 24) as f32
        })
        .collect()
}

/// Writes an EXR of one layer with the given channels (name, samples).
fn write_exr(
    path: &Path,
    w: usize,
    h: usize,
    compression: Compression,
    order: LineOrder,
    channels: Vec<AnyChannel<FlatSamples>>,
) {
    let encoding = Encoding { compression, blocks: Blocks::ScanLines, line_order: order };
    let channels = AnyChannels::sort(SmallVec::from_vec(channels));
    let layer = Layer::new((w, h), LayerAttributes::default(), encoding, channels);
    Image::from_layer(layer).write().to_file(path).unwrap();
}

fn streamed_rows(path: &Path, channel: Option<Channel>) -> Vec<f32> {
    let mut rows = ExrRows::open(path, &ReadOptions::default(), channel).unwrap().expect("streamable");
    let (w, h) = (rows.width(), rows.height());
    let mut out = vec![0.0f64; w * h];
    out.chunks_exact_mut(w).for_each(|row| rows.next_row(row).unwrap());
    assert!(rows.next_row(&mut vec![0.0; w]).is_err(), "a row past the end");
    assert_eq!(rows.unit(), 1.0, "EXR values are heights");
    // Exact: every value is a float sample widened, or luma that the
    // whole-image reader rounds to f32 the same way.
    out.iter().map(|&v| v as f32).collect()
}

#[test]
fn rows_equal_the_whole_image_reader_for_every_compression_type_and_order() {
    let dir = tempfile::tempdir().unwrap();
    let compressions = [
        Compression::Uncompressed,
        Compression::RLE,
        Compression::ZIP1,
        Compression::ZIP16,
        Compression::PIZ,
        Compression::PXR24,
        Compression::B44,
    ];
    for (w, h) in [(1, 1), (5, 3), (37, 61), (130, 301)] {
        let v = field(w, h, (w * 7 + h) as u32);
        let half: Vec<f16> = v.iter().map(|&x| f16::from_f32(x)).collect();
        for (k, &compression) in compressions.iter().enumerate() {
            for order in [LineOrder::Increasing, LineOrder::Decreasing] {
                let what = format!("{w}×{h} {compression:?} {order:?}");
                let path = dir.path().join(format!("y{w}x{h}-{k}-{order:?}.exr"));
                // Float gray, and half RGB read as luma.
                write_exr(&path, w, h, compression, order, vec![AnyChannel::new("Y", FlatSamples::F32(v.clone()))]);
                let whole = read_path(&path, &ReadOptions::default()).unwrap();
                assert_eq!(streamed_rows(&path, None), whole.heights(None).unwrap(), "{what} Y");

                let rgb = dir.path().join(format!("c{w}x{h}-{k}-{order:?}.exr"));
                let tint = |m: f32| FlatSamples::F16(half.iter().map(|x| f16::from_f32(x.to_f32() * m)).collect());
                let channels = vec![
                    AnyChannel::new("R", tint(1.0)),
                    AnyChannel::new("G", tint(0.5)),
                    AnyChannel::new("B", tint(0.25)),
                ];
                write_exr(&rgb, w, h, compression, order, channels);
                let whole = read_path(&rgb, &ReadOptions::default()).unwrap();
                for channel in [None, Some(Channel::G)] {
                    assert_eq!(
                        streamed_rows(&rgb, channel.clone()),
                        whole.heights(channel.clone()).unwrap(),
                        "{what} {channel:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn last_rows_are_the_image_s_last_rows() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (19, 100);
    let v = field(w, h, 3);
    let path = dir.path().join("t.exr");
    write_exr(
        &path,
        w,
        h,
        Compression::ZIP16,
        LineOrder::Increasing,
        vec![AnyChannel::new("height", FlatSamples::F32(v.clone()))],
    );
    for rows in [0, 1, 15, 16, 17, 40, 100, 250] {
        let tail = ExrRows::last_rows(&path, &ReadOptions::default(), None, rows).unwrap();
        let keep = rows.min(h);
        let tail: Vec<f32> = tail.iter().map(|&t| t as f32).collect();
        assert_eq!(tail, v[(h - keep) * w..], "{rows} rows");
    }
}

/// What the whole-image path writes: fit, map to (n + 1)/2 unless signed
/// (here, plainly), and write the values as they are.
fn whole_exr(path: &Path, opts: &Options, depth: ExrDepth, signed: bool) -> Vec<u8> {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    let (w, h) = (raster.width, raster.height);
    let heights = raster.heights(None).unwrap();
    let mut texels = vec![[0f32; 3]; w * h];
    FitRequest::new(opts).normals_into(&heights, w, h, &mut texels).unwrap();
    if !signed {
        texels.iter_mut().for_each(|t| *t = t.map(|c| (c + 1.0) * 0.5));
    }
    let mut out = std::io::Cursor::new(Vec::new());
    encode_normals(&texels, None, w, h, &as_given(depth, Layout::Rgb), &mut out).unwrap();
    out.into_inner()
}

/// An EXR encoding that writes the values given as they are.
fn as_given(depth: ExrDepth, layout: Layout) -> normalfit::io::Encoding {
    ExrOptions::new(depth).with_signed(true).with_layout(layout).into()
}

#[test]
fn exr_output_is_byte_identical_to_the_whole_image_path() {
    let dir = tempfile::tempdir().unwrap();
    for (w, h) in [(1, 1), (7, 2), (33, 47), (64, 300), (21, 700)] {
        let path = dir.path().join(format!("h{w}x{h}.exr"));
        write_exr(
            &path,
            w,
            h,
            Compression::ZIP16,
            LineOrder::Increasing,
            vec![AnyChannel::new("Y", FlatSamples::F32(field(w, h, 11)))],
        );
        for n in [3, 9, 33] {
            for y in [Border::Wrap, Border::Clamp, Border::Mirror] {
                let opts = Options::new()
                    .with_patch(n)
                    .with_borders(Borders { x: Border::Wrap, y })
                    .with_strength(Strength::Scale(20.0));
                for (depth, signed) in [(ExrDepth::Float, false), (ExrDepth::Half, false), (ExrDepth::Float, true)] {
                    let what = format!("{w}×{h} N {n} {y:?} {depth:?} signed {signed}");
                    let rows = ExrRows::open(&path, &ReadOptions::default(), None).unwrap().unwrap();
                    let tail = (y == Border::Wrap)
                        .then(|| ExrRows::last_rows(&path, &ReadOptions::default(), None, n / 2).unwrap());
                    let mut out = std::io::Cursor::new(Vec::new());
                    let format = ExrOptions::new(depth).with_signed(signed);
                    convert_exr(rows, tail.as_deref(), &opts, format, |_| {}, &mut out).unwrap();
                    assert!(out.get_ref() == &whole_exr(&path, &opts, depth, signed), "{what}");
                }
            }
        }
    }
}

/// Alpha of heights (as stored, beyond [0, 1] too), opaque alpha and
/// red-green only: the streamed file is the whole-image writer's, byte for
/// byte, and holds the channels the layout names.
#[test]
fn every_channel_layout_streams_to_the_whole_image_writer_s_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (29, 333);
    let path = dir.path().join("h.exr");
    let stored: Vec<f32> = field(w, h, 7).iter().map(|v| 4.0 * v - 1.5).collect();
    write_exr(
        &path,
        w,
        h,
        Compression::ZIP1,
        LineOrder::Increasing,
        vec![AnyChannel::new("Y", FlatSamples::F32(stored.clone()))],
    );
    let opts = Options::new().with_patch(7).with_strength(Strength::Scale(3.0));
    for (layout, names) in [
        (Layout::RgbHeight, &["A", "B", "G", "R"][..]),
        (Layout::RgbOpaque, &["A", "B", "G", "R"][..]),
        (Layout::Rg, &["G", "R"][..]),
    ] {
        for signed in [false, true] {
            let format = ExrOptions::new(ExrDepth::Float).with_signed(signed).with_layout(layout);
            let rows = ExrRows::open(&path, &ReadOptions::default(), None).unwrap().unwrap();
            let tail = ExrRows::last_rows(&path, &ReadOptions::default(), None, 3).unwrap();
            let mut streamed = std::io::Cursor::new(Vec::new());
            convert_exr(rows, Some(&tail), &opts, format, |_| {}, &mut streamed).unwrap();

            let mut texels = vec![[0f32; 3]; w * h];
            FitRequest::new(&opts).normals_into(&stored, w, h, &mut texels).unwrap();
            if !signed {
                texels.iter_mut().for_each(|t| *t = t.map(|c| (c + 1.0) * 0.5));
            }
            let mut whole = std::io::Cursor::new(Vec::new());
            encode_normals(&texels, Some(&stored), w, h, &as_given(ExrDepth::Float, layout), &mut whole).unwrap();
            assert!(streamed.get_ref() == whole.get_ref(), "{layout:?} signed {signed}");

            let raster = normalfit::io::decode(streamed.get_ref(), &ReadOptions::default()).unwrap();
            let mut got: Vec<&str> = raster.planes.iter().map(|p| p.name.as_str()).collect();
            got.sort_unstable();
            assert_eq!(got, names, "{layout:?}");
            let plane = |name: &str| raster.plane(name).unwrap().data.to_f32().unwrap();
            match layout {
                Layout::RgbHeight => assert!(plane("A") == stored, "the alpha holds the heights as stored"),
                Layout::RgbOpaque => assert!(plane("A").iter().all(|&a| a == 1.0)),
                _ => {}
            }
            let k = 17 * w + 5;
            assert_eq!(plane("R")[k], texels[k][0]);
            assert_eq!(plane("G")[k], texels[k][1]);
        }
    }
}

#[test]
fn exr_input_streams_to_png_with_the_whole_image_s_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (50, 333);
    let path = dir.path().join("h.exr");
    write_exr(
        &path,
        w,
        h,
        Compression::PIZ,
        LineOrder::Increasing,
        vec![AnyChannel::new("Y", FlatSamples::F32(field(w, h, 5)))],
    );
    let opts = Options::new().with_patch(5).with_strength(Strength::Scale(10.0));
    let rows = ExrRows::open(&path, &ReadOptions::default(), None).unwrap().unwrap();
    let mut png = std::io::Cursor::new(Vec::new());
    convert_png_seekable(rows, &opts, PngDepth::Sixteen, |_| {}, &mut png).unwrap();
    let decoded = image::load_from_memory(png.get_ref()).unwrap().into_rgb16().into_raw();

    let heights = read_path(&path, &ReadOptions::default()).unwrap().heights(None).unwrap();
    let mut whole = vec![[0u16; 3]; w * h];
    FitRequest::new(&opts).normals_into(&heights, w, h, &mut whole).unwrap();
    assert!(decoded == whole.into_flattened());
}

#[test]
fn what_cannot_stream_is_left_to_the_whole_image_path() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (16, 16);
    // Tiled.
    let tiled = dir.path().join("tiled.exr");
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::Tiles((8, 8).into()),
        line_order: LineOrder::Increasing,
    };
    let channels = AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new("Y", FlatSamples::F32(field(w, h, 1)))]));
    Image::from_layer(Layer::new((w, h), LayerAttributes::default(), encoding, channels))
        .write()
        .to_file(&tiled)
        .unwrap();
    assert!(ExrRows::open(&tiled, &ReadOptions::default(), None).unwrap().is_none());
    // Not an EXR.
    let png = dir.path().join("a.png");
    image::GrayImage::from_pixel(4, 4, image::Luma([9])).save(&png).unwrap();
    assert!(ExrRows::open(&png, &ReadOptions::default(), None).unwrap().is_none());
    // Too large for the limit: refused from the header.
    let big = dir.path().join("big.exr");
    write_exr(
        &big,
        64,
        64,
        Compression::ZIP16,
        LineOrder::Increasing,
        vec![AnyChannel::new("Y", FlatSamples::F32(vec![0.5; 64 * 64]))],
    );
    let err = ExrRows::open(&big, &ReadOptions::default().with_max_texels(1000), None).err().expect("over the limit");
    assert!(matches!(err, normalfit::Error::Limits(_)), "{err:?}");
}

#[test]
fn a_truncated_file_is_a_decode_error() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (200, 300);
    let path = dir.path().join("t.exr");
    write_exr(
        &path,
        w,
        h,
        Compression::ZIP16,
        LineOrder::Increasing,
        vec![AnyChannel::new("Y", FlatSamples::F32(field(w, h, 2)))],
    );
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let opts = Options::new().with_borders(Borders::both(Border::Clamp));
    let result = ExrRows::open(&path, &ReadOptions::default(), None).and_then(|rows| {
        let rows = rows.expect("the header is intact");
        convert_exr(rows, None, &opts, ExrOptions::default(), |_| {}, std::io::Cursor::new(Vec::new()))
    });
    assert!(matches!(result, Err(normalfit::Error::Decode(_))), "{result:?}");
}

#[test]
fn exr_output_decodes_to_its_values_and_smooth_maps_compress() {
    let (w, h) = (301, 100);
    // Smooth values, which compress, with a noisy corner.
    let texels: Vec<[f32; 3]> = (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f32, (k / w) as f32);
            let noise = if x < 20.0 && y < 20.0 { ((k * 7919) % 1000) as f32 * 1e-3 } else { 0.0 };
            [0.5 + 0.4 * (x * 0.01).sin() + noise, 0.5 + 0.3 * (y * 0.02).cos(), 0.9]
        })
        .collect();
    for (depth, bytes_per_sample) in [(ExrDepth::Float, 4), (ExrDepth::Half, 2)] {
        let mut out = std::io::Cursor::new(Vec::new());
        encode_normals(&texels, None, w, h, &as_given(depth, Layout::Rgb), &mut out).unwrap();
        let bytes = out.into_inner();
        assert!(bytes.len() < w * h * 3 * bytes_per_sample / 2, "{depth:?}: {} bytes", bytes.len());
        let raster = normalfit::io::decode(&bytes, &ReadOptions::default()).unwrap();
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let plane = raster.plane(name).expect("channel").data.to_f32().unwrap();
            let expected: Vec<f32> = texels
                .iter()
                .map(|t| if depth == ExrDepth::Half { f16::from_f32(t[c]).to_f32() } else { t[c] })
                .collect();
            assert!(plane == expected, "{depth:?} {name}");
        }
    }
}
