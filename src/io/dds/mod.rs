//! DirectDraw Surface (DDS) files: a mip chain of one 2D texture, written
//! with the DX10 header extension so every format is named by its
//! `DXGI_FORMAT` (BC4, BC5, BC7, 8-bit and half-float layouts) rather than
//! a FourCC code or bit masks. Written by hand (`write.rs`): the header is
//! 148 bytes of little-endian words, and the one crate that composes them
//! (`ddsfile`) wants the texture's bytes in one buffer of its own, a copy
//! this way avoids.

pub(crate) mod write;
