//! A build that leaves input formats out (`default-features = false`,
//! CI's minimal build): a format whose decoder is not built in is still
//! recognised by its content, and reading it is one `Unsupported` error
//! that names the feature to enable, from bytes and from a file alike.
//!
//! The tests exist only in builds that leave at least one format out; in
//! the default build every format is read, and io_formats.rs reads them.
#![cfg(not(all(
    feature = "tiff",
    feature = "jpeg",
    feature = "tga",
    feature = "bmp",
    feature = "webp",
    feature = "gif",
    feature = "hdr",
    feature = "pnm",
    feature = "qoi"
)))]

use normalfit::Error;
use normalfit::io::read::formats::{FORMATS, names};
use normalfit::io::{InputFormat, ReadOptions, decode, read_path};

/// The start of a file of `format`, written here from each format's
/// documentation, not from the registry: enough to be recognised, not to
/// be decoded.
fn file_of(format: &InputFormat) -> Vec<u8> {
    let mut bytes = match format {
        InputFormat::Tiff => b"II*\0\x08\0\0\0".to_vec(),
        InputFormat::Jpeg => vec![0xff, 0xd8, 0xff, 0xe0, 0, 16, b'J', b'F', b'I', b'F', 0],
        InputFormat::Tga => {
            // 4×2 gray, raw (image type 3), 8 bits per texel.
            let mut header = vec![0u8; 18];
            header[2] = 3;
            header[12] = 4;
            header[14] = 2;
            header[16] = 8;
            header
        }
        InputFormat::Bmp => b"BM\x46\0\0\0\0\0\0\0\x36\0\0\0".to_vec(),
        InputFormat::WebP => b"RIFF\x24\0\0\0WEBPVP8 ".to_vec(),
        InputFormat::Gif => b"GIF89a\x04\0\x02\0\0\0\0".to_vec(),
        InputFormat::Hdr => b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n".to_vec(),
        InputFormat::Pnm => b"P5\n4 2\n255\n".to_vec(),
        InputFormat::Qoi => b"qoif\0\0\0\x04\0\0\0\x02\x03\0".to_vec(),
        other => panic!("{other:?} is always built in"),
    };
    bytes.resize(bytes.len() + 64, 0);
    bytes
}

/// The formats this build leaves out, by the registry.
fn left_out() -> Vec<&'static normalfit::io::FormatInfo> {
    FORMATS.iter().filter(|f| !f.built_in()).collect()
}

#[test]
fn this_build_leaves_formats_out() {
    let expected = [
        ("tiff", cfg!(feature = "tiff")),
        ("jpeg", cfg!(feature = "jpeg")),
        ("tga", cfg!(feature = "tga")),
        ("bmp", cfg!(feature = "bmp")),
        ("webp", cfg!(feature = "webp")),
        ("gif", cfg!(feature = "gif")),
        ("hdr", cfg!(feature = "hdr")),
        ("pnm", cfg!(feature = "pnm")),
        ("qoi", cfg!(feature = "qoi")),
    ];
    let out: Vec<&str> = left_out().iter().map(|f| f.feature().expect("PNG and EXR are always read")).collect();
    let want: Vec<&str> = expected.iter().filter(|(_, on)| !on).map(|(name, _)| *name).collect();
    assert_eq!(out, want);
    assert!(!out.is_empty());
    for info in left_out() {
        assert!(!names().split(", ").any(|n| n == info.title), "{} is listed as read: {}", info.title, names());
    }
    assert!(names().starts_with("PNG, OpenEXR"), "{}", names());
}

#[test]
fn a_format_left_out_is_recognised_and_refused_naming_its_feature() {
    let dir = tempfile::tempdir().unwrap();
    for info in left_out() {
        let feature = info.feature().unwrap();
        let want = format!("{} support is not built in: enable normalfit's `{feature}` feature", info.title);
        let bytes = file_of(&info.format);
        match decode(&bytes, &ReadOptions::default()) {
            Err(Error::Unsupported(message)) => assert_eq!(message, want, "{}", info.name),
            other => panic!("{}: {other:?}", info.name),
        }
        let path = dir.path().join(format!("height.{}", info.extensions[0]));
        std::fs::write(&path, &bytes).unwrap();
        let message = read_path(&path, &ReadOptions::default()).unwrap_err().to_string();
        assert!(message.ends_with(&want), "{}: {message}", info.name);
        assert!(!message.contains('\n'), "one line: {message}");
    }
}
