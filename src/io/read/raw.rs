//! RAW heightmaps: bare samples with no header, as Unity, Unreal, World
//! Machine and Gaea export terrain: 16-bit unsigned integers, little-endian
//! by default (Unity's "Windows" byte order, Unreal's `.r16`), or 8-bit.
//!
//! With no header there is nothing to recognise the content by, so a RAW
//! file is known by its extension (`.raw`, `.r16`, `.r8`; [`super::read_path`])
//! or because the caller says so ([`ReadOptions::raw`]). Its size is the
//! caller's, or found from the length: a square of n² bytes (8-bit) or
//! 2n² bytes (16-bit). One length cannot be both (n² = 2m² has no whole
//! solution), so the inference never has to guess between depths.
//!
//! Units: samples are stored unsigned integers, so SPEC §1's rule holds as
//! for a PNG of the same depth: height = value / (2^bits − 1).

use crate::error::{Error, Result};
use crate::memory;
use crate::options::named_values;
use crate::samples::{Samples, try_vec};

use crate::io::{InputFormat, Plane, Raster, ReadOptions, SampleType, check_size, to_usize};

/// The order of a 16-bit sample's two bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ByteOrder {
    /// Least significant byte first (Unity's "Windows", Unreal, most
    /// tools): the default.
    #[default]
    Little,
    /// Most significant byte first (Unity's "Mac", old Photoshop RAW).
    Big,
}

named_values!(ByteOrder, "byte order", { Little => "little" | "le", Big => "big" | "be" });

/// How a RAW heightmap is laid out: what a header would say.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub struct RawOptions {
    /// Width and height; `None` infers a square from the file's length.
    pub size: Option<(usize, usize)>,
    /// The byte order of 16-bit samples (8-bit samples have none).
    pub byte_order: ByteOrder,
    /// Bits per sample, 8 or 16; `None` takes them from the extension
    /// (`.r8`, `.r16`) or else from the length and the size.
    pub bits: Option<u8>,
}

impl RawOptions {
    /// The RAW layout a front end's options ask for (`--size WxH`,
    /// `--byte-order`; Python's `size=`, `byte_order=`): `None` when
    /// neither is given (files named `.raw`, `.r16`, `.r8` are still RAW,
    /// square, little-endian), else the size if given and the byte order
    /// (little by default). Giving either also reads standard input and
    /// files whose extension names no format as RAW ([`ReadOptions::raw`]).
    ///
    /// [`ReadOptions::raw`]: super::ReadOptions::raw
    #[must_use]
    pub fn given(size: Option<(usize, usize)>, byte_order: Option<ByteOrder>) -> Option<RawOptions> {
        if size.is_none() && byte_order.is_none() {
            return None;
        }
        Some(RawOptions { size, byte_order: byte_order.unwrap_or_default(), bits: None })
    }

    /// The same options with a size.
    #[must_use]
    pub fn with_size(mut self, width: usize, height: usize) -> Self {
        self.size = Some((width, height));
        self
    }

    /// The same options with a byte order.
    #[must_use]
    pub fn with_byte_order(mut self, order: ByteOrder) -> Self {
        self.byte_order = order;
        self
    }

    /// The same options with a sample depth (8 or 16; checked by
    /// [`RawOptions::validate`]).
    #[must_use]
    pub fn with_bits(mut self, bits: u8) -> Self {
        self.bits = Some(bits);
        self
    }

    /// Checks the options as a caller gave them: a size of at least 1 × 1,
    /// 8 or 16 bits.
    ///
    /// Errors: [`Error::InvalidOption`] naming the value.
    pub fn validate(&self) -> Result<()> {
        if let Some((w, h)) = self.size
            && (w == 0 || h == 0)
        {
            return Err(Error::InvalidOption(format!("a RAW heightmap's size must be at least 1×1, got {w}×{h}")));
        }
        match self.bits {
            None | Some(8 | 16) => Ok(()),
            Some(b) => Err(Error::InvalidOption(format!("a RAW heightmap holds 8- or 16-bit samples, got {b}"))),
        }
    }

    /// The depth an extension gives: `.r8` 8 bits, `.r16` 16; `.raw`, none
    /// (the length decides).
    pub(crate) fn with_extension_bits(mut self, extension: &str) -> Self {
        if self.bits.is_none() {
            self.bits = match extension.to_ascii_lowercase().as_str() {
                "r8" => Some(8),
                "r16" => Some(16),
                _ => None,
            };
        }
        self
    }
}

/// Parses "W×H" as the command line and Python take it: "1025x1025",
/// "1025X513" or with the multiplication sign, whole numbers of at least 1.
///
/// Errors: [`Error::InvalidOption`] naming the text.
pub fn parse_size(text: &str) -> Result<(usize, usize)> {
    let bad = || {
        Error::InvalidOption(format!(
            "expected a size WIDTHxHEIGHT such as 1025x1025, got '{}'",
            crate::error::one_line(text)
        ))
    };
    let (w, h) = text.trim().split_once(['x', 'X', '×']).ok_or_else(bad)?;
    let (w, h): (usize, usize) = (w.trim().parse().map_err(|_| bad())?, h.trim().parse().map_err(|_| bad())?);
    RawOptions::default().with_size(w, h).validate()?;
    Ok((w, h))
}

/// The decoder the registry holds: the caller's layout, or the default
/// (square, depth from the length, little-endian).
pub(super) fn decode(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    decode_raw(bytes, &opts.raw.clone().unwrap_or_default(), opts)
}

/// Decodes a RAW heightmap laid out as `raw` says.
///
/// Errors: [`Error::InvalidOption`] for a layout [`RawOptions::validate`]
/// refuses; [`Error::Decode`] when the length does not fit it (empty, not
/// a square, not the size given at 8 or 16 bits); [`Error::Limits`] as for
/// every format.
pub(super) fn decode_raw(bytes: &[u8], raw: &RawOptions, opts: &ReadOptions) -> Result<Raster> {
    raw.validate()?;
    if bytes.is_empty() {
        return Err(Error::Decode("file is empty".into()));
    }
    let (width, height, bits) = layout(bytes.len() as u64, raw)?;
    check_size(width, height, opts)?;
    let texels = to_usize(width * height)?;
    memory::check_memory("decoding", 2 * texels as u64)?;
    let data = match bits {
        8 => {
            let mut v = try_vec(texels)?;
            v.extend_from_slice(bytes);
            Samples::U8(v)
        }
        _ => {
            let mut v = try_vec(texels)?;
            let order = raw.byte_order;
            v.extend(bytes.chunks_exact(2).map(|p| match order {
                ByteOrder::Little => u16::from_le_bytes([p[0], p[1]]),
                ByteOrder::Big => u16::from_be_bytes([p[0], p[1]]),
            }));
            Samples::U16(v)
        }
    };
    Ok(Raster {
        width: to_usize(width)?,
        height: to_usize(height)?,
        format: InputFormat::Raw,
        sample: SampleType::Int { bits },
        planes: vec![Plane { name: "Y".into(), data }],
        georef: None,
    })
}

/// Width, height and bits for a file of `len` bytes, or the error that
/// says what the length would have to be.
fn layout(len: u64, raw: &RawOptions) -> Result<(u64, u64, u8)> {
    let depths: &[u8] = match raw.bits {
        Some(8) => &[8],
        Some(_) => &[16],
        None => &[16, 8],
    };
    let named = |b: u8| format!("{b}-bit");
    let which = match raw.bits {
        Some(b) => named(b),
        None => "8- or 16-bit".into(),
    };
    match raw.size {
        Some((w, h)) => {
            let (w, h) = (w as u64, h as u64);
            let texels = w.checked_mul(h).ok_or_else(|| Error::Limits(format!("{w} × {h} is 2^64 texels or more")))?;
            for &bits in depths {
                if texels.checked_mul(u64::from(bits / 8)) == Some(len) {
                    return Ok((w, h, bits));
                }
            }
            let wanted: Vec<String> = depths
                .iter()
                .rev()
                .map(|&b| match texels.checked_mul(u64::from(b / 8)) {
                    Some(bytes) => format!("{bytes} bytes at {b} bits"),
                    None => format!("2^64 bytes or more at {b} bits"),
                })
                .collect();
            Err(Error::Decode(format!(
                "RAW heightmap of {len} bytes does not hold {w}×{h} {which} samples (that takes {})",
                wanted.join(" or ")
            )))
        }
        None => {
            for &bits in depths {
                let bytes = u64::from(bits / 8);
                if len.is_multiple_of(bytes) {
                    let side = len / bytes;
                    let n = side.isqrt();
                    if n * n == side {
                        return Ok((n, n, bits));
                    }
                }
            }
            Err(Error::Decode(format!(
                "RAW heightmap of {len} bytes is not a square of {which} samples (n² bytes at 8 bits, 2·n² at 16): \
                 give its width and height"
            )))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_sizes_are_found_from_the_length_at_one_depth_only() {
        let any = RawOptions::default();
        assert_eq!(layout(2 * 1025 * 1025, &any).unwrap(), (1025, 1025, 16));
        assert_eq!(layout(1025 * 1025, &any).unwrap(), (1025, 1025, 8));
        assert_eq!(layout(2 * 513 * 513, &any.clone().with_bits(16)).unwrap(), (513, 513, 16));
        // 8 bytes: 2·2² at 16 bits; not a square of bytes.
        assert_eq!(layout(8, &any).unwrap(), (2, 2, 16));
        // 16 bytes is 4² at 8 bits and not 2·n² (8 is no square).
        assert_eq!(layout(16, &any).unwrap(), (4, 4, 8));
        let e = layout(16, &any.clone().with_bits(16)).unwrap_err().to_string();
        assert!(e.contains("not a square of 16-bit samples"), "{e}");
        let e = layout(7, &any).unwrap_err().to_string();
        assert!(e.contains("RAW heightmap of 7 bytes is not a square of 8- or 16-bit samples"), "{e}");
    }

    #[test]
    fn a_size_given_picks_the_depth_or_says_what_it_needs() {
        let sized = RawOptions::default().with_size(4, 2);
        assert_eq!(layout(16, &sized).unwrap(), (4, 2, 16));
        assert_eq!(layout(8, &sized).unwrap(), (4, 2, 8));
        let e = layout(9, &sized).unwrap_err().to_string();
        assert!(
            e.contains("does not hold 4×2 8- or 16-bit samples (that takes 8 bytes at 8 bits or 16 bytes at 16 bits)"),
            "{e}"
        );
        let e = layout(8, &sized.with_bits(16)).unwrap_err().to_string();
        assert!(e.contains("(that takes 16 bytes at 16 bits)"), "{e}");
        // (2^32 − 1)(2^32 + 1) = 2^64 − 1 texels: one byte each fits a u64,
        // two do not, and are said so rather than saturated (issue 32).
        let e = layout(16, &RawOptions::default().with_size(u32::MAX as usize, (1 << 32) + 1)).unwrap_err().to_string();
        assert!(e.contains("18446744073709551615 bytes at 8 bits or 2^64 bytes or more at 16 bits"), "{e}");
        let e = layout(16, &RawOptions::default().with_size(1 << 32, 1 << 32)).unwrap_err().to_string();
        assert_eq!(e, "too large: 4294967296 × 4294967296 is 2^64 texels or more");
    }

    #[test]
    fn sizes_parse_and_are_checked() {
        assert_eq!(parse_size("1025x513").unwrap(), (1025, 513));
        assert_eq!(parse_size("4X2").unwrap(), (4, 2));
        assert_eq!(parse_size("4×2").unwrap(), (4, 2));
        for bad in ["", "4", "4x", "x4", "0x4", "4x-1", "4x2x1", "a×b"] {
            assert!(matches!(parse_size(bad), Err(Error::InvalidOption(_))), "{bad}");
        }
        assert!(RawOptions::default().with_bits(12).validate().is_err());
        assert_eq!("BE".parse::<ByteOrder>().unwrap(), ByteOrder::Big);
        assert_eq!("little".parse::<ByteOrder>().unwrap(), ByteOrder::Little);
    }
}
