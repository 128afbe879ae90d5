//! SPEC §1's channel rule: which channel of a decoded image, or which three
//! for luma, hold the height ([`Raster::heights`]).

use std::fmt;

use crate::par::prelude::*;

use crate::error::{Error, Result};
use crate::io::{InputFormat, Plane, Raster};
use crate::samples::{Samples, luma, try_vec};

/// Which channel of the image gives the height (SPEC §1, `--channel`).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Channel {
    /// 0.2126 R + 0.7152 G + 0.0722 B of the stored values; the gray
    /// channel of a gray image.
    Luma,
    /// Red (the gray channel of a gray image).
    R,
    /// Green (the gray channel of a gray image).
    G,
    /// Blue (the gray channel of a gray image).
    B,
    /// Alpha; an error when the image has none.
    A,
    /// A channel by name, as `--channel` passes it: an OpenEXR channel of
    /// exactly this name ("Z", "height", "disparityL.x"; with a layer
    /// chosen, also the name within it), else one of the keywords above
    /// in any case ("luma", "R"), else the one OpenEXR channel whose name
    /// matches in any case. Formats other than OpenEXR take the keywords
    /// only.
    Named(String),
}

impl Channel {
    /// The channel a caller names (`--channel`, `channel=`): a keyword
    /// (luma, r, g, b, a) or an OpenEXR channel's name, kept as
    /// [`Channel::Named`] and resolved per file by the rule of
    /// [`Raster::heights`].
    ///
    /// Errors: [`Error::InvalidOption`] for an empty name, which no
    /// channel has.
    ///
    /// ```
    /// use normalfit::io::Channel;
    /// assert_eq!(Channel::named("Z").unwrap(), Channel::Named("Z".into()));
    /// assert!(Channel::named("").is_err());
    /// ```
    pub fn named(name: &str) -> Result<Channel> {
        if name.is_empty() {
            return Err(Error::InvalidOption(
                "expected luma, r, g, b, a or an OpenEXR channel's name, got an empty name".into(),
            ));
        }
        Ok(Channel::Named(name.to_string()))
    }

    /// The keyword this channel is: itself, or for [`Channel::Named`] the
    /// keyword its name spells in any case.
    fn keyword(&self) -> Option<Channel> {
        let Channel::Named(name) = self else { return Some(self.clone()) };
        Some(match name.to_ascii_lowercase().as_str() {
            "luma" => Channel::Luma,
            "r" => Channel::R,
            "g" => Channel::G,
            "b" => Channel::B,
            "a" => Channel::A,
            _ => return None,
        })
    }
}

impl fmt::Display for Channel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Channel::Luma => "luma",
            Channel::R => "r",
            Channel::G => "g",
            Channel::B => "b",
            Channel::A => "a",
            Channel::Named(name) => name,
        })
    }
}

impl Raster {
    /// The heights in contract units, row-major, chosen by `channel` as
    /// SPEC §1 says (`None` is the default rule).
    ///
    /// * A gray image (a "Y" plane, or an EXR's only channel) gives its gray
    ///   channel for `None`, `Luma`, `R`, `G` and `B`.
    /// * A colour image gives luma of R, G, B for `None` and `Luma`, else
    ///   the channel asked for.
    /// * An EXR applies the rule to its root channels, those whose names
    ///   have no dot: "Y", then its only root channel, then luma of R, G,
    ///   B, matching names in any case. A channel `layer.name` is a layer's
    ///   ("disparityL.y" is never the image's Y); the layers are read by
    ///   choosing one ([`ReadOptions::layer`](super::ReadOptions::layer))
    ///   or a channel by its full name. When every channel shares one layer ("diffuse.R",
    ///   "diffuse.G", …), the names within it are the root; when they are
    ///   spread over several layers and none is at the root, the default
    ///   is an error naming the layers.
    /// * `A` gives alpha, an error when there is none.
    /// * [`Channel::Named`] picks an EXR channel by its exact name first
    ///   (see there).
    ///
    /// The heights are rounded to `f32`, for views and checks; the fit
    /// takes the samples themselves ([`Raster::into_heights`]).
    ///
    /// Errors: [`Error::Unsupported`] when the channel is missing,
    /// [`Error::NonFiniteHeight`] naming the first NaN or infinite height in
    /// row order.
    pub fn heights(&self, channel: Option<Channel>) -> Result<Vec<f32>> {
        let heights = match self.select(channel.as_ref())? {
            Source::Plane(i) => self.planes[i].data.to_f32()?,
            Source::Luma(rgb) => self.luma(rgb)?.into_f32()?,
        };
        // After the rounding: a double beyond f32's range is infinite here.
        match crate::samples::first_non_finite(&heights, self.width.max(1)) {
            None => Ok(heights),
            Some((x, y)) => Err(Error::NonFiniteHeight { x, y }),
        }
    }

    /// The samples the heights are made of, chosen as [`Raster::heights`]
    /// chooses them, as stored (one channel, moved out, not copied) or as
    /// luma in f64: what the fit reads, with no rounding between the file
    /// and the fit.
    ///
    /// Errors: as [`Raster::heights`].
    pub fn into_heights(self, channel: Option<Channel>) -> Result<Samples> {
        self.into_heights_checked(channel, true)
    }

    /// [`Raster::into_heights`], NaN and infinite heights refused (`check`)
    /// or kept (holes).
    fn into_heights_checked(mut self, channel: Option<Channel>, check: bool) -> Result<Samples> {
        let heights = match self.select(channel.as_ref())? {
            Source::Plane(i) => self.planes.swap_remove(i).data,
            Source::Luma(rgb) => self.luma(rgb)?,
        };
        if check {
            self.check_finite(&heights)?;
        }
        Ok(heights)
    }

    /// The heights with holes (docs/terrain.md, "Holes"): as
    /// [`Raster::into_stored_heights`] gives them (`stored`) or as
    /// [`Raster::into_heights`] does, NaN and infinite values kept, and the
    /// value a nodata value `nodata` (as stored: a DEM's −32768) becomes
    /// among them. Stored integers that were divided when decoded (signed
    /// and 32-bit ones, in contract units) cannot be compared with it
    /// exactly: those equal to it once multiplied back are made NaN, and
    /// the value returned is NaN.
    ///
    /// Errors: as [`Raster::heights`], but no [`Error::NonFiniteHeight`].
    pub fn into_heights_with_holes(
        self,
        channel: Option<Channel>,
        stored: bool,
        nodata: f64,
    ) -> Result<(Samples, f64)> {
        let scale = self.sample.stored_per_unit();
        if stored {
            return Ok((self.into_stored_heights_checked(channel, false)?, nodata));
        }
        let heights = self.into_heights_checked(channel, false)?;
        let divided = |v: &mut f64| {
            if (*v * scale).round() == nodata {
                *v = f64::NAN;
            }
        };
        Ok(match heights {
            Samples::F64(mut values) if scale != 1.0 && nodata.is_finite() => {
                values.iter_mut().for_each(divided);
                (Samples::F64(values), f64::NAN)
            }
            Samples::F32(mut values) if scale != 1.0 && nodata.is_finite() => {
                for v in &mut values {
                    let mut d = f64::from(*v);
                    divided(&mut d);
                    if d.is_nan() {
                        *v = f32::NAN;
                    }
                }
                (Samples::F32(values), f64::NAN)
            }
            other => (other, nodata),
        })
    }

    /// The heights as the file stored them, chosen as [`Raster::heights`]
    /// chooses them, in f64: a DEM's int16 metres as metres, a 16-bit
    /// PNG's or RAW's integers as integers, floats unchanged; luma of
    /// stored values for a colour image. This is each height in contract
    /// units times [`SampleType::stored_per_unit`](crate::io::SampleType::stored_per_unit),
    /// with integers made whole again (the signed and 32-bit ones were
    /// divided in f64 when decoded; rounding the product undoes that
    /// exactly, its error being under 2⁻²⁰). For fits in the file's own
    /// units (docs/terrain.md).
    ///
    /// Errors: as [`Raster::heights`].
    pub fn into_stored_heights(self, channel: Option<Channel>) -> Result<Samples> {
        self.into_stored_heights_checked(channel, true)
    }

    fn into_stored_heights_checked(self, channel: Option<Channel>, check: bool) -> Result<Samples> {
        let scale = self.sample.stored_per_unit();
        let whole = matches!(self.sample, crate::io::SampleType::Int { bits } | crate::io::SampleType::SignedInt { bits } if bits <= 32)
            && !matches!(self.select(channel.as_ref())?, Source::Luma(_));
        let heights = self.into_heights_checked(channel, check)?;
        if scale == 1.0 {
            return Ok(heights);
        }
        let mut out = try_vec(heights.len())?;
        let at = |i: usize| heights.height(i).unwrap_or(0.0) * scale;
        if whole {
            out.par_extend((0..heights.len()).into_par_iter().map(|i| at(i).round()));
        } else {
            out.par_extend((0..heights.len()).into_par_iter().map(at));
        }
        Ok(Samples::F64(out))
    }

    /// The plane with exactly this name, if any.
    #[must_use]
    pub fn plane(&self, name: &str) -> Option<&Plane> {
        self.planes.iter().find(|p| p.name == name)
    }

    /// Applies SPEC §1's channel rule to this raster's plane names.
    fn select(&self, channel: Option<&Channel>) -> Result<Source> {
        let names: Vec<&str> = self.planes.iter().map(|p| p.name.as_str()).collect();
        select_channel(&names, channel, &self.format)
    }

    /// Luma of three planes in contract units, each texel in f64 by the one
    /// formula every reader uses ([`luma`]).
    fn luma(&self, [r, g, b]: [usize; 3]) -> Result<Samples> {
        let (r, g, b) = (&self.planes[r].data, &self.planes[g].data, &self.planes[b].data);
        let len = r.len().min(g.len()).min(b.len());
        let mut out = try_vec(len)?;
        // Every i < len is in all three planes: `height` gives Some.
        let at = |p: &Samples, i: usize| p.height(i).unwrap_or(0.0);
        out.par_extend((0..len).into_par_iter().map(|i| luma(at(r, i), at(g, i), at(b, i))));
        Ok(Samples::F64(out))
    }

    /// SPEC §1: a NaN or infinite height is an error naming the first such
    /// texel in row order.
    fn check_finite<'s>(&self, heights: &'s Samples) -> Result<&'s Samples> {
        match heights.first_non_finite(self.width.max(1)) {
            None => Ok(heights),
            Some((x, y)) => Err(Error::NonFiniteHeight { x, y }),
        }
    }
}

/// Where the heights come from.
pub(crate) enum Source {
    /// One stored plane, by index.
    Plane(usize),
    /// Luma of the R, G, B planes at these indices.
    Luma([usize; 3]),
}

/// SPEC §1's channel rule (see [`Raster::heights`]) over a list of channel
/// names: which channel, or which three for luma, hold the height. The
/// names are an OpenEXR file's own when `format` is [`InputFormat::Exr`];
/// the other formats' planes have fixed names ("Y", "R", …) that
/// [`Channel::Named`] cannot pick, only its keywords.
pub(crate) fn select_channel(names: &[&str], channel: Option<&Channel>, format: &InputFormat) -> Result<Source> {
    let names = Names::new(names);
    let exr = *format == InputFormat::Exr;
    let keyword = match channel {
        None => Channel::Luma,
        Some(Channel::Named(name)) => {
            if let Some(i) = names.exact(name).filter(|_| exr) {
                return Ok(Source::Plane(i));
            }
            match channel.and_then(Channel::keyword) {
                Some(keyword) => keyword,
                None if exr => {
                    return names.unique_ignoring_case(name).map(Source::Plane).ok_or_else(|| {
                        Error::Unsupported(format!("no channel {name} (channels: {})", names.channel_list()))
                    });
                }
                None => {
                    return Err(Error::Unsupported(format!(
                        "no channel {name}: {format} images take luma, r, g, b or a (only OpenEXR channels are \
                         chosen by name)"
                    )));
                }
            }
        }
        Some(keyword) => keyword.clone(),
    };
    let roots = names.roots()?;
    let wanted = match keyword {
        Channel::R => Some("r"),
        Channel::G => Some("g"),
        Channel::B => Some("b"),
        Channel::A => {
            return names
                .find(&roots, "a")
                .map(Source::Plane)
                .ok_or_else(|| Error::Unsupported("image has no alpha channel".into()));
        }
        Channel::Luma | Channel::Named(_) => None,
    };
    // An explicit R, G or B names a stored channel when there is one,
    // overriding an EXR's "Y"; a gray image has none and gives gray.
    if let Some(i) = wanted.and_then(|name| names.find(&roots, name)) {
        return Ok(Source::Plane(i));
    }
    match (names.gray_plane(&roots), wanted) {
        (Some(i), _) => Ok(Source::Plane(i)),
        (None, Some(name)) => {
            Err(Error::Unsupported(format!("image has no {name} channel (channels: {})", names.channel_list())))
        }
        (None, None) => names.rgb(&roots).map(Source::Luma),
    }
}

/// Channel names, for the channel rule.
///
/// OpenEXR names channels `layer.name` ("diffuse.R", "disparityL.x"); a
/// name without a dot is a root channel. The rule's keywords (the default,
/// luma, r, g, b, a) look at the root channels only, so a layer's "x" or
/// "R" is never mistaken for the image's own. When every name shares a
/// layer prefix (a file or `--layer` holding one layer only), the names
/// after that prefix are the root.
struct Names<'a> {
    all: &'a [&'a str],
    /// The length of the layer prefix every name shares ("diffuse."), or 0.
    shared: usize,
}

impl<'a> Names<'a> {
    fn new(all: &'a [&'a str]) -> Self {
        let mut shared = 0;
        if let Some(first) = all.first() {
            for (dot, _) in first.match_indices('.') {
                let prefix = &first[..=dot];
                if !all.iter().all(|name| name.starts_with(prefix)) {
                    break;
                }
                shared = dot + 1;
            }
        }
        Names { all, shared }
    }

    /// A name after the shared layer prefix.
    fn relative(&self, i: usize) -> &'a str {
        &self.all[i][self.shared..]
    }

    /// The root channels, by index: names (after the shared prefix) without
    /// a dot. An error when every channel is in a layer and the layers
    /// differ: which one holds the height is the user's choice.
    fn roots(&self) -> Result<Vec<usize>> {
        let roots: Vec<usize> = (0..self.all.len()).filter(|&i| !self.relative(i).contains('.')).collect();
        if roots.is_empty() && !self.all.is_empty() {
            let mut layers: Vec<&str> = Vec::new();
            for i in 0..self.all.len() {
                let layer = self.relative(i).split('.').next().unwrap_or_default();
                let layer = &self.all[i][..self.shared + layer.len()];
                if !layers.contains(&layer) {
                    layers.push(layer);
                }
            }
            return Err(Error::Unsupported(format!(
                "every channel is in a layer ({}) and none is at the root: choose a layer, or a channel by its \
                 full name",
                layers.join(", ")
            )));
        }
        Ok(roots)
    }

    /// The channel of exactly this name, or of this name after the shared
    /// layer prefix ("x" for "disparityL.x" when the layer was chosen).
    fn exact(&self, name: &str) -> Option<usize> {
        (self.all.iter().position(|n| *n == name)).or_else(|| (0..self.all.len()).find(|&i| self.relative(i) == name))
    }

    /// The one channel whose name, whole or after the shared prefix,
    /// matches in any case; none when no channel or several do.
    fn unique_ignoring_case(&self, name: &str) -> Option<usize> {
        let matches: Vec<usize> = (0..self.all.len())
            .filter(|&i| self.all[i].eq_ignore_ascii_case(name) || self.relative(i).eq_ignore_ascii_case(name))
            .collect();
        match matches.as_slice() {
            [i] => Some(*i),
            _ => None,
        }
    }

    /// The gray channel: "Y" if present, else the only root channel.
    fn gray_plane(&self, roots: &[usize]) -> Option<usize> {
        let only = match roots {
            [only] => Some(*only),
            _ => None,
        };
        self.find(roots, "y").or(only)
    }

    /// The R, G and B planes that luma is made of.
    fn rgb(&self, roots: &[usize]) -> Result<[usize; 3]> {
        match (self.find(roots, "r"), self.find(roots, "g"), self.find(roots, "b")) {
            (Some(r), Some(g), Some(b)) => Ok([r, g, b]),
            _ => Err(Error::Unsupported(format!(
                "no usable height channel: need y, a single channel, or r, g and b (channels: {})",
                self.channel_list()
            ))),
        }
    }

    /// The root channel for a letter (lower case), in any case; the upper
    /// case one, OpenEXR's spelling, when both are there.
    fn find(&self, roots: &[usize], letter: &str) -> Option<usize> {
        let upper = letter.to_ascii_uppercase();
        (roots.iter().copied().find(|&i| self.relative(i) == upper))
            .or_else(|| roots.iter().copied().find(|&i| self.relative(i).eq_ignore_ascii_case(letter)))
    }

    /// The channel names, for messages.
    fn channel_list(&self) -> String {
        if self.all.is_empty() {
            return "none".into();
        }
        self.all.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_named_channel_is_kept_as_named_and_an_empty_name_refused() {
        for name in ["luma", "R", "Z", "diffuse.R", " "] {
            assert_eq!(Channel::named(name).unwrap(), Channel::Named(name.into()));
        }
        assert_eq!(
            Channel::named("").unwrap_err().to_string(),
            "invalid option: expected luma, r, g, b, a or an OpenEXR channel's name, got an empty name"
        );
    }
}
