//! Reading height maps and writing normal maps: image files, bytes, atomic writes.
//!
//! [`read`] turns the bytes of any supported format into planes of `f32`
//! in the contract's height units (SPEC §1) and picks the height channel;
//! [`write`](mod@write) encodes normal maps (SPEC §3) and puts files in place
//! atomically (SPEC §4). Neither knows about the fit, and the fit knows
//! nothing of files. [`encoding`] is the one vocabulary of outputs: an
//! [`Encoding`] (PNG, EXR or TIFF and their options, the layout of the
//! channels), chosen from a file name and the input by its rules. The
//! engine ([`crate::engine`]) joins reading and writing through a stage.

mod atomic;
pub mod encoding;
#[cfg(feature = "tiff")]
pub(crate) mod geotiff;
mod identity;
mod memory;
pub mod read;
pub mod sidecar;
pub mod write;

pub use encoding::{
    Alpha, Encoding, ExrDepth, ExrOptions, Layout, OutputChannels, OutputFormat, PngCompression, PngDepth, PngOptions,
};
pub use identity::{FileId, same_file};
pub use memory::check_memory;
pub use read::{
    Affine, ByteOrder, Channel, FormatInfo, Georef, InputFormat, ModelType, PackedElevation, Plane, Raster, RasterType,
    RawOptions, ReadOptions, SampleType, decode, metres_per_degree, parse_size, read_path,
};
// The paths the streaming readers take these by.
pub(crate) use read::exr::subsampled as exr_subsampled;
pub(crate) use read::png::zlib as png_zlib;
pub use write::{
    GrayValue, NormalTexel, PngSample, Sample, encode_gray, encode_normals, write_atomically, write_file_atomically,
};
