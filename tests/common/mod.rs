//! Helpers shared by the integration tests.
// Runs the program, which only the `cli` feature builds.
#[cfg(feature = "cli")]
pub mod cli;
pub mod mips;
pub mod reference;
pub mod rng;
// GeoTIFFs of every layout, made with the `tiff` crate's encoder.
#[cfg(feature = "tiff")]
pub mod geotiff;
// `../shared/data`'s real textures.
pub mod shared_data;
