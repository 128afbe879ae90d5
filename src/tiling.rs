//! Whether a texture tiles: a seam score per axis.
