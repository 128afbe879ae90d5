//! What the tiling check is asked ([`TilingOptions`]) and what it answers
//! ([`TilingReport`], an [`AxisReport`] per axis).

use crate::error::Number;
use crate::normal_map::{ImageKind, KindChoice};
use crate::options::{Border, Borders};
use crate::{Error, Result};

/// The default [`TilingOptions::threshold`]; see the [module docs](crate::tiling)
/// for the figures it was chosen from.
pub const DEFAULT_THRESHOLD: f64 = 1.5;

/// What [`check`](super::check) is asked to do.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct TilingOptions {
    /// An axis is seamless when its score is at most this. Default:
    /// [`DEFAULT_THRESHOLD`] (1.5). A NaN threshold passes nothing.
    pub threshold: f64,
    /// What the planes hold. Default: [`KindChoice::Auto`].
    pub kind: KindChoice,
    /// Holes: with a value, texels equal to it and non-finite ones are not
    /// heights, and every pair that reads one is skipped (see the
    /// [module docs](crate::tiling#holes)); NaN makes only the non-finite
    /// texels holes. Default: `None`, and [`check`](super::check) refuses
    /// a non-finite texel.
    pub nodata: Option<f64>,
}

impl Default for TilingOptions {
    fn default() -> Self {
        TilingOptions { threshold: DEFAULT_THRESHOLD, kind: KindChoice::Auto, nodata: None }
    }
}

impl TilingOptions {
    /// The defaults: threshold 1.5, kind detected.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets [`threshold`](Self::threshold).
    #[must_use]
    pub fn with_threshold(mut self, threshold: f64) -> Self {
        self.threshold = threshold;
        self
    }

    /// Sets [`kind`](Self::kind).
    #[must_use]
    pub fn with_kind(mut self, kind: KindChoice) -> Self {
        self.kind = kind;
        self
    }

    /// Sets [`nodata`](Self::nodata).
    #[must_use]
    pub fn with_nodata(mut self, nodata: Option<f64>) -> Self {
        self.nodata = nodata;
        self
    }

    /// Checks the options as a caller gave them: the threshold must be a
    /// positive number (the library itself judges with any value; a NaN
    /// passes nothing).
    ///
    /// Errors: [`Error::InvalidOption`] naming the threshold.
    pub fn validate(&self) -> Result<()> {
        if self.threshold.is_nan() || self.threshold <= 0.0 {
            return Err(Error::InvalidOption(format!("threshold must be positive, got {}", Number(self.threshold))));
        }
        Ok(())
    }
}

/// The verdict on one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct AxisReport {
    /// How the wrap pair compares with the interior pairs: about 1 or less
    /// when it looks like them, larger for a more visible seam. Finite and
    /// positive, but infinite when holes leave no pair of valid texels
    /// across the seam (or none inside to compare it with): nothing shows
    /// that the axis tiles. Never NaN.
    pub score: f64,
    /// `score <= threshold`.
    pub seamless: bool,
}

/// The verdict on an image: the kind judged, and each axis.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct TilingReport {
    /// What the image was judged as (given, or detected).
    pub kind: ImageKind,
    /// The x seam: last column against first.
    pub x: AxisReport,
    /// The y seam: last row against first.
    pub y: AxisReport,
}

impl TilingReport {
    /// Whether the image tiles on both axes.
    #[must_use]
    pub fn seamless(&self) -> bool {
        self.x.seamless && self.y.seamless
    }

    /// Wrap on the axes that tile, mirror on the others: borders that add
    /// no seam of their own (what `normalfit convert --border auto` uses).
    /// Mirror rather than clamp, because clamping flattens the slope at the
    /// edge while mirroring keeps the texels' own neighbourhood.
    #[must_use]
    pub fn suggested_borders(&self) -> Borders {
        let pick = |axis: &AxisReport| if axis.seamless { Border::Wrap } else { Border::Mirror };
        Borders { x: pick(&self.x), y: pick(&self.y) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggested_borders_wrap_only_what_tiles() {
        let axis = |seamless| AxisReport { score: if seamless { 1.0 } else { 9.0 }, seamless };
        let r = TilingReport { kind: ImageKind::Height, x: axis(true), y: axis(false) };
        assert_eq!(r.suggested_borders(), Borders { x: Border::Wrap, y: Border::Mirror });
    }
}
