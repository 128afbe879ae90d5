//! Streaming PNG conversion (`normalfit::pipeline`) gives exactly what
//! the whole-image path gives: decode everything, `normals_into`, encode.
//! Sizes cross band edges, patches reach beyond short images, and every
//! y border is used, so a row taken from the wrong place would show.

use std::path::Path;

use image::{ExtendedColorType, ImageEncoder};
use normalfit::io::{Channel, Layout, PngCompression, ReadOptions, encode_normals, read_path};
use normalfit::pipeline::{PngDepth, PngOptions, PngRows, RowSource, convert_png, convert_png_seekable};
use normalfit::{Border, Borders, FitRequest, Options, Strength};

/// Heights with detail in both directions and no symmetry, as 16-bit.
fn field(w: usize, h: usize, seed: u64) -> Vec<u16> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..w * h)
        .map(|k| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            let smooth = 0.5 + 0.3 * (x * 0.21 + y * 0.07).sin() * (y * 0.13).cos();
            let v = smooth + 0.1 * ((s >> 40) as f64 / (1u64 << 24) as f64);
            (v.clamp(0.0, 1.0) * 65535.0).round() as u16
        })
        .collect()
}

fn write_png(path: &Path, w: usize, h: usize, color: ExtendedColorType, samples: &[u8]) {
    let file = std::fs::File::create(path).unwrap();
    image::codecs::png::PngEncoder::new(file).write_image(samples, w as u32, h as u32, color).unwrap();
}

/// Decodes a PNG, verifying every chunk's CRC and the zlib stream's
/// Adler-32 (which decoders skip by default), to samples widened to u16.
fn strict_decode(png_bytes: &[u8]) -> Vec<u16> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(png_bytes));
    decoder.ignore_checksums(false);
    let mut reader = decoder.read_info().expect("a valid header");
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).expect("valid, checksummed data");
    let buf = &buf[..info.buffer_size()];
    match info.bit_depth {
        png::BitDepth::Sixteen => buf.chunks_exact(2).map(|c| u16::from_be_bytes([c[0], c[1]])).collect(),
        _ => buf.iter().map(|&b| u16::from(b)).collect(),
    }
}

/// Streams `path` to PNG bytes both ways (in order, after a first pass for
/// a wrap in y; and in one pass into a seekable output, the top rows
/// last), checks both decode to the same samples, and returns them.
fn streamed(path: &Path, channel: Option<Channel>, opts: &Options, depth: PngDepth) -> Vec<u16> {
    streamed_as(path, channel, opts, depth, Layout::Rgb)
}

/// [`streamed`] with the channels of `layout`.
fn streamed_as(path: &Path, channel: Option<Channel>, opts: &Options, depth: PngDepth, layout: Layout) -> Vec<u16> {
    let open = || PngRows::open(path, &ReadOptions::default(), channel.clone()).unwrap().expect("streamable");
    let tail = (opts.borders.y == Border::Wrap).then(|| open().read_tail(opts.patch / 2, |_| {}).unwrap());
    let mut ordered = Vec::new();
    let output = PngOptions::new(depth).with_layout(layout);
    convert_png(open(), tail.as_deref(), opts, output, |_| {}, &mut ordered).unwrap();
    let mut seekable = std::io::Cursor::new(Vec::new());
    convert_png_seekable(open(), opts, output, |_| {}, &mut seekable).unwrap();
    let (a, b) = (strict_decode(&ordered), strict_decode(seekable.get_ref()));
    assert!(a == b, "the two streaming modes differ");
    a
}

/// The whole-image path for the same file.
fn whole(path: &Path, channel: Option<Channel>, opts: &Options, depth: PngDepth) -> Vec<u16> {
    let raster = read_path(path, &ReadOptions::default()).unwrap();
    let (w, h) = (raster.width, raster.height);
    // The samples as stored (integers stay integers), as the fit reads them.
    let heights = raster.into_heights(channel).unwrap();
    match depth {
        PngDepth::Eight => {
            let mut out = vec![[0u8; 3]; w * h];
            FitRequest::new(opts).normals_into(&heights, w, h, &mut out).unwrap();
            out.as_flattened().iter().map(|&v| u16::from(v)).collect()
        }
        PngDepth::Sixteen => {
            let mut out = vec![[0u16; 3]; w * h];
            FitRequest::new(opts).normals_into(&heights, w, h, &mut out).unwrap();
            out.into_flattened()
        }
    }
}

fn assert_same(path: &Path, channel: Option<Channel>, opts: &Options, depth: PngDepth, what: &str) {
    let (s, w) = (streamed(path, channel.clone(), opts, depth), whole(path, channel, opts, depth));
    assert_eq!(s.len(), w.len(), "{what}");
    if let Some(k) = s.iter().zip(&w).position(|(a, b)| a != b) {
        panic!("{what}: sample {k} differs: streamed {} whole {}", s[k], w[k]);
    }
}

#[test]
fn gray_16_bit_equals_the_whole_image_path_for_every_size_patch_and_border() {
    let dir = tempfile::tempdir().unwrap();
    // Heights below, at and across band edges (a band is a few hundred rows).
    for (w, h) in [(1, 1), (7, 1), (1, 9), (5, 3), (37, 61), (64, 300), (23, 700), (130, 1031)] {
        let path = dir.path().join(format!("g{w}x{h}.png"));
        let v = field(w, h, (w * 31 + h) as u64);
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_be_bytes()).collect();
        // `image` takes 16-bit samples in native order.
        let ne: Vec<u8> = bytes.chunks(2).flat_map(|c| u16::from_be_bytes([c[0], c[1]]).to_ne_bytes()).collect();
        write_png(&path, w, h, ExtendedColorType::L16, &ne);
        for n in [3, 7, 33] {
            for y in [Border::Wrap, Border::Clamp, Border::Mirror] {
                let opts = Options::new()
                    .with_patch(n)
                    .with_borders(Borders { x: Border::Mirror, y })
                    .with_strength(Strength::Scale(30.0));
                for depth in [PngDepth::Eight, PngDepth::Sixteen] {
                    assert_same(&path, None, &opts, depth, &format!("{w}×{h} N {n} {y:?} {depth:?}"));
                }
            }
        }
    }
}

/// Alpha of heights, opaque alpha and red-green: the streamed PNG holds the
/// samples the whole-image encoder writes, in both streaming modes, for
/// wraps that fit the top rows last and for rows read through mirrors.
#[test]
fn every_channel_layout_streams_the_whole_image_path_s_samples() {
    let dir = tempfile::tempdir().unwrap();
    for (w, h) in [(1, 1), (9, 4), (40, 530)] {
        let path = dir.path().join(format!("g{w}x{h}.png"));
        let ne: Vec<u8> = field(w, h, 3).iter().flat_map(|x| x.to_ne_bytes()).collect();
        write_png(&path, w, h, ExtendedColorType::L16, &ne);
        let raster = read_path(&path, &ReadOptions::default()).unwrap();
        let samples = raster.clone().into_heights(None).unwrap();
        let heights = raster.heights(None).unwrap();
        for y in [Border::Wrap, Border::Mirror] {
            let opts = Options::new().with_patch(5).with_borders(Borders { x: Border::Wrap, y });
            for layout in [Layout::RgbHeight, Layout::RgbOpaque, Layout::Rg] {
                for depth in [PngDepth::Eight, PngDepth::Sixteen] {
                    let mut whole = std::io::Cursor::new(Vec::new());
                    let encoding = PngOptions::new(depth).with_layout(layout).into();
                    match depth {
                        PngDepth::Eight => {
                            let mut t = vec![[0u8; 3]; w * h];
                            FitRequest::new(&opts).normals_into(&samples, w, h, &mut t).unwrap();
                            encode_normals(&t, Some(&heights), w, h, &encoding, &mut whole)
                        }
                        PngDepth::Sixteen => {
                            let mut t = vec![[0u16; 3]; w * h];
                            FitRequest::new(&opts).normals_into(&samples, w, h, &mut t).unwrap();
                            encode_normals(&t, Some(&heights), w, h, &encoding, &mut whole)
                        }
                    }
                    .unwrap();
                    let whole = strict_decode(whole.get_ref());
                    let channels = if layout == Layout::Rg { 3 } else { 4 };
                    assert_eq!(whole.len(), w * h * channels, "{layout:?}");
                    let streamed = streamed_as(&path, None, &opts, depth, layout);
                    assert!(streamed == whole, "{w}×{h} {y:?} {layout:?} {depth:?}");
                }
            }
        }
    }
}

#[test]
fn colour_alpha_and_8_bit_layouts_pick_the_same_heights() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (45, 290);
    let v = field(w, h, 5);
    let byte = |k: usize, c: usize| ((u32::from(v[k]) * (c as u32 + 3) / 7) & 0xff) as u8;
    // Name, layout, samples, channels to pick.
    type Case = (&'static str, ExtendedColorType, Vec<u8>, Vec<Option<Channel>>);
    let cases: Vec<Case> = vec![
        ("l8", ExtendedColorType::L8, (0..w * h).map(|k| byte(k, 0)).collect(), vec![None, Some(Channel::R)]),
        (
            "la8",
            ExtendedColorType::La8,
            (0..w * h * 2).map(|i| byte(i / 2, i % 2)).collect(),
            vec![None, Some(Channel::A)],
        ),
        (
            "rgb8",
            ExtendedColorType::Rgb8,
            (0..w * h * 3).map(|i| byte(i / 3, i % 3)).collect(),
            vec![None, Some(Channel::Luma), Some(Channel::G), Some(Channel::B)],
        ),
        (
            "rgba16",
            ExtendedColorType::Rgba16,
            (0..w * h * 4).flat_map(|i| (v[i / 4] / (i % 4 + 1) as u16).to_ne_bytes()).collect(),
            vec![None, Some(Channel::R), Some(Channel::A)],
        ),
    ];
    for (name, color, samples, channels) in cases {
        let path = dir.path().join(format!("{name}.png"));
        write_png(&path, w, h, color, &samples);
        for channel in channels {
            let opts = Options::new().with_patch(5).with_strength(Strength::Scale(12.0));
            let what = format!("{name} {channel:?}");
            assert_same(&path, channel, &opts, PngDepth::Sixteen, &what);
        }
    }
}

#[test]
fn interlaced_and_other_formats_are_left_to_the_whole_image_path() {
    let dir = tempfile::tempdir().unwrap();
    // `image` writes the JPEG only with its encoder, which the `jpeg` feature builds.
    #[cfg(feature = "jpeg")]
    {
        let jpeg = dir.path().join("a.jpg");
        image::RgbImage::from_pixel(8, 8, image::Rgb([9, 9, 9])).save(&jpeg).unwrap();
        assert!(PngRows::open(&jpeg, &ReadOptions::default(), None).unwrap().is_none());
    }
    // A missing alpha channel is an error, as it is for the whole image.
    let gray = dir.path().join("g.png");
    write_png(&gray, 4, 4, ExtendedColorType::L8, &[7; 16]);
    assert!(PngRows::open(&gray, &ReadOptions::default(), Some(Channel::A)).is_err());
}

#[test]
fn data_ending_early_is_a_decode_error() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (300, 400);
    let path = dir.path().join("t.png");
    let v = field(w, h, 9);
    let ne: Vec<u8> = v.iter().flat_map(|x| x.to_ne_bytes()).collect();
    write_png(&path, w, h, ExtendedColorType::L16, &ne);
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let rows = PngRows::open(&path, &ReadOptions::default(), None).unwrap().unwrap();
    let opts = Options::new().with_borders(Borders::both(Border::Clamp));
    let mut out = Vec::new();
    let err = convert_png(rows, None, &opts, PngDepth::Eight, |_| {}, &mut out).unwrap_err();
    assert!(matches!(err, normalfit::Error::Decode(_)), "{err:?}");
}

#[test]
fn chosen_filters_give_the_same_pixels_in_a_smaller_file() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (97, 410);
    let path = dir.path().join("c.png");
    let ne: Vec<u8> = field(w, h, 21).iter().flat_map(|x| x.to_ne_bytes()).collect();
    write_png(&path, w, h, ExtendedColorType::L16, &ne);
    let open = || PngRows::open(&path, &ReadOptions::default(), None).unwrap().expect("streamable");
    for depth in [PngDepth::Eight, PngDepth::Sixteen] {
        for y in [Border::Wrap, Border::Clamp] {
            let opts = Options::new().with_borders(Borders { x: Border::Wrap, y }).with_strength(Strength::Scale(40.0));
            let encode = |compression| {
                let mut out = std::io::Cursor::new(Vec::new());
                let output = PngOptions::new(depth).with_compression(compression);
                convert_png_seekable(open(), &opts, output, |_| {}, &mut out).unwrap();
                out.into_inner()
            };
            let (fast, small) = (encode(PngCompression::Fast), encode(PngCompression::Default));
            let whole = whole(&path, None, &opts, depth);
            assert!(strict_decode(&small) == whole, "{depth:?} {y:?}");
            assert!(strict_decode(&fast) == whole, "{depth:?} {y:?}");
            // At 16 bits, deflate (fdeflate's table is made for 8-bit
            // rows) does not shrink these rows: the fast setting stores
            // them without trying, the small one after trying.
            match depth {
                PngDepth::Eight => {
                    assert!(small.len() < fast.len(), "{depth:?} {y:?}: {} ≥ {}", small.len(), fast.len())
                }
                PngDepth::Sixteen => {
                    assert!(small.len() <= fast.len(), "{depth:?} {y:?}: {} > {}", small.len(), fast.len())
                }
            }
        }
    }
}
