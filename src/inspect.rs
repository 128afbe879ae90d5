//! Decoded images inspected as `normalfit tiling` does: the tiling report
//! of an image file whatever it holds (a normal map judged on its R, G, B
//! planes, a height map on its height), and the previews that show its
//! seams.

use std::path::Path;

use crate::error::Result;
use crate::io::{self, Channel, Raster, ReadOptions};
use crate::normal_map::{ImageKind, KindChoice, kind_of, rgb_planes};
use crate::options::{Convention, Options, Strength};
use crate::shade::{Light, shade};
use crate::tiling::{self, TilingOptions, TilingReport};

/// The tiling report of a decoded image: its kind as `opts.kind` says or
/// detected ([`kind_of`]); a normal map judged on its R, G, B planes, a
/// height map on its height (`channel`, else SPEC §1's rule). A height
/// map's holes are skipped ([holes](crate::tiling#holes)) when a nodata
/// value is known: `opts.nodata` (as stored, as `--nodata` gives it),
/// else the GeoTIFF's GDAL_NODATA tag as read.
///
/// Errors: those of [`kind_of`] and of reading the height.
pub fn tiling_report(raster: &Raster, opts: &TilingOptions, channel: Option<&Channel>) -> Result<TilingReport> {
    let (w, h) = (raster.width, raster.height);
    let kind = kind_of(raster, opts.kind, channel)?;
    let fixed = TilingOptions {
        kind: match kind {
            ImageKind::Height => KindChoice::Height,
            ImageKind::Normal => KindChoice::Normal,
        },
        ..*opts
    };
    let holes = crate::io::read::georef::holes_value(opts.nodata, raster.georef.as_ref());
    match (kind, rgb_planes(raster)?) {
        (ImageKind::Normal, Some(planes)) => {
            tiling::check(&planes.each_ref().map(Vec::as_slice), w, h, &fixed.with_nodata(None))
        }
        (_, _) if holes.is_some() => {
            // The heights as a conversion's fit reads them, holes and all:
            // the streamed check takes them in their own type.
            let nodata = holes.unwrap_or(f64::NAN);
            let (heights, nodata) = raster.clone().into_heights_with_holes(channel.cloned(), false, nodata)?;
            let mut seams = tiling::HeightSeams::new(w, h)?.with_nodata(Some(nodata));
            seams.push_samples(&heights)?;
            seams.finish(&fixed)
        }
        _ => {
            let heights = raster.heights(channel.cloned())?;
            tiling::check(&[&heights], w, h, &fixed)
        }
    }
}

/// [`tiling_report`] of the image at `path`, and the decoded image (for
/// its size, or previews).
///
/// Errors: those of [`io::read_path`] and [`tiling_report`].
pub fn tiling_report_of_file(
    path: &Path,
    read: &ReadOptions,
    opts: &TilingOptions,
    channel: Option<&Channel>,
) -> Result<(Raster, TilingReport)> {
    let raster = io::read_path(path, read)?;
    let report = tiling_report(&raster, opts, channel)?;
    Ok((raster, report))
}

/// The image as it is, shifted by half its size so both wrap seams cross
/// the middle, as 8-bit RGB: a normal map's colours, or a height map's
/// heights stretched to the full gray range (so any map is visible).
///
/// Errors: those of reading the planes or the height.
pub fn seam_preview(raster: &Raster, report: &TilingReport, channel: Option<&Channel>) -> Result<Vec<[u8; 3]>> {
    let (w, h) = (raster.width, raster.height);
    let rgb = match (report.kind, rgb_planes(raster)?) {
        (ImageKind::Normal, Some(planes)) => {
            (0..w * h).map(|k| planes.each_ref().map(|p| (p[k].clamp(0.0, 1.0) * 255.0).round() as u8)).collect()
        }
        _ => stretched_gray(&raster.heights(channel.cloned())?),
    };
    tiling::shift_half(&rgb, w, h)
}

/// The image lit by the default light, shifted by half its size, as 8-bit
/// RGB: a normal map's colours read back as n = 2c − 1, or a height map's
/// normals fitted with a gain that makes its relief visible whatever its
/// units (the typical step between neighbours a slope of 0.3).
///
/// Errors: those of reading the planes or the height, and of the fit.
pub fn seam_preview_lit(raster: &Raster, report: &TilingReport, channel: Option<&Channel>) -> Result<Vec<[u8; 3]>> {
    let (w, h) = (raster.width, raster.height);
    let normals: Vec<[f32; 3]> = match (report.kind, rgb_planes(raster)?) {
        (ImageKind::Normal, Some(_)) => crate::normal_map::decode(raster, false)?,
        _ => {
            let heights = raster.heights(channel.cloned())?;
            let opts = Options::new().with_strength(Strength::Scale(exposure(&heights, w)));
            crate::normals(&heights, w, h, &opts)?
        }
    };
    let gray = shade(&normals, w, h, Light::default(), Convention::OpenGl)?;
    let rgb: Vec<[u8; 3]> = gray.iter().map(|&g| [g; 3]).collect();
    tiling::shift_half(&rgb, w, h)
}

/// Heights stretched to the full gray range.
fn stretched_gray(heights: &[f32]) -> Vec<[u8; 3]> {
    let (lo, hi) = heights.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let span = if hi > lo { hi - lo } else { 1.0 };
    heights.iter().map(|&v| [((v - lo) / span * 255.0).round() as u8; 3]).collect()
}

/// A gain that makes the typical step between neighbours a slope of 0.3
/// (about 17°): enough relief to see creases whatever the map's units.
fn exposure(heights: &[f32], width: usize) -> f64 {
    let steps = heights.windows(2).enumerate().filter(|(k, _)| (k + 1) % width != 0);
    let (sum, count) = steps.fold((0.0f64, 0usize), |(s, c), (_, p)| (s + f64::from((p[1] - p[0]).abs()), c + 1));
    let mean = if count > 0 { sum / count as f64 } else { 0.0 };
    if mean > 0.0 { 0.3 / mean } else { 1.0 }
}
