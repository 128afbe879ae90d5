//! KTX 2.0 files (the Khronos texture container): a mip chain of one 2D
//! texture, no supercompression, its format named by `vkFormat` and
//! described by a basic Data Format Descriptor. Written by hand
//! (`write.rs`): the `ktx2` crate reads these files but writes none, and
//! the layout is a fixed header, an index and the levels.

pub(crate) mod write;
