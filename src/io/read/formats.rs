//! The registry of input formats: every format normalfit reads, once, with
//! how its content is recognised, the file extensions that name it, how
//! messages and help name it, whether its rows can stream, and which
//! decoder reads it.
//!
//! Everything that needs a list of formats asks here: content sniffing in
//! [`decode`](super::decode), the folder search's "is this an image file"
//! ([`InputFormat::from_extension`]), the check that a file's extension
//! agrees with its content, the command-line help ([`names`]) and the
//! error for bytes no format recognises. Adding a format is an entry in
//! [`FORMATS`] and, when the `image` crate does not read it, a decoder
//! beside the others in `io/read/`.
//!
//! Every format but PNG and OpenEXR has a Cargo feature of its own name
//! ([`FormatInfo::feature`]). A format whose feature is off stays in the
//! table, so its files are still recognised (by content and by extension),
//! and reading one is an [`Error::Unsupported`] naming the feature to
//! enable; [`names`] lists only the formats built in.

use std::fmt;
use std::io::Read;
use std::path::Path;

use image::ImageFormat;

use crate::error::{Error, Result};
use crate::io::{InputFormat, Raster, ReadOptions};

/// One input format: how it is recognised, named and read.
#[derive(Debug)]
#[non_exhaustive]
pub struct FormatInfo {
    /// The format.
    pub format: InputFormat,
    /// Its name in messages, lower case ("png", "exr"): what
    /// [`InputFormat`]'s `Display` writes.
    pub name: &'static str,
    /// Its name in help text and prose ("PNG", "OpenEXR").
    pub title: &'static str,
    /// The file extensions that name it, lower case, without the dot, the
    /// usual one first.
    pub extensions: &'static [&'static str],
    /// Whether its rows can stream from the file, through the fit, to the
    /// output without the whole image in memory (the engine's sources; for
    /// OpenEXR, scan-line files only).
    pub streams: bool,
    /// The Cargo feature that builds its decoder; `None` for the formats
    /// always read (PNG, OpenEXR).
    feature: Option<&'static str>,
    /// How its content is recognised.
    signature: Signature,
    /// What decodes it.
    decoder: Decoder,
}

/// How a format's content is recognised.
#[derive(Debug)]
enum Signature {
    /// The file starts with one of these byte patterns, each a list of
    /// byte strings at offsets, all present (WebP: "RIFF" at 0 and "WEBP"
    /// at 8, the file size between them).
    Magic(&'static [&'static [(usize, &'static [u8])]]),
    /// None: the format is tried after every signature failed, and taken
    /// when its header parses (TGA, whose header has enough fixed fields,
    /// image type and pixel depth, that text and most other data fail it).
    Probe(fn(&[u8]) -> bool),
    /// Nothing: any bytes could be the format's (RAW heightmaps, bare
    /// samples). It is never found from the content, only named: by a
    /// file's extension or by the caller ([`ReadOptions::raw`]).
    Named,
}

/// The decoder of a format.
#[derive(Debug)]
enum Decoder {
    /// A decoder of its own, in a file beside this one.
    Own(fn(&[u8], &ReadOptions) -> Result<Raster>),
    /// The `image` crate, told the format.
    Image(ImageFormat),
    /// None: the format's feature is off.
    NotBuilt,
}

/// The `image` crate's decoder of `format` if its feature (`built`) is on.
const fn image_decoder(format: ImageFormat, built: bool) -> Decoder {
    if built { Decoder::Image(format) } else { Decoder::NotBuilt }
}

/// TIFF's decoder, its own, when the `tiff` feature is on.
#[cfg(feature = "tiff")]
const TIFF_DECODER: Decoder = Decoder::Own(crate::io::tiff::decode);
#[cfg(not(feature = "tiff"))]
const TIFF_DECODER: Decoder = Decoder::NotBuilt;

/// TGA has no signature: with its decoder built, bytes are TGA when its
/// header parses; without, when the header's fixed fields look like one
/// (`tga_header_plausible`), so that the error names the feature.
#[cfg(feature = "tga")]
const TGA_PROBE: fn(&[u8]) -> bool = super::image_crate::is_tga;
#[cfg(not(feature = "tga"))]
const TGA_PROBE: fn(&[u8]) -> bool = tga_header_plausible;

/// Every format normalfit reads, in the order help text lists them.
/// Signatures do not overlap, so the order does not change which format
/// bytes are recognised as.
pub static FORMATS: &[FormatInfo] = &[
    FormatInfo {
        format: InputFormat::Png,
        name: "png",
        title: "PNG",
        extensions: &["png"],
        streams: true,
        feature: None,
        signature: Signature::Magic(&[&[(0, &crate::io::png::PNG_SIGNATURE)]]),
        decoder: Decoder::Own(crate::io::png::decode),
    },
    FormatInfo {
        format: InputFormat::Exr,
        name: "exr",
        title: "OpenEXR",
        extensions: &["exr"],
        streams: true,
        feature: None,
        signature: Signature::Magic(&[&[(0, &crate::io::exr::EXR_MAGIC)]]),
        decoder: Decoder::Own(crate::io::exr::decode_exr),
    },
    FormatInfo {
        format: InputFormat::Tiff,
        name: "tiff",
        title: "TIFF",
        extensions: &["tif", "tiff"],
        streams: false,
        feature: Some("tiff"),
        // Classic and BigTIFF, little- and big-endian (`image` knows only
        // classic TIFF's signature; its decoder reads BigTIFF too).
        signature: Signature::Magic(&[&[(0, b"II*\0")], &[(0, b"MM\0*")], &[(0, b"II+\0")], &[(0, b"MM\0+")]]),
        decoder: TIFF_DECODER,
    },
    FormatInfo {
        format: InputFormat::Jpeg,
        name: "jpeg",
        title: "JPEG",
        extensions: &["jpg", "jpeg"],
        streams: false,
        feature: Some("jpeg"),
        signature: Signature::Magic(&[&[(0, &[0xff, 0xd8, 0xff])]]),
        decoder: image_decoder(ImageFormat::Jpeg, cfg!(feature = "jpeg")),
    },
    FormatInfo {
        format: InputFormat::Tga,
        name: "tga",
        title: "TGA",
        extensions: &["tga"],
        streams: false,
        feature: Some("tga"),
        signature: Signature::Probe(TGA_PROBE),
        decoder: image_decoder(ImageFormat::Tga, cfg!(feature = "tga")),
    },
    FormatInfo {
        format: InputFormat::Bmp,
        name: "bmp",
        title: "BMP",
        extensions: &["bmp"],
        streams: false,
        feature: Some("bmp"),
        signature: Signature::Magic(&[&[(0, b"BM")]]),
        decoder: image_decoder(ImageFormat::Bmp, cfg!(feature = "bmp")),
    },
    FormatInfo {
        format: InputFormat::WebP,
        name: "webp",
        title: "WebP",
        extensions: &["webp"],
        streams: false,
        feature: Some("webp"),
        signature: Signature::Magic(&[&[(0, b"RIFF"), (8, b"WEBP")]]),
        decoder: image_decoder(ImageFormat::WebP, cfg!(feature = "webp")),
    },
    FormatInfo {
        format: InputFormat::Gif,
        name: "gif",
        title: "GIF",
        extensions: &["gif"],
        streams: false,
        feature: Some("gif"),
        signature: Signature::Magic(&[&[(0, b"GIF87a")], &[(0, b"GIF89a")]]),
        decoder: image_decoder(ImageFormat::Gif, cfg!(feature = "gif")),
    },
    FormatInfo {
        format: InputFormat::Hdr,
        name: "hdr",
        title: "Radiance HDR",
        extensions: &["hdr"],
        streams: false,
        feature: Some("hdr"),
        // `image`'s decoder takes this signature only, not "#?RGBE".
        signature: Signature::Magic(&[&[(0, b"#?RADIANCE")]]),
        decoder: image_decoder(ImageFormat::Hdr, cfg!(feature = "hdr")),
    },
    FormatInfo {
        format: InputFormat::Pnm,
        name: "pnm",
        title: "PNM",
        extensions: &["pgm", "ppm", "pbm", "pam", "pnm"],
        streams: false,
        feature: Some("pnm"),
        signature: Signature::Magic(&[
            &[(0, b"P1")],
            &[(0, b"P2")],
            &[(0, b"P3")],
            &[(0, b"P4")],
            &[(0, b"P5")],
            &[(0, b"P6")],
            &[(0, b"P7")],
        ]),
        decoder: image_decoder(ImageFormat::Pnm, cfg!(feature = "pnm")),
    },
    FormatInfo {
        format: InputFormat::Qoi,
        name: "qoi",
        title: "QOI",
        extensions: &["qoi"],
        streams: false,
        feature: Some("qoi"),
        signature: Signature::Magic(&[&[(0, b"qoif")]]),
        decoder: image_decoder(ImageFormat::Qoi, cfg!(feature = "qoi")),
    },
    FormatInfo {
        format: InputFormat::Raw,
        name: "raw",
        title: "RAW heightmap",
        // Unity's and World Machine's `.raw`, Unreal's `.r16`, and `.r8`
        // for the 8-bit ones (the names Unity, L3DT and Gaea write).
        extensions: &["raw", "r16", "r8"],
        streams: false,
        // No dependency: the samples are read as they are.
        feature: None,
        signature: Signature::Named,
        decoder: Decoder::Own(super::raw::decode),
    },
];

impl FormatInfo {
    /// Whether `head`, a file's first bytes (16 are enough), carries this
    /// format's signature. Always false for a format without one (TGA).
    #[must_use]
    pub fn signature_matches(&self, head: &[u8]) -> bool {
        let Signature::Magic(patterns) = self.signature else { return false };
        patterns
            .iter()
            .any(|parts| parts.iter().all(|(at, bytes)| head.get(*at..).is_some_and(|h| h.starts_with(bytes))))
    }

    /// Whether the format has a signature a file's first bytes can be
    /// compared with (TGA and RAW have none).
    #[must_use]
    pub fn has_signature(&self) -> bool {
        matches!(self.signature, Signature::Magic(_))
    }

    /// The Cargo feature that builds the format's decoder ("jpeg"), or
    /// `None` for the formats always read (PNG and OpenEXR, which are also
    /// the output formats).
    #[must_use]
    pub fn feature(&self) -> Option<&'static str> {
        self.feature
    }

    /// Whether this build reads the format: false when its feature is
    /// off, and reading it is an [`Error::Unsupported`] naming the feature.
    #[must_use]
    pub fn built_in(&self) -> bool {
        !matches!(self.decoder, Decoder::NotBuilt)
    }

    /// Decodes `bytes`, known to be of this format.
    pub(crate) fn decode(&self, bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
        match self.decoder {
            Decoder::Own(decode) => decode(bytes, opts),
            Decoder::Image(format) => super::image_crate::decode_with_image(bytes, opts, format, self.format.clone()),
            Decoder::NotBuilt => Err(self.not_built_in()),
        }
    }

    /// The error for reading a format this build leaves out.
    pub(crate) fn not_built_in(&self) -> Error {
        let feature = self.feature.unwrap_or(self.name);
        Error::Unsupported(format!("{} support is not built in: enable normalfit's `{feature}` feature", self.title))
    }
}

impl InputFormat {
    /// The format's entry in the registry.
    #[must_use]
    pub fn info(&self) -> &'static FormatInfo {
        // Every variant has an entry (tests/integration/io_formats.rs checks).
        FORMATS.iter().find(|f| f.format == *self).unwrap_or(&FORMATS[0])
    }

    /// The format a file extension (without the dot, any case) names:
    /// "PGM" → [`InputFormat::Pnm`].
    #[must_use]
    pub fn from_extension(extension: &str) -> Option<InputFormat> {
        let extension = extension.to_ascii_lowercase();
        FORMATS.iter().find(|f| f.extensions.contains(&extension.as_str())).map(|f| f.format.clone())
    }

    /// The format whose signature a file's first bytes (16 are enough)
    /// carry. TGA has none, so it is never found here.
    #[must_use]
    pub fn sniff(head: &[u8]) -> Option<InputFormat> {
        FORMATS.iter().find(|f| f.signature_matches(head)).map(|f| f.format.clone())
    }

    /// The format of a whole file's bytes: by signature, else (only then)
    /// a format without one whose header parses (TGA).
    ///
    /// Errors: [`Error::Unsupported`] for a format the `image` crate knows
    /// by its signature but normalfit does not read (ICO, DDS, …);
    /// [`Error::Decode`] for bytes of no known format.
    pub(crate) fn recognise(bytes: &[u8]) -> Result<InputFormat> {
        if let Some(format) = InputFormat::sniff(bytes) {
            return Ok(format);
        }
        if let Some(other) = super::image_crate::unread_format(bytes) {
            return Err(Error::Unsupported(format!("{other} images are not read; normalfit reads {}", names())));
        }
        let probed = FORMATS.iter().find(|f| matches!(f.signature, Signature::Probe(parses) if parses(bytes)));
        if let Some(format) = probed {
            return Ok(format.format.clone());
        }
        let start: String = bytes.iter().take(8).map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" ");
        Err(Error::Decode(format!(
            "not a recognised image format (starts with bytes {start}); normalfit reads {}",
            names()
        )))
    }
}

impl fmt::Display for InputFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.info().name)
    }
}

/// Refuses a file whose extension names one image format while its first
/// bytes are another's ([`Error::Misnamed`]): in a pipeline that is a
/// mix-up upstream (a file saved under the wrong name, or a name reused
/// for the wrong output), and converting it anyway would hide it. Every
/// read of a file by its path passes here ([`read_path`](super::read_path)
/// and the streaming readers). Files without an extension, with one that
/// names no format or a format without a signature (TGA, RAW), or whose
/// content no signature recognises (the decoder then says what is wrong),
/// are read by content, as are bytes without a name
/// ([`decode`](super::decode)). A file that cannot be opened or read
/// passes too: the read that follows reports it.
///
/// Errors: [`Error::Misnamed`].
pub fn check_extension(path: &Path) -> Result<()> {
    let Some(extension) = path.extension() else { return Ok(()) };
    let mut head = Vec::with_capacity(16);
    let Ok(file) = std::fs::File::open(path) else { return Ok(()) };
    if file.take(16).read_to_end(&mut head).is_err() {
        return Ok(());
    }
    check_named(&extension.to_string_lossy(), &head)
}

/// [`check_extension`] of a file named `.extension` whose first bytes (16
/// are enough) are `head`.
fn check_named(extension: &str, head: &[u8]) -> Result<()> {
    let extension = extension.to_ascii_lowercase();
    // TGA has no signature to compare with: an extension of .tga says nothing.
    let Some(named) = InputFormat::from_extension(&extension).filter(|f| f.info().has_signature()) else {
        return Ok(());
    };
    match InputFormat::sniff(head) {
        Some(content) if content != named => Err(Error::Misnamed { extension, content: content.info().name }),
        _ => Ok(()),
    }
}

/// The formats this build reads, for help text and messages: "PNG,
/// OpenEXR, TIFF, …" (those whose feature is off left out).
#[must_use]
pub fn names() -> String {
    FORMATS.iter().filter(|f| f.built_in()).map(|f| f.title).collect::<Vec<_>>().join(", ")
}

/// Whether a file's first 18 bytes are a TGA header whose fixed fields
/// hold values TGA allows: a colour map type of 0 or 1, an image type
/// with data (colour-mapped, true-colour or gray, raw or run-length), a
/// pixel depth of 8, 15, 16, 24 or 32 bits, and a non-zero size. The
/// stand-in for parsing the header when the `tga` feature is off.
#[cfg(any(not(feature = "tga"), test))]
fn tga_header_plausible(bytes: &[u8]) -> bool {
    let Some(header) = bytes.get(..18) else { return false };
    let (map_type, image_type, depth) = (header[1], header[2], header[16]);
    let (width, height) = (u16::from_le_bytes([header[12], header[13]]), u16::from_le_bytes([header[14], header[15]]));
    map_type <= 1
        && matches!(image_type, 1 | 2 | 3 | 9 | 10 | 11)
        && matches!(depth, 8 | 15 | 16 | 24 | 32)
        && width > 0
        && height > 0
}

/// Every extension the formats are named by, lower case, in registry
/// order: "png, exr, tif, tiff, …".
#[must_use]
pub fn extensions() -> String {
    FORMATS.iter().flat_map(|f| f.extensions.iter().copied()).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every variant, by a match that stops compiling when one is added
    /// until it is listed here (and, by the test below, in [`FORMATS`]).
    fn every_variant() -> Vec<InputFormat> {
        use InputFormat::*;
        let all = vec![Png, Exr, Jpeg, Tiff, Tga, Bmp, WebP, Gif, Hdr, Pnm, Qoi, Raw];
        for format in &all {
            match format {
                Png | Exr | Jpeg | Tiff | Tga | Bmp | WebP | Gif | Hdr | Pnm | Qoi | Raw => {}
            }
        }
        all
    }

    #[test]
    fn every_variant_has_one_entry() {
        for format in every_variant() {
            assert_eq!(FORMATS.iter().filter(|f| f.format == format).count(), 1, "{format:?}");
            assert_eq!(format.info().format, format);
        }
        assert_eq!(FORMATS.len(), every_variant().len());
    }

    /// A file start carrying one signature pattern, zeros elsewhere.
    fn start_of(parts: &[(usize, &[u8])]) -> Vec<u8> {
        let mut head = vec![0u8; 16];
        for (at, bytes) in parts {
            head[*at..at + bytes.len()].copy_from_slice(bytes);
        }
        head
    }

    /// The signatures do not overlap (so the table's order does not
    /// matter), and each picks the format the `image` crate's own guess
    /// picked before the registry, so every file goes to the decoder it
    /// went to before.
    #[test]
    fn signatures_are_disjoint_and_agree_with_image() {
        for info in FORMATS {
            let Signature::Magic(patterns) = info.signature else { continue };
            for parts in patterns {
                let head = start_of(parts);
                let matching: Vec<&str> =
                    FORMATS.iter().filter(|f| f.signature_matches(&head)).map(|f| f.name).collect();
                assert_eq!(matching, [info.name], "{head:02x?}");
                let expected = match info.format {
                    InputFormat::Png => ImageFormat::Png,
                    InputFormat::Exr => ImageFormat::OpenExr,
                    InputFormat::Tiff => ImageFormat::Tiff,
                    InputFormat::Jpeg => ImageFormat::Jpeg,
                    InputFormat::Tga => ImageFormat::Tga,
                    InputFormat::Bmp => ImageFormat::Bmp,
                    InputFormat::WebP => ImageFormat::WebP,
                    InputFormat::Gif => ImageFormat::Gif,
                    InputFormat::Hdr => ImageFormat::Hdr,
                    InputFormat::Pnm => ImageFormat::Pnm,
                    InputFormat::Qoi => ImageFormat::Qoi,
                    InputFormat::Raw => unreachable!("RAW has no signature"),
                };
                if let Decoder::Image(format) = info.decoder {
                    assert_eq!(format, expected, "{}: the decoder is told its own format", info.name);
                }
                let bigtiff = head[2] == b'+' || head[3] == b'+';
                if !bigtiff {
                    // `image` knows only classic TIFF's signature.
                    assert_eq!(image::guess_format(&head).ok(), Some(expected), "{}", info.name);
                }
            }
        }
    }

    /// The formats whose feature is off in this build are recognised and
    /// refused with the feature's name; the rest are listed by `names`.
    #[test]
    fn a_format_left_out_is_named_with_its_feature() {
        for info in FORMATS {
            let built = match info.feature {
                None => true,
                Some("tiff") => cfg!(feature = "tiff"),
                Some("jpeg") => cfg!(feature = "jpeg"),
                Some("tga") => cfg!(feature = "tga"),
                Some("bmp") => cfg!(feature = "bmp"),
                Some("webp") => cfg!(feature = "webp"),
                Some("gif") => cfg!(feature = "gif"),
                Some("hdr") => cfg!(feature = "hdr"),
                Some("pnm") => cfg!(feature = "pnm"),
                Some("qoi") => cfg!(feature = "qoi"),
                Some(other) => panic!("{}: unknown feature {other}", info.name),
            };
            assert_eq!(info.built_in(), built, "{}", info.name);
            assert_eq!(names().split(", ").any(|n| n == info.title), built, "{}", info.name);
            if !built {
                let message = info.decode(&[], &ReadOptions::default()).unwrap_err().to_string();
                let feature = info.feature.unwrap();
                assert_eq!(
                    message,
                    format!(
                        "unsupported: {} support is not built in: enable normalfit's `{feature}` feature",
                        info.title
                    )
                );
            }
        }
    }

    /// A file's extension is checked against its content for the formats
    /// with a signature, in any case; the rest, and content no signature
    /// recognises, pass.
    #[test]
    fn an_extension_naming_another_format_is_refused() {
        let png: &[u8] = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR";
        let exr: &[u8] = &[0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
        for (extension, head, content) in [("exr", png, "png"), ("PNG", exr, "exr"), ("tif", png, "png")] {
            let e = check_named(extension, head).unwrap_err();
            assert!(matches!(&e, Error::Misnamed { .. }), "{e:?}");
            let lower = extension.to_ascii_lowercase();
            assert_eq!(
                e.to_string(),
                format!(
                    "is named .{lower} but its content is {content}: rename it, or pass it on standard input to read it by content"
                )
            );
        }
        for (extension, head) in [
            ("png", png),
            ("EXR", exr),
            // No signature to compare with: TGA and RAW are read as before.
            ("tga", png),
            ("raw", png),
            ("r16", exr),
            // An extension that names no format.
            ("bin", png),
            ("", png),
            // Content no signature recognises: the decoder's to report.
            ("png", b"this is not an image"),
            ("png", b""),
        ] {
            assert!(check_named(extension, head).is_ok(), "{extension} {head:?}");
        }
    }

    /// [`check_extension`] reads a file's first bytes; a file it cannot
    /// open passes, for the read to report.
    #[test]
    fn check_extension_reads_the_files_start() {
        let dir = tempfile::tempdir().unwrap();
        let png = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n', 0, 0, 0, 13];
        for (name, ok) in [("a.exr", false), ("a.png", true), ("a", true), ("a.txt", true)] {
            let path = dir.path().join(name);
            std::fs::write(&path, png).unwrap();
            assert_eq!(check_extension(&path).is_ok(), ok, "{name}");
        }
        assert!(check_extension(&dir.path().join("missing.exr")).is_ok());
        assert!(check_extension(dir.path()).is_ok(), "a folder");
    }

    /// A TGA header the `image` crate parses passes the plausibility check
    /// used without the `tga` feature; text and a header with an image
    /// type TGA lacks do not.
    #[test]
    fn tga_plausibility() {
        // 2×1 gray, raw (type 3), 8 bits, then its two texels.
        let mut tga = vec![0u8; 18];
        tga[2] = 3;
        tga[12] = 2;
        tga[14] = 1;
        tga[16] = 8;
        tga.extend([10, 20]);
        assert!(tga_header_plausible(&tga));
        #[cfg(feature = "tga")]
        assert!(super::super::image_crate::is_tga(&tga), "the image crate parses it too");
        assert!(!tga_header_plausible(b"just some text that is long enough"));
        let mut odd = tga.clone();
        odd[2] = 4;
        assert!(!tga_header_plausible(&odd));
        let mut empty = tga;
        empty[12] = 0;
        assert!(!tga_header_plausible(&empty));
    }
}
