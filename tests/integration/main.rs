//! Every integration test, as one test program: one build and one link
//! instead of one per file (about forty, each built twice in CI: with no
//! features and with all). Each module is one subject; a module that needs
//! the program or decoders other than PNG and OpenEXR is built only with
//! the features it names, so CI's minimal build
//! (`cargo test --no-default-features`) runs the rest.
//!
//! One module's tests: `cargo test --test integration hostile::`, or
//! `cargo nextest run -E 'test(/^hostile::/)'`.

// Helpers shared by the modules (tests/common), the hostile corpus's
// file builders (tests/corpus) and the tiling check's cases
// (tests/tiling_support, also read by two examples).
#[path = "../common/mod.rs"]
mod common;
#[path = "../corpus/mod.rs"]
mod corpus;
#[path = "../tiling_support/mod.rs"]
mod tiling_support;

// The library, in every build.
mod blend;
mod check;
mod convert_api;
mod curvature;
mod detail;
mod exr_layouts;
mod features;
mod fit_reference;
mod fit_request;
mod fuzz_regressions;
mod gpu_containers;
mod height;
mod mips;
mod nodata;
mod png_checksum;
mod same_bits;
mod stream;
mod stream_exr;
mod terrain_units;
mod tiling;
mod weights;
mod window;

// Readers of the formats other than PNG and OpenEXR: GeoTIFFs made with
// the `tiff` crate's encoder, WebP and PNG tiles; GeoTIFFs written and read
// by GDAL (ignored where gdal-bin is absent); the real textures, which are
// JPEG files.
#[cfg(feature = "jpeg")]
mod height_real_data;
#[cfg(feature = "all-formats")]
mod io_formats;
#[cfg(feature = "jpeg")]
mod real_data;
#[cfg(feature = "all-formats")]
mod terrain_gdal;
#[cfg(feature = "all-formats")]
mod terrain_gdal_out;
#[cfg(feature = "all-formats")]
mod terrain_gdal_units;
#[cfg(feature = "all-formats")]
mod terrain_io;
#[cfg(feature = "all-formats")]
mod terrain_stream;

// The program as it ships (every format).
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod awkward;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_batch;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_batch_commands;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_blend_check;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_completions_man;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_curvature;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_detail;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_height;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_mips;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_nodata;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_shade;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_terrain;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod cli_tiling;
#[cfg(all(feature = "cli", feature = "tiff"))]
mod tiff_out;
// Faults while writing, and every path under a 1 GiB address-space limit.
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod faults;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod hostile;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod memory_limit;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod products;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod samples;
#[cfg(all(feature = "cli", feature = "all-formats"))]
mod shade_map_units;
