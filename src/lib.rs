//! # normalfit
//!
//! Tangent-space normal maps from height maps, by fitting a least-squares
//! plane to the N×N patch of points (u, v, height) around every texel, and a
//! check of whether a texture tiles seamlessly.
//!
//! The crate has three layers, each usable without the next, and a
//! fourth for people to look at the result:
//!
//! * [`fit`]: the compute core. Heights in a caller's row-major `f32`
//!   buffer, [`Options`] in, normals out ([`FitRequest`], the one way in:
//!   holes, a window of a larger image, the residual, any texel type;
//!   [`normals`] for the plainest case).
//!   It knows nothing of files. The cost per texel does not depend on the
//!   patch size, rows run in parallel on rayon's pool (with the `parallel`
//!   feature), and the result is the same bit for bit whatever the number
//!   of threads, or with none.
//! * [`io`]: decoding (PNG, OpenEXR, TIFF, JPEG, … chosen by content, with
//!   size limits checked before any pixel buffer exists) and encoding (PNG,
//!   OpenEXR) as an [`io::Encoding`] says ([`io::encode_normals`]), and
//!   [`io::write_atomically`] for outputs that appear whole or not at all.
//! * [`pipeline`]: the same conversion streamed, rows from the decoder
//!   through the fit to the encoder, for PNG and scan-line EXR files.
//! * [`convert`]: a height map file (or bytes) to a normal map file (or any
//!   writer) in one call, with every rule the `normalfit` program follows:
//!   output format and depth, streaming or whole, memory checks, `auto`
//!   borders, atomic writes ([`convert::Conversion`]).
//! * [`tiling`]: a seam score and a verdict per axis ([`tiling::check`]).
//! * [`units`]: fits in real-world units ([`Units::Map`]): the texel
//!   spacing of a GeoTIFF, and slope and aspect in degrees as GIS tools
//!   give them.
//! * [`shade`]: normals lit by a directional light as a gray picture
//!   ([`shade::shade`]), repeated 2×2 so seams show ([`shade::tile_2x2`]).
//! * [`blend`]: a detail normal map onto a base (RNM, whiteout, UDN,
//!   linear; [`blend::blend`], files by [`blend::BlendFiles`]).
//! * [`check`]: a normal map's lengths, negative z, RG layout, convention
//!   (guessed from its curl), banding and seams ([`check::check`]), and its
//!   repair ([`check::write_fixed`]).
//!
//! Every fallible call returns the typed [`Error`].
//!
//! # From heights in memory to a PNG
//!
//! ```
//! use std::io::Cursor;
//!
//! use normalfit::io::{Encoding, encode_normals};
//! use normalfit::{Border, Borders, Convention, FitRequest, Fit, Options, Strength};
//!
//! // Heights from anywhere: here a round bump on a 64 × 48 grid, in [0, 1].
//! let (width, height) = (64, 48);
//! let heights: Vec<f32> = (0..width * height)
//!     .map(|k| {
//!         let (x, y) = ((k % width) as f32 - 32.0, (k / width) as f32 - 24.0);
//!         (-(x * x + y * y) / 60.0).exp()
//!     })
//!     .collect();
//!
//! // The defaults are the contract's: 3×3 patch, orthogonal fit, wrap
//! // borders, OpenGL green, scale 1. Change what the texture needs.
//! let opts = Options::new()
//!     .with_patch(5)
//!     .with_fit(Fit::Orthogonal)
//!     .with_borders(Borders { x: Border::Clamp, y: Border::Mirror })
//!     .with_convention(Convention::OpenGl)
//!     .with_strength(Strength::Scale(8.0));
//!
//! // Encoded straight to 8-bit RGB, c = round(255 (n + 1) / 2).
//! let mut rgb = vec![[0u8; 3]; width * height];
//! FitRequest::new(&opts).normals_into(&heights, width, height, &mut rgb)?;
//! assert!(rgb[24 * width + 36][0] > 128, "right of the bump leans right: red above mid-grey");
//! assert!(rgb[20 * width + 32][1] > 128, "above the bump leans up (OpenGL): green above mid-grey");
//! assert_eq!(rgb[0], [128, 128, 255], "far from the bump the map is flat");
//!
//! // Any `impl Write + Seek`: a file, or a buffer in a `Cursor`. The
//! // texels' type goes with the encoding: [u8; 3] for an 8-bit PNG.
//! let mut png = Vec::new();
//! encode_normals(&rgb, None, width, height, &Encoding::png8(), Cursor::new(&mut png))?;
//! assert!(png.starts_with(b"\x89PNG"));
//! # Ok::<(), normalfit::Error>(())
//! ```
//!
//! To a file, use [`io::write_file_atomically`], which writes a new file
//! beside the target (without a name, on Linux) and gives it the target's
//! name only once it is complete. To read an
//! image, [`io::read_path`] or [`io::decode`] give an [`io::Raster`], and
//! [`io::Raster::heights`] the heights in the contract's units.
//!
//! # From a file to a file
//!
//! [`convert::Conversion`] does all of the above for image files, as the
//! `normalfit convert` command does: the format from the output's name, 16
//! bits for a 16-bit input, streaming where the input allows.
//!
//! ```
//! use normalfit::convert::{BorderChoice, BorderChoices, Conversion, Input, Output};
//! use normalfit::io::{Encoding, OutputFormat};
//!
//! # let dir = std::env::temp_dir().join(format!("normalfit-doc-{}", std::process::id()));
//! # std::fs::create_dir_all(&dir)?;
//! # let heights: Vec<[u8; 3]> = (0..64 * 64).map(|k| [(k % 64 * 4) as u8; 3]).collect();
//! # let mut file = std::fs::File::create(dir.join("height.png"))?;
//! # normalfit::io::encode_normals(&heights, None, 64, 64, &Encoding::png8(), &mut file)?;
//! // Wrap where the texture tiles, mirror where it does not.
//! let conversion = Conversion::new().with_borders(BorderChoices::both(BorderChoice::Auto));
//! let summary = conversion.convert_file(&dir.join("height.png"), &dir.join("normal.exr"))?;
//! assert_eq!((summary.width, summary.height, summary.encoding.format()), (64, 64, OutputFormat::Exr));
//! assert!(summary.streamed, "a PNG streams");
//!
//! // Or into any writer: the bytes of a PNG, say.
//! let mut png = Vec::new();
//! let input = std::fs::read(dir.join("height.png"))?;
//! let summary = conversion.convert(Input::Bytes(&input), Output::Writer(&mut png))?;
//! assert_eq!(summary.encoding, Encoding::png8());
//! assert!(png.starts_with(b"\x89PNG"));
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # A picture to look at
//!
//! ```
//! use std::io::Cursor;
//!
//! use normalfit::io::{PngCompression, PngDepth, PngOptions, encode_gray};
//! use normalfit::shade::{Light, shade, tile_2x2};
//! use normalfit::{Options, Strength, normals};
//!
//! // A round bump in the middle of a 32 × 32 map.
//! let (width, height) = (32, 32);
//! let heights: Vec<f32> = (0..width * height)
//!     .map(|k| {
//!         let (x, y) = ((k % width) as f32 - 16.0, (k / width) as f32 - 16.0);
//!         (-(x * x + y * y) / 30.0).exp()
//!     })
//!     .collect();
//! let opts = Options::new().with_strength(Strength::Scale(6.0));
//! let n = normals(&heights, width, height, &opts)?;
//!
//! // Light from the top-left (the default): the bump's upper-left side
//! // faces it, its lower-right side turns away.
//! let lit = shade(&n, width, height, Light::default(), opts.convention)?;
//! assert!(lit[13 * width + 13] > lit[16 * width + 16] && lit[16 * width + 16] > lit[19 * width + 19]);
//!
//! // Repeated 2×2, then an 8-bit gray PNG.
//! let tiled = tile_2x2(&lit, width, height)?;
//! let gray8 = PngOptions::new(PngDepth::Eight).with_compression(PngCompression::Best).into();
//! let mut png = Vec::new();
//! encode_gray(&tiled, 2 * width, 2 * height, &gray8, Cursor::new(&mut png))?;
//! assert!(png.starts_with(b"\x89PNG"));
//! # Ok::<(), normalfit::Error>(())
//! ```
//!
//! # Does it tile?
//!
//! ```
//! use normalfit::tiling::{self, TilingOptions};
//!
//! // Periodic in x (one whole sine period), a ramp in y: tiles in x only.
//! let (width, height) = (128, 96);
//! let heights: Vec<f32> = (0..width * height)
//!     .map(|k| {
//!         let (x, y) = ((k % width) as f32, (k / width) as f32);
//!         0.5 + 0.25 * (x * std::f32::consts::TAU / width as f32).sin() + y / 400.0
//!     })
//!     .collect();
//!
//! let report = tiling::check(&[&heights], width, height, &TilingOptions::new())?;
//! assert!(report.x.seamless && report.x.score < 1.5);
//! assert!(!report.y.seamless, "the ramp's last row is far from its first");
//! // Borders that add no seam of their own: wrap in x, mirror in y.
//! let borders = report.suggested_borders();
//! assert_eq!((borders.x, borders.y), (normalfit::Border::Wrap, normalfit::Border::Mirror));
//! # Ok::<(), normalfit::Error>(())
//! ```
//!
//! # Cargo features
//!
//! Every feature is on by default, as the `normalfit` program ships. A
//! library user who wants less starts from `default-features = false`
//! and adds what it needs: that build reads PNG and OpenEXR (the output
//! formats, always built) and runs on the calling thread.
//!
//! | feature | what it adds | default |
//! |---|---|---|
//! | `cli` | the `normalfit` program (clap, serde_json; implies `serde`) | on |
//! | `serde` | `Serialize` for the reports ([`tiling::TilingReport`] and its parts) | via `cli` |
//! | `parallel` | fits, decoding and encoding on rayon's pool, EXR blocks on threads | on |
//! | `all-formats` | every input decoder below | on |
//! | `tiff`, `jpeg`, `tga`, `bmp`, `webp`, `gif`, `hdr`, `pnm`, `qoi` | reading that format | via `all-formats` |
//! | `bc7` | BC7 blocks in GPU textures ([`io::gpu`]; `block_compression`'s encoder) | on |
//!
//! Without `parallel` the same code runs serially and gives the same bits:
//! results never depend on the number of threads. A format whose feature
//! is off is still recognised by its content (and its extension), and
//! reading it is an [`Error::Unsupported`], "JPEG support is not built in:
//! enable normalfit's `jpeg` feature"; [`io::read::formats::names`] and the
//! program's help list only the formats built in, and
//! [`io::FormatInfo::built_in`] says whether one is.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod blend;
pub mod borders;
pub mod check;
pub mod convert;
pub mod engine;
pub mod error;
pub mod fit;
pub mod height;
pub mod inspect;
pub mod io;
mod light;
mod memory;
pub mod mips;
pub mod normal_map;
pub mod options;
mod par;
pub mod pipeline;
pub mod products;
pub mod samples;
pub mod shade;
pub mod tiling;
pub mod units;

// The unit tests that read `tests/common/reference.rs` (the one reference
// of the tests, written against the public API) name the crate as it does.
#[cfg(test)]
extern crate self as normalfit;

pub use error::{Error, Result};
pub use fit::{FitRequest, FromNormal, Heights, curvature, normals};
pub use options::{
    Border, Borders, Convention, Detail, Fit, Options, Product, SlopeUnits, Spacing, Strength, Units, Weights,
};
pub use samples::{Sample, Samples};

/// The README's Rust code, compiled and run by `cargo test` as doc tests,
/// so the front page's snippet keeps up with the API.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
