//! GeoTIFF georeferencing: where a raster's texels are on the ground, read
//! from the tags GeoTIFF 1.1 (OGC 19-008r4) and GDAL define, so terrain can
//! be fitted in its own units (issue 17: a 30 m DEM fitted as if its texels
//! were 1 unit wide gives slopes 30 times too steep).
//!
//! Only what a fit in real-world units needs is read: the raster-to-model
//! transform (ModelPixelScale with a tiepoint, or ModelTransformation),
//! whether the model is projected or geographic (GTModelTypeGeoKey), the
//! EPSG code of its coordinate system, its linear and vertical units, and
//! GDAL's nodata value. Projections are not evaluated: a projected raster's
//! spacing is taken in its linear unit, a geographic one's converted to
//! metres on the WGS84 ellipsoid ([`metres_per_degree`]).

#[cfg(feature = "tiff")]
use crate::error::{Error, Result};

/// The GeoTIFF and GDAL tag numbers read here (by the TIFF reader, a
/// feature of its own).
#[cfg(feature = "tiff")]
pub(crate) mod tags {
    pub const MODEL_PIXEL_SCALE: u16 = 33550;
    pub const MODEL_TIEPOINT: u16 = 33922;
    pub const MODEL_TRANSFORMATION: u16 = 34264;
    pub const GEO_KEY_DIRECTORY: u16 = 34735;
    pub const GEO_DOUBLE_PARAMS: u16 = 34736;
    pub const GEO_ASCII_PARAMS: u16 = 34737;
    pub const GDAL_NODATA: u16 = 42113;
}

/// The GeoKeys read from the key directory (GeoTIFF 1.1, §7).
#[cfg(feature = "tiff")]
mod keys {
    pub const GT_MODEL_TYPE: u16 = 1024;
    pub const GT_RASTER_TYPE: u16 = 1025;
    pub const GEOGRAPHIC_TYPE: u16 = 2048;
    pub const GEOG_ANGULAR_UNITS: u16 = 2054;
    pub const PROJECTED_CS_TYPE: u16 = 3072;
    pub const PROJ_LINEAR_UNITS: u16 = 3076;
    pub const VERTICAL_CS_TYPE: u16 = 4096;
    pub const VERTICAL_UNITS: u16 = 4099;
    /// The value GeoTIFF uses for "user-defined": no EPSG code.
    pub const USER_DEFINED: u16 = 32767;
}

/// What kind of coordinates the model space holds (GTModelTypeGeoKey).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ModelType {
    /// Projected coordinates (metres, feet, … east and north): the
    /// spacing is a length in [`Georef::linear_unit`].
    Projected,
    /// Longitude and latitude in degrees (or [`Georef::angular_unit`]):
    /// the spacing is an angle, its length depends on the latitude.
    Geographic,
    /// Earth-centred cartesian coordinates.
    Geocentric,
    /// Another code, kept as stored.
    Other(u16),
}

impl ModelType {
    /// The model as messages name it: "projected", "geographic",
    /// "geocentric", or "code 7" for another.
    #[must_use]
    pub fn name(self) -> String {
        match self {
            ModelType::Projected => "projected".into(),
            ModelType::Geographic => "geographic".into(),
            ModelType::Geocentric => "geocentric".into(),
            ModelType::Other(code) => format!("code {code}"),
        }
    }
}

/// Whether a tiepoint names a texel's corner or its centre
/// (GTRasterTypeGeoKey).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum RasterType {
    /// Raster coordinate (0, 0) is the top-left corner of the first texel
    /// (GeoTIFF's default).
    PixelIsArea,
    /// Raster coordinate (0, 0) is the centre of the first texel.
    PixelIsPoint,
    /// Another code, kept as stored.
    Other(u16),
}

/// A raster's georeferencing as its GeoTIFF tags give it. Every field is
/// optional: a TIFF may carry some tags and not others.
#[derive(Clone, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct Georef {
    /// ModelPixelScaleTag: (ScaleX, ScaleY, ScaleZ), model units per texel,
    /// all positive by convention (ScaleY is the distance between rows; the
    /// rows go south, so the model y of row r is tiepoint y − r · ScaleY).
    pub pixel_scale: Option<[f64; 3]>,
    /// ModelTiepointTag: (I, J, K, X, Y, Z) each: raster point (I, J, K) is
    /// model point (X, Y, Z).
    pub tiepoints: Vec<[f64; 6]>,
    /// ModelTransformationTag: the 4 × 4 raster-to-model matrix, row-major.
    pub transformation: Option<[f64; 16]>,
    /// GTModelTypeGeoKey.
    pub model: Option<ModelType>,
    /// GTRasterTypeGeoKey.
    pub raster_type: Option<RasterType>,
    /// The EPSG code of the coordinate system: ProjectedCSTypeGeoKey for a
    /// projected model, GeographicTypeGeoKey for a geographic one; `None`
    /// when absent or user-defined (32767).
    pub epsg: Option<u16>,
    /// The EPSG code of the vertical coordinate system
    /// (VerticalCSTypeGeoKey), when given and not user-defined.
    pub vertical_epsg: Option<u16>,
    /// ProjLinearUnitsGeoKey: the EPSG unit of projected coordinates
    /// (9001 metre, 9002 foot, 9003 US survey foot, …).
    pub linear_unit: Option<u16>,
    /// GeogAngularUnitsGeoKey: the EPSG unit of geographic coordinates
    /// (9102 degree, 9101 radian, …).
    pub angular_unit: Option<u16>,
    /// VerticalUnitsGeoKey: the EPSG unit of the heights.
    pub vertical_unit: Option<u16>,
    /// GDAL_NODATA (tag 42113), parsed: the stored value that marks a
    /// missing texel (NaN when the tag says "nan").
    pub nodata: Option<f64>,
    /// The georeferencing tags as stored, which a GeoTIFF written from
    /// this raster copies: every key (a user-defined coordinate system's
    /// parameters too) stays as the source had it.
    pub(crate) stored: StoredGeoTags,
}

/// A GeoTIFF's georeferencing tags, as stored (empty when absent).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct StoredGeoTags {
    pub(crate) pixel_scale: Vec<f64>,
    pub(crate) tiepoints: Vec<f64>,
    pub(crate) transformation: Vec<f64>,
    pub(crate) key_directory: Vec<u16>,
    pub(crate) double_params: Vec<f64>,
    pub(crate) ascii_params: String,
}

/// The raster-to-model map of a georeferenced raster:
/// model x = a · col + b · row + c, model y = d · col + e · row + f, for
/// raster coordinates (col, row) as the GeoTIFF's raster type defines them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine {
    /// Model x per column.
    pub a: f64,
    /// Model x per row (0 unless rotated or sheared).
    pub b: f64,
    /// Model x of raster (0, 0).
    pub c: f64,
    /// Model y per column (0 unless rotated or sheared).
    pub d: f64,
    /// Model y per row: negative for the usual north-up raster.
    pub e: f64,
    /// Model y of raster (0, 0).
    pub f: f64,
}

impl Affine {
    /// The model point of raster coordinates (col, row).
    #[must_use]
    pub fn apply(&self, col: f64, row: f64) -> (f64, f64) {
        (self.a * col + self.b * row + self.c, self.d * col + self.e * row + self.f)
    }
}

impl Georef {
    /// Whether any georeferencing tag was present.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        *self == Georef::default()
    }

    /// The raster-to-model map: from ModelTransformation when present
    /// (it wins, as in GDAL), else from ModelPixelScale and the first
    /// tiepoint (x = X + (col − I) · ScaleX, y = Y − (row − J) · ScaleY).
    /// `None` without either.
    #[must_use]
    pub fn affine(&self) -> Option<Affine> {
        if let Some(m) = self.transformation {
            return Some(Affine { a: m[0], b: m[1], c: m[3], d: m[4], e: m[5], f: m[7] });
        }
        let [sx, sy, _] = self.pixel_scale?;
        let [i, j, _, x, y, _] = *self.tiepoints.first()?;
        Some(Affine { a: sx, b: 0.0, c: x - i * sx, d: 0.0, e: -sy, f: y + j * sy })
    }

    /// The signed model step from one column to the next and from one row
    /// to the next, (a, e) of [`Georef::affine`]: y is usually negative
    /// (rows go south). `None` when there is no transform, or when it
    /// rotates or shears the raster (then use [`Georef::spacing`]).
    #[must_use]
    pub fn pixel_size(&self) -> Option<(f64, f64)> {
        let t = self.affine()?;
        (t.b == 0.0 && t.d == 0.0).then_some((t.a, t.e))
    }

    /// The distance in model units between neighbouring texel centres
    /// along a row and along a column, (√(a² + d²), √(b² + e²)): what a
    /// fit needs, rotated or not. For a geographic model these are angles
    /// (see [`Georef::spacing_metres`]).
    #[must_use]
    pub fn spacing(&self) -> Option<(f64, f64)> {
        let t = self.affine()?;
        Some((t.a.hypot(t.d), t.b.hypot(t.e)))
    }

    /// Whether the model is longitude and latitude.
    #[must_use]
    pub fn is_geographic(&self) -> bool {
        self.model == Some(ModelType::Geographic)
    }

    /// The spacing in metres at raster row `row` (its centre): for a
    /// projected model, [`Georef::spacing`] times the linear unit in
    /// metres (metres when the unit is not given); for a geographic model
    /// (degrees, or the angular unit given), the angles converted at that
    /// row's latitude by [`metres_per_degree`]. `None` without a transform,
    /// for a geocentric or unknown model, an unknown unit, or a rotated
    /// geographic raster (its rows do not follow parallels).
    #[must_use]
    pub fn spacing_metres(&self, row: f64) -> Option<(f64, f64)> {
        let (sx, sy) = self.spacing()?;
        match self.model? {
            ModelType::Projected => {
                let unit = match self.linear_unit {
                    None => 1.0,
                    Some(code) => linear_unit_metres(code)?,
                };
                Some((sx * unit, sy * unit))
            }
            ModelType::Geographic => {
                let degrees = match self.angular_unit {
                    None => 1.0,
                    Some(code) => angular_unit_degrees(code)?,
                };
                let t = self.affine()?;
                if t.b != 0.0 || t.d != 0.0 {
                    return None;
                }
                // The centre of the row: half a texel down for PixelIsArea.
                let centre = match self.raster_type {
                    Some(RasterType::PixelIsPoint) => row,
                    _ => row + 0.5,
                };
                let latitude = (t.e * centre + t.f) * degrees;
                let (east, north) = metres_per_degree(latitude);
                Some((sx * degrees * east, sy * degrees * north))
            }
            _ => None,
        }
    }

    /// The height unit in metres (VerticalUnitsGeoKey), when given and
    /// known.
    #[must_use]
    pub fn vertical_unit_metres(&self) -> Option<f64> {
        linear_unit_metres(self.vertical_unit?)
    }
}

/// Metres in one EPSG linear unit: 9001 metre, 9002 international foot,
/// 9003 US survey foot, 9036 kilometre.
#[must_use]
pub fn linear_unit_metres(code: u16) -> Option<f64> {
    Some(match code {
        9001 => 1.0,
        9002 => 0.3048,
        9003 => 1200.0 / 3937.0,
        9036 => 1000.0,
        _ => return None,
    })
}

/// Degrees in one EPSG angular unit: 9102 degree, 9101 radian,
/// 9105 grad, 9104 arc-second, 9103 arc-minute.
fn angular_unit_degrees(code: u16) -> Option<f64> {
    Some(match code {
        9102 | 9122 => 1.0,
        9101 => 180.0 / std::f64::consts::PI,
        9105 => 0.9,
        9103 => 1.0 / 60.0,
        9104 => 1.0 / 3600.0,
        _ => return None,
    })
}

/// WGS84's semi-major axis in metres.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS84's flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;

/// The length in metres of one degree of longitude (east) and of latitude
/// (north) at `latitude` degrees, on the WGS84 ellipsoid:
///
/// * north: M(φ) · π/180, M = a(1 − e²) / (1 − e² sin²φ)^(3/2), the
///   meridional radius of curvature;
/// * east: N(φ) · cos φ · π/180, N = a / √(1 − e² sin²φ), the prime
///   vertical radius of curvature (N cos φ is the parallel's radius);
///
/// with e² = f(2 − f). These are the lengths of an infinitesimal step
/// scaled to one degree, the right measure for the spacing of neighbouring
/// texels (a whole degree's arc differs by under 1e-5 relative).
/// At the equator 111319.49 m east and 110574.28 m north; at 45°, 78846.84 m
/// and 111131.78 m (tests/integration/terrain_io.rs checks them against published tables
/// and the series expansions of both lengths).
#[must_use]
pub fn metres_per_degree(latitude: f64) -> (f64, f64) {
    let e2 = WGS84_F * (2.0 - WGS84_F);
    let phi = latitude.to_radians();
    let w2 = 1.0 - e2 * phi.sin().powi(2);
    let m = WGS84_A * (1.0 - e2) / (w2 * w2.sqrt());
    let n = WGS84_A / w2.sqrt();
    let per_radian = std::f64::consts::PI / 180.0;
    (n * phi.cos() * per_radian, m * per_radian)
}

/// The GeoKeys of a key directory (GeoTIFF 1.1 §7.1: a header of four
/// shorts, then four shorts per key: id, location, count, value). The keys
/// read here are SHORT values stored inline (location 0); those kept in
/// GeoDoubleParams or GeoAsciiParams (ellipsoid parameters, citations) are
/// not needed to place texels.
#[cfg(feature = "tiff")]
pub(crate) fn apply_key_directory(georef: &mut Georef, directory: &[u16]) -> Result<()> {
    let bad = |why: &str| Error::Decode(format!("GeoKeyDirectory tag: {why}"));
    let [version, _, _, count, ..] = *directory else {
        return Err(bad(&format!("{} values, a directory has at least 4", directory.len())));
    };
    if version != 1 {
        return Err(bad(&format!("version {version}, only version 1 exists")));
    }
    let entries = &directory[4..];
    if entries.len() < 4 * usize::from(count) {
        return Err(bad(&format!("{count} keys announced, room for {}", entries.len() / 4)));
    }
    let mut projected_code = false;
    for key in entries.chunks_exact(4).take(usize::from(count)) {
        let [id, location, _count, value] = [key[0], key[1], key[2], key[3]];
        // The keys read here are all SHORT values stored inline.
        if location != 0 {
            continue;
        }
        let code = |v: u16| (v != 0 && v != keys::USER_DEFINED).then_some(v);
        match id {
            keys::GT_MODEL_TYPE => {
                georef.model = Some(match value {
                    1 => ModelType::Projected,
                    2 => ModelType::Geographic,
                    3 => ModelType::Geocentric,
                    other => ModelType::Other(other),
                });
            }
            keys::GT_RASTER_TYPE => {
                georef.raster_type = Some(match value {
                    1 => RasterType::PixelIsArea,
                    2 => RasterType::PixelIsPoint,
                    other => RasterType::Other(other),
                });
            }
            // A projected raster's code is its projected system's; the
            // geographic system it is based on (its datum) is also given,
            // in either order, and must not replace it.
            keys::GEOGRAPHIC_TYPE if georef.model != Some(ModelType::Projected) && !projected_code => {
                georef.epsg = code(value).or(georef.epsg);
            }
            keys::PROJECTED_CS_TYPE => {
                if let Some(c) = code(value) {
                    georef.epsg = Some(c);
                    projected_code = true;
                }
            }
            keys::PROJ_LINEAR_UNITS => georef.linear_unit = code(value),
            keys::GEOG_ANGULAR_UNITS => georef.angular_unit = code(value),
            keys::VERTICAL_CS_TYPE => georef.vertical_epsg = code(value),
            keys::VERTICAL_UNITS => georef.vertical_unit = code(value),
            _ => {}
        }
    }
    Ok(())
}

/// The value that marks holes in a raster: the one given (the fit's
/// [`Options::nodata`](crate::Options::nodata), `--nodata V`), else the
/// GeoTIFF's GDAL_NODATA tag as read ([`Georef::nodata`], absent when
/// [`ReadOptions::nodata_tag`](crate::io::ReadOptions::nodata_tag) is
/// false), else none. The one rule of `convert` and `shade`, whole and
/// streamed.
pub(crate) fn holes_value(given: Option<f64>, georef: Option<&Georef>) -> Option<f64> {
    given.or_else(|| georef.and_then(|g| g.nodata))
}

/// GDAL_NODATA's text as a number: GDAL writes it with `%.18g` or as
/// "nan", "inf", "-inf"; spaces around it are allowed.
#[cfg(feature = "tiff")]
pub(crate) fn parse_nodata(text: &str) -> Result<f64> {
    let trimmed = text.trim_matches(|c: char| c.is_whitespace() || c == '\0');
    trimmed.parse::<f64>().map_err(|_| {
        Error::Decode(format!("GDAL_NODATA tag (42113) holds '{}', not a number", crate::error::one_line(trimmed)))
    })
}

/// The most values a georeferencing tag may hold, checked against the
/// count in the file's directory before a value is read: a count no
/// GeoTIFF has (a forged 2^31) is refused in one line, and never reaches
/// the TIFF decoder, which allocates by it (or, for a text tag, prints a
/// line of its own debug output to standard error before refusing it).
///
/// Pixel scale and transformation have fixed lengths; the key directory
/// holds at most 65535 keys of 4 shorts after its 4-short header, and the
/// double and text parameters are addressed by 16-bit offsets, so 65535
/// values are their most. Tiepoints have no bound in GeoTIFF: 65536 of
/// them (3 MiB) is far more than any control-point grid holds. GDAL writes
/// a nodata value in at most a few dozen characters.
#[cfg(feature = "tiff")]
pub(crate) fn most_values(code: u16) -> u64 {
    match code {
        tags::MODEL_PIXEL_SCALE => 3,
        tags::MODEL_TRANSFORMATION => 16,
        tags::MODEL_TIEPOINT => 6 * 65536,
        tags::GEO_KEY_DIRECTORY => 4 * 65536,
        tags::GDAL_NODATA => 1024,
        _ => 65535,
    }
}

/// Checks the lengths of the model tags and their values, and copies them
/// into `georef`: every value finite, and a pixel scale or transformation
/// that gives texels a size. A NaN tiepoint or a zero scale read as it is
/// would place every texel nowhere, or at one point, and be copied into
/// every output's georeferencing.
#[cfg(feature = "tiff")]
pub(crate) fn apply_model_tags(
    georef: &mut Georef,
    scale: Option<Vec<f64>>,
    tiepoints: Option<Vec<f64>>,
    transformation: Option<Vec<f64>>,
) -> Result<()> {
    let bad = |name: &str, n: usize, want: &str| {
        Error::Decode(format!("{name} tag holds {n} values, GeoTIFF gives it {want}"))
    };
    for (name, values) in
        [("ModelPixelScale", &scale), ("ModelTiepoint", &tiepoints), ("ModelTransformation", &transformation)]
    {
        let values = values.as_deref().unwrap_or_default();
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(Error::Decode(format!(
                "{name} tag: value {} of {} is {}: georeferencing must be finite",
                k + 1,
                values.len(),
                crate::error::Number(values[k])
            )));
        }
    }
    if let Some(s) = scale {
        match *s.as_slice() {
            [x, y, z] => georef.pixel_scale = Some([x, y, z]),
            // GDAL reads a two-value scale too (some writers leave Z out).
            [x, y] => georef.pixel_scale = Some([x, y, 0.0]),
            _ => return Err(bad("ModelPixelScale", s.len(), "3")),
        }
    }
    if let Some(t) = tiepoints {
        if t.is_empty() || t.len() % 6 != 0 {
            return Err(bad("ModelTiepoint", t.len(), "6 per tiepoint"));
        }
        georef.tiepoints = t.chunks_exact(6).map(|c| std::array::from_fn(|i| c[i])).collect();
    }
    if let Some(m) = transformation {
        if m.len() != 16 {
            return Err(bad("ModelTransformation", m.len(), "16"));
        }
        georef.transformation = Some(std::array::from_fn(|i| m[i]));
    }
    // Only the raster's own axes need a size: ScaleZ (heights) is 0 in
    // most files.
    if let Some([x, y, _]) = georef.pixel_scale
        && (x == 0.0 || y == 0.0)
    {
        let (x, y) = (crate::error::Number(x), crate::error::Number(y));
        return Err(Error::Decode(format!(
            "ModelPixelScale tag: a texel of {x} × {y} has no size: ScaleX and ScaleY must not be 0"
        )));
    }
    if let Some(m) = georef.transformation
        && m[0] * m[5] - m[1] * m[4] == 0.0
    {
        return Err(Error::Decode(
            "ModelTransformation tag: it maps the raster onto a line or a point (a·e − b·d = 0): texels have no area"
                .into(),
        ));
    }
    // A huge scale times a huge tiepoint's raster point: the texels' place
    // beyond f64's range.
    if let Some(t) = georef.affine()
        && ![t.a, t.b, t.c, t.d, t.e, t.f].iter().all(|v| v.is_finite())
    {
        return Err(Error::Decode(
            "ModelTiepoint and ModelPixelScale tags place the raster beyond the range of 64-bit floats".into(),
        ));
    }
    Ok(())
}
