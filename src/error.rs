//! The library's one error type, split by who is at fault.

use std::fmt;

/// Everything that can go wrong in normalfit's library calls.
///
/// Messages are one line, lower case, and never name a file: the caller
/// knows which file it passed and prefixes it.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// An option is out of range (even patch, non-finite scale, …).
    InvalidOption(String),
    /// The caller's buffers do not match the dimensions given.
    BufferSize {
        /// What the dimensions need.
        expected: usize,
        /// What was passed.
        actual: usize,
    },
    /// A height is NaN or infinite; (x, y) is the first such texel in row order.
    NonFiniteHeight {
        /// Column of the texel.
        x: usize,
        /// Row of the texel.
        y: usize,
    },
    /// A component of a normal map's normal is NaN or infinite; (x, y) is
    /// the first such texel in row order.
    NonFiniteNormal {
        /// Column of the texel.
        x: usize,
        /// Row of the texel.
        y: usize,
    },
    /// The bytes are not a readable image: unknown format, corrupt or
    /// truncated data, zero size.
    Decode(String),
    /// A valid image that normalfit cannot use (a missing channel, a layout
    /// it does not read) or an output it cannot write (8-bit EXR, …).
    Unsupported(String),
    /// A file whose extension names one image format while its content is
    /// another's (a PNG named `.exr`): refused rather than read by its
    /// content, since in a pipeline it is a mix-up upstream
    /// ([`check_extension`](crate::io::read::formats::check_extension)).
    /// The same bytes without the name ([`crate::io::decode`], standard
    /// input) are read by content.
    Misnamed {
        /// The file's extension, lower case, without the dot.
        extension: String,
        /// The name of the format its content is (`InputFormat`'s, as
        /// `FormatInfo::name`: the error type sits below the formats).
        content: &'static str,
    },
    /// The image is larger than the limit set for the read.
    Limits(String),
    /// Encoding the output failed.
    Encode(String),
    /// Reading or writing failed at the operating system.
    Io(std::io::Error),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidOption(m) => write!(f, "invalid option: {m}"),
            Error::BufferSize { expected, actual } => {
                write!(f, "buffer holds {actual} elements, the dimensions need {expected}")
            }
            Error::NonFiniteHeight { x, y } => {
                write!(f, "height at texel (x {x}, y {y}) is NaN or infinite")
            }
            Error::NonFiniteNormal { x, y } => {
                write!(f, "normal at texel (x {x}, y {y}) has a NaN or infinite component")
            }
            Error::Decode(m) => write!(f, "cannot decode: {m}"),
            Error::Unsupported(m) => write!(f, "unsupported: {m}"),
            Error::Misnamed { extension, content } => write!(
                f,
                "is named .{extension} but its content is {content}: rename it, or pass it on standard input to read it by content"
            ),
            Error::Limits(m) => write!(f, "too large: {m}"),
            Error::Encode(m) => write!(f, "cannot encode: {m}"),
            Error::Io(e) => write!(f, "{}", one_line(&e.to_string())),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        Error::Io(e)
    }
}

/// A number as messages show it: Rust's shortest form that reads back to
/// the same value (`0.1`, `30`, `-1500.25`), but in exponent form where
/// that form would be long: from 1e16 up (`1e308`, where `{}` writes 309
/// digits) and below 1e-4 (`1.5e-7`), the bounds of Python's `repr`, so a
/// number in a message reads the same from the command line and from the
/// Python package. NaN and infinities as `{}` writes them.
///
/// ```
/// use normalfit::error::Number;
/// assert_eq!(Number(1e308).to_string(), "1e308");
/// assert_eq!(Number(-2.5e-7).to_string(), "-2.5e-7");
/// assert_eq!(Number(30.0).to_string(), "30");
/// assert_eq!(Number(0.1).to_string(), "0.1");
/// assert_eq!(Number(f64::NAN).to_string(), "NaN");
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Number(pub f64);

impl fmt::Display for Number {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        let magnitude = v.abs();
        if v.is_finite() && v != 0.0 && !(1e-4..1e16).contains(&magnitude) {
            write!(f, "{v:e}")
        } else {
            write!(f, "{v}")
        }
    }
}

/// Collapses a message from a dependency onto one line.
pub(crate) fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Shorthand for results of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
