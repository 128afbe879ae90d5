//! Georeferencing beside an output image: a world file and a GDAL
//! auxiliary file, so a normal map or lit view of a GeoTIFF overlays its
//! source in QGIS and other GDAL-based tools.
//!
//! * The world file (`<stem>.pgw` beside a PNG: the extension's first and
//!   last letters and `w`, as GDAL looks for it) holds six lines: x per
//!   column, y per column, x per row, y per row (a, d, b, e of
//!   [`Affine`](super::read::Affine)), then the model x and y of the *centre* of the top-left
//!   texel. The centre is raster point (0.5, 0.5) of a PixelIsArea
//!   GeoTIFF (GeoTIFF's default; the tiepoint names a texel's corner) and
//!   (0, 0) of a PixelIsPoint one (the tiepoint names its centre). GDAL
//!   reads the PixelIsPoint file the same way (its geotransform moves the
//!   origin half a texel to the corner), so both give the source's
//!   geotransform back.
//! * The auxiliary file (`<name>.aux.xml`) holds the coordinate system as
//!   its EPSG code (`<SRS>EPSG:32633</SRS>`), which GDAL resolves from its
//!   own database. Written only when the GeoTIFF names an EPSG code: a
//!   user-defined system would need its parameters turned into WKT, which
//!   is not done here.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::atomic::FileSet;
use super::read::{Georef, RasterType};
use crate::error::{Error, Result};

/// The six lines of the world file of `georef` (see the module), or
/// `None` without a transform.
#[must_use]
pub fn world_file(georef: &Georef) -> Option<String> {
    let t = georef.affine()?;
    let centre = match georef.raster_type {
        Some(RasterType::PixelIsPoint) => 0.0,
        _ => 0.5,
    };
    let (x, y) = t.apply(centre, centre);
    // `{:?}` prints the shortest text that reads back as the same f64.
    Some(format!("{:?}\n{:?}\n{:?}\n{:?}\n{x:?}\n{y:?}\n", t.a, t.d, t.b, t.e))
}

/// The world file's name beside `image`: the extension's first and last
/// letters and `w` (`.png` → `.pgw`), or `.wld` for an extension of fewer
/// than two letters.
#[must_use]
pub fn world_file_path(image: &Path) -> PathBuf {
    let ext = image.extension().and_then(|e| e.to_str()).unwrap_or("");
    let mut letters = ext.chars();
    match (letters.next(), letters.next_back()) {
        (Some(first), Some(last)) => image.with_extension(format!("{first}{last}w")),
        _ => image.with_extension("wld"),
    }
}

/// Writes the sidecars of `image` placed by `georef` (see the module)
/// into `files`, named with the image when the set is committed: the
/// world file when there is a transform, the auxiliary file when there is
/// an EPSG code too. Returns their paths (none without a transform).
///
/// Errors: [`crate::Error::Io`] when a sidecar would be the `input` file
/// (or a link to it), when the set's policy keeps a file there, or when a
/// file cannot be written.
pub fn write_sidecars(
    image: &Path,
    georef: &Georef,
    input: Option<&Path>,
    files: &mut FileSet,
) -> Result<Vec<PathBuf>> {
    let Some(world) = world_file(georef) else { return Ok(Vec::new()) };
    let mut sidecars = vec![(world_file_path(image), world)];
    if let Some(epsg) = georef.epsg {
        let mut name = image.as_os_str().to_owned();
        name.push(".aux.xml");
        sidecars.push((PathBuf::from(name), format!("<PAMDataset>\n  <SRS>EPSG:{epsg}</SRS>\n</PAMDataset>\n")));
    }
    // Every name checked before any is written.
    for (path, _) in &sidecars {
        if input.is_some_and(|input| super::same_file(input, path)) {
            let problem = format!(
                "the georeferencing file {} beside the output is the input: normalfit never writes over an input",
                path.display()
            );
            return Err(Error::Io(std::io::Error::new(std::io::ErrorKind::InvalidInput, problem)));
        }
    }
    let mut written = Vec::new();
    for (path, text) in sidecars {
        files.write(&path, |out| Ok(out.write_all(text.as_bytes())?))?;
        written.push(path);
    }
    Ok(written)
}
