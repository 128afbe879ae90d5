//! # normalfit
//!
//! Tangent-space normal maps from height maps, by fitting a least-squares
//! plane to the N×N patch of points (u, v, height) around every texel.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod error;
pub mod fit;
pub mod io;
pub mod options;
pub mod shade;
pub mod tiling;

pub use error::{Error, Result};
pub use fit::{FromNormal, normals, normals_into};
pub use options::{Border, Borders, Convention, Fit, Options, Strength};
