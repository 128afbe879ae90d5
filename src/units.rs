//! Real-world units (docs/terrain.md): the texel spacing of a georeferenced
//! raster for a fit in map units ([`Units::Map`]), and the slope and aspect
//! of a normal in the GIS tools' conventions.
//!
//! A fit in map units takes the heights as they are stored (a DEM's
//! metres) and the texel centres as far apart as the ground says, so the
//! normal's slope is the terrain's: arctan of rise over run. Where the
//! spacing comes from:
//!
//! * a projected GeoTIFF: its pixel size ([`Georef::spacing_metres`]), the
//!   same for every row, x and y apart (a pixel is not always square);
//! * a geographic GeoTIFF (degrees): converted to metres at each row's
//!   latitude, so one spacing per row ([`Spacing::Rows`]); a texel's patch
//!   takes its centre row's;
//! * a caller's pixel size ([`MapSpacing::Given`]), for files without
//!   georeferencing (a PNG, a RAW heightmap).
//!
//! A GeoTIFF that states its heights' unit (VerticalUnitsGeoKey: feet, say)
//! gets its spacing in that unit, so rise and run are measured alike.

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::io::Georef;
use crate::io::read::georef::{ModelType, linear_unit_metres};
use crate::options::{Convention, Spacing, Units};

/// Where a fit in map units takes its texel spacing from.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum MapSpacing {
    /// The file's georeferencing (a GeoTIFF's pixel size or transform); a
    /// file without it is an error.
    FromFile,
    /// This spacing, in the heights' unit: `x` column to column, `y` row
    /// to row. The file's georeferencing, if any, is not read.
    Given {
        /// Column to column.
        x: f64,
        /// Row to row.
        y: f64,
    },
}

impl MapSpacing {
    /// The map units a front end asks for: `--units map` (`map`) and
    /// `--pixel-size X[,Y]` (`pixel_size`, which implies map units): the
    /// given size, else the file's; `None` for the contract's units.
    #[must_use]
    pub fn choose(units: crate::options::UnitsName, pixel_size: Option<[f64; 2]>) -> Option<MapSpacing> {
        match (units, pixel_size) {
            (_, Some([x, y])) => Some(MapSpacing::Given { x, y }),
            (crate::options::UnitsName::Map, None) => Some(MapSpacing::FromFile),
            (crate::options::UnitsName::Texels, None) => None,
        }
    }

    /// The units of a fit of a `height`-row raster with georeferencing
    /// `georef` (if any), in map units.
    ///
    /// Errors: those of [`map_spacing`] for [`MapSpacing::FromFile`], and
    /// [`Error::Unsupported`] when the spacing it gives is out of range;
    /// [`Error::InvalidOption`] for a given spacing that is not finite and
    /// positive.
    pub fn units(&self, georef: Option<&Georef>, height: usize) -> Result<Units> {
        let spacing = match *self {
            MapSpacing::Given { x, y } => {
                let spacing = Spacing::Uniform { x, y };
                spacing.validate(Some(height))?;
                spacing
            }
            MapSpacing::FromFile => {
                let spacing = map_spacing(georef, height)?;
                // The file's tags, not the caller's option, are at fault.
                spacing.validate(Some(height)).map_err(|e| match e {
                    Error::InvalidOption(m) => Error::Unsupported(format!("the file's georeferencing: {m}")),
                    other => other,
                })?;
                spacing
            }
        };
        Ok(Units::Map(spacing))
    }
}

/// A pixel size as front ends take it: `X` (square) or `X,Y` (x column to
/// column, y row to row), each finite and positive.
///
/// Errors: [`Error::InvalidOption`] naming the text.
pub fn parse_pixel_size(text: &str) -> Result<[f64; 2]> {
    let number = |t: &str| t.trim().parse::<f64>().ok().filter(|v| v.is_finite() && *v > 0.0);
    let parsed = match text.split_once(',') {
        None => number(text).map(|v| [v, v]),
        Some((x, y)) => number(x).zip(number(y)).map(|(x, y)| [x, y]),
    };
    parsed.ok_or_else(|| {
        Error::InvalidOption(format!(
            "pixel size '{}' is not X or X,Y with finite positive numbers (10, or 30,20)",
            crate::error::one_line(text)
        ))
    })
}

/// The texel spacing of a georeferenced raster of `height` rows, in its
/// heights' unit (metres unless VerticalUnitsGeoKey says otherwise):
///
/// * projected: the pixel size times the linear unit, one for every row;
/// * geographic: the pixel size in degrees turned into metres at each
///   row's latitude ([`Georef::spacing_metres`]), one per row;
/// * no model type given (a TIFF with a pixel scale and no GeoKeys): the
///   pixel size as it is, in the model's unit.
///
/// Errors ([`Error::Unsupported`], one line each): no georeferencing, or no
/// transform in it; a rotated or sheared raster (its rows do not run east);
/// a geocentric or unknown model; a linear, angular or vertical unit whose
/// EPSG code is not known.
pub fn map_spacing(georef: Option<&Georef>, height: usize) -> Result<Spacing> {
    let unsupported = |why: String| Error::Unsupported(why);
    let no_spacing = || {
        unsupported(
            "map units need the texel spacing, and the file has no georeferencing (GeoTIFF ModelPixelScale or \
             ModelTransformation tags): give the pixel size"
                .into(),
        )
    };
    let georef = georef.ok_or_else(no_spacing)?;
    let affine = georef.affine().ok_or_else(no_spacing)?;
    if affine.b != 0.0 || affine.d != 0.0 {
        return Err(unsupported(turned(&affine)));
    }
    // Metres per height unit: the spacing is given in the heights' unit.
    let vertical = match georef.vertical_unit {
        None => 1.0,
        Some(code) => linear_unit_metres(code).ok_or_else(|| {
            unsupported(format!("the heights' unit (EPSG {code}, VerticalUnitsGeoKey) is not a known length"))
        })?,
    };
    let in_height_units = |[x, y]: [f64; 2]| [x / vertical, y / vertical];
    match georef.model {
        None => {
            let (x, y) = georef.spacing().ok_or_else(no_spacing)?;
            Ok(Spacing::Uniform { x, y })
        }
        Some(ModelType::Projected) => {
            let (x, y) = georef.spacing_metres(0.0).ok_or_else(|| {
                let code = georef.linear_unit.map_or("none".into(), |c| c.to_string());
                unsupported(format!("the map's linear unit (EPSG {code}, ProjLinearUnitsGeoKey) is not known"))
            })?;
            let [x, y] = in_height_units([x, y]);
            Ok(Spacing::Uniform { x, y })
        }
        Some(ModelType::Geographic) => {
            let mut rows = Vec::new();
            rows.try_reserve_exact(height).map_err(|_| Error::Limits(format!("{height} rows of spacing")))?;
            for row in 0..height {
                let (x, y) = georef.spacing_metres(row as f64).ok_or_else(|| {
                    let code = georef.angular_unit.map_or("none".into(), |c| c.to_string());
                    unsupported(format!("the map's angular unit (EPSG {code}, GeogAngularUnitsGeoKey) is not known"))
                })?;
                rows.push(in_height_units([x, y]));
            }
            Ok(Spacing::Rows(Arc::from(rows)))
        }
        Some(other) => Err(unsupported(format!(
            "map units take projected or geographic rasters, this one's model is {} (GTModelTypeGeoKey)",
            other.name()
        ))),
    }
}

/// What the coordinates of a raster known by its transform alone measure
/// (an xarray DataArray's, whose CRS rioxarray holds): the GeoKeys a
/// GeoTIFF would carry, given by a caller that is not reading a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Crs {
    /// No coordinate system: the step is taken as it is, in the heights'
    /// unit (a GeoTIFF with a pixel scale and no GeoKeys).
    Unknown,
    /// Projected coordinates in this EPSG linear unit (9001 metre, 9002
    /// foot, 9003 US survey foot, 9036 kilometre).
    Projected {
        /// The EPSG code of the unit.
        unit: u16,
    },
    /// Longitude and latitude in this EPSG angular unit (9102 or 9122
    /// degree, 9101 radian, …).
    Geographic {
        /// The EPSG code of the unit.
        unit: u16,
    },
}

/// The texel spacing of a raster of `height` rows whose GDAL geotransform
/// is `transform` (x of the first texel's corner, x per column, x per
/// row, y of that corner, y per column, y per row: rioxarray's and
/// rasterio's transform in GDAL's order) in `crs`, in metres: the rule of
/// [`map_spacing`] on a GeoTIFF with that transform and those GeoKeys
/// (PixelIsArea), so an array's spacing is the command line's on the same
/// file, bit for bit (a geographic raster's one per row).
///
/// Errors: those of [`MapSpacing::units`] from a file: a rotated or
/// sheared transform (naming its angle), an unknown unit, a spacing that
/// is not finite and positive ([`Error::Unsupported`]).
pub fn geotransform_spacing(transform: [f64; 6], crs: Crs, height: usize) -> Result<Spacing> {
    let [c, a, b, f, d, e] = transform;
    let mut georef = Georef {
        transformation: Some([a, b, 0.0, c, d, e, 0.0, f, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
        raster_type: Some(crate::io::read::georef::RasterType::PixelIsArea),
        ..Georef::default()
    };
    match crs {
        Crs::Unknown => {}
        Crs::Projected { unit } => {
            georef.model = Some(ModelType::Projected);
            georef.linear_unit = Some(unit);
        }
        Crs::Geographic { unit } => {
            georef.model = Some(ModelType::Geographic);
            georef.angular_unit = Some(unit);
        }
    }
    match MapSpacing::FromFile.units(Some(&georef), height)? {
        Units::Map(spacing) => Ok(spacing),
        Units::Texels => Err(Error::Unsupported("map units gave no spacing".into())),
    }
}

/// The GDAL geotransform (see [`geotransform_spacing`]) of a north-up
/// raster whose texel centres are at `x` (one per column) and `y` (one
/// per row), as an xarray DataArray's coordinates hold them: each axis's
/// step is its mean, (last − first) / (n − 1), and every step between
/// neighbours must be within 1e-6 of it relative (plus the rounding of
/// f64 coordinates of that size): a grid whose texels are not equally
/// spaced has no one spacing to fit with.
///
/// Errors ([`Error::InvalidOption`], one line): an axis of fewer than 2
/// coordinates, a coordinate that is not finite, a step of 0, or steps
/// that differ (naming the first that does).
pub fn centres_geotransform(x: &[f64], y: &[f64]) -> Result<[f64; 6]> {
    let step = |name: &str, c: &[f64]| -> Result<f64> {
        let bad = |why: String| Error::InvalidOption(format!("the {name} coordinates {why}"));
        let (Some(&first), Some(&last)) = (c.first(), c.last()) else {
            return Err(bad("are empty: the spacing needs 2 of them".into()));
        };
        if c.len() < 2 {
            return Err(bad("are one: the spacing needs 2 of them (give the pixel size)".into()));
        }
        if let Some(i) = c.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!("hold {} at index {i}", crate::error::Number(c[i]))));
        }
        let mean = (last - first) / (c.len() - 1) as f64;
        if mean == 0.0 || !mean.is_finite() {
            return Err(bad("do not advance: their step is 0".into()));
        }
        // f64 coordinates of this size hold their step to about an ulp of
        // the largest; beyond that, and beyond 1e-6 of the step, the grid
        // is not regular.
        let largest = c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let tolerance = 1e-6 * mean.abs() + 8.0 * f64::EPSILON * largest;
        if let Some(i) = c.windows(2).position(|w| ((w[1] - w[0]) - mean).abs() > tolerance) {
            return Err(bad(format!(
                "are not equally spaced: from index {i} to {} the step is {}, the mean step is {}; a fit needs \
                 one spacing (resample the grid, or give the pixel size)",
                i + 1,
                crate::error::Number(c[i + 1] - c[i]),
                crate::error::Number(mean)
            )));
        }
        Ok(mean)
    };
    let (sx, sy) = (step("x", x)?, step("y", y)?);
    // The first texel's corner: half a step before its centre.
    Ok([x[0] - sx / 2.0, sx, 0.0, y[0] - sy / 2.0, 0.0, sy])
}

/// Why a raster whose transform has terms b or d is refused, naming how
/// it is turned: the angle of its rows from the map's x axis, and for a
/// sheared one the angle its rows and columns make. Map units take
/// north-up rasters: the spacing and the sun's azimuth of a turned one
/// would be in its own frame, not the map's.
fn turned(affine: &crate::io::read::georef::Affine) -> String {
    let (column, row) = ((affine.a, affine.d), (affine.b, affine.e));
    // The row direction's angle from the map's x axis (a row runs along
    // increasing columns), counter-clockwise as the map's axes turn.
    let rotation = column.1.atan2(column.0).to_degrees();
    let cos = (column.0 * row.0 + column.1 * row.1) / (column.0.hypot(column.1) * row.0.hypot(row.1));
    let between = cos.clamp(-1.0, 1.0).acos().to_degrees();
    let how = if (between - 90.0).abs() > 1e-6 {
        format!("sheared (its rows and columns meet at {between:.3}°, not 90°)")
    } else {
        let sense = if rotation > 0.0 { "counter-clockwise" } else { "clockwise" };
        format!("rotated {:.3}° {sense} from north-up", rotation.abs())
    };
    format!(
        "the raster is {how}: its transform has b = {} and d = {} where a north-up raster has 0: map units take \
         north-up rasters; warp it first (gdalwarp), or give the pixel size to fit it in its own frame",
        crate::error::Number(affine.b),
        crate::error::Number(affine.d)
    )
}

pub(crate) use crate::fit::MapAxes;

impl MapAxes {
    /// Normal `n` of a fit in `convention` as (east, north, up): OpenGL's
    /// components on a north-up raster. The north-up axes give `n`'s own
    /// bits back (times 1, or −1 for DirectX's y).
    #[inline(always)]
    pub(crate) fn to_map(self, [x, y, up]: [f64; 3], convention: Convention) -> [f64; 3] {
        let y = match convention {
            Convention::OpenGl => y,
            Convention::DirectX => -y,
        };
        let MapAxes { x: (xe, xn), up: (ye, yn) } = self;
        if xn == 0.0 && ye == 0.0 {
            // Axes along the map's (the only ones map units take): a sign
            // each, exact.
            [x * xe, y * yn, up]
        } else {
            [x * xe + y * ye, x * xn + y * yn, up]
        }
    }
}

/// A surface's slope and aspect at a texel, as GIS tools give them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlopeAspect {
    /// The angle between the surface and the horizontal, in degrees
    /// (0 flat, 90 vertical): arctan of rise over run for a fit in map
    /// units ([`Units::Map`]).
    pub slope: f64,
    /// The compass direction the slope faces (downhill), in degrees
    /// clockwise from north (0 north, 90 east, 180 south, 270 west), as
    /// `gdaldem aspect` gives it; `None` where the surface is flat (GDAL
    /// writes −9999 there by default).
    pub aspect: Option<f64>,
}

/// The slope and aspect of unit normal `n` from a fit in `convention`, for a
/// raster whose rows run east and whose row 0 is north (a north-up raster,
/// as GeoTIFFs almost always are). The normal's +x is east; its +y is
/// north in OpenGL's convention and south in DirectX's.
///
/// ```
/// use normalfit::Convention;
/// use normalfit::units::slope_aspect;
/// // A surface falling to the east at 45°: its normal leans east.
/// let n = [0.5f64.sqrt(), 0.0, 0.5f64.sqrt()];
/// let s = slope_aspect(n, Convention::OpenGl);
/// assert!((s.slope - 45.0).abs() < 1e-12 && (s.aspect.unwrap() - 90.0).abs() < 1e-12);
/// assert_eq!(slope_aspect([0.0, 0.0, 1.0], Convention::OpenGl).aspect, None);
/// ```
#[must_use]
pub fn slope_aspect(n: [f64; 3], convention: Convention) -> SlopeAspect {
    let [east, y, up] = n;
    let north = match convention {
        Convention::OpenGl => y,
        Convention::DirectX => -y,
    };
    let slope = slope_degrees(east, north, up);
    // The normal leans downhill: its horizontal part is the aspect.
    let aspect = leans(east, north).then(|| aspect_degrees(east, north));
    SlopeAspect { slope, aspect }
}

/// The slope, in degrees, of a normal whose horizontal parts are `east`
/// and `north`: arctan of the horizontal length over `up`. The length is
/// √(e² + n²) rather than libm's `hypot`, which guards against overflow
/// (not needed for normals of length near 1) at a tenth of a slope map's
/// time; its one rounding moves the angle by under 1e-15 rad.
#[inline(always)]
fn slope_degrees(east: f64, north: f64, up: f64) -> f64 {
    atan2((east * east + north * north).sqrt(), up).to_degrees()
}

/// Whether a normal leans at all: a horizontal part that is not zero (a
/// NaN one does not: its aspect is a flat texel's).
#[inline(always)]
fn leans(east: f64, north: f64) -> bool {
    !(east.is_nan() || north.is_nan()) && (east != 0.0 || north != 0.0)
}

/// The aspect in degrees clockwise from north, in [0, 360], of a normal
/// leaning `east` and `north` (not both zero).
#[inline(always)]
fn aspect_degrees(east: f64, north: f64) -> f64 {
    let a = atan2(east, north).to_degrees();
    if a < 0.0 { a + 360.0 } else { a }
}

/// tan(π/8): above it, atan(t) is π/4 + atan((t − 1)/(t + 1)), whose
/// argument is again within ±tan(π/8).
const TAN_PI_8: f64 = 0.414_213_562_373_095_03;

/// atan(u) / u as a polynomial in s = u², for |u| ≤ tan(π/8): Chebyshev
/// interpolation of degree 10 on [0, tan²(π/8)] (200 nodes), turned into
/// powers of s, lowest first. Its error, with Horner's roundings, is
/// within 3.4e-16 of atan over a sweep of 2 million points of u
/// (`atan2_matches_libm` in tests/integration/products.rs measures the
/// whole [`atan2`] against libm).
const ATAN: [f64; 11] = [
    1.0,
    -0.333_333_333_333_298_5,
    0.199_999_999_992_553_1,
    -0.142_857_142_162_274_66,
    0.111_111_076_958_758_37,
    -0.090_908_098_524_097_29,
    0.076_904_905_482_391_96,
    -0.066_450_427_623_661_56,
    0.057_141_674_933_940_84,
    -0.044_242_839_617_617_38,
    0.022_086_473_948_729_576,
];

/// atan2(y, x) in radians, as libm's within 2e-15 (4e-13° after the turn
/// into degrees: far inside the 1e-9° the products promise; measured
/// against libm by `atan2_matches_libm`), and libm's in every special
/// case: ±0 and the signs of zero, infinities (atan2(±∞, ±∞) is ±π/4 or
/// ±3π/4), NaN. Branch-free, so that a loop of it vectorises: libm's
/// atan2 was most of a slope or aspect map's processor time. The ratio of
/// the smaller part over the larger is reduced to ±tan(π/8) by the
/// tangent of a difference, then [`ATAN`] gives the arctangent; the
/// octant puts it back.
#[inline(always)]
pub(crate) fn atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = (ax.min(ay), ax.max(ay));
    // The ratio t = small / large, or above tan(π/8) (t − 1)/(t + 1)
    // as (small − large)/(small + large): one division either way.
    let reduced = large != 0.0 && (small > TAN_PI_8 * large || small == large);
    let (num, den) = if reduced { (small - large, small + large) } else { (small, large) };
    // 0/0 is the angle 0 (libm: ±0 or ±π by the signs); equal parts (∞/∞
    // too) are π/4.
    let u = if large == 0.0 || small == large { 0.0 } else { num / den };
    let s = u * u;
    let mut p = ATAN[10];
    for c in ATAN[..10].iter().rev() {
        p = p * s + c;
    }
    let mut r = if reduced { FRAC_PI_4 + u * p } else { u * p };
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x.is_sign_negative() {
        r = PI - r;
    }
    if x.is_nan() || y.is_nan() { f64::NAN } else { r.copysign(y) }
}

/// gdaldem's nodata value of a slope or an aspect map (its `-9999`): the
/// value of a hole, and an aspect's where the surface is flat.
pub const NODATA: f32 = -9999.0;

/// What a slope or an aspect map holds at each texel: a number of the
/// plane fitted over its patch (docs/products.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Measure {
    /// The slope ([`SlopeAspect::slope`]), in degrees, or in percent (100 ·
    /// rise over run, `gdaldem slope -p`).
    Slope(crate::options::SlopeUnits),
    /// The aspect ([`SlopeAspect::aspect`]), degrees clockwise from north
    /// in [0, 360); where the plane is flat, [`NODATA`] as gdaldem writes,
    /// or 0 with `zero_for_flat` (`gdaldem aspect -zero_for_flat`).
    Aspect {
        /// A flat texel's aspect is 0, not [`NODATA`].
        zero_for_flat: bool,
    },
}

impl Measure {
    /// The measure of unit normal `n` of a fit in `convention` (see
    /// [`slope_aspect`]), as the map stores it. A normal need not be unit
    /// length: both numbers are ratios of its components (the slope's
    /// horizontal length √(x² + y²) holds while x² + y² is a normal f64).
    ///
    /// ```
    /// use normalfit::{Convention, SlopeUnits};
    /// use normalfit::units::{Measure, NODATA};
    /// // Rising 1 in 2 to the north: it faces south, 26.565° or 50 %.
    /// let n = [0.0, -1.0, 2.0];
    /// let (gl, degrees) = (Convention::OpenGl, Measure::Slope(SlopeUnits::Degrees));
    /// assert!((degrees.of(n, gl) - 26.565051).abs() < 1e-5);
    /// assert_eq!(Measure::Slope(SlopeUnits::Percent).of(n, gl), 50.0);
    /// assert_eq!(Measure::Aspect { zero_for_flat: false }.of(n, gl), 180.0);
    /// assert_eq!(Measure::Aspect { zero_for_flat: false }.of([0.0, 0.0, 1.0], gl), NODATA);
    /// assert_eq!(Measure::Aspect { zero_for_flat: true }.of([0.0, 0.0, 1.0], gl), 0.0);
    /// ```
    #[must_use]
    #[inline(always)]
    pub fn of(self, n: [f64; 3], convention: Convention) -> f32 {
        use crate::options::SlopeUnits;
        let [east, y, up] = n;
        let north = match convention {
            Convention::OpenGl => y,
            Convention::DirectX => -y,
        };
        match self {
            Measure::Slope(SlopeUnits::Degrees) => slope_degrees(east, north, up) as f32,
            // tan of the slope, without the round trip through the angle.
            Measure::Slope(SlopeUnits::Percent) => (100.0 * (east * east + north * north).sqrt() / up) as f32,
            Measure::Aspect { zero_for_flat } => {
                if leans(east, north) {
                    // An angle just below 360 can round to it: gdaldem
                    // makes that 0 too, so that the range is [0, 360).
                    let a = aspect_degrees(east, north) as f32;
                    if a < 360.0 { a } else { 0.0 }
                } else if zero_for_flat {
                    0.0
                } else {
                    NODATA
                }
            }
        }
    }
}

/// A slope map's texel, made by the fit in its own loop over a row (the
/// row's normals still in the core's cache) rather than from a band of
/// normals stored and read back: 4 bytes a texel where the `f64` normal
/// took 24, and no pass of its own. A slope is a ratio of the normal's
/// components, so the square grid's fit leaves its normalisation out
/// ([`crate::fit::FromNormal::UNIT`]); the ratio, and the angle, are the unit
/// normal's within an ulp of `f64`. It needs neither the convention nor
/// the raster's axes: turning or mirroring the map's axes keeps
/// √(x² + y²) (a mirror, bit for bit).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct SlopeTexel<const PERCENT: bool>(f32);

impl<const PERCENT: bool> crate::fit::FromNormal for SlopeTexel<PERCENT> {
    const UNIT: bool = false;
    #[inline(always)]
    fn from_normal(n: [f64; 3]) -> Self {
        use crate::options::SlopeUnits;
        let units = if PERCENT { SlopeUnits::Percent } else { SlopeUnits::Degrees };
        SlopeTexel(Measure::Slope(units).of(n, Convention::OpenGl))
    }
}

/// An aspect map's texel, made by the fit in its own loop over a row, as
/// [`SlopeTexel`] is, from the normal leaning (east, north) in the map:
/// the raster's axes and the convention ([`crate::fit::TexelFrame`])
/// turn the fit's normal into the map's, exactly (a sign each) on a
/// raster whose rows run east or west. An aspect is the angle of the
/// normal's horizontal part, a ratio of its components, so the fit leaves
/// the normalisation out, as for a slope.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct AspectTexel<const ZERO_FOR_FLAT: bool>(f32);

impl<const ZERO_FOR_FLAT: bool> crate::fit::Texel for AspectTexel<ZERO_FOR_FLAT> {
    const UNIT: bool = false;
    #[inline(always)]
    fn make(n: [f64; 3], frame: &crate::fit::TexelFrame) -> Self {
        let aspect = Measure::Aspect { zero_for_flat: ZERO_FOR_FLAT };
        AspectTexel(aspect.of(frame.axes.to_map(n, frame.convention), Convention::OpenGl))
    }
}

/// What the fit makes at each texel of a slope or an aspect map
/// ([`Measure::with_texel`] says which): the map's value itself.
pub(crate) trait MeasureTexel: crate::fit::Texel + Default + Send {
    /// The map's value of the texel.
    fn value(self) -> f32;
}

impl<const PERCENT: bool> MeasureTexel for SlopeTexel<PERCENT> {
    #[inline(always)]
    fn value(self) -> f32 {
        self.0
    }
}

impl<const ZERO_FOR_FLAT: bool> MeasureTexel for AspectTexel<ZERO_FOR_FLAT> {
    #[inline(always)]
    fn value(self) -> f32 {
        self.0
    }
}

/// A computation over a measure's texels, generic in their type: what
/// [`Measure::with_texel`] runs.
pub(crate) trait WithTexel {
    type Output;
    fn run<T: MeasureTexel>(self) -> Self::Output;
}

impl Measure {
    /// Runs `work` with the texel the fit makes for this measure, in its
    /// own loop: the slope ([`SlopeTexel`]) or the aspect
    /// ([`AspectTexel`], which needs the fit told the raster's axes). The
    /// one choice of every slope or aspect map, streamed, whole or in
    /// memory.
    pub(crate) fn with_texel<W: WithTexel>(self, work: W) -> W::Output {
        use crate::options::SlopeUnits;
        match self {
            Measure::Slope(SlopeUnits::Degrees) => work.run::<SlopeTexel<false>>(),
            Measure::Slope(SlopeUnits::Percent) => work.run::<SlopeTexel<true>>(),
            Measure::Aspect { zero_for_flat: false } => work.run::<AspectTexel<false>>(),
            Measure::Aspect { zero_for_flat: true } => work.run::<AspectTexel<true>>(),
        }
    }
}
