//! Reading height maps and writing normal maps: image files, bytes, atomic writes.
//!
//! [`read`] turns the bytes of any supported format into planes of `f32`
//! in the contract's height units (SPEC §1) and picks the height channel;
//! [`write`](mod@write) encodes normal maps (SPEC §3) and puts files in place
//! atomically (SPEC §4). Neither knows about the fit, and the fit knows
//! nothing of files. [`stream`] joins them for PNG and scan-line EXR
//! files, streaming rows from decoder to encoder.

mod atomic;
mod memory;
pub mod read;
pub mod stream;
pub mod write;

pub use memory::check_memory;
pub use read::{Channel, FormatInfo, InputFormat, Plane, Raster, ReadOptions, SampleType, decode, read_path};
// The paths the streaming readers take these by.
pub(crate) use read::exr::subsampled as exr_subsampled;
pub(crate) use read::png::zlib as png_zlib;
pub use write::{
    ExrDepth, Layout, PngCompression, PngSample, Sample, encode_exr, encode_exr_gray, encode_exr_normals,
    encode_png_gray8, encode_png_gray16, encode_png_normals, encode_png_rgb8, encode_png_rgb16, write_atomically,
    write_file_atomically,
};
