//! The border modes a caller asks for: each axis fixed (wrap, clamp,
//! mirror) or `auto`, which the tiling check settles (wrap where the image
//! tiles, mirror where it does not), and the warnings the check gives
//! about a wrap that draws a seam. The conversion, the lit view and the
//! Python package all settle borders here.

use std::fmt;

use crate::error::{Error, Result};
use crate::normal_map::KindChoice;
use crate::tiling::{HeightSeams, TilingOptions, TilingReport};
use crate::{Border, Borders};

/// One axis's border mode: as given, or chosen by the tiling check.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BorderChoice {
    /// This mode, whatever the image.
    Fixed(Border),
    /// Wrap if the image tiles along the axis, else mirror.
    Auto,
}

/// The border choice of each axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BorderChoices {
    /// Left and right.
    pub x: BorderChoice,
    /// Top and bottom.
    pub y: BorderChoice,
}

impl BorderChoices {
    /// The same choice on both axes.
    #[must_use]
    pub fn both(choice: BorderChoice) -> BorderChoices {
        BorderChoices { x: choice, y: choice }
    }

    /// The modes themselves, for what was made with known borders (a
    /// normal map going back to heights): `auto` names no mode.
    ///
    /// Errors: [`Error::InvalidOption`] when an axis is `auto`.
    pub fn fixed(&self) -> Result<Borders> {
        match (self.x, self.y) {
            (BorderChoice::Fixed(x), BorderChoice::Fixed(y)) => Ok(Borders { x, y }),
            _ => Err(Error::InvalidOption(
                "border of a normal map names the modes it was made with (wrap, clamp, mirror), not auto".into(),
            )),
        }
    }

    /// Whether an axis is [`BorderChoice::Auto`].
    #[must_use]
    pub fn any_auto(&self) -> bool {
        self.x == BorderChoice::Auto || self.y == BorderChoice::Auto
    }

    /// Whether these borders need the tiling check: a wrap (to warn when
    /// it draws a seam) or `auto`.
    #[must_use]
    pub fn needs_check(&self) -> bool {
        let check = |c: BorderChoice| matches!(c, BorderChoice::Auto | BorderChoice::Fixed(Border::Wrap));
        check(self.x) || check(self.y)
    }

    /// The border modes for one image: `auto` becomes wrap where the image
    /// tiles and mirror where it does not (`report`: the tiling check;
    /// without it, `auto` is mirror).
    #[must_use]
    pub fn resolve(&self, report: Option<&TilingReport>) -> Borders {
        let suggested = report.map_or(Borders::both(Border::Mirror), TilingReport::suggested_borders);
        let resolve = |asked: BorderChoice, auto: Border| match asked {
            BorderChoice::Fixed(b) => b,
            BorderChoice::Auto => auto,
        };
        Borders { x: resolve(self.x, suggested.x), y: resolve(self.y, suggested.y) }
    }

    /// The border modes for heights held in memory (`width` × `height`,
    /// row-major, any [`Sample`](crate::Sample) type): `auto` settled by
    /// the tiling check of a height map, as a conversion settles it;
    /// fixed modes as they are, without a check.
    ///
    /// Errors: those of [`HeightSeams`] (the memory for the check, heights
    /// that are not `width` × `height`).
    pub fn settle<H: crate::Sample>(&self, heights: &[H], width: usize, height: usize) -> Result<Borders> {
        self.settle_with_holes(heights, width, height, None)
    }

    /// [`settle`](Self::settle) for heights with holes: texels equal to
    /// `nodata` (as stored, the fit's rule) and non-finite ones are
    /// skipped by the tiling check ([holes](crate::tiling#holes)).
    ///
    /// Errors: as [`settle`](Self::settle).
    pub fn settle_with_holes<H: crate::Sample>(
        &self,
        heights: &[H],
        width: usize,
        height: usize,
        nodata: Option<f64>,
    ) -> Result<Borders> {
        if !self.any_auto() {
            return Ok(self.resolve(None));
        }
        if Some(heights.len()) != width.checked_mul(height) {
            return Err(Error::BufferSize { expected: width.saturating_mul(height), actual: heights.len() });
        }
        let mut seams = HeightSeams::new(width, height)?.with_nodata(nodata);
        seams.push_heights(heights)?;
        Ok(self.resolve(Some(&seams.finish(&TilingOptions::new().with_kind(KindChoice::Height))?)))
    }

    /// The warning about a wrap asked for on an axis that does not tile
    /// (it draws a seam there), if there is one.
    #[must_use]
    pub fn seams(&self, report: &TilingReport) -> Option<Warning> {
        let wrap = BorderChoice::Fixed(Border::Wrap);
        let seam = |asked: BorderChoice, axis: crate::tiling::AxisReport| {
            (asked == wrap && !axis.seamless).then_some(axis.score)
        };
        let (x, y) = (seam(self.x, report.x), seam(self.y, report.y));
        (x.is_some() || y.is_some()).then_some(Warning::Seams { x, y })
    }
}

impl std::str::FromStr for BorderChoice {
    type Err = Error;

    /// A [`Border`]'s name, or `auto`.
    fn from_str(s: &str) -> Result<Self> {
        if s.trim().eq_ignore_ascii_case("auto") {
            return Ok(BorderChoice::Auto);
        }
        s.parse::<Border>().map(BorderChoice::Fixed).map_err(|_| {
            let names: Vec<&str> = Border::ALL.iter().map(|b| b.name()).chain(["auto"]).collect();
            Error::InvalidOption(format!("unknown border mode '{}': use {}", s.trim(), crate::options::one_of(&names)))
        })
    }
}

impl std::str::FromStr for BorderChoices {
    type Err = Error;

    /// One choice for both axes (`mirror`), or x then y (`wrap,auto`).
    fn from_str(s: &str) -> Result<Self> {
        match s.split_once(',') {
            None => Ok(BorderChoices::both(s.parse()?)),
            Some((x, y)) => Ok(BorderChoices { x: x.parse()?, y: y.parse()? }),
        }
    }
}

impl From<Borders> for BorderChoices {
    fn from(b: Borders) -> Self {
        BorderChoices { x: BorderChoice::Fixed(b.x), y: BorderChoice::Fixed(b.y) }
    }
}

/// Something the caller may want to tell its user; the work went on.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Warning {
    /// A wrap was asked for along an axis that does not tile, so the
    /// normal map shows a seam there: the seam scores of those axes.
    Seams {
        /// The seam score along x, if x wraps and does not tile.
        x: Option<f64>,
        /// The seam score along y, if y wraps and does not tile.
        y: Option<f64>,
    },
    /// The tiling check, which only warns here, was skipped: its memory
    /// was not there (a conversion of an image 2^24 texels wide can fit
    /// where its check does not).
    SeamCheckSkipped(String),
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Warning::Seams { x, y } => {
                let axes: Vec<String> = [("x", x), ("y", y)]
                    .iter()
                    .filter_map(|(name, score)| score.map(|s| format!("{name} (seam score {s:.2})")))
                    .collect();
                write!(f, "does not tile along {}: wrap borders will show a seam there", axes.join(" and "))
            }
            Warning::SeamCheckSkipped(why) => write!(f, "seam check skipped: {why}"),
        }
    }
}
