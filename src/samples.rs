//! Height samples as they were stored: 8- and 16-bit integers, or floats.
//!
//! SPEC §1 makes an integer sample v of b bits the height v / (2^b − 1).
//! Dividing before the fit and keeping the quotient as `f32` rounds every
//! height by up to 2⁻²⁴ of its value, and the gain S multiplies that error:
//! a 16-bit ramp around 30000 at `-s 1000` moved normals by 1.5e-5, 7e-5 at
//! `-s 5000`, outside the contract's 1e-5. So integers stay integers until
//! the fit, which folds 1 / (2^b − 1) into the gain in f64
//! (z = (S · [`Sample::UNIT`]) · v): exact in every input the contract
//! names, at any gain.
//!
//! [`Sample`] is what the fit reads (`u8`, `u16`, `f32`, `f64`), and
//! [`Samples`] an owned plane of any of them, as decoders give it.

use crate::error::{Error, Result};
use crate::par::prelude::*;

/// A height sample type the fit reads: the stored value times
/// [`UNIT`](Self::UNIT) is the height in the contract's units.
pub trait Sample: Copy + Send + Sync + 'static {
    /// The height of a stored value of 1: 1 / (2^bits − 1) for an integer
    /// type (1/255, 1/65535), 1 for a float.
    const UNIT: f64;

    /// The stored value, exactly.
    fn to_f64(self) -> f64;

    /// Whether the value is a height the contract holds: a number
    /// (integers always are) within `f32`'s range. The contract's heights
    /// are `f32`; a double beyond that range is infinite there, as
    /// [`Raster::heights`](crate::io::Raster::heights) rounds it, and in
    /// the fit its squares overflow even `f64`'s sums.
    fn is_finite(self) -> bool;
}

/// `Sample` for an integer type (its unit one over its largest value) or
/// a float type (unit 1).
macro_rules! sample {
    ($t:ty, integer) => {
        sample!($t, 1.0 / <$t>::MAX as f64, |_v: $t| true);
    };
    ($t:ty, float) => {
        sample!($t, 1.0, <$t>::is_finite);
    };
    ($t:ty, $unit:expr, $finite:expr) => {
        impl Sample for $t {
            const UNIT: f64 = $unit;
            #[inline(always)]
            fn to_f64(self) -> f64 {
                f64::from(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                $finite(self)
            }
        }
    };
}

sample!(u8, integer);
sample!(u16, integer);
sample!(f32, float);
sample!(f64, 1.0, |v: f64| (v as f32).is_finite());

/// One channel's samples, row-major, in the type they were stored in.
///
/// Integer channels keep their stored values (`U8`, `U16`); floats are
/// `F32`; values that are neither (luma of a colour image, 32-bit and
/// signed integers, 64-bit floats) are `F64` in the contract's units.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Samples {
    /// 8-bit values: height v / 255.
    U8(Vec<u8>),
    /// 16-bit values: height v / 65535.
    U16(Vec<u16>),
    /// Heights as stored.
    F32(Vec<f32>),
    /// Heights in f64.
    F64(Vec<f64>),
}

/// Runs `$body` with `$s` bound to the samples' slice, whatever their type.
macro_rules! with_slice {
    ($samples:expr, $s:ident => $body:expr) => {
        match $samples {
            Samples::U8(v) => {
                let $s: &[u8] = v;
                $body
            }
            Samples::U16(v) => {
                let $s: &[u16] = v;
                $body
            }
            Samples::F32(v) => {
                let $s: &[f32] = v;
                $body
            }
            Samples::F64(v) => {
                let $s: &[f64] = v;
                $body
            }
        }
    };
}

pub(crate) use with_slice;

impl Samples {
    /// How many samples.
    #[must_use]
    pub fn len(&self) -> usize {
        with_slice!(self, s => s.len())
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sample `i` as a height in contract units, `None` past the end.
    #[must_use]
    pub fn height(&self, i: usize) -> Option<f64> {
        with_slice!(self, s => s.get(i).map(|&v| contract(v)))
    }

    /// The heights of `out.len()` samples from `start` into `out`, in
    /// contract units rounded to `f32`, for the consumers that take `f32`
    /// (the tiling check, lit views, an alpha of heights) a row at a time.
    ///
    /// Errors: [`Error::BufferSize`] when the samples end before
    /// `start + out.len()` (`out` is then unchanged).
    pub fn heights_f32_into(&self, start: usize, out: &mut [f32]) -> Result<()> {
        let (len, available) = (out.len(), self.len().saturating_sub(start));
        if len > available {
            return Err(Error::BufferSize { expected: len, actual: available });
        }
        with_slice!(self, s => {
            for (o, &v) in out.iter_mut().zip(&s[start..start + len]) {
                *o = contract(v) as f32;
            }
        });
        Ok(())
    }

    /// All heights in contract units, rounded to `f32` (a copy; the fit
    /// itself reads the samples as they are).
    ///
    /// Errors: [`Error::Limits`] if the memory for the copy is not there.
    pub fn to_f32(&self) -> Result<Vec<f32>> {
        if let Samples::F32(v) = self {
            let mut out = try_vec(v.len())?;
            out.extend_from_slice(v);
            return Ok(out);
        }
        let mut out = try_vec(self.len())?;
        out.resize(self.len(), 0.0);
        self.heights_f32_into(0, &mut out)?;
        Ok(out)
    }

    /// Into heights in contract units as `f32`, without a copy when they
    /// are already.
    ///
    /// Errors: as [`Samples::to_f32`].
    pub fn into_f32(self) -> Result<Vec<f32>> {
        match self {
            Samples::F32(v) => Ok(v),
            other => other.to_f32(),
        }
    }

    /// Bytes a sample.
    #[must_use]
    pub fn bytes_per_sample(&self) -> usize {
        match self {
            Samples::U8(_) => 1,
            Samples::U16(_) => 2,
            Samples::F32(_) => 4,
            Samples::F64(_) => 8,
        }
    }

    /// The height of a stored value of 1 ([`Sample::UNIT`] of the type held).
    pub(crate) fn unit(&self) -> f64 {
        fn unit_of<H: Sample>(_: &[H]) -> f64 {
            H::UNIT
        }
        with_slice!(self, s => unit_of(s))
    }

    /// The first (x, y) in row order whose value is NaN or infinite.
    pub(crate) fn first_non_finite(&self, width: usize) -> Option<(usize, usize)> {
        with_slice!(self, s => first_non_finite(s, width))
    }
}

/// Heights a task of [`first_non_finite`] checks (256 KiB of f32).
const FINITE_CHUNK: usize = 1 << 16;

/// The first texel (x, y) in row order whose height is NaN or infinite.
pub(crate) fn first_non_finite<H: Sample>(heights: &[H], width: usize) -> Option<(usize, usize)> {
    // A loop without an early exit vectorises (a search one value at a time
    // took 2.5 % of a conversion): it finds whether there is one, and only
    // then is it looked for. On every core: on one, the check of a 4096²
    // float map took a tenth of the fit's wall time.
    let all_finite =
        heights.par_chunks(FINITE_CHUNK).all(|chunk| chunk.iter().fold(true, |all, h| all & h.is_finite()));
    if all_finite {
        return None;
    }
    heights.iter().position(|h| !h.is_finite()).map(|k| (k % width, k / width))
}

/// A sample's height in contract units: the stored value times the unit,
/// in f64 (the product the fit forms too).
#[inline(always)]
pub(crate) fn contract<H: Sample>(v: H) -> f64 {
    v.to_f64() * H::UNIT
}

/// Rec. 709 luma weights of R, G and B (SPEC §1).
pub(crate) const LUMA: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// The luma of one texel's R, G and B heights (contract units), in f64:
/// every reader, whole-image or streaming, makes it by this one formula,
/// so both give the same bits.
#[inline(always)]
pub(crate) fn luma(r: f64, g: f64, b: f64) -> f64 {
    LUMA[0] * r + LUMA[1] * g + LUMA[2] * b
}

/// A vector with room for `len` values, or [`Error::Limits`] if the memory
/// is not there (instead of the abort a plain allocation would give).
pub(crate) fn try_vec<T>(len: usize) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len)
        .map_err(|_| Error::Limits(format!("cannot allocate {len} values of {} bytes", size_of::<T>())))?;
    Ok(v)
}

/// `values` appended to `v`, or [`Error::Limits`] if the memory for them
/// is not there.
pub(crate) fn try_extend<T: Copy>(v: &mut Vec<T>, values: &[T]) -> Result<()> {
    v.try_reserve(values.len())
        .map_err(|_| Error::Limits(format!("cannot allocate {} values of {} bytes", values.len(), size_of::<T>())))?;
    v.extend_from_slice(values);
    Ok(())
}

/// `v` resized to `len` (new values `value`), or [`Error::Limits`] if the
/// memory for them is not there.
pub(crate) fn try_resize<T: Clone>(v: &mut Vec<T>, len: usize, value: T) -> Result<()> {
    v.try_reserve(len.saturating_sub(v.len()))
        .map_err(|_| Error::Limits(format!("cannot allocate {len} values of {} bytes", size_of::<T>())))?;
    v.resize(len, value);
    Ok(())
}

/// [`try_vec`] holding `len` copies of `value`, written in parallel. The
/// first write to each page of a large vector costs a page fault, and a
/// serial fill of one plane of a 4096² image (134 MB) took 70 ms of the
/// height inverse's 2 s on one core while the other waited.
pub(crate) fn try_filled<T: Copy + Send + Sync>(len: usize, value: T) -> Result<Vec<T>> {
    use crate::par::prelude::*;
    let mut v = try_vec(len)?;
    v.par_extend((0..len).into_par_iter().map(|_| value));
    Ok(v)
}

/// `width * height`, or the error naming a size that overflows.
pub(crate) fn image_len(width: usize, height: usize) -> Result<usize> {
    width
        .checked_mul(height)
        .ok_or_else(|| Error::InvalidOption(format!("an image of {width}×{height} texels is too large")))
}

/// Fails unless every plane holds at least `len` values.
pub(crate) fn check_planes(planes: &[&[f32]], len: usize) -> Result<()> {
    match planes.iter().find(|p| p.len() < len) {
        Some(short) => Err(Error::BufferSize { expected: len, actual: short.len() }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_are_one_over_the_top_value() {
        assert!((contract(255u8) - 1.0).abs() < 1e-15);
        assert!((contract(65535u16) - 1.0).abs() < 1e-15);
        assert_eq!(contract(0u16), 0.0);
        assert_eq!(contract(0.25f32), 0.25);
        // 30000 / 65535 in f64, not rounded through f32.
        assert!((contract(30000u16) - 30000.0 / 65535.0).abs() < 1e-16);
        assert_ne!(contract(30000u16), f64::from(30000.0f32 / 65535.0));
    }

    #[test]
    fn samples_convert_to_contract_f32() {
        let s = Samples::U16(vec![0, 65535, 32768]);
        assert_eq!(s.to_f32().unwrap(), vec![0.0, 1.0, (32768.0f64 / 65535.0) as f32]);
        assert!((Samples::U8(vec![51]).height(0).unwrap() - 0.2).abs() < 1e-16);
        assert_eq!(Samples::U8(vec![51]).height(1), None);
        let mut two = [7.0f32; 2];
        assert!(Samples::U16(vec![1, 2]).heights_f32_into(1, &mut two).is_err());
        assert_eq!(two, [7.0; 2], "a refused read leaves the buffer");
        assert_eq!(Samples::F64(vec![f64::NAN, 1.0, 2.0, f64::INFINITY]).first_non_finite(2), Some((0, 0)));
        assert_eq!(Samples::F32(vec![1.0, 2.0, 3.0, f32::INFINITY]).first_non_finite(2), Some((1, 1)));
        assert_eq!(Samples::U8(vec![0; 4]).first_non_finite(2), None);
    }
}
